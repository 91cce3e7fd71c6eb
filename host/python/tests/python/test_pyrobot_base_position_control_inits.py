# Copyright (c) Facebook, Inc. and its affiliates.

# This source code is licensed under the MIT license found in the
# LICENSE file in the root directory of this source tree.

# PyRobot's tests/test_base_position_control_inits.py, run against Ferrobot's references.
# Changed: `pyrobot` is `ferrobot`; the plots of each reference to PDF files beside the test
# (matplotlib) are left out: they assert nothing.

import pytest

import numpy as np

from ferrobot.locobot.base_control_utils import position_control_init_fn
from ferrobot.locobot.bicycle_model import wrap_theta


def _states_close(state1, state2):
    dist = np.linalg.norm(state1[:2] - state2[:2])
    angle = wrap_theta(state1[2] - state2[2])
    assert dist < 0.05
    assert np.abs(angle) < 10 / 180.0 * np.pi


def _test_init(init_type, start_pos, goal_pos, reverse):
    dt = 0.1
    max_v = 0.2
    max_w = 0.4
    init_states = position_control_init_fn(
        init_type, start_pos, goal_pos, dt, max_v, max_w, reverse
    )
    _states_close(init_states[-1, :], goal_pos)


goal_poss = np.array(
    [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [-1.0, -0.2, 0.0],
        [1.0, 1.0, 0.0],
        [-1.0, -1.0, 0],
        [0.0, 0.0, np.pi / 2.0],
        [1.0, 1.0, 0.0],
        [-1.0, 1.0, 0],
        [0.0, 1.0, np.pi / 2.0],
        [0.1, 0.1, 0.0],
        [-0.1, -0.1, 0],
        [0.0, 0.0, 0.1],
    ],
    dtype=np.float32,
)


@pytest.mark.parametrize("init_type", ["sharp", "smooth"])
@pytest.mark.parametrize("reverse", [False, True])
@pytest.mark.parametrize("goal_pos", goal_poss)
def test_init(init_type, reverse, goal_pos):
    start_pos = np.array([0.0, 0.0, 0.0], dtype=np.float32)
    _test_init(init_type, start_pos, goal_pos, reverse=reverse)
