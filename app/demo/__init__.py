"""Scripted demo trials: a Commander and a Driver played by scripts over the trial sockets."""
