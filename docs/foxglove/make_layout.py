"""Writes robotslang-layout.json beside this file with the foxglove-sdk's typed layout API:
`python docs/foxglove/make_layout.py` (needs `pip install foxglove-sdk==0.30.3`)."""

from pathlib import Path

import foxglove.layouts as fl

POSE_COLOURS = {
    "/robot/pose/sim": "#1f77b4",
    "/robot/pose/tracker": "#2ca02c",
    "/robot/pose/annotated": "#9467bd",
    "/commander/estimate": "#ff7f0e",
}

camera = fl.ImagePanel(
    title="Driver camera", config=fl.ImageConfig(image_mode=fl.ImageModeConfig(image_topic="/driver/camera"))
)
scene = fl.ThreeDeePanel(
    title="Maze (table frame)",
    config=fl.ThreeDeeConfig(
        follow_tf="table",
        topics={
            "/maze/scene": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
            **{
                topic: fl.BaseRendererPoseTopicSettings(
                    visible=True, type="arrow", color=colour, arrow_scale=(0.12, 0.03, 0.03)
                )
                for topic, colour in POSE_COLOURS.items()
            },
        },
    ),
)
chat = fl.LogPanel(title="Dialog", config=fl.LogConfig(topic_to_render="/chat", show_name=True))
moves = fl.PlotPanel(
    title="Moves and position",
    config=fl.PlotConfig(
        show_legend=True,
        paths=[
            fl.PlotSeries(
                value="/driver/cmd.move_id",
                label="move id",
                line_interpolation="step",
                timestamp_method="receiveTime",
                enabled=True,
            ),
            fl.PlotSeries(
                value="/robot/pose/sim.pose.position.x", label="x (m)", timestamp_method="receiveTime", enabled=True
            ),
            fl.PlotSeries(
                value="/robot/pose/sim.pose.position.y", label="y (m)", timestamp_method="receiveTime", enabled=True
            ),
        ],
    ),
)
events = fl.RawMessagesPanel(title="Trial events", config=fl.RawMessagesConfig(topic_path="/trial/event"))

layout = fl.Layout(
    content=fl.SplitContainer(
        direction="row",
        items=[
            fl.SplitItem(
                proportion=1,
                content=fl.SplitContainer(
                    direction="column",
                    items=[fl.SplitItem(proportion=1, content=camera), fl.SplitItem(proportion=1, content=chat)],
                ),
            ),
            fl.SplitItem(
                proportion=1.4,
                content=fl.SplitContainer(
                    direction="column",
                    items=[
                        fl.SplitItem(proportion=2, content=scene),
                        fl.SplitItem(proportion=1, content=moves),
                        fl.SplitItem(proportion=0.7, content=events),
                    ],
                ),
            ),
        ],
    )
)

if __name__ == "__main__":
    out = Path(__file__).with_name("robotslang-layout.json")
    out.write_text(layout.to_json() + "\n")
    print(out)
