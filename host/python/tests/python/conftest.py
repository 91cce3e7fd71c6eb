"""Shared by the Python package's tests (run by ../pytest.rs, which stages the package
built by this test build on PYTHONPATH).

The files named ``test_pyrobot_*.py`` are PyRobot's own tests (facebookresearch/pyrobot,
``tests/``, MIT licence, Copyright (c) Facebook, Inc. and its affiliates), kept as written
but for what needs ROS or Gazebo; each says what was changed and why.
"""

import os
import pathlib

import pytest

REPO = pathlib.Path(os.environ.get("FERROBOT_REPO", pathlib.Path(__file__).parents[4]))


def pytest_addoption(parser):
    # PyRobot's conftest: which robot its tests drive.
    parser.addoption("--botname", metavar="botname", default="locobot", help="which robot to test")


@pytest.fixture
def botname(request):
    return request.config.getoption("botname")


@pytest.fixture(scope="session")
def repo():
    """The repository's root."""
    return REPO
