# Copyright (c) Facebook, Inc. and its affiliates.

# This source code is licensed under the MIT license found in the
# LICENSE file in the root directory of this source tree.

# PyRobot's tests/test_arm_utils.py, run against Ferrobot's simulator. Changed:
# - `pyrobot` is `ferrobot`; `time.sleep(t)` is `bot.wait(t)` (the simulator's time passes
#   while the program waits on the robot); the fixture builds the robot `--botname` names;
# - the expected values that are facts of PyRobot's URDF and of Gazebo are facts of Ferrobot's
#   URDF, read by yourdfpy (an independent URDF library from PyPI), not by Ferrobot:
#   - test_get_ee_pose: PyRobot's numbers are Gazebo's pose of the gripper at home, sagging
#     under gravity (pitch 0.018 rad). Here: the URDF's forward kinematics at the joint angles
#     the simulated servos hold at home (they sag too: 0.011 rad), tolerances unchanged.
#   - test_compute_fk_position: PyRobot's LoCoBot numbers are of its original URDF, whose arm
#     base sits at (0.0973, 0, 0.0897625) in base_link; LoCoBot-Lite's at (0.08, 0, 0.066).
#     Ferrobot's LoCoBot is PyRobot's "cmu" variant (its arm base 6.24 mm higher): the
#     expected position moves by the difference of the arm bases, read from our URDF.

import pytest

import numpy as np
import yourdfpy
from ferrobot import Robot

from conftest import REPO

PYROBOT_ARM_BASE = {"locobot": [0.0973, 0.0, 0.0897625], "locobot_lite": [0.08, 0.0, 0.066]}


def _urdf(botname):
    path = REPO / "host/description/robots" / (botname + ".urdf")
    return yourdfpy.URDF.load(str(path), load_meshes=False, build_collision_scene_graph=False)


def _fk(urdf, joints, frame, base="base_link"):
    urdf.update_cfg({n: q for n, q in joints.items() if n in urdf.actuated_joint_names})
    return urdf.get_transform(frame, base)


@pytest.fixture(scope="module")
def create_robot(request):
    return Robot(request.config.getoption("botname"), use_base=False)


def test_get_ee_pose(create_robot, botname):
    bot = create_robot
    bot.arm.go_home()
    bot.wait(0.4)
    trans, rot, quat = bot.arm.pose_ee
    urdf = _urdf(botname)
    held = dict(zip(bot.arm.arm_joint_names, bot.arm.get_joint_angles()))
    t = _fk(urdf, held, bot.arm.configs.ARM.EE_FRAME)
    trans_des = t[:3, 3].reshape(3, 1)
    rot_des = t[:3, :3]
    quat_des = yourdfpy_quat(rot_des)
    trans_err = np.linalg.norm(trans_des - trans)
    rot_err = np.linalg.norm(rot - rot_des)
    quat_err = np.linalg.norm(quat - quat_des)
    assert trans_err < 0.005
    assert rot_err < 0.005
    assert quat_err < 0.005


def yourdfpy_quat(rot):
    """[x, y, z, w], w >= 0, by trimesh's transformations (installed with yourdfpy)."""
    import trimesh.transformations as tt

    m = np.eye(4)
    m[:3, :3] = rot
    w, x, y, z = tt.quaternion_from_matrix(m)
    q = np.array([x, y, z, w])
    return -q if q[3] < 0 else q


def test_get_jacobian(create_robot):
    bot = create_robot
    jac = bot.arm.get_jacobian([0, 0, 0, 0, 0])
    jac_des = np.array(
        [
            [-0.0001, 0.2, 0.0, 0.0, 0.0],
            [0.3132, 0.0, 0.0, 0.0, 0.0],
            [0.0, -0.3132, -0.2632, -0.063, 0.0],
            [0.0, 0.0, 0.0, 0.0, -1.0],
            [0.0, 1.0, 1.0, 1.0, 0.0],
            [1.0, 0.0, 0.0, 0.0, 0.0],
        ]
    )
    jac_err = np.linalg.norm(jac - jac_des)
    assert jac_err < 0.001


def test_compute_fk_position(create_robot, botname):
    bot = create_robot
    pos, rot = bot.arm.compute_fk_position(
        np.array([0.1, 0.2, 0.3, 0.4, 0.5]), bot.arm.configs.ARM.EE_FRAME
    )
    if "lite" in botname:
        pos_des = np.array([[0.3821], [0.0304], [0.22]])

    else:
        pos_des = np.array([[0.3994], [0.0304], [0.2438]])
    ours = _urdf(botname).get_transform("arm_base_link", "base_link")[:3, 3]
    pyrobots = PYROBOT_ARM_BASE["locobot_lite" if "lite" in botname else "locobot"]
    pos_des = pos_des + (ours - np.array(pyrobots)).reshape(3, 1)
    rot_des = np.array(
        [[0.6185, -0.4613, 0.6361], [0.0621, 0.8357, 0.5457], [-0.7833, -0.298, 0.5455]]
    )
    pos_err = np.linalg.norm(pos - pos_des)
    rot_err = np.linalg.norm(rot - rot_des)
    assert pos_err < 0.001
    assert rot_err < 0.001


def test_compute_fk_velocity(create_robot):
    bot = create_robot
    vel = bot.arm.compute_fk_velocity(
        np.zeros(bot.arm.arm_dof),
        np.array([0.1, 0.2, 0.3, 0.4, 0.5]),
        bot.arm.configs.ARM.EE_FRAME,
    )
    vel_des = np.array([0.04, 0.0313, -0.1668, -0.5, 0.9, 0.1])
    vel_err = np.linalg.norm(vel - vel_des)
    assert vel_err < 0.001


@pytest.mark.parametrize("numerical", ["True", "False"])
def test_compute_ik(create_robot, numerical):
    bot = create_robot

    pos_des = np.array([0.3821, 0.0304, 0.22])
    rot_des = np.array(
        [[0.6185, -0.4613, 0.6361], [0.0621, 0.8357, 0.5457], [-0.7833, -0.298, 0.5455]]
    )
    sol = bot.arm.compute_ik(pos_des, rot_des, numerical=numerical)
    pos, rot = bot.arm.compute_fk_position(sol, bot.arm.configs.ARM.EE_FRAME)
    pos_err = np.linalg.norm(pos.flatten() - pos_des.flatten())
    rot_err = np.linalg.norm(rot - rot_des)
    assert pos_err < 0.01
    assert rot_err < 0.1
