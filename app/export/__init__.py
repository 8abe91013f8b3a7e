"""Exports of recorded trials: MCAP for Foxglove, NDH/LDH JSON in the benchmark's schema."""
