"""``pyrobot.locobot.bicycle_model``'s angle helper."""

import numpy as np


def wrap_theta(theta):
    """``theta`` (rad, scalar or array) wrapped to [-pi, pi)."""
    return np.mod(np.asarray(theta) + np.pi, 2 * np.pi) - np.pi


__all__ = ["wrap_theta"]
