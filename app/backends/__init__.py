"""Robot backends: what fills the robot seat of a trial (the simulator, or the rover)."""
