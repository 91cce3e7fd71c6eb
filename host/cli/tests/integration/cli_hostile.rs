//! The `ferrobot` command line under hostile invocations: every subcommand with non-finite,
//! huge, negative and empty values, wrong counts, unknown names, and bad, binary, huge,
//! device and directory configuration paths.
//!
//! Each invocation runs as its own process in a scratch directory holding files it did not
//! create. It must end within [`LIMIT`], by itself, with exit code 2 (the input was wrong) or
//! the code the case names, never by a signal (abort) or a panic; with `--json` its standard
//! output must be exactly one JSON error object; and every file that was in the directory
//! before must be there after, byte for byte and untouched. `FERROBOT_CLI_BIN=PATH` runs the
//! same table against another `ferrobot` binary.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant, SystemTime};

/// The longest any hostile invocation may take (they are all refused before any work).
const LIMIT: Duration = Duration::from_secs(60);

/// What a case must end with.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Expect {
    /// Exit code 2: the input was wrong.
    Input,
    /// A non-zero exit code of the program's own (not a signal).
    Failure,
}

struct Case {
    args: Vec<String>,
    expect: Expect,
}

fn case(args: &[&str], expect: Expect) -> Case {
    Case {
        args: args.iter().map(|s| s.to_string()).collect(),
        expect,
    }
}

/// Non-finite, huge, negative-huge, tiny and empty numbers.
const HOSTILE: [&str; 8] = ["nan", "inf", "-inf", "1e300", "-1e308", "1e9", "NaN", ""];

/// The LoCoBot's hand-eye marker line.
const MARKER: &str = r#"marker = { link = "ar_tag", size = 0.03, xyz = [0.0, 0.0, 0.0026] }"#;

/// Copies of the bundled LoCoBot configuration with one hostile edit each, and the key the
/// error must name: every number in a configuration is checked at load.
fn hostile_configs() -> Vec<(&'static str, String, &'static str)> {
    let base = include_str!("../../../description/robots/locobot.toml");
    let edit = |from: &str, to: &str| {
        assert!(base.contains(from), "{from}");
        base.replacen(from, to, 1)
    };
    let j1 = r#"servo = { id = 1, model = "xm430-w350" }"#;
    let stow = "stow = [0.0, -0.45, 1.15, 1.05, 0.0]";
    vec![
        ("stow_short", edit(stow, "stow = [0.0, -0.45]"), "arm.stow"),
        (
            "stow_nan",
            edit(stow, "stow = [0.0, nan, 1.15, 1.05, 0.0]"),
            "arm.stow[1]",
        ),
        (
            "stow_beyond_limit",
            edit(stow, "stow = [0.0, -0.45, 4.0, 1.05, 0.0]"),
            "arm.stow[2]",
        ),
        (
            "timeout_neg",
            edit("timeout = 20.0", "timeout = -1.0"),
            "arm.timeout",
        ),
        (
            "timeout_nan",
            edit("timeout = 20.0", "timeout = nan"),
            "arm.timeout",
        ),
        (
            "timeout_huge",
            edit("timeout = 20.0", "timeout = 1e30"),
            "arm.timeout",
        ),
        (
            "offset_nan",
            edit(
                j1,
                r#"servo = { id = 1, model = "xm430-w350", offset = nan }"#,
            ),
            "joint[0].servo.offset",
        ),
        (
            "limits_inf",
            edit(j1, &format!("{j1}\nlimits = {{ min = -inf, max = inf }}")),
            "joint[0].limits.min",
        ),
        (
            "velocity_tiny",
            edit(j1, &format!("{j1}\nlimits = {{ velocity = 1e-45 }}")),
            "joint[0].limits.velocity",
        ),
        (
            "max_linear_huge",
            edit("max_linear = 0.5", "max_linear = 1e30"),
            "base.max_linear",
        ),
        ("fx_nan", edit("fx = 619.8997", "fx = nan"), "camera.fx"),
        (
            "marker_size_nan",
            edit(MARKER, &MARKER.replace("size = 0.03", "size = nan")),
            "camera.marker.size",
        ),
        (
            "marker_link_unknown",
            edit(MARKER, &MARKER.replace("ar_tag", "nowhere")),
            "camera.marker.link",
        ),
        (
            "width_zero",
            edit("width = 640", "width = 0"),
            "camera.width",
        ),
        (
            "home_nan",
            edit(
                "home = [0.0, 0.0, 0.0, 0.0, 0.0]",
                "home = [0.0, nan, 0.0, 0.0, 0.0]",
            ),
            "arm.home[1]",
        ),
        (
            "ik_tolerance_negative",
            edit(
                "ik_position_tolerance = 1e-5",
                "ik_position_tolerance = -1e-5",
            ),
            "arm.ik_position_tolerance",
        ),
        (
            "effort_nan",
            edit("effort_limit = 3.5", "effort_limit = nan"),
            "joint[0].effort_limit",
        ),
        (
            "wheel_radius_zero",
            edit("wheel_radius = 0.035", "wheel_radius = 0.0"),
            "base.wheel_radius",
        ),
        (
            "camera_rate_nan",
            edit("rate = 30.0", "rate = nan"),
            "camera.rate",
        ),
        (
            "camera_rate_zero",
            edit("rate = 30.0", "rate = 0.0"),
            "camera.rate",
        ),
        (
            "depth_inverted",
            edit("depth_max = 1.5", "depth_max = 0.1"),
            "camera.depth_max",
        ),
        (
            "gripper_ticks_inverted",
            edit("closed_tick = 1800", "closed_tick = 2900"),
            "gripper.open_tick",
        ),
        (
            "gripper_stop_negative",
            edit("stops = [1650, 3050]", "stops = [-5, 3050]"),
            "gripper.stops[0]",
        ),
        (
            "bus_baud_zero",
            edit("baud = 4_000_000", "baud = 0"),
            "bus.baud",
        ),
        (
            "loop_period_tiny",
            edit("loop_period_us = 1000", "loop_period_us = 1"),
            "bus.loop_period_us",
        ),
        (
            "rotation_tolerance_huge",
            edit("rotation_tolerance = 0.0175", "rotation_tolerance = 1e9"),
            "base.rotation_tolerance",
        ),
    ]
}

/// The scratch directory: the LoCoBot URDF, the hostile configurations, a file that is not
/// TOML, a binary file, a 2 MiB file, an empty one, a user's file and a subdirectory.
fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ferrobot-cli-hostile-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("subdir")).expect("scratch dir");
    std::fs::write(
        dir.join("locobot.urdf"),
        include_str!("../../../description/robots/locobot.urdf"),
    )
    .expect("urdf");
    for (name, text, _) in hostile_configs() {
        std::fs::write(dir.join(format!("{name}.toml")), text).expect("config");
    }
    std::fs::write(dir.join("notes.txt"), "a user's file\n").expect("notes");
    let binary: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    std::fs::write(dir.join("binary.toml"), binary).expect("binary");
    std::fs::write(dir.join("huge.toml"), vec![b'#'; 2 << 20]).expect("huge");
    std::fs::write(dir.join("empty.toml"), "").expect("empty");
    // A map in map_server's format (a 4 m × 4 m room of 10 cm cells, walled), and a map file
    // whose image is this test's notes.
    let mut grid = ferrobot::nav::OccupancyGrid::new([0.05, 0.05], 0.1, 40, 40).expect("grid");
    for j in 0..40 {
        for i in 0..40 {
            grid.occupied[j * 40 + i] = i == 0 || j == 0 || i == 39 || j == 39;
        }
    }
    ferrobot::nav::MapImage::from_grid(&grid)
        .save(&dir.join("map.yaml"))
        .expect("map");
    std::fs::write(
        dir.join("bad-map.yaml"),
        "image: notes.txt\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
    )
    .expect("bad map");
    // Planning problems files: a malformed object, a start of the wrong length.
    let joints = r#"["joint_1", "joint_2", "joint_3", "joint_4", "joint_5"]"#;
    std::fs::write(
        dir.join("bad-object.json"),
        format!(
            r#"{{"joints": {joints}, "objects": [{{"id": "x", "shape": "box", "size": [-1, 1, 1]}}],
                "problems": [{{"start": [0, 0, 0, 0, 0], "goal": [0.1, 0, 0, 0, 0]}}]}}"#
        ),
    )
    .expect("problems");
    // Point clouds for `cluster`: a good one, one with a NaN vertex, one with a coordinate
    // far beyond any sensor, one with no vertices, one whose vertex count lies.
    let ply = |n: usize, body: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex {n}\nproperty float x\nproperty float y\n\
             property float z\nend_header\n{body}"
        )
    };
    for (name, text) in [
        ("cloud.ply", ply(3, "0 0 0\n0.01 0 0\n0 0.01 0\n")),
        ("nan.ply", ply(2, "0 0 0\nnan 0 0\n")),
        ("far.ply", ply(2, "0 0 0\n1e300 0 0\n")),
        ("no-points.ply", ply(0, "")),
        ("short.ply", ply(1000, "0 0 0\n")),
    ] {
        std::fs::write(dir.join(name), text).expect("cloud");
    }
    std::fs::write(
        dir.join("bad-start.json"),
        format!(
            r#"{{"joints": {joints}, "objects": [],
                "problems": [{{"start": [0, 0], "goal": [0.1, 0, 0, 0, 0]}}]}}"#
        ),
    )
    .expect("problems");
    dir
}

/// Every file below `dir`: size, modification time and content.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, (u64, SystemTime, Vec<u8>)> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("read dir").flatten() {
            let p = e.path();
            let m = std::fs::symlink_metadata(&p).expect("metadata");
            if m.is_dir() {
                stack.push(p);
            } else {
                let content = if m.is_file() {
                    std::fs::read(&p).expect("read")
                } else {
                    Vec::new()
                };
                out.insert(p, (m.len(), m.modified().expect("mtime"), content));
            }
        }
    }
    out
}

fn cases() -> Vec<Case> {
    use Expect::*;
    let mut c = Vec::new();
    // robots, info
    c.push(case(&["robots", "--bogus"], Input));
    c.push(case(&["robots", "extra"], Input));
    for robot in [
        "wall-e",
        "",
        "./",
        "./subdir",
        "./binary.toml",
        "./huge.toml",
        "./empty.toml",
        "./nonexistent.toml",
        "/dev/zero",
        "./notes.txt",
    ] {
        c.push(case(&["info", robot, "--json"], Input));
    }
    for (name, _, _) in hostile_configs() {
        let path = format!("./{name}.toml");
        c.push(case(&["info", &path, "--json"], Input));
        c.push(case(
            &["fk", &path, "0", "0", "0", "0", "0", "--json"],
            Input,
        ));
    }
    // fk, jacobian: each hostile value in each position class, wrong counts, unknown names.
    for v in HOSTILE {
        c.push(case(
            &["fk", "locobot", v, "0", "0", "0", "0", "--json"],
            Input,
        ));
        c.push(case(&["fk", "locobot", "0", "0", "0", "0", v], Input));
        c.push(case(
            &[
                "jacobian", "sawyer", "0", "0", "0", v, "0", "0", "0", "--json",
            ],
            Input,
        ));
        c.push(case(&["jacobian", "locobot", v, "0", "0", "0", "0"], Input));
    }
    c.push(case(
        &["fk", "locobot", "0", "0", "0", "0", "--json"],
        Input,
    ));
    c.push(case(&["fk", "locobot", "--json"], Input));
    c.push(case(
        &[
            "fk", "locobot", "0", "0", "0", "0", "0", "--frame", "nowhere", "--json",
        ],
        Input,
    ));
    c.push(case(&["fk", "wall-e", "0", "--json"], Input));
    c.push(case(&["jacobian", "sawyer", "0", "0", "--json"], Input));
    // ik
    for v in HOSTILE {
        c.push(case(
            &[
                "ik",
                "locobot",
                "--position",
                v,
                "0",
                "0.2",
                "--pitch",
                "1",
                "--json",
            ],
            Input,
        ));
        c.push(case(
            &[
                "ik",
                "locobot",
                "--position",
                "0.3",
                "0",
                "0.2",
                "--pitch",
                v,
                "--json",
            ],
            Input,
        ));
        c.push(case(
            &[
                "ik",
                "locobot",
                "--position",
                "0.3",
                "0",
                "0.2",
                "--pitch",
                "1",
                "--roll",
                v,
            ],
            Input,
        ));
        c.push(case(
            &[
                "ik",
                "sawyer",
                "--position",
                "0.6",
                "0.1",
                "0.4",
                "--quaternion",
                "0",
                v,
                "0",
                "0",
                "--json",
            ],
            Input,
        ));
        c.push(case(
            &[
                "ik",
                "sawyer",
                "--position",
                "0.6",
                "0.1",
                "0.4",
                "--rpy",
                v,
                "0",
                "0",
                "--json",
            ],
            Input,
        ));
    }
    c.push(case(
        &[
            "ik",
            "sawyer",
            "--position",
            "0.6",
            "0.1",
            "0.4",
            "--quaternion",
            "0",
            "1e30",
            "0",
            "0",
            "--json",
        ],
        Input,
    ));
    c.push(case(
        &[
            "ik",
            "sawyer",
            "--position",
            "0.6",
            "0.1",
            "0.4",
            "--quaternion",
            "0",
            "0",
            "0",
            "0",
            "--json",
        ],
        Input,
    ));
    c.push(case(
        &["ik", "sawyer", "--position", "0.6", "0.1", "0.4", "--json"],
        Input,
    ));
    c.push(case(
        &[
            "ik",
            "sawyer",
            "--position",
            "0.6",
            "0.1",
            "--quaternion",
            "0",
            "0",
            "0",
            "1",
        ],
        Input,
    ));
    c.push(case(
        &[
            "ik",
            "locobot",
            "--position",
            "0.3",
            "0",
            "0.2",
            "--pitch",
            "1",
            "--seed",
            "0",
            "1",
            "--json",
        ],
        Input,
    ));
    c.push(case(
        &[
            "ik",
            "locobot",
            "--position",
            "0.3",
            "0",
            "0.2",
            "--pitch",
            "1",
            "--seed",
            "nan",
            "0",
            "0",
            "0",
            "0",
            "--json",
        ],
        Input,
    ));
    // scene, snapshot: unknown and hostile scene names and files, hostile poses, angles and
    // ranges, robots without a camera, wrong counts.
    for scene in [
        "kitchen",
        "",
        "./",
        "./binary.toml",
        "./huge.toml",
        "./empty.toml",
        "/dev/zero",
        "./notes.txt",
        "./nonexistent.toml",
    ] {
        c.push(case(&["scene", scene, "--json"], Input));
        c.push(case(
            &[
                "snapshot", "locobot", "--scene", scene, "--out", "./out", "--json",
            ],
            Input,
        ));
    }
    for v in HOSTILE {
        c.push(case(
            &[
                "snapshot", "locobot", "--pan", v, "--out", "./out", "--json",
            ],
            Input,
        ));
        c.push(case(
            &["snapshot", "locobot", "--tilt", v, "--out", "./out"],
            Input,
        ));
        c.push(case(
            &[
                "snapshot", "locobot", "--base", v, "0", "0", "--out", "./out", "--json",
            ],
            Input,
        ));
        c.push(case(
            &[
                "snapshot", "locobot", "--joints", "0", v, "0", "0", "0", "--out", "./out",
                "--json",
            ],
            Input,
        ));
        c.push(case(
            &[
                "snapshot",
                "locobot",
                "--depth-range",
                "0.2",
                v,
                "--out",
                "./out",
                "--json",
            ],
            Input,
        ));
    }
    // arm-plan: hostile goals, starts and paddings, wrong counts, unknown scenes, a goal out
    // of the limits (the input's fault) and one in the robot's own body (the planner's refusal).
    for v in HOSTILE {
        c.push(case(
            &[
                "arm-plan", "locobot", "--to", "0", v, "0", "0", "0", "--json",
            ],
            Input,
        ));
        c.push(case(
            &[
                "arm-plan", "locobot", "--from", v, "0", "0", "0", "0", "--to", "0", "0", "0", "0",
                "0", "--json",
            ],
            Input,
        ));
    }
    // Beyond the hostile numbers, a negative padding and one over the largest (0.2 m).
    for padding in HOSTILE.iter().chain(&["-0.01", "0.5"]) {
        c.push(case(
            &[
                "arm-plan",
                "locobot",
                "--to",
                "0",
                "0",
                "0",
                "0",
                "0",
                "--padding",
                padding,
                "--json",
            ],
            Input,
        ));
    }
    c.push(case(
        &["arm-plan", "locobot", "--to", "0", "0", "--json"],
        Input,
    ));
    c.push(case(
        &[
            "arm-plan", "locobot", "--scene", "kitchen", "--to", "0", "0", "0", "0", "0", "--json",
        ],
        Input,
    ));
    c.push(case(
        &[
            "arm-plan", "locobot", "--to", "3", "0", "0", "0", "0", "--json",
        ],
        Input,
    ));
    c.push(case(
        &[
            "arm-plan", "locobot", "--to", "0", "1.4", "0.6", "0", "0", "--json",
        ],
        Failure,
    ));
    c.push(case(
        &["snapshot", "sawyer", "--out", "./out", "--json"],
        Input,
    ));
    c.push(case(
        &[
            "snapshot", "locobot", "--joints", "0", "0", "--out", "./out", "--json",
        ],
        Input,
    ));
    c.push(case(
        &[
            "snapshot", "locobot", "--tilt", "3", "--out", "./out", "--json",
        ],
        Input,
    ));
    c.push(case(
        &[
            "snapshot",
            "locobot",
            "--depth-range",
            "1.5",
            "0.2",
            "--out",
            "./out",
            "--json",
        ],
        Input,
    ));
    c.push(case(&["snapshot", "locobot", "--json"], Input));
    // An output path that is a file, not a directory.
    c.push(case(
        &["snapshot", "locobot", "--out", "./notes.txt", "--json"],
        Failure,
    ));
    // base-move: absurd goals for every controller, unknown controller, wrong counts.
    for v in HOSTILE {
        c.push(case(
            &["base-move", "locobot", "--relative", v, "0", "0", "--json"],
            Input,
        ));
        c.push(case(
            &["base-move", "locobot_lite", "--relative", "0", "0", v],
            Input,
        ));
    }
    for ctl in ["proportional", "lqr", "ilqr", "dwa"] {
        c.push(case(
            &[
                "base-move",
                "locobot",
                "--relative",
                "1e9",
                "0",
                "0",
                "--controller",
                ctl,
                "--json",
            ],
            Input,
        ));
        c.push(case(
            &[
                "base-move",
                "locobot",
                "--relative",
                "1000",
                "1000",
                "0",
                "--controller",
                ctl,
                "--json",
            ],
            Input,
        ));
    }
    c.push(case(
        &[
            "base-move",
            "locobot",
            "--relative",
            "1",
            "0",
            "0",
            "--controller",
            "warp",
            "--json",
        ],
        Input,
    ));
    c.push(case(
        &["base-move", "locobot", "--relative", "1", "1", "--json"],
        Input,
    ));
    c.push(case(
        &["base-move", "sawyer", "--relative", "1", "0", "0", "--json"],
        Input,
    ));
    c.push(case(
        &[
            "base-move",
            "locobot",
            "--relative",
            "1",
            "0",
            "0",
            "--seed",
            "-1",
            "--json",
        ],
        Input,
    ));
    // calibrate-odometry, bench base, demo
    c.push(case(&["calibrate-odometry", "wall-e", "--json"], Input));
    c.push(case(&["calibrate-odometry", "sawyer", "--json"], Input));
    c.push(case(
        &[
            "bench",
            "base",
            "--trials",
            "18446744073709551615",
            "--json",
        ],
        Input,
    ));
    c.push(case(&["bench", "base", "--trials", "0", "--json"], Input));
    c.push(case(&["bench", "base", "--trials", "-1", "--json"], Input));
    c.push(case(
        &[
            "bench", "base", "--trials", "1", "--robot", "wall-e", "--json",
        ],
        Input,
    ));
    c.push(case(
        &[
            "bench", "base", "--trials", "1", "--robot", "sawyer", "--json",
        ],
        Input,
    ));
    c.push(case(&["bench", "warp"], Input));
    // bench grasp: unknown or armless robots, unknown scenes and scenes without a table,
    // absurd trial counts and seeds, a backend without its port or firmware.
    fn grasp<'a>(extra: &[&'a str]) -> Vec<&'a str> {
        let mut a = vec!["bench", "grasp"];
        a.extend_from_slice(extra);
        a.extend_from_slice(&["--trials", "1", "--json"]);
        a
    }
    for robot in ["wall-e", "", "./binary.toml", "/dev/zero", "sawyer"] {
        c.push(case(&grasp(&[robot]), Input));
    }
    for scene in ["kitchen", "", "./binary.toml", "/dev/zero", "empty"] {
        c.push(case(&grasp(&["locobot", "--scene", scene]), Input));
    }
    for n in ["0", "-1", "1e9", "10001", "18446744073709551616", "nan", ""] {
        c.push(case(
            &["bench", "grasp", "locobot", "--trials", n, "--json"],
            Input,
        ));
    }
    for seed in ["-1", "nan", "1e300", ""] {
        c.push(case(&grasp(&["locobot", "--seed", seed]), Input));
    }
    c.push(case(&grasp(&["locobot", "--backend", "serial"]), Input));
    c.push(case(&grasp(&["locobot", "--backend", "warp"]), Input));
    c.push(case(
        &grasp(&[
            "locobot",
            "--backend",
            "emulated",
            "--firmware",
            "./missing.elf",
        ]),
        Input,
    ));
    // bench plan: unknown robots, scenes and planners, absurd counts and limits, malformed
    // problems files; an export path is never written when the input is refused.
    fn plan<'a>(extra: &[&'a str]) -> Vec<&'a str> {
        let mut a = vec!["bench", "plan"];
        a.extend_from_slice(extra);
        a
    }
    for robot in ["wall-e", "", "./binary.toml", "./empty.toml", "/dev/zero"] {
        c.push(case(
            &plan(&["--robot", robot, "--scene", "tabletop", "--json"]),
            Input,
        ));
    }
    for scene in ["kitchen", "", "./binary.toml", "/dev/zero", "./notes.txt"] {
        c.push(case(
            &plan(&["--robot", "locobot", "--scene", scene, "--json"]),
            Input,
        ));
    }
    for n in [
        "0",
        "-1",
        "1e9",
        "1000000000",
        "18446744073709551616",
        "nan",
        "",
    ] {
        c.push(case(
            &plan(&[
                "--robot",
                "locobot",
                "--scene",
                "tabletop",
                "--problems",
                n,
                "--json",
            ]),
            Input,
        ));
    }
    for v in HOSTILE {
        c.push(case(
            &plan(&[
                "--robot",
                "locobot",
                "--scene",
                "tabletop",
                "--time-limit",
                v,
                "--json",
            ]),
            Input,
        ));
    }
    c.push(case(
        &plan(&[
            "--robot",
            "locobot",
            "--scene",
            "tabletop",
            "--planner",
            "warp",
            "--json",
        ]),
        Input,
    ));
    c.push(case(&plan(&["--robot", "locobot", "--json"]), Input));
    fn tabletop<'a>(flag: &'a str, v: &'a str) -> Vec<&'a str> {
        plan(&[
            "--robot", "locobot", "--scene", "tabletop", flag, v, "--json",
        ])
    }
    c.push(case(&tabletop("--engine", "warp"), Input));
    for v in HOSTILE.iter().copied().chain(["101"]) {
        c.push(case(&tabletop("--smoothing", v), Input));
    }
    for v in HOSTILE.iter().copied().chain(["100001"]) {
        c.push(case(&tabletop("--shortcuts", v), Input));
    }
    c.push(case(
        &plan(&[
            "--robot",
            "locobot",
            "--scene",
            "tabletop",
            "--problems-file",
            "./bad-start.json",
        ]),
        Input,
    ));
    c.push(case(
        &plan(&["--robot", "sawyer", "--problems-file", "./bad-start.json"]),
        Input,
    ));
    for file in [
        "./bad-object.json",
        "./bad-start.json",
        "./notes.txt",
        "./binary.toml",
        "./huge.toml",
        "./empty.toml",
        "./subdir",
        "/dev/zero",
        "./nonexistent.json",
    ] {
        c.push(case(
            &plan(&[
                "--config",
                "locobot",
                "--problems-file",
                file,
                "--export",
                "./notes.txt",
                "--json",
            ]),
            Input,
        ));
    }
    c.push(case(
        &plan(&[
            "--robot",
            "wall-e",
            "--scene",
            "tabletop",
            "--export",
            "./notes.txt",
            "--ompl",
        ]),
        Input,
    ));
    for export in ["./subdir", "./no/such/dir/out.json", "/"] {
        c.push(case(
            &plan(&[
                "--robot", "locobot", "--scene", "tabletop", "--export", export, "--json",
            ]),
            Input,
        ));
    }
    // collision-matrix: unknown robots, absurd sample counts.
    // `serve`: robots of one world (`--also`) and start poses, refused before anything serves.
    fn serve<'a>(extra: &[&'a str]) -> Vec<&'a str> {
        let mut a = vec![
            "serve",
            "locobot",
            "--no-camera",
            "--listen",
            "tcp/127.0.0.1:0",
        ];
        a.extend_from_slice(extra);
        a
    }
    for also in [
        "",
        "/b",
        "/b=locobot",
        "/b=locobot@1,2",
        "/b=locobot@1,2,3,4",
        "/b=locobot@nan,0,0",
        "/b=locobot@1e300,0,0",
        "/b=locobot@inf,0,0",
        "/b=@2,0,0",
        "/b=wall-e@2,0,0",
        "/b=./binary.toml@2,0,0",
        "/b=/dev/zero@2,0,0",
        "/=locobot@2,0,0",
        "/b=locobot@0.1,0,0",
        "bad ns=locobot@2,0,0",
    ] {
        c.push(case(&serve(&["--also", also]), Input));
    }
    c.push(case(
        &serve(&["--also", "/b=locobot@2,0,0", "--also", "/b=locobot@-2,0,0"]),
        Input,
    ));
    c.push(case(
        &serve(&[
            "--also",
            "/b=locobot@2,0,0",
            "--backend",
            "serial",
            "--port",
            "/dev/null",
        ]),
        Input,
    ));
    for v in HOSTILE {
        c.push(case(&serve(&["--start-pose", v, "0", "0"]), Input));
    }
    c.push(case(&serve(&["--start-pose", "0", "0"]), Input));
    for robot in ["wall-e", "", "./binary.toml", "./huge.toml", "/dev/zero"] {
        c.push(case(&["collision-matrix", robot], Input));
    }
    for n in ["0", "-1", "1e9", "1000000000", "nan"] {
        c.push(case(
            &["collision-matrix", "locobot", "--samples", n],
            Input,
        ));
    }
    // record: no file replaced, none made for a refused invocation.
    for out in ["notes.txt", "subdir", "locobot.urdf"] {
        c.push(case(
            &["record", "locobot", "-o", out, "--seconds", "0.1"],
            Input,
        ));
    }
    c.push(case(
        &[
            "record",
            "locobot",
            "-o",
            "no/such/dir/x.mcap",
            "--seconds",
            "0.1",
        ],
        Failure,
    ));
    for n in HOSTILE {
        c.push(case(
            &["record", "locobot", "-o", "new.mcap", "--seconds", n],
            Input,
        ));
        c.push(case(
            &[
                "record",
                "locobot",
                "-o",
                "new.mcap",
                "--progress",
                n,
                "--json",
            ],
            Input,
        ));
    }
    c.push(case(
        &["record", "wall-e", "-o", "new.mcap", "--json"],
        Input,
    ));
    // replay: files that are not recordings, nothing to do, hostile numbers.
    for file in ["notes.txt", "subdir", "/dev/zero", "binary.toml"] {
        c.push(case(&["replay", file, "--slam", "--json"], Input));
        c.push(case(&["replay", file, "--commands"], Input));
    }
    c.push(case(
        &["replay", "nothing.mcap", "--slam", "--json"],
        Failure,
    ));
    c.push(case(&["replay", "notes.txt"], Input));
    for n in HOSTILE {
        c.push(case(
            &["replay", "notes.txt", "--slam", "--speed", n],
            Input,
        ));
        c.push(case(
            &["replay", "notes.txt", "--slam", "--start", n, "0", "0"],
            Input,
        ));
    }
    // export-lerobot: files that are not recordings, an existing directory, tasks that do
    // not match the recordings, hostile rates; no dataset is made.
    for file in ["notes.txt", "subdir", "/dev/zero", "binary.toml"] {
        c.push(case(
            &["export-lerobot", file, "-o", "new-dataset", "--task", "t"],
            Input,
        ));
    }
    c.push(case(
        &[
            "export-lerobot",
            "nothing.mcap",
            "-o",
            "new-dataset",
            "--task",
            "t",
        ],
        Failure,
    ));
    c.push(case(
        &["export-lerobot", "notes.txt", "-o", "subdir", "--task", "t"],
        Input,
    ));
    c.push(case(
        &[
            "export-lerobot",
            "notes.txt",
            "notes.txt",
            "-o",
            "new-dataset",
            "--task",
            "a",
            "--task",
            "b",
            "--task",
            "c",
        ],
        Input,
    ));
    let export = |extra: &[&'static str]| -> Vec<&'static str> {
        let mut v = vec!["export-lerobot", "notes.txt", "-o", "new-dataset"];
        v.extend_from_slice(extra);
        v
    };
    c.push(case(&export(&["--task", " "]), Input));
    for n in HOSTILE {
        c.push(case(&export(&["--task", "t", "--fps", n]), Input));
    }
    c.push(case(&["demo", "--robot", "wall-e"], Input));
    c.push(case(&["demo", "--robot", ""], Input));
    // sim-firmware: never replace what exists at the link path.
    c.push(case(
        &["sim-firmware", "locobot", "--link", "notes.txt"],
        Input,
    ));
    c.push(case(
        &["sim-firmware", "locobot", "--link", "subdir"],
        Input,
    ));
    c.push(case(
        &["sim-firmware", "locobot", "--link", "locobot.urdf"],
        Input,
    ));
    c.push(case(
        &["sim-firmware", "locobot", "--link", "no/such/dir/link"],
        Failure,
    ));
    c.push(case(
        &["sim-firmware", "wall-e", "--link", "new-link"],
        Input,
    ));
    // The host-run firmware: unknown robots, robots without their own cables, devices that
    // are files, directories or nothing, and a link path that exists; the hardware check
    // refuses before anything is opened for writing or created.
    for robot in ["wall-e", "", "./notes.txt"] {
        c.push(case(&["hardware", "check", robot, "--json"], Input));
        c.push(case(&["drive", robot, "--link", "new-link"], Input));
    }
    c.push(case(&["hardware", "check", "sawyer", "--json"], Failure));
    for dev in [
        "./notes.txt",
        "./binary.toml",
        "./",
        "",
        "/dev/zero",
        "no/such/device",
    ] {
        c.push(case(
            &[
                "hardware", "check", "locobot", "--servo", dev, "--base", dev, "--json",
            ],
            Failure,
        ));
        c.push(case(
            &[
                "drive",
                "locobot",
                "--link",
                "notes.txt",
                "--servo",
                dev,
                "--base",
                dev,
            ],
            Failure,
        ));
        c.push(case(
            &["demo", "--backend", "direct", "--servo", dev, "--base", dev],
            Failure,
        ));
    }
    for v in HOSTILE.iter().chain(&["0", "-1", "1e6"]) {
        c.push(case(
            &["bench", "host-loop", "--seconds", v, "--json"],
            Input,
        ));
    }
    c.push(case(
        &["bench", "host-loop", "--robot", "sawyer", "--json"],
        Input,
    ));
    // scene --map, nav-plan: files that are not maps, existing files not to write over,
    // hostile numbers and resolutions.
    for map in [
        "./notes.txt",
        "./binary.toml",
        "./empty.toml",
        "/dev/zero",
        "./",
        "",
        "./nonexistent.yaml",
        "./bad-map.yaml",
        "./subdir",
    ] {
        c.push(case(
            &[
                "nav-plan", "--map", map, "--from", "0.5", "0.5", "--to", "1", "1", "--radius",
                "0.1", "--json",
            ],
            Input,
        ));
        if map != "./nonexistent.yaml" {
            c.push(case(&["scene", "apartment", "--map", map, "--json"], Input));
        }
    }
    c.push(case(
        &["scene", "apartment", "--map", "./map.yaml", "--json"],
        Input,
    ));
    for v in HOSTILE {
        c.push(case(
            &[
                "scene",
                "apartment",
                "--map",
                "./new.yaml",
                "--resolution",
                v,
                "--json",
            ],
            Input,
        ));
        for (from, to, r) in [
            ([v, "0.5"], ["1", "1"], "0.1"),
            (["0.5", "0.5"], ["1", v], "0.1"),
            (["0.5", "0.5"], ["1", "1"], v),
        ] {
            c.push(case(
                &[
                    "nav-plan",
                    "--map",
                    "./map.yaml",
                    "--from",
                    from[0],
                    from[1],
                    "--to",
                    to[0],
                    to[1],
                    "--radius",
                    r,
                    "--json",
                ],
                Input,
            ));
        }
    }
    // cluster: files that are not clouds or hold no usable points, and hostile parameters.
    for cloud in [
        "./notes.txt",
        "./binary.toml",
        "./empty.toml",
        "/dev/zero",
        "./",
        "",
        "./nonexistent.ply",
        "./subdir",
        "./nan.ply",
        "./far.ply",
        "./no-points.ply",
        "./short.ply",
    ] {
        c.push(case(
            &[
                "cluster",
                "--in",
                cloud,
                "--eps",
                "0.02",
                "--min-samples",
                "15",
                "--json",
            ],
            Input,
        ));
    }
    for eps in HOSTILE.iter().copied().chain(["0", "-0.02", "100.5", "-0"]) {
        c.push(case(
            &[
                "cluster",
                "--in",
                "./cloud.ply",
                "--eps",
                eps,
                "--min-samples",
                "2",
                "--json",
            ],
            Input,
        ));
    }
    for m in [
        "0",
        "-1",
        "1e3",
        "",
        "nan",
        "1000001",
        "18446744073709551615",
        "99999999999999999999999",
    ] {
        c.push(case(
            &[
                "cluster",
                "--in",
                "./cloud.ply",
                "--eps",
                "0.02",
                "--min-samples",
                m,
                "--json",
            ],
            Input,
        ));
    }
    c.push(case(
        &["cluster", "--eps", "0.02", "--min-samples", "15"],
        Input,
    ));
    c.push(case(
        &["cluster", "--in", "./cloud.ply", "--min-samples", "15"],
        Input,
    ));
    // bench push: unknown robots and scenes, a scene without a table, absurd trial counts,
    // a serial backend without its port.
    fn push<'a>(extra: &[&'a str]) -> Vec<&'a str> {
        let mut a = vec!["bench", "push"];
        a.extend_from_slice(extra);
        a
    }
    for robot in ["wall-e", "", "./binary.toml", "/dev/zero"] {
        c.push(case(&push(&[robot, "--trials", "1", "--json"]), Input));
    }
    for scene in ["kitchen", "", "./binary.toml", "/dev/zero", "empty"] {
        c.push(case(
            &push(&["locobot", "--scene", scene, "--trials", "1", "--json"]),
            Input,
        ));
    }
    for n in ["0", "-1", "1e9", "1000000000", "nan", ""] {
        c.push(case(&push(&["locobot", "--trials", n, "--json"]), Input));
    }
    c.push(case(
        &push(&["locobot", "--trials", "1", "--backend", "serial", "--json"]),
        Input,
    ));
    c.push(case(
        &push(&["locobot", "--trials", "1", "--backend", "warp", "--json"]),
        Input,
    ));
    // bench arm: unknown robots, a robot without a pitch-roll arm's poses, absurd cycles.
    for robot in ["wall-e", "", "/dev/zero"] {
        c.push(case(
            &["bench", "arm", robot, "--cycles", "1", "--json"],
            Input,
        ));
    }
    for n in ["0", "-1", "1e9", "100000", "nan", ""] {
        c.push(case(
            &["bench", "arm", "locobot", "--cycles", n, "--json"],
            Input,
        ));
    }
    c.push(case(&["teleport", "locobot"], Input));
    // teleop: unknown robots, scenes and backends, hostile times, and no terminal (the
    // table's standard input is not one).
    for robot in [
        "wall-e",
        "",
        "./nonexistent.toml",
        "./binary.toml",
        "/dev/zero",
    ] {
        c.push(case(&["teleop", robot], Input));
    }
    for v in HOSTILE.iter().copied().chain(["0", "-20", "1001"]) {
        c.push(case(&["teleop", "locobot", "--step-ms", v], Input));
        c.push(case(&["teleop", "locobot", "--repeat-delay", v], Input));
    }
    for args in [
        &["--backend", "bogus"][..],
        &["--backend", "serial"],
        &[
            "--backend",
            "serial",
            "--port",
            "./notes.txt",
            "--step-ms",
            "10",
        ],
        &["--backend", "emulated", "--step-ms", "10"],
        &["--scene", "nowhere"],
        &["--scene", "./notes.txt"],
        &["--seed", "-1"],
        &["--trace", "./notes.txt"],
        &[],
    ] {
        let mut a = vec!["teleop", "locobot"];
        a.extend_from_slice(args);
        c.push(case(&a, Input));
    }
    // calibrate-camera: hostile and absurd mount errors, counts, robots, scenes, output paths.
    for v in HOSTILE {
        for at in [1, 5] {
            let mut p = ["0"; 6];
            p[at] = v;
            let mut a = vec!["calibrate-camera", "locobot", "--perturb"];
            a.extend_from_slice(&p);
            a.push("--json");
            c.push(case(&a, Input));
        }
    }
    for args in [
        &["--perturb", "0.2", "0", "0", "0", "0", "0"][..],
        &["--perturb", "0", "0", "0", "0.6", "0", "0"],
        &["--perturb", "0", "0"],
        &["--poses", "0"],
        &["--poses", "7"],
        &["--grid", "0"],
        &["--grid", "99"],
        &["--poses", "-1"],
        &["--scene", "nowhere"],
        &["--out", "./no-such-dir/cal.toml"],
        &["--out", "."],
    ] {
        let mut a = vec!["calibrate-camera", "locobot"];
        a.extend_from_slice(args);
        a.push("--json");
        c.push(case(&a, Input));
    }
    c.push(case(&["calibrate-camera", "nobot", "--json"], Input));
    c.push(case(&["calibrate-camera", "sawyer", "--json"], Input));
    c.push(case(
        &[
            "calibrate-camera",
            "locobot",
            "--backend",
            "serial",
            "--json",
        ],
        Failure,
    ));
    c
}

struct Outcome {
    code: Option<i32>,
    stdout: String,
    stderr: String,
    took: Duration,
}

fn run(dir: &Path, args: &[String]) -> Outcome {
    let start = Instant::now();
    // `FERROBOT_CLI_BIN` runs the table against another build (e.g. an older one).
    let bin = std::env::var_os("FERROBOT_CLI_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_ferrobot")));
    let mut child = Command::new(bin)
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ferrobot starts");
    // Read both pipes on threads so that a chatty child never blocks on a full pipe.
    let mut out = child.stdout.take().expect("stdout");
    let mut err = child.stderr.take().expect("stderr");
    let t_out = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut out, &mut s);
        s
    });
    let t_err = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut err, &mut s);
        s
    });
    // The limit is a budget, not a wait for state: the child ends by itself or is a hang.
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break Some(s);
        }
        if start.elapsed() > LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Outcome {
        code: status.and_then(|s| s.code()),
        stdout: t_out.join().unwrap_or_default(),
        stderr: t_err.join().unwrap_or_default(),
        took: start.elapsed(),
    }
}

/// Any `null` (a NaN or infinity serialised) anywhere in a JSON value.
fn has_null(v: &serde_json::Value) -> bool {
    match v {
        serde_json::Value::Null => true,
        serde_json::Value::Array(a) => a.iter().any(has_null),
        serde_json::Value::Object(o) => o.values().any(has_null),
        _ => false,
    }
}

fn judge(c: &Case, o: &Outcome) -> Result<(), String> {
    let code = o.code.ok_or_else(|| {
        if o.took > LIMIT {
            format!("hung (killed after {:?})", o.took)
        } else {
            "ended by a signal (abort)".to_string()
        }
    })?;
    if o.stderr.contains("panicked") || code == 101 {
        return Err(format!("panicked: {}", o.stderr));
    }
    match c.expect {
        Expect::Input if code != 2 => {
            return Err(format!(
                "exit code {code}, expected 2; stdout {:?} stderr {:?}",
                o.stdout, o.stderr
            ))
        }
        Expect::Failure if code == 0 => {
            return Err(format!("succeeded on nonsense: {:?}", o.stdout))
        }
        _ => {}
    }
    let message = if c.args.iter().any(|a| a == "--json") {
        let lines: Vec<&str> = o.stdout.lines().collect();
        if lines.len() != 1 {
            return Err(format!(
                "--json printed {} lines: {:?}",
                lines.len(),
                o.stdout
            ));
        }
        let v: serde_json::Value = serde_json::from_str(lines[0])
            .map_err(|e| format!("not JSON ({e}): {:?}", lines[0]))?;
        if has_null(&v) || v["success"] != serde_json::json!(false) {
            return Err(format!("not a clean error object: {v}"));
        }
        v["error"].as_str().unwrap_or_default().to_string()
    } else {
        // `sim-firmware` speaks JSON lines always; the others write errors to stderr.
        format!("{}{}", o.stderr, o.stdout)
    };
    if message.trim().is_empty() {
        return Err("no error message".into());
    }
    Ok(())
}

#[test]
fn hostile_invocations_end_quickly_with_clear_errors_and_touch_no_file() {
    let dir = scratch();
    let before = snapshot(&dir);
    let cases = cases();
    let mut failures = Vec::new();
    let mut slowest = Duration::ZERO;
    for c in &cases {
        let o = run(&dir, &c.args);
        slowest = slowest.max(o.took);
        if let Err(why) = judge(c, &o) {
            failures.push(format!("ferrobot {}: {why}", c.args.join(" ")));
        }
        // Nothing that was there before may change, whatever the case.
        let now = snapshot(&dir);
        for (p, was) in &before {
            if now.get(p) != Some(was) {
                failures.push(format!(
                    "ferrobot {}: touched {} which it did not create",
                    c.args.join(" "),
                    p.display()
                ));
            }
        }
    }
    // The hostile configurations name their file and the key at fault.
    for (name, _, key) in hostile_configs() {
        let o = run(
            &dir,
            &["info".into(), format!("./{name}.toml"), "--json".into()],
        );
        if !(o.stdout.contains(&format!("{name}.toml")) && o.stdout.contains(key)) {
            failures.push(format!(
                "{name}.toml: the error does not name the file and {key}: {}",
                o.stdout
            ));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!(
        "cli_hostile: {} invocations, {} failures, slowest {:.2} s",
        cases.len(),
        failures.len(),
        slowest.as_secs_f64()
    );
    assert!(
        failures.is_empty(),
        "{} of {} failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
