"""Exports of recorded trials: MCAP for Foxglove, NDH/LDH JSON in the benchmark's schema."""

from enum import StrEnum


class Episode(StrEnum):
    """What one exported LeRobot episode holds: an NDH instance, or a whole trial. Here, not in
    `app.export.lerobot`, so that the CLI declares its option without importing the exporter."""

    ndh = "ndh"
    trial = "trial"
