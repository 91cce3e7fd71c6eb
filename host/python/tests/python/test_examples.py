"""The Python examples run to their end (examples/python): PyRobot's own LoCoBot examples
with the import changed (examples/python/pyrobot) and Ferrobot's. Each runs in a child
interpreter, in a temporary directory for what it writes; a motion that fails raises, so a
clean exit means every motion of the program ended where it was sent."""

import os
import subprocess
import sys

import pytest

from conftest import REPO

EXAMPLES = REPO / "examples/python"
ARGS = {
    # PyRobot's README's command line (its default controller, gpmp, is gone from PyRobot).
    "pyrobot/base_position_control.py": [
        "--base_controller", "ilqr", "--base_planner", "none",
        "--relative_position", "1,1,1.57", "--smooth",
    ],
    "pyrobot/base_trajectory_tracking.py": ["--type", "twocircles"],
    "slam.py": ["--seconds", "20"],
}
# What each of Ferrobot's examples must print.
EXPECT = {
    "grasping.py": "holding an object",
    "pushing.py": "pushed object",
    "point_cloud.py": "points above the floor",
    "camera.py": "median depth",
    "slam.py": "3-D map",
    "demonstrations.py": "3 episodes",
}


def _all():
    return sorted(str(p.relative_to(EXAMPLES)) for p in EXAMPLES.rglob("*.py"))


@pytest.mark.parametrize("example", _all())
def test_example_runs(example, tmp_path):
    out = subprocess.run(
        [sys.executable, str(EXAMPLES / example), *ARGS.get(example, [])],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
        env=dict(os.environ),
    )
    assert out.returncode == 0, out.stdout + out.stderr
    if example in EXPECT:
        assert EXPECT[example] in out.stdout, out.stdout


def test_every_pyrobot_example_differs_only_in_its_imports():
    for path in (EXAMPLES / "pyrobot").glob("*.py"):
        for line in path.read_text().splitlines():
            assert "pyrobot" not in line or line.startswith("#"), (path.name, line)
