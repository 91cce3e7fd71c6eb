"""``pyrobot.locobot.camera``: the camera classes (Ferrobot's :class:`ferrobot.Camera`, which
has both PyRobot's ``SimpleCamera`` calls and ``LoCoBotCamera``'s pan and tilt)."""

from .._native import Camera as LoCoBotCamera

SimpleCamera = LoCoBotCamera

__all__ = ["LoCoBotCamera", "SimpleCamera"]
