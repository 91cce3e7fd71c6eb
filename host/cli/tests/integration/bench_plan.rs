//! `ferrobot bench plan` and `ferrobot collision-matrix`: the JSON summary's shape, an export
//! that FCL (the Python peer's `check`) finds free of collision at 1 mm (proven by either
//! engine), the export read back
//! as a problems file, and OMPL in the same run.
//!
//! The peer's tests need a Python with OMPL and FCL: `FERROBOT_PYTHON` (scripts/test.sh
//! installs them with `scripts/python-env.sh plan` and sets it; then they must be there), or
//! else the workspace's `target/py-venv`; without either they are skipped, saying so.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::support;
use support::ferrobot;

/// A fresh scratch directory for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "ferrobot-cli-bench-plan-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch");
    dir
}

fn peer_script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../planning/peer/plan_peer.py")
}

/// The peer's Python, or `None` (skip): [`ferrobot_peers::for_test`]'s rule.
fn peer_python() -> Option<PathBuf> {
    ferrobot_peers::for_test("ompl.geometric, fcl, numpy", "scripts/python-env.sh plan")
}

fn keys(v: &serde_json::Value) -> Vec<String> {
    let mut k: Vec<String> = v
        .as_object()
        .map(|o| o.keys().cloned().collect())
        .unwrap_or_default();
    k.sort();
    k
}

fn successes(export: &Path) -> Vec<bool> {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(export).expect("export")).expect("JSON");
    v["problems"]
        .as_array()
        .expect("problems")
        .iter()
        .map(|p| p["success"].as_bool().expect("success"))
        .collect()
}

#[test]
fn the_summary_has_its_keys_and_every_tabletop_problem_is_solved() {
    let (ok, v, text) = ferrobot(&[
        "bench",
        "plan",
        // Generous: the test checks outcomes, not speed, on a busy machine too. Above 200 s,
        // the hub's reach (three times it) is held to the planner's 600 s (it was refused, and
        // every candidate counted unreached).
        "--time-limit",
        "300",
        "--robot",
        "locobot",
        "--scene",
        "tabletop",
        "--problems",
        "5",
        "--seed",
        "1",
        "--json",
    ]);
    assert!(ok, "{text}");
    assert_eq!(
        keys(&v),
        [
            "collision_checks_per_s",
            "edges_checked",
            "engine",
            "path_length_rad",
            "planner",
            "problems",
            "robot",
            "scene",
            "states_checked",
            "success_rate",
            "time_ms",
            "unreached"
        ]
    );
    assert_eq!(keys(&v["time_ms"]), ["max", "median", "p95"]);
    // The LoCoBot's spheres cover meshes: its edges are proven by advancement.
    assert_eq!(v["engine"], "Advancement", "{v}");
    // Five plans prove tens of edges or more, each measuring a state or more.
    let (edges, states) = (v["edges_checked"].as_u64(), v["states_checked"].as_u64());
    assert!(edges.is_some_and(|e| e >= 5), "{v}");
    assert!(states >= edges, "{v}");
    // No tabletop problem is cut off from the arm's home.
    assert_eq!(v["unreached"], 0, "{v}");
    assert_eq!(keys(&v["path_length_rad"]), ["median"]);
    assert_eq!(v["success_rate"], 1.0, "{v}");
    assert_eq!(v["problems"], 5);
    assert_eq!(v["robot"], "locobot");
    assert_eq!(v["scene"], "tabletop");
    assert_eq!(v["planner"], "rrt-connect");
    let t = &v["time_ms"];
    let (median, p95, max) = (
        t["median"].as_f64().expect("median"),
        t["p95"].as_f64().expect("p95"),
        t["max"].as_f64().expect("max"),
    );
    assert!(0.0 < median && median <= p95 && p95 <= max, "{t}");
    assert!(v["path_length_rad"]["median"].as_f64().expect("length") > 0.0);
    assert!(v["collision_checks_per_s"].as_f64().expect("rate") > 0.0);
}

#[test]
fn an_export_is_free_under_fcl_and_plans_again_as_a_problems_file() {
    let dir = scratch("export");
    let export = dir.join("tabletop.json");
    let ex = export.to_str().expect("utf-8");
    let (ok, v, text) = ferrobot(&[
        "bench",
        "plan",
        // Generous: the test checks outcomes, not speed, on a busy machine too.
        "--time-limit",
        "30",
        "--robot",
        "locobot",
        "--scene",
        "tabletop",
        "--problems",
        "5",
        "--seed",
        "2",
        "--export",
        ex,
        "--json",
    ]);
    assert!(ok, "{text}");
    // The bundled URDF and the scene's two meshes are written beside the export.
    let e: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&export).expect("export")).expect("JSON");
    assert_eq!(e["urdf"], "tabletop.urdf");
    assert!(dir.join("tabletop.urdf").is_file());
    let meshes: Vec<&str> = e["objects"]
        .as_array()
        .expect("objects")
        .iter()
        .filter_map(|o| o["mesh"].as_str())
        .collect();
    assert_eq!(meshes.len(), 2, "{meshes:?}");
    assert!(meshes.iter().all(|m| dir.join(m).is_file()));
    assert_eq!(e["root_link"], "base_footprint");
    assert!(e["objects"]
        .as_array()
        .expect("objects")
        .iter()
        .any(|o| o["id"] == "floor"));
    assert_eq!(successes(&export), vec![true; 5]);

    // The export as a problems file: the same problems, solved again, their edges proven by
    // the vectorised engine (the walk's exact stage often runs on the LoCoBot's covers).
    // The export planned again with `engine`, exported to `out`.
    let replan = |engine: &str, out: &Path| {
        ferrobot(&[
            "bench",
            "plan",
            // Generous: the test checks outcomes, not speed, on a busy machine too.
            "--time-limit",
            "30",
            "--config",
            "locobot",
            "--problems-file",
            ex,
            "--engine",
            engine,
            "--export",
            out.to_str().expect("utf-8"),
            "--json",
        ])
    };
    let again = dir.join("again.json");
    let (ok, w, text) = replan("lanes", &again);
    assert!(ok, "{text}");
    assert_eq!(w["engine"], "Lanes", "{w}");
    assert_eq!(w["success_rate"], v["success_rate"]);
    assert_eq!(w["problems"], 5);
    assert_eq!(successes(&again), successes(&export));
    // The same engine on the baseline's instructions (SSE2 halves, where the run above took
    // AVX2 on a CPU that has it): the same paths, value for value.
    let baseline = dir.join("baseline.json");
    let (ok, b, text) = replan("baseline", &baseline);
    assert!(ok, "{text}");
    assert_eq!(b["engine"], "Baseline", "{b}");
    // Every problem's start, goal, success and path; not its time.
    let paths = |f: &Path| {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(f).expect("export")).expect("JSON");
        let problems = v["problems"].as_array().expect("problems").iter();
        problems
            .map(|p| [&p["start"], &p["goal"], &p["success"], &p["path"]].map(|x| x.clone()))
            .collect::<Vec<_>>()
    };
    assert_eq!(paths(&baseline), paths(&again));

    if let Some(py) = peer_python() {
        for file in [&export, &again] {
            let out = Command::new(&py)
                .arg(peer_script())
                .arg("check")
                .arg(file)
                .output()
                .expect("peer runs");
            let report: serde_json::Value =
                serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null);
            assert!(
                out.status.success() && report["ok"] == true,
                "FCL finds collisions on {}: {report} {}",
                file.display(),
                String::from_utf8_lossy(&out.stderr)
            );
            assert_eq!(report["paths"], 5, "{report}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ompl_runs_in_the_same_run() {
    if peer_python().is_none() {
        return;
    }
    let (ok, v, text) = ferrobot(&[
        "bench",
        "plan",
        "--robot",
        "locobot",
        "--scene",
        "tabletop",
        "--problems",
        "2",
        "--ompl",
        "--ompl-time-limit",
        "0.5",
        "--json",
    ]);
    assert!(ok, "{text}");
    let peer = &v["peer"];
    assert_eq!(peer["planner"], "ompl-RRTConnect", "{v}");
    assert_eq!(peer["problems"], 2);
    assert!(
        peer["ratio_median"].as_f64().expect("ratio") > 0.0,
        "{peer}"
    );
    // OMPL gets the same extension step as ours: the LoCoBot's configured one.
    let range = ferrobot::RobotConfig::bundled("locobot")
        .expect("locobot")
        .arm
        .and_then(|a| a.planning_range);
    assert_eq!(peer["range_rad"].as_f64(), range, "{peer}");
}

#[test]
fn problems_files_written_by_anyone_are_checked() {
    let dir = scratch("files");
    let joints = r#"["joint_1", "joint_2", "joint_3", "joint_4", "joint_5"]"#;
    let problem = r#"[{"start": [0, 0, 0, 0, 0], "goal": [0.5, 0, 0, 0, 0]}]"#;
    let file = |name: &str, joints: &str, objects: &str, problems: &str| {
        let p = dir.join(name);
        std::fs::write(
            &p,
            format!(r#"{{"joints": {joints}, "objects": {objects}, "problems": {problems}}}"#),
        )
        .expect("write");
        p
    };
    std::fs::write(
        dir.join("tetra.obj"),
        "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .expect("mesh");
    // Every shape, a mesh relative to the file, a quaternion a little off unit length, and
    // the keys `scene --json` adds (read and ignored).
    let good = file(
        "good.json",
        joints,
        r#"[{"id": "b", "shape": "box", "size": [0.1, 0.1, 0.1], "position": [-0.6, 0, 0.3],
              "colour": [0.8, 0.2, 0.2], "static": true},
            {"id": "c", "shape": "cylinder", "size": [0.05, 0.2], "position": [-0.6, 0.3, 0.3]},
            {"id": "s", "shape": "sphere", "size": [0.05], "position": [-0.6, -0.3, 0.3]},
            {"id": "k", "shape": "capsule", "size": [0.03, 0.1], "position": [-0.6, 0.5, 0.3],
             "quaternion": [0, 0, 0.70711, 0.70711]},
            {"id": "m", "shape": "mesh", "mesh": "tetra.obj", "position": [-0.6, -0.5, 0.3]}]"#,
        problem,
    );
    let (ok, v, text) = ferrobot(&[
        "bench",
        "plan",
        // Generous: the test checks outcomes, not speed, on a busy machine too.
        "--time-limit",
        "30",
        "--robot",
        "locobot",
        "--problems-file",
        good.to_str().expect("utf-8"),
        "--json",
    ]);
    assert!(ok, "{text}");
    assert_eq!(v["success_rate"], 1.0, "{v}");
    let bad = [
        (
            "negative.json",
            joints,
            r#"[{"id": "neg", "shape": "box", "size": [0.1, -0.1, 0.1]}]"#,
            problem,
            "neg",
        ),
        (
            "cone.json",
            joints,
            r#"[{"id": "cone", "shape": "cone", "size": [0.1, 0.1]}]"#,
            problem,
            "cone",
        ),
        (
            "count.json",
            joints,
            r#"[{"id": "short", "shape": "box", "size": [0.1, 0.1]}]"#,
            problem,
            "short",
        ),
        (
            "pose.json",
            joints,
            r#"[{"id": "far", "shape": "sphere", "size": [0.1], "position": [1e300, 0, 0]}]"#,
            problem,
            "far",
        ),
        (
            "quaternion.json",
            joints,
            r#"[{"id": "spin", "shape": "sphere", "size": [0.1], "quaternion": [0, 0, 0, 0]}]"#,
            problem,
            "spin",
        ),
        (
            "nomesh.json",
            joints,
            r#"[{"id": "ghost", "shape": "mesh", "mesh": "missing.obj"}]"#,
            problem,
            "ghost",
        ),
        (
            "twice.json",
            joints,
            r#"[{"id": "dup", "shape": "sphere", "size": [0.1]},
                {"id": "dup", "shape": "sphere", "size": [0.1]}]"#,
            problem,
            "dup",
        ),
        (
            "joints.json",
            r#"["joint_1", "joint_2"]"#,
            "[]",
            problem,
            "joints",
        ),
        (
            "length.json",
            joints,
            "[]",
            r#"[{"start": [0, 0, 0, 0], "goal": [0, 0, 0, 0, 0]}]"#,
            "problems[0].start",
        ),
        (
            "limits.json",
            joints,
            "[]",
            r#"[{"start": [0, 0, 0, 0, 0], "goal": [0, 0, 0, 0, 1e300]}]"#,
            "problems[0].goal",
        ),
        (
            "typo.json",
            joints,
            r#"[{"id": "lost", "shape": "sphere", "size": [0.1], "positon": [0.5, 0, 0.3]}]"#,
            problem,
            "positon",
        ),
        (
            "link.json",
            joints,
            r#"[{"id": "gripper_link", "shape": "sphere", "size": [0.1], "position": [0.5, 0, 0.3]}]"#,
            problem,
            "gripper_link",
        ),
        ("none.json", joints, "[]", "[]", "problems"),
    ];
    for (name, j, objects, problems, named) in bad {
        let p = file(name, j, objects, problems);
        let (ok, v, text) = ferrobot(&[
            "bench",
            "plan",
            "--robot",
            "locobot",
            "--problems-file",
            p.to_str().expect("utf-8"),
            "--json",
        ]);
        assert!(!ok, "{name}: {text}");
        let error = v["error"].as_str().unwrap_or_default();
        assert!(
            error.contains(named) && v["input_error"] == true,
            "{name}: the error does not name {named:?}: {text}"
        );
        assert!(!text.contains("panicked"), "{name}: {text}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn collision_matrix_prints_the_stored_section() {
    let (ok, _, text) = ferrobot(&["collision-matrix", "sawyer", "--samples", "10000"]);
    assert!(ok, "{text}");
    assert!(text.contains("[collision]\ndisabled = ["), "{text}");
    let stored = include_str!("../../../description/robots/sawyer.toml");
    assert!(
        stored.ends_with(&text),
        "sawyer.toml does not end with the section computed now:\n{text}"
    );
}

/// The path of the VAMP comparison (`host/planning/peer/vamp_peer.py`): a description given
/// with `--config` whose hand holds two fixed finger joints, the second keeping a `<mimic>`
/// of the first, as VAMP's `panda_spherized.urdf` has them. urdfdom ignores such a tag; so do
/// we, and the arm plans (it was refused from 3e37cd8 on, and the comparison solved 0 of 699).
#[test]
fn a_description_whose_fixed_fingers_keep_a_mimic_plans_as_vamps_panda_does() {
    let dir = scratch("fixed-mimic");
    let robots = Path::new(env!("CARGO_MANIFEST_DIR")).join("../description/robots");
    let urdf = std::fs::read_to_string(robots.join("sawyer.urdf")).expect("the Sawyer's URDF");
    let fingers = r#"
  <link name="finger_left"/><link name="finger_right"/>
  <joint name="finger_joint1" type="fixed"><parent link="right_hand"/><child link="finger_left"/>
    <origin xyz="0 0.04 0.05"/></joint>
  <joint name="finger_joint2" type="fixed"><parent link="right_hand"/><child link="finger_right"/>
    <origin xyz="0 -0.04 0.05"/><mimic joint="finger_joint1"/></joint>
</robot>"#;
    assert!(urdf.contains("</robot>"));
    std::fs::write(dir.join("sawyer.urdf"), urdf.replace("</robot>", fingers)).expect("URDF");
    std::fs::copy(robots.join("sawyer.toml"), dir.join("sawyer.toml")).expect("description");
    let home = [0.002, -1.182, 0.002, 2.177, 0.001, 0.567, 3.316];
    let mut goal = home;
    goal[0] += 0.3;
    let problems = dir.join("problems.json");
    std::fs::write(
        &problems,
        serde_json::json!({
            "joints": ["right_j0", "right_j1", "right_j2", "right_j3", "right_j4", "right_j5", "right_j6"],
            "objects": [],
            "problems": [{"start": home, "goal": goal}],
        })
        .to_string(),
    )
    .expect("problems");
    let (ok, v, text) = ferrobot(&[
        "bench",
        "plan",
        "--config",
        dir.join("sawyer.toml").to_str().expect("utf-8"),
        "--problems-file",
        problems.to_str().expect("utf-8"),
        "--time-limit",
        "30",
        "--json",
    ]);
    assert!(ok, "{text}");
    assert_eq!(v["success_rate"], 1.0, "{v}");
    let _ = std::fs::remove_dir_all(&dir);
}
