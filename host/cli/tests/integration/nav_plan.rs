//! `ferrobot nav-plan` on map_server maps written by the library: the JSON path agrees with
//! the library's planner, the picture is written, and each failure has its exit code.

use std::process::Command;

use ferrobot::nav::{GlobalPlanner, GridAStar, MapImage, OccupancyGrid};

/// Exit code and standard output (JSON) of `ferrobot ARGS`.
fn run(args: &[&str]) -> (i32, serde_json::Value) {
    let out = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(args)
        .output()
        .expect("runs");
    let v = serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null);
    (out.status.code().unwrap_or(-1), v)
}

/// A 3 m × 3 m map of 5 cm cells with a wall across y = 1.5 m from x = 0 to `end` and a
/// pillar at (2.2, 0.7), saved as `NAME.yaml` in a temporary directory removed with the guard.
fn map(name: &str, end: f64) -> (tempfile::TempDir, std::path::PathBuf, OccupancyGrid) {
    let mut g = OccupancyGrid::new([0.025, 0.025], 0.05, 60, 60).expect("grid");
    for j in 0..g.height {
        for i in 0..g.width {
            let (x, y) = (0.025 + 0.05 * i as f64, 0.025 + 0.05 * j as f64);
            if (x <= end && (y - 1.5).abs() < 0.05) || (x - 2.2).hypot(y - 0.7) < 0.15 {
                g.occupied[j * g.width + i] = true;
            }
        }
    }
    let d = tempfile::tempdir().expect("temporary directory");
    let yaml = d.path().join(format!("{name}.yaml"));
    MapImage::from_grid(&g).save(&yaml).expect("save");
    (d, yaml, g)
}

#[test]
fn the_path_printed_is_the_librarys() {
    let (_tmp, yaml, grid) = map("wall", 2.0);
    let plot = yaml.with_file_name("wall-path.png");
    let y = yaml.to_str().expect("utf-8");
    let (code, v) = run(&[
        "nav-plan",
        "--map",
        y,
        "--from",
        "0.5",
        "0.5",
        "--to",
        "0.5",
        "2.5",
        "--radius",
        "0.18",
        "--plot",
        plot.to_str().expect("utf-8"),
        "--json",
    ]);
    assert_eq!(code, 0, "{v}");
    // The saved map, read back, plans the same path as the grid it came from.
    let lib = GridAStar
        .plan(&grid, [0.5, 0.5], [0.5, 2.5], 0.18)
        .expect("library path");
    let points: Vec<[f64; 2]> = v["path"]
        .as_array()
        .expect("path")
        .iter()
        .map(|p| [p[0].as_f64().expect("x"), p[1].as_f64().expect("y")])
        .collect();
    // JSON carries 15 significant digits.
    assert_eq!(points.len(), lib.points.len());
    for (p, q) in points.iter().zip(&lib.points) {
        assert!(
            (p[0] - q[0]).abs() < 1e-12 && (p[1] - q[1]).abs() < 1e-12,
            "{p:?} {q:?}"
        );
    }
    let length = v["length_m"].as_f64().expect("length");
    assert!((length - lib.length).abs() < 1e-12);
    // Around the wall's end: longer than the 2 m straight line.
    assert!(length > 3.0, "{length}");
    let png = std::fs::read(&plot).expect("plot written");
    assert_eq!(&png[1..4], b"PNG");
}

#[test]
fn failures_have_their_exit_codes() {
    let (_tmp, yaml, _) = map("closed", 3.0);
    let y = yaml.to_str().expect("utf-8");
    let plan = |from: [&str; 2], to: [&str; 2], r: &str| {
        run(&[
            "nav-plan", "--map", y, "--from", from[0], from[1], "--to", to[0], to[1], "--radius",
            r, "--json",
        ])
    };
    // The wall closes the map: no path, the world's fault (1).
    let (code, v) = plan(["0.5", "0.5"], ["0.5", "2.5"], "0.1");
    assert_eq!(code, 1, "{v}");
    assert!(
        v["error"].as_str().is_some_and(|e| e.contains("no path")),
        "{v}"
    );
    assert_eq!(v["input_error"], false);
    // Input errors (2): an end in the pillar, off the map, a bad radius, a missing map.
    for (from, r, says) in [
        (["2.2", "0.7"], "0.1", "nearer than the robot's radius"),
        (["-4", "0.5"], "0.1", "outside the map"),
        (["0.5", "0.5"], "-0.1", "robot radius"),
        (["0.5", "0.5"], "NaN", "robot radius"),
    ] {
        let (code, v) = plan(from, ["0.5", "1.0"], r);
        assert_eq!(code, 2, "{v}");
        assert!(
            v["error"].as_str().is_some_and(|e| e.contains(says)),
            "{says}: {v}"
        );
    }
    let (code, v) = run(&[
        "nav-plan",
        "--map",
        "/nonexistent/map.yaml",
        "--from",
        "0",
        "0",
        "--to",
        "1",
        "1",
        "--radius",
        "0.1",
        "--json",
    ]);
    assert_eq!(code, 2, "{v}");
    assert!(
        v["error"]
            .as_str()
            .is_some_and(|e| e.contains("/nonexistent/map.yaml")),
        "{v}"
    );
}
