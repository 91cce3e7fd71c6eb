"""``pyrobot.locobot.base``: the base class (Ferrobot's :class:`ferrobot.Base`)."""

from .._native import Base as LoCoBotBase

__all__ = ["LoCoBotBase"]
