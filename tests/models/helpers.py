"""Result rows for the report's tests."""

from __future__ import annotations

from sim.core.metrics import EpisodeResult


def rows(split, agent, tds, seed=0):
    return [
        EpisodeResult(
            split=split,
            inst_idx=k,
            agent=agent,
            seed=seed,
            start_x=0,
            start_y=0,
            start_heading=0,
            goal_x=0,
            goal_y=0,
            td=float(td),
            otd=float(td) * 0.9,
            steps=10,
            success=td < 0.5,
            spl=0.5 if td < 0.5 else 0.0,
        )
        for k, td in enumerate(tds)
    ]
