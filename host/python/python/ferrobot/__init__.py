"""Ferrobot: PyRobot's API, in Rust, without ROS.

    from ferrobot import Robot
    bot = Robot("locobot")                  # the in-process simulator by default
    bot.arm.go_home()
    bot.arm.set_joint_positions([0.4, 0.7, -0.5, -1.4, 0.9], plan=False)
    rgb, depth = bot.camera.get_rgb_depth()
    bot.base.go_to_relative([1.0, 0.0, 0.0])

Units are SI (m, rad, s, N m); frames are right-handed; quaternions are ``[x, y, z, w]``.
Arrays are numpy; every error is a :class:`ferrobot.Error` (see :mod:`ferrobot.errors`).
"""

from . import errors
from ._native import (
    Arm,
    Base,
    Camera,
    Gripper,
    Motion,
    Plan,
    Recorder,
    Robot,
    SharedWorld,
    __version__,
    bench_base,
    calibrate_camera,
    export_lerobot,
    grasp,
    push,
    robots,
    scenes,
)
from .errors import Error

__all__ = [
    "Robot",
    "SharedWorld",
    "Arm",
    "Base",
    "Camera",
    "Gripper",
    "Motion",
    "Plan",
    "Recorder",
    "export_lerobot",
    "Error",
    "errors",
    "grasp",
    "push",
    "calibrate_camera",
    "bench_base",
    "robots",
    "scenes",
    "__version__",
]
