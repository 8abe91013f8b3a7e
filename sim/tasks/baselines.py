"""The NDH baseline Drivers: Immediate Stop, Random and Shortest path (`sim.tasks.evaluation` plays
them as one batch; the tests hold it against each played one pose at a time)."""

BASELINES = ("stop", "random", "shortest")
