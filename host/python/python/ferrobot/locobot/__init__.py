"""PyRobot's LoCoBot module layout (``pyrobot.locobot.*``), so that PyRobot's imports resolve
with ``pyrobot`` changed to ``ferrobot``. The classes are Ferrobot's, for every robot."""
