"""``pyrobot.locobot.arm``: the arm class (Ferrobot's :class:`ferrobot.Arm`)."""

from .._native import Arm as LoCoBotArm

__all__ = ["LoCoBotArm"]
