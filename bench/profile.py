"""Where the server's time goes: a py-spy speedscope profile (`bench.load --profile FILE.json`)
summed into the hot path's parts, per thread kind (the event loop, the render/file threads).

    python -m bench.profile var/load.json
"""

from __future__ import annotations

import argparse
import collections
import json

# (part, a frame that puts a sample in it); the first part whose frame is on the stack wins.
PARTS = [
    ("commit (EventLog's group commit)", ("_commit", "app/trial/log.py")),
    ("event log queueing (EventLog.append)", ("append", "app/trial/log.py")),
    ("history load (EventLog.load)", ("load", "app/trial/log.py")),
    ("validation (pydantic + token)", ("read_message", "app/routes/seat_ws.py")),
    ("decide", ("decide", "app/trial/decide.py")),
    ("fold (TrialState.apply_event)", ("apply_event", "app/trial/state.py")),
    ("views + status", ("app/trial/views.py",)),
    ("JSON encode", ("json/encoder.py",)),
    ("JSON decode (relay)", ("json/decoder.py",)),
    ("websocket send", ("send", "websockets_sansio_impl.py")),
    ("websocket receive", ("receive", "websockets_sansio_impl.py")),
    ("particle filter (TrialBelief)", ("app/perception/belief.py",)),
    ("simulator rays (SimulatorBackend.frame_at)", ("cast_rays", "sim/core/observations.py")),
    ("render (first_person)", ("first_person", "sim/robot/render.py")),
    ("JPEG encode", ("render_jpeg", "app/backends/render.py")),
    ("frame file write", ("write", "app/trial/frames_store.py")),
    ("base64 of frames", ("b64encode", "base64.py")),
    ("redis relay", ("app/trial/relay.py",)),
    ("mazes and graphs loaded (trial start)", ("app/mazes.py",)),
    ("other app code", ("/app/",)),
]
NOT_HOT = ("app/cli.py", "app/commands.py", "app/serving.py")  # on every stack: the server's start
# A thread with nothing to do: its leaf is one of these waits, in one of these files.
RECEIVES = {"_recv", "_recv_bytes", "recv_bytes"}
IDLE_LEAVES = {"run", "wait", "select", "poll", "_worker", "get", "__enter__", "acquire", *RECEIVES}
IDLE_FILES = ("threading.py", "runners.py", "thread.py", "queue.py", "connection.py", "synchronize.py")
# (leaf, file) of threads that only wait: a render process watching for its server's death, and
# multiprocessing's resource tracker (a process of its own, which py-spy counts with the render processes)
WAITERS = {("_exit_with", "app/backends/render.py"), ("main", "multiprocessing/resource_tracker.py")}


def idle(leaf: dict) -> bool:
    name, where = leaf["name"], leaf.get("file", "")
    if any(name == n and where.endswith(w) for n, w in WAITERS):
        return True
    return name in IDLE_LEAVES and any(f in where for f in IDLE_FILES)


def matches(frame: dict, pattern: tuple[str, ...]) -> bool:
    where = frame.get("file", "")
    if len(pattern) == 1:
        return pattern[0] in where and not where.endswith(NOT_HOT)
    return frame["name"] == pattern[0] and where.endswith(pattern[1])


def summarize(path: str) -> dict[str, dict[str, float]]:
    with open(path) as f:
        data = json.load(f)
    frames = data["shared"]["frames"]
    out: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    for profile in data["profiles"]:
        # py-spy roots a child's stacks in its parent's: the render processes' say `multiprocessing`.
        spawned = any(
            "from multiprocessing" in frames[i]["name"] for stack in profile["samples"][:1] for i in stack[:2]
        )
        kind = "render processes" if spawned else "event loop" if '"MainThread"' in profile["name"] else "threads"
        for stack, weight in zip(profile["samples"], profile["weights"]):
            if not stack:
                continue
            leaf = frames[stack[-1]]
            if idle(leaf):
                out[kind]["idle"] += weight
                continue
            part = next(
                (name for name, pattern in PARTS if any(matches(frames[i], pattern) for i in stack)),
                "framework (uvicorn, starlette, asyncio)" if kind == "event loop" else "other",
            )
            out[kind][part] += weight
    return {kind: dict(parts) for kind, parts in out.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("profile")
    args = parser.parse_args()
    for kind, parts in summarize(args.profile).items():
        busy = sum(v for k, v in parts.items() if k != "idle")
        print(f"{kind}: {busy:.1f} s busy of {busy + parts.get('idle', 0):.1f} s sampled")
        for part, seconds in sorted(parts.items(), key=lambda kv: -kv[1]):
            if part != "idle":
                print(f"  {part:42s} {seconds:7.2f} s  {100 * seconds / busy:5.1f} %")


if __name__ == "__main__":
    main()
