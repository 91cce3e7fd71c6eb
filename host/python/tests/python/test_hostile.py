"""Hostile values at every entry point of the Python API: NaN and infinities, huge numbers,
wrong lengths, shapes and dtypes, None, strings, booleans where numbers go, nested junk. Each
call must raise a clear exception (a ``ferrobot.Error``, or Python's TypeError or
OverflowError where Python itself converts a plain argument), never crash the interpreter or
raise pyo3's PanicException (a BaseException: a Rust panic), and the robot must still work
afterwards."""

import math

import numpy as np
import pytest

import ferrobot
import ferrobot.locobot.base_control_utils
from ferrobot import Robot

# What every vector-valued argument is given.
VECTORS = [
    None,
    "abc",
    b"bytes",
    {"a": 1},
    True,
    [],
    [[]],
    [1.0, None, 2.0],
    ["1", "2", "3"],
    [[1.0, 2.0], [3.0]],
    [[[[1.0]]]],
    [float("nan")] * 5,
    [float("inf")] * 5,
    [-float("inf")] * 5,
    [1e308] * 5,
    [-1e308] * 5,
    [10**400] * 5,
    [1.0] * 1000,
    np.zeros(5, dtype=complex),
    np.array(["a"] * 5),
    np.zeros((5, 5)),
    np.zeros((2, 3, 4, 5)),
    np.array([object()] * 5),
    np.full(5, np.nan, dtype=np.float32),
]
# What every scalar argument is given.
SCALARS = [None, "1.0", [1.0], float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 10**400]
ALLOWED = (ferrobot.Error, TypeError, OverflowError)
# Arguments whose default is None: None is a value they take.
OPTIONAL = {
    "Robot backend",
    "compute_ik qinit",
    "set_ee_pose_pitch_roll roll",
    "track_trajectory controls",
    "track_trajectory dt",
    "Motion.wait timeout",
    "get_ee_pose",
    "load_controller",
    "load_planner",
    "start_slam",
    "Robot start_pose",
    "Robot camera_mount_error",
    "Robot scene",
}


@pytest.fixture(scope="module")
def bot():
    return Robot("locobot", scene="tabletop")


def _refused(call, value):
    try:
        call(value)
    except ALLOWED as e:
        assert str(e), f"an empty message for {value!r}"
        return e
    except BaseException as e:  # a panic, or an exception outside the hierarchy
        pytest.fail(f"{type(e).__module__}.{type(e).__name__} for {value!r}: {e}")
    return None


def _vector_calls(bot):
    arm, base, cam = bot.arm, bot.base, bot.camera
    ok5 = [0.0] * 5
    return {
        "set_joint_positions": lambda v: arm.set_joint_positions(v, plan=False),
        "set_joint_positions plan": lambda v: arm.set_joint_positions(v),
        "set_joint_velocities": arm.set_joint_velocities,
        "set_joint_torques": arm.set_joint_torques,
        "set_ee_pose position": lambda v: arm.set_ee_pose(v, [0.0, 1.5, 0.0]),
        "set_ee_pose orientation": lambda v: arm.set_ee_pose([0.3, 0.0, 0.2], v),
        "set_ee_pose_pitch_roll": lambda v: arm.set_ee_pose_pitch_roll(v, 1.0),
        "move_ee_xyz": arm.move_ee_xyz,
        "compute_fk_position": lambda v: arm.compute_fk_position(v, "gripper_link"),
        "compute_fk_velocity q": lambda v: arm.compute_fk_velocity(v, ok5, "gripper_link"),
        "compute_fk_velocity qd": lambda v: arm.compute_fk_velocity(ok5, v, "gripper_link"),
        "compute_ik position": lambda v: arm.compute_ik(v, [0.0, 1.5, 0.0]),
        "compute_ik orientation": lambda v: arm.compute_ik([0.3, 0.0, 0.2], v),
        "compute_ik qinit": lambda v: arm.compute_ik([0.3, 0.0, 0.2], [0.0, 1.5, 0.0], qinit=v),
        "get_jacobian": arm.get_jacobian,
        "make_plan_joint_positions": arm.make_plan_joint_positions,
        "make_plan_pose": lambda v: arm.make_plan_pose(v, [0.0, 1.5, 0.0]),
        "add_world_object pose": lambda v: arm.add_world_object("box", v, [0.1, 0.1, 0.1]),
        "add_world_object size": lambda v: arm.add_world_object("box", [1, 0, 0, 0, 0, 0, 1], v),
        "attach_arm_object pose": lambda v: arm.attach_arm_object("gripper_link", "t", v, [0.1] * 3),
        "attach_arm_object size": lambda v: arm.attach_arm_object("gripper_link", "t", [0] * 6, v),
        "go_to_relative": base.go_to_relative,
        "go_to_absolute": base.go_to_absolute,
        "track_trajectory states": base.track_trajectory,
        "track_trajectory controls": lambda v: base.track_trajectory([[0, 0, 0], [0.01, 0, 0]], controls=v),
        "pix_to_3dpt rows": lambda v: cam.pix_to_3dpt(v, [0] * 5),
        "pix_to_3dpt cols": lambda v: cam.pix_to_3dpt([0] * 5, v),
        "start_slam": bot.start_slam,
        "Robot start_pose": lambda v: Robot("locobot", use_arm=False, start_pose=v),
        "Robot camera_mount_error": lambda v: Robot("locobot", use_arm=False, camera_mount_error=v),
        "position_control_init_fn": lambda v: ferrobot.locobot.base_control_utils.position_control_init_fn(
            "sharp", [0, 0, 0], v, 0.1, 0.2, 0.4
        ),
        "get_trajectory_circle": lambda v: ferrobot.locobot.base_control_utils.get_trajectory_circle(
            v, 0.1, 0.5, 0.1, 1.0
        ),
    }


def _scalar_calls(bot):
    arm, base, cam = bot.arm, bot.base, bot.camera
    return {
        "set_ee_pose_pitch_roll pitch": lambda v: arm.set_ee_pose_pitch_roll([0.3, 0, 0.2], v),
        "set_ee_pose_pitch_roll roll": lambda v: arm.set_ee_pose_pitch_roll([0.3, 0, 0.2], 1.0, roll=v),
        "move_ee_xyz eef_step": lambda v: arm.move_ee_xyz([0, 0, 0.01], eef_step=v),
        "set_vel v": lambda v: base.set_vel(v, 0.0, 0.5),
        "set_vel w": lambda v: base.set_vel(0.0, v, 0.5),
        "set_vel exe_time": lambda v: base.set_vel(0.1, 0.0, v),
        "track_trajectory dt": lambda v: base.track_trajectory([[0, 0, 0], [0.01, 0, 0]], dt=v),
        "set_pan": cam.set_pan,
        "set_tilt": cam.set_tilt,
        "set_pan_tilt": lambda v: cam.set_pan_tilt(v, v),
        "wait": bot.wait,
        "slam_map_3d": bot.slam_map_3d,
        "Motion.wait timeout": lambda v: arm.set_joint_positions([0.0] * 5, plan=False, wait=False).wait(v),
        "Plan.sample dt": lambda v: arm.make_plan_joint_positions([0.1] * 5).sample(v),
        "circle dt": lambda v: ferrobot.locobot.base_control_utils.get_trajectory_circle([0, 0, 0], v, 0.5, 0.1, 1.0),
        "circle r": lambda v: ferrobot.locobot.base_control_utils.get_trajectory_circle([0, 0, 0], 0.1, v, 0.1, 1.0),
        "init max_v": lambda v: ferrobot.locobot.base_control_utils.position_control_init_fn(
            "sharp", [0, 0, 0], [1, 0, 0], 0.1, v, 0.4
        ),
    }


def _name_calls(bot):
    arm, cam = bot.arm, bot.camera
    return {
        "get_joint_angle": arm.get_joint_angle,
        "get_ee_pose": arm.get_ee_pose,
        "compute_fk_position frame": lambda v: arm.compute_fk_position([0.0] * 5, v),
        "get_link_transform": lambda v: cam.get_link_transform(v, "base_link"),
        "remove_world_object": arm.remove_world_object,
        "get_state": bot.base.get_state,
        "load_controller": bot.base.load_controller,
        "load_planner": bot.base.load_planner,
        "Robot name": lambda v: Robot(v),
        "Robot scene": lambda v: Robot("locobot", scene=v),
        "Robot backend": lambda v: Robot("locobot", backend=v),
        "base_reference init_type": lambda v: ferrobot._native.base_reference(v, [0, 0, 0], [1, 0, 0], 0.1, 0.2, 0.4),
    }


NAMES = [None, 3, "", "\x00", "ü" * 10_000, "../../etc/passwd", ["joint_1"], b"joint_1"]


def test_vectors_are_refused_everywhere(bot):
    calls = _vector_calls(bot)
    for name, call in calls.items():
        for v in VECTORS:
            if v is None and name in OPTIONAL:
                continue
            e = _refused(call, v)
            if e is None:
                # A value accepted must be one the call can take (e.g. [] for no trajectory).
                assert name.startswith(("pix_to_3dpt",)) and isinstance(v, list), (name, v)
        bot.cancel_motions()
    _robot_still_works(bot)


def test_scalars_are_refused_everywhere(bot):
    for name, call in _scalar_calls(bot).items():
        for v in SCALARS:
            if v is None and name in OPTIONAL:
                continue
            e = _refused(call, v)
            assert e is not None, f"{name} accepted {v!r}"
        bot.cancel_motions()
    _robot_still_works(bot)


def test_names_are_refused_everywhere(bot):
    for name, call in _name_calls(bot).items():
        for v in NAMES:
            if v is None and name in OPTIONAL:
                continue
            e = _refused(call, v)
            assert e is not None, f"{name} accepted {v!r}"
    _robot_still_works(bot)


def test_teach_mode_takes_only_a_boolean(bot):
    for v in [None, 1, 0.0, "yes", [True], float("nan")]:
        assert _refused(bot.arm.set_teach_mode, v) is not None, v
    assert bot.arm.set_teach_mode(True)
    assert bot.arm.set_teach_mode(False)
    _robot_still_works(bot)


def test_constructor_dictionaries_are_checked():
    for bad in [{"base_controller": 3}, {"nonsense": 1}, {1: 2}]:
        assert _refused(lambda v: Robot("locobot", base_config=v), bad) is not None
    for bad in [{"arm.joint_tolerance": float("nan")}, {"arm.joint_tolerance": object()}, {3: 1}]:
        assert _refused(lambda v: Robot("locobot", overrides=v), bad) is not None
    assert _refused(lambda v: Robot("locobot", seed=v), -1) is not None
    # A mount error beyond MAX_CAMERA_MOUNT_ERROR (0.1 m, 0.5 rad).
    for bad in ([0.2, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0.6, 0], [0.0] * 6 + [1.0]):
        assert _refused(lambda v: Robot("locobot", camera_mount_error=v), bad) is not None
    assert _refused(lambda v: Robot("locobot", config_file=v), "/nonexistent.toml") is not None


def test_the_skills_refuse_absurd_options():
    bot = Robot("locobot", scene="tabletop")
    for v in [0, 10**6, -1]:
        assert _refused(lambda a: ferrobot.grasp(bot, attempts=a), v) is not None
    for v in [float("nan"), 10.0]:
        assert _refused(lambda t: ferrobot.grasp(bot, head_tilt=t), v) is not None
    for v in [0, 99]:
        assert _refused(lambda p: ferrobot.calibrate_camera(bot, poses=p), v) is not None
    for v in [0, 101, -1]:
        assert _refused(lambda t: ferrobot.bench_base(trials=t), v) is not None
    for v in NAMES:
        assert _refused(lambda r: ferrobot.bench_base(r, trials=1), v) is not None


def test_the_recorder_refuses_what_is_not_a_new_file(bot, tmp_path):
    (tmp_path / "taken.mcap").write_text("a user's file")
    for v in NAMES + [tmp_path, tmp_path / "taken.mcap", tmp_path / "no" / "dir.mcap", "/dev/null"]:
        assert _refused(lambda p: ferrobot.Recorder(bot, p), v) is not None, v
    assert _refused(lambda c: ferrobot.Recorder(bot, tmp_path / "c.mcap", camera=c), "yes") is not None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.mcap"]
    _robot_still_works(bot)


def test_the_lerobot_export_refuses_hostile_recordings_tasks_and_rates(bot, tmp_path):
    (tmp_path / "notes.txt").write_text("not a recording")
    (tmp_path / "taken").mkdir()
    notes = [tmp_path / "notes.txt"]
    out = tmp_path / "dataset"
    for v in NAMES + [[], [tmp_path], ["/dev/zero"], notes * 2]:
        assert _refused(lambda r: ferrobot.export_lerobot(r, out, "task"), v) is not None, v
    for v in NAMES + [tmp_path / "taken", "/dev/null"]:
        assert _refused(lambda o: ferrobot.export_lerobot(notes, o, "task"), v) is not None, v
    for v in [None, 3, "", " ", ["a", "b"], [3], b"task"]:
        assert _refused(lambda t: ferrobot.export_lerobot(notes, out, t), v) is not None, v
    for v in [0, -1, 1001, 2**40, float("nan"), 30.5, "30", None]:
        assert _refused(lambda f: ferrobot.export_lerobot(notes, out, "task", fps=f), v) is not None, v
    assert _refused(lambda c: ferrobot.export_lerobot(notes, out, "task", camera=c), "yes") is not None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "taken"]
    _robot_still_works(bot)


def _robot_still_works(bot):
    bot.cancel_motions()
    bot.arm.remove_all_objects()
    assert bot.arm.go_home(plan=False) is True
    assert np.allclose(bot.arm.get_joint_angles(), 0.0, atol=0.02)
    assert all(math.isfinite(x) for x in bot.base.get_state())
    assert bot.camera.get_rgb().shape[2] == 3


def test_backend_specs_are_refused_with_typed_errors(monkeypatch):
    for spec in ["direct:", "direct:servo=", "direct:bogus=1", "direct:servo=a,servo=b", "directx", "direct-emulated:1"]:
        with pytest.raises(ferrobot.errors.InvalidArgument):
            Robot("locobot", backend=spec)
    # The remote backend's spec: an endpoint, then known options with values.
    for spec in [
        "remote:",
        "remote:,namespace=/a",
        "remote:tcp/127.0.0.1:1,bogus=1",
        "remote:tcp/127.0.0.1:1,namespace=",
        "remote:tcp/127.0.0.1:1,credentials=/nonexistent/usrpwd",
    ]:
        with pytest.raises(ferrobot.errors.InvalidArgument):
            Robot("locobot", backend=spec)
    # An endpoint of a transport this build does not speak is refused before any connection.
    with pytest.raises(ferrobot.errors.Usage):
        Robot("locobot", backend="remote:udp/127.0.0.1:1")
    # The host-run firmware refuses to start before its hardware check passes: a typed error
    # that names each missing device.
    with pytest.raises(ferrobot.errors.HardwareCheck) as e:
        Robot("locobot", backend="direct:servo=/nonexistent/u2d2,base=/nonexistent/kobuki")
    assert "no servo bus at /nonexistent/u2d2" in str(e.value)
    assert "no base at /nonexistent/kobuki" in str(e.value)
    assert "hardware check of locobot" in e.value.table
    # The environment names the backend of a Robot that does not; it is checked the same.
    monkeypatch.setenv("FERROBOT_BACKEND", "serial:")
    with pytest.raises(ferrobot.errors.InvalidArgument):
        Robot("locobot")


def test_shared_worlds_refuse_bad_scenes_places_and_companions():
    for scene in ["kitchen", "", "/dev/zero", "/nonexistent/scene.toml"]:
        with pytest.raises(ferrobot.Error):
            ferrobot.SharedWorld(scene)
    for scene in [None, 3, 1.5, ["empty"]]:
        with pytest.raises((TypeError, ferrobot.Error)):
            ferrobot.SharedWorld(scene)
    world = ferrobot.SharedWorld("empty")
    Robot("locobot", world=world, start_pose=[0.0, 0.0, 0.0])
    # On top of the first robot; beyond any floor; not finite; not three numbers.
    for pose in [[0.1, 0.0, 0.0], [1e300, 0.0, 0.0], [math.nan, 0.0, 0.0], [0.0, math.inf, 0.0], [1.0, 2.0]]:
        with pytest.raises(ferrobot.Error):
            Robot("locobot", world=world, start_pose=pose)
    # A scene beside a world, another backend, something that is not a world.
    with pytest.raises(ferrobot.errors.Usage):
        Robot("locobot", world=world, scene="tabletop", start_pose=[2.0, 0.0, 0.0])
    with pytest.raises(ferrobot.Error):
        Robot("locobot", world=world, backend="serial:/dev/null", start_pose=[2.0, 0.0, 0.0])
    for not_a_world in ["empty", 1, object()]:
        with pytest.raises(TypeError):
            Robot("locobot", world=not_a_world, start_pose=[2.0, 0.0, 0.0])
    assert world.robots() == 1
    for i in [1, -1, 2**70]:
        with pytest.raises((ferrobot.Error, OverflowError)):
            world.true_pose(i)
