"""``pyrobot.locobot.gripper``: the gripper class (Ferrobot's :class:`ferrobot.Gripper`)."""

from .._native import Gripper as LoCoBotGripper

__all__ = ["LoCoBotGripper"]
