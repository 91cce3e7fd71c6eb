"""``pyrobot.utils``: PyRobot's helpers that programs import."""
