"""The Python surface beyond PyRobot's own tests: arrays and their memory, values checked
against independent computations, motions without waiting, plans, the planning scene, errors
and their fields, constructor keywords, and Ferrobot's extras (SLAM, skills, catalogues)."""

import pickle

import numpy as np
import pytest

import ferrobot
import ferrobot.utils.util
from ferrobot import Robot
from ferrobot import errors


@pytest.fixture(scope="module")
def bot():
    # Without the depth camera's noise: pixels of two frames agree exactly.
    return Robot("locobot", scene="tabletop", depth_noise=False)


def test_images_are_numpy_arrays_owning_the_rust_buffers(bot):
    rgb, depth = bot.camera.get_rgb_depth()
    h, w = bot.configs.CAMERA.HEIGHT, bot.configs.CAMERA.WIDTH
    assert rgb.shape == (h, w, 3) and rgb.dtype == np.uint8
    assert depth.shape == (h, w) and depth.dtype == np.float32
    # Not copied into numpy: the arrays are views of a buffer numpy does not own (Rust's).
    for a in (rgb, depth):
        assert not a.flags.owndata and a.base is not None
        assert a.flags.c_contiguous and a.flags.writeable
    # The tabletop is in view at the default tilt: depths in metres, within the D435's range.
    valid = depth[depth > 0]
    assert valid.size > 0.5 * depth.size
    assert 0.2 < float(np.median(valid)) < 10.0


def test_point_clouds_agree_with_the_intrinsics(bot):
    k = bot.camera.get_intrinsics()
    assert k.shape == (3, 3) and k[2, 2] == 1.0 and k[0, 1] == 0.0
    depth = bot.camera.get_depth()
    rows, cols = np.nonzero(depth > 0)
    r, c = int(rows[len(rows) // 2]), int(cols[len(cols) // 2])
    pts, colours = bot.camera.pix_to_3dpt([r], [c], in_cam=True)
    assert pts.shape == (1, 3) and colours.shape == (1, 3) and colours.dtype == np.uint8
    # The pinhole model by hand: z is the depth, x and y scale with the pixel's offset.
    z = depth[r, c]
    expected = [(c - k[0, 2]) * z / k[0, 0], (r - k[1, 2]) * z / k[1, 1], z]
    assert np.allclose(pts[0], expected, atol=1e-3 * z + 1e-4)
    cloud, cloud_colours = bot.camera.get_current_pcd(in_cam=True)
    assert cloud.ndim == 2 and cloud.shape[1] == 3 and cloud.dtype == np.float64
    assert cloud_colours.shape == cloud.shape and cloud_colours.dtype == np.uint8
    lo, hi = bot.configs.BASE.VSLAM.DEPTH_MIN, bot.configs.BASE.VSLAM.DEPTH_MAX
    assert np.all((cloud[:, 2] > lo) & (cloud[:, 2] < hi))


def test_a_pixel_without_depth_gives_nans():
    # Level in the empty world: the floor below the horizon has depth, the sky above none.
    bot = Robot("locobot", scene="empty", use_arm=False, depth_noise=False)
    bot.camera.set_tilt(0.0)
    depth = bot.camera.get_depth()
    holes = np.argwhere(depth == 0)
    seen = np.argwhere(depth > 0)
    assert len(holes) > 0 and len(seen) > 0
    (r, c), (r2, c2) = holes[0], seen[-1]
    pts, colours = bot.camera.pix_to_3dpt([int(r), int(r2)], np.array([c, c2]))
    assert np.isnan(pts[0]).all() and np.isfinite(pts[1]).all() and colours.shape == (2, 3)


def test_frames_in_base_link_are_the_optical_frames_moved(bot):
    trans, rot, t = bot.camera.get_link_transform(
        bot.configs.BASE.VSLAM.RGB_CAMERA_CENTER_FRAME, "base_link"
    )
    assert t.shape == (4, 4) and np.allclose(t[:3, :3], rot) and np.allclose(t[:3, 3], trans)
    pts_cam, _ = bot.camera.pix_to_3dpt([240], [320], in_cam=True)
    pts_base, _ = bot.camera.pix_to_3dpt([240], [320], in_cam=False)
    assert np.allclose(rot @ pts_cam[0] + trans, pts_base[0], atol=1e-6)


def test_pose_ee_is_forward_kinematics_of_the_joints(bot):
    bot.arm.set_joint_positions([0.3, 0.2, 0.1, 0.4, -0.2], plan=False)
    trans, rot, quat = bot.arm.pose_ee
    pos, rot_fk = bot.arm.compute_fk_position(bot.arm.get_joint_angles(), "gripper_link")
    assert trans.shape == (3, 1) and rot.shape == (3, 3) and quat.shape == (4,)
    assert np.allclose(trans, pos, atol=1e-9) and np.allclose(rot, rot_fk, atol=1e-9)
    assert quat[3] >= 0 and abs(np.linalg.norm(quat) - 1) < 1e-12
    same = ferrobot.utils.util.quat_to_rot_mat(quat)
    assert np.allclose(same, rot, atol=1e-9)
    # In another frame: the same pose seen from arm_base_link.
    t2, _, _ = bot.arm.get_ee_pose("arm_base_link")
    offset, _, _ = bot.arm.get_transform("base_link", "arm_base_link")
    assert np.allclose(t2 + offset, trans, atol=1e-9)


def test_joint_state_getters_agree(bot):
    names = bot.arm.arm_joint_names
    assert names == list(bot.configs.ARM.JOINT_NAMES) and bot.arm.arm_dof == len(names)
    q = bot.arm.get_joint_angles()
    assert q.shape == (len(names),) and q.dtype == np.float64
    for i, n in enumerate(names):
        assert bot.arm.get_joint_angle(n) == pytest.approx(q[i], abs=1e-9)
    assert bot.arm.get_joint_velocities().shape == q.shape
    assert bot.arm.get_joint_torques().shape == q.shape
    with pytest.raises(errors.UnknownName) as e:
        bot.arm.get_joint_angle("elbow")
    assert e.value.name == "elbow" and isinstance(e.value, KeyError)


def test_motions_without_waiting_can_be_polled_waited_and_cancelled(bot):
    bot.arm.go_home()
    m = bot.arm.set_joint_positions([0.5, 0.3, 0.2, -0.3, 0.1], plan=False, wait=False)
    assert isinstance(m, ferrobot.Motion) and "under way" in repr(m)
    assert m.wait(timeout=0) is False or m.done()
    steps = 0
    while not m.done():
        steps += 1
    assert steps > 0 and m.wait() is True
    assert np.allclose(bot.arm.get_joint_angles(), [0.5, 0.3, 0.2, -0.3, 0.1], atol=0.02)
    m2 = bot.base.set_vel(0.0, 0.3, exe_time=5.0, wait=False) if bot.base else None
    m3 = bot.arm.set_joint_positions([0.0, 0.0, 0.0, 0.0, 0.0], plan=False, wait=False)
    m3.cancel()
    with pytest.raises(errors.Cancelled):
        m3.wait()
    assert m3.done()
    if m2 is not None:
        m2.cancel()
    with pytest.raises(errors.InvalidArgument):
        m3.wait(timeout=float("nan"))


def test_robot_wait_lets_simulated_time_pass(bot):
    t0 = bot.time()
    bot.wait(0.25)
    assert bot.time() - t0 == pytest.approx(0.25, abs=0.011)


def test_plans_are_made_without_moving_and_run_later(bot):
    bot.arm.go_home()
    before = bot.arm.get_joint_angles()
    plan = bot.arm.make_plan_joint_positions([0.4, 0.7, -0.5, -1.4, 0.9])
    assert np.allclose(bot.arm.get_joint_angles(), before, atol=1e-3)
    assert len(plan) >= 2 and plan.path.shape == (len(plan), 5)
    assert np.allclose(plan[0], before, atol=0.02) and np.allclose(plan[-1], [0.4, 0.7, -0.5, -1.4, 0.9])
    t, q, qd = plan.sample(0.05)
    assert t[0] == 0 and t[-1] == pytest.approx(plan.duration) and q.shape == (len(t), 5)
    assert plan.planning_time >= 0 and plan.joint_names == bot.arm.arm_joint_names
    assert bot.arm.execute_plan(plan) is True
    assert np.allclose(bot.arm.get_joint_angles(), [0.4, 0.7, -0.5, -1.4, 0.9], atol=0.02)
    pose_plan = bot.arm.make_plan_pose([0.3, 0.0, 0.25], [0.0, np.pi / 2, 0.0])
    assert len(pose_plan) >= 2


def test_the_planning_scene_blocks_and_releases(bot):
    bot.arm.go_home()
    bot.arm.remove_all_objects()
    # A wall across the arm's way to the left, as PyRobot's MoveitObjectHandler poses it.
    bot.arm.add_world_object("wall", [0.25, 0.0, 0.2, 0, 0, 0, 1], [0.02, 0.02, 0.02])
    assert bot.arm.get_collision_state() is False
    with pytest.raises(errors.Planning):
        bot.arm.make_plan_pose([0.25, 0.0, 0.2], [0.0, 0.0, 0.0])
    bot.arm.remove_world_object("wall")
    bot.arm.attach_arm_object("gripper_link", "tool", [0.05, 0, 0, 0, 0, 0], [0.02, 0.02, 0.02])
    bot.arm.detach_arm_object("gripper_link", "tool", remove_from_world=False)
    bot.arm.remove_world_object("tool")  # left in the world: it is there to remove
    bot.arm.attach_arm_object("gripper_link", "tool", [0.05, 0, 0, 0, 0, 0], [0.02, 0.02, 0.02])
    bot.arm.detach_arm_object("gripper_link", "tool")
    with pytest.raises(errors.Planning):
        bot.arm.remove_world_object("tool")  # removed with the detach
    with pytest.raises(errors.Usage):
        bot.arm.attach_arm_object("base_link", "tool", [0, 0, 0, 0, 0, 0, 1], [0.1, 0.1, 0.1])
    assert bot.arm.add_scene_objects() > 0
    bot.arm.remove_all_objects()


def test_errors_carry_their_fields_and_pickle(bot):
    with pytest.raises(errors.OutOfLimits) as e:
        bot.arm.set_joint_positions([3.0, 0, 0, 0, 0], plan=False)
    err = e.value
    assert isinstance(err, ferrobot.Error) and isinstance(err, ValueError)
    assert err.joint == "joint_1" and err.value == 3.0 and err.max < 3.0 < 10
    assert "joint_1" in str(err)
    again = pickle.loads(pickle.dumps(err))
    assert type(again) is errors.OutOfLimits and again.joint == "joint_1"
    with pytest.raises(errors.JointCount) as e:
        bot.arm.set_joint_positions([0.0, 0.0])
    assert (e.value.expected, e.value.got) == (5, 2)


def test_every_error_class_is_in_the_hierarchy():
    for name in errors.__all__:
        cls = getattr(errors, name)
        assert issubclass(cls, ferrobot.Error), name
        err = cls("message", a=1)
        assert err.a == 1 and str(err) == "message" and err.fields == {"a": 1}


def test_constructor_keywords_are_checked():
    with pytest.raises(errors.UnknownRobot) as e:
        Robot("wall-e")
    assert "locobot" in e.value.known
    with pytest.raises(errors.InvalidArgument):
        Robot("locobot", base_config={"base_controller": "teleport"})
    with pytest.raises(errors.InvalidArgument):
        Robot("locobot", arm_config={"speed": 3})
    with pytest.raises(errors.InvalidArgument):
        Robot("locobot", backend="bluetooth")
    with pytest.raises(errors.Scene):
        Robot("locobot", scene="moon")
    with pytest.raises(errors.Config):
        Robot("locobot", overrides={"arm.joint_tolerance": "tight"})


def test_constructor_keywords_take_effect(repo):
    bot = Robot("locobot", use_arm=False, start_pose=[1.0, 2.0, 0.5], overrides={"arm.joint_tolerance": 0.02})
    assert bot.arm is None and bot.gripper is None and bot.base is not None
    lite = Robot("locobot_lite", use_camera=False, use_base=False)
    assert lite.camera is None and lite.base is None and lite.arm.arm_dof == 5
    sawyer = Robot("sawyer", config_file=repo / "host/description/robots/sawyer.toml")
    assert sawyer.arm.arm_dof == 7 and sawyer.name == "sawyer"
    kobuki = Robot("locobot_kobuki", base_config={"base_controller": "proportional"})
    assert kobuki.configs.BASE.BASE_CONTROLLER == "proportional"


def test_configs_are_read_only(bot):
    assert bot.configs.ARM.EE_FRAME == bot.configs["ARM"]["EE_FRAME"] == "gripper_link"
    with pytest.raises(AttributeError):
        bot.configs.ARM.EE_FRAME = "x"
    with pytest.raises(TypeError):
        bot.configs["ARM"] = {}
    with pytest.raises(AttributeError):
        bot.configs.NOT_A_KEY


def test_telemetry_reports_every_joint(bot):
    t = bot.telemetry()
    assert len(t["joint_names"]) == len(t["positions"]) == len(t["efforts"])
    assert set(bot.arm.arm_joint_names) <= set(t["joint_names"])
    assert len(t["odometry"]) == 3 and len(t["base_velocity"]) == 2 and t["time"] > 0


def test_slam_gives_the_base_a_vslam_state():
    bot = Robot("locobot", scene="apartment", use_arm=False, slam=True)
    bot.base.go_to_relative([0.3, 0.0, 0.3])
    odom = np.array(bot.base.get_state("odom"))
    vslam = np.array(bot.base.get_state("vslam"))
    assert np.linalg.norm(odom[:2] - vslam[:2]) < 0.1
    pts, colours = bot.slam_map_3d(0.05)
    assert pts.shape[0] > 100 and colours.shape == pts.shape
    grid = bot.slam_occupancy_map()
    assert grid is not None
    cells, resolution, origin = grid
    assert cells.ndim == 2 and resolution > 0 and origin.shape == (2,)
    assert set(np.unique(cells)) <= {0, 100, 255} and (cells == 100).any()
    with pytest.raises(errors.InvalidArgument):
        bot.base.get_state("gps")
    assert bot.stop_slam() is True


def test_the_catalogues():
    assert {"locobot", "locobot_lite", "sawyer"} <= set(ferrobot.robots())
    assert {"empty", "tabletop", "apartment"} <= set(ferrobot.scenes())
    assert ferrobot.__version__


def test_grasping_lifts_an_object_off_the_table():
    bot = Robot("locobot", scene="tabletop", seed=3)
    g = ferrobot.grasp(bot)
    assert g["objects"] >= 1 and g["gripper_state"] == 2
    assert len(g["position"]) == 3 and 0 < g["width"] < 0.1


def test_pushing_moves_an_object():
    bot = Robot("locobot", scene="tabletop", seed=1, depth_noise=False)

    def view():
        bot.arm.clear_view()
        bot.camera.set_pan_tilt(0.0, 0.8)
        return bot.camera.get_depth()

    def changed(a, b):
        # Pixels whose depth differs by more than 1 cm from every pixel within 2 of them in the
        # other look: the head's tilt servo settles within a couple of encoder ticks (3 mrad,
        # 2 pixels), which moves every edge in view by as much from one look to the next.
        best = np.full(a.shape, np.inf)
        for dy in range(-2, 3):
            for dx in range(-2, 3):
                s = np.roll(b, (dy, dx), axis=(0, 1))
                best = np.minimum(best, np.where((a > 0) & (s > 0), np.abs(a - s), np.inf))
        return np.count_nonzero(np.isfinite(best) & (best > 0.01))

    before = view()
    # What changes between two looks without a push (the arm's settling, objects at rest).
    still = changed(before, view())
    p = ferrobot.push(bot)
    assert p["objects"] >= 1 and 0 <= p["target"] < p["objects"]
    assert p["side"] in {"near", "left", "right", "far"} and p["lift"] > 0
    assert p["base_move"] == [0.0, 0.0]  # this seed's push is made from where the robot stands
    # The same view before and after: the pushed object changes more than 1 cm of depth on
    # ten times as many pixels as two looks without a push do.
    moved = changed(before, view())
    print(f"pushing: {moved} px changed, {still} px between two looks without a push")
    assert moved > 10 * max(still, 100), (moved, still)


def test_the_base_benchmark_runs_pyrobots_table():
    r = ferrobot.bench_base("locobot", trials=1, seed=1)
    rows = r["rows"]
    # Four controllers, three categories, each against ground truth and odometry.
    assert len(rows) == 24 and r["markdown"].count("\n| ") == 25
    assert {row["controller"] for row in rows} == {"proportional", "lqr", "ilqr", "dwa"}
    for row in rows:
        assert row["successes"] == [2, 2], row
        # Every controller ends within 2 cm and 2 degrees of each target, by either measure.
        assert row["translation_mm"][0] < 20 and row["rotation_deg"][0] < 2, row


def test_hand_eye_calibration_finds_the_cameras_true_mount(repo):
    import yourdfpy

    error = [0.02, 0.0, 0.0, 0.0, 0.0524, 0.0]  # 2 cm forward, 3 degrees of pitch
    bot = Robot("locobot", calibration_marker=True, camera_mount_error=error)
    r = ferrobot.calibrate_camera(bot, poses=6, grid=3)
    c = r["calibration"]
    assert r["used"] >= 3 and r["rms_px"] < 2.0
    # The truth: the URDF's mount (read by yourdfpy, not by Ferrobot) moved by the error.
    urdf = yourdfpy.URDF.load(
        str(repo / "host/description/robots/locobot.urdf"), load_meshes=False, build_collision_scene_graph=False
    )
    nominal = urdf.get_transform(c["child"], c["parent"])
    shift = np.eye(4)
    shift[:3, :3] = ferrobot.utils.util.euler_to_rot_mat([error[5], error[4], error[3]])
    shift[:3, 3] = error[:3]
    truth = nominal @ shift
    assert np.linalg.norm(np.array(c["xyz"]) - truth[:3, 3]) < 0.005
    fitted = ferrobot.utils.util.quat_to_rot_mat(c["quaternion"])
    angle = np.arccos(np.clip((np.trace(truth[:3, :3].T @ fitted) - 1) / 2, -1, 1))
    assert np.degrees(angle) < 0.5
    # The nominal mount is 2 cm and 3 degrees away: the fit is not the URDF's.
    assert np.linalg.norm(np.array(c["xyz"]) - nominal[:3, 3]) > 0.015


def test_two_robots_share_one_world_and_one_clock():
    import math

    world = ferrobot.SharedWorld("empty")
    a = Robot("locobot", world=world, start_pose=[0.0, 0.0, 0.0])
    b = Robot("locobot", world=world, start_pose=[1.2, 0.0, math.pi])
    assert world.robots() == 2
    # B's arm moves while A drives into B; A's bumper ends its goal with a typed fault.
    q = [0.4, 0.3, -0.3, 0.2, 0.0]
    arm = b.arm.set_joint_positions(q, plan=False, wait=False)
    with pytest.raises(errors.Fault):
        a.base.go_to_relative([1.0, 0.0, 0.0])
    a.wait(3.0)
    assert arm.done()
    assert np.allclose(b.arm.get_joint_angles(), q, atol=0.02)
    # A stands against B's plate: its bumper ring (0.177 m) and the plate's reach (0.247 m).
    pa, pb = world.true_pose(0), world.true_pose(1)
    assert abs(pb[0] - pa[0] - 0.4243) < 0.005, (pa, pb)
    assert abs(pb[0] - 1.2) < 1e-9 and abs(pb[1]) < 1e-9, pb  # B was not pushed
    assert abs(a.time() - b.time()) < 1e-6 and abs(a.time() - world.time()) < 1e-6
