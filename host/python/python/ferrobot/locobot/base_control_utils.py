"""``pyrobot.locobot.base_control_utils``: the base trajectories PyRobot's programs build for
``bot.base.track_trajectory``, made by Ferrobot's references (Rust, ``ferrobot-control``).

States are ``[x, y, theta]`` (m, m, rad), controls ``[v, w]`` (m/s, rad/s), one sample every
``dt`` s; a trajectory of ``n`` controls has ``n + 1`` states, the first the start.
"""

from __future__ import annotations

import numpy as np

from .._native import base_reference, circle_reference
from .bicycle_model import wrap_theta

__all__ = [
    "get_trajectory_circle",
    "get_trajectory_negcircle",
    "position_control_init_fn",
    "_get_absolute_pose",
    "wrap_theta",
]


def _get_absolute_pose(rel_pose, start_pos):
    """The pose ``rel_pose`` (``[dx, dy, dtheta]`` in the frame of ``start_pos``) in the frame
    ``start_pos`` is given in."""
    x, y, theta = (float(v) for v in np.asarray(start_pos).reshape(3))
    dx, dy, dtheta = (float(v) for v in np.asarray(rel_pose).reshape(3))
    return np.array(
        [
            x + dx * np.cos(theta) - dy * np.sin(theta),
            y + dx * np.sin(theta) + dy * np.cos(theta),
            theta + dtheta,
        ]
    )


def get_trajectory_circle(start_pos, dt, r, v, angle):
    """A left turn of radius ``r`` at speed ``v`` through ``angle`` from ``start_pos``:
    ``(states, controls)``."""
    return circle_reference(start_pos, dt, r, v, angle)


def get_trajectory_negcircle(start_pos, dt, r, v, angle):
    """A right turn of radius ``r`` at speed ``v`` through ``angle`` from ``start_pos``:
    ``(states, controls)``."""
    return circle_reference(start_pos, dt, -r, v, angle)


def position_control_init_fn(init_type, start_pos, goal_pos, dt, max_v, max_w, reverse=False):
    """The states of a reference from ``start_pos`` to ``goal_pos`` under ``max_v`` and
    ``max_w``: ``init_type`` ``"sharp"`` (turn, drive, turn) or ``"smooth"`` (a Bezier curve).

    Ferrobot's sharp reference drives backwards to a goal more than 90 degrees behind the
    base whatever ``reverse`` says (PyRobot did so beyond 135 degrees, and only with
    ``reverse=True``); both end at the goal."""
    del reverse
    states, _ = base_reference(init_type, start_pos, goal_pos, dt, max_v, max_w)
    return states
