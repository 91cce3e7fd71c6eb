# Copyright (c) Facebook, Inc. and its affiliates.

# This source code is licensed under the MIT license found in the
# LICENSE file in the root directory of this source tree.

# PyRobot's tests/test_make_robots.py and tests/test_pyrobot_classes.py, run against
# Ferrobot. Changed: `pyrobot` is `ferrobot`; `import rospy` (ROS) is gone.

import pytest

from ferrobot import Robot


@pytest.fixture
def botname(request):
    return request.config.getoption("botname")


@pytest.mark.parametrize("base_controller", ["ilqr", "proportional", "movebase"])
@pytest.mark.parametrize("base_planner", ["movebase", "none"])
def test_make_robot_base(botname, base_controller, base_planner):
    bot = Robot(
        botname,
        base_config={"base_controller": base_controller, "base_planner": base_planner},
        use_arm=False,
        use_camera=False,
    )
    return bot

@pytest.mark.parametrize("use_moveit", ["True", "False"])
def test_make_robot_arm(botname, use_moveit):
    bot = Robot(botname, arm_config={"use_moveit": use_moveit}, use_base=False)
    return bot


def test_simple_camera():
    from ferrobot.locobot.camera import SimpleCamera


def test_locobot_arm():
    from ferrobot.locobot.arm import LoCoBotArm


def test_locobot_base():
    from ferrobot.locobot.base import LoCoBotBase


def test_locobot_camera():
    from ferrobot.locobot.camera import LoCoBotCamera


def test_locobot_gripper():
    from ferrobot.locobot.gripper import LoCoBotGripper
