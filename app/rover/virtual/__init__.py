"""The software rover: `robot_client`'s real networking with simulated motors and cameras.

`truth` is the side file of true poses (for test harnesses only), `devices` the simulated
motors and cameras that plug into `robot_client`, `command` the `robotslang robot virtual` runner.
"""
