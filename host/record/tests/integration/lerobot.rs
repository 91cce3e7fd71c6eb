//! LeRobot export: two recorded demonstrations of the simulated LoCoBot (arm, gripper and
//! base moving, the camera on) exported as one dataset, then read back by the libraries
//! LeRobot reads with and checked row by row against the recordings as read by rosbags
//! (host/record/peer/check_lerobot_export.py). LeRobot's own loader reads the same export in
//! scripts/lerobot-check.sh (outside the fast suite: torch).

use std::path::{Path, PathBuf};
use std::process::Command;

use ferrobot::Robot;
use ferrobot_record::lerobot::{export, Demonstration, ExportOptions};
use ferrobot_record::{RecordError, RecordOptions, Recorder};

fn python() -> Option<PathBuf> {
    ferrobot_peers::for_test(
        "rosbags.highlevel, numpy, pyarrow.parquet, pandas, PIL",
        "scripts/python-env.sh record",
    )
}

/// Records `work` on a fresh simulated LoCoBot into `path`.
fn record(path: &Path, work: impl FnOnce(&Robot)) {
    let robot = Robot::new("locobot").unwrap();
    let rec = Recorder::start(&robot, path, RecordOptions::default()).unwrap();
    work(&robot);
    rec.finish().unwrap();
}

/// Two demonstrations: a reach with the gripper closing while the base turns, and a push of
/// the wrist with the base driving straight.
fn demonstrations(dir: &Path) -> Vec<Demonstration> {
    let (a, b) = (dir.join("reach.mcap"), dir.join("push.mcap"));
    record(&a, |r| {
        r.base().unwrap().set_vel(0.1, 0.4, 0.6).unwrap();
        r.arm()
            .unwrap()
            .set_joint_positions(&[0.4, 0.3, -0.2, 0.5, 0.0])
            .unwrap();
        r.gripper().unwrap().close().unwrap();
    });
    record(&b, |r| {
        r.arm()
            .unwrap()
            .set_joint_velocities(&[0.0, 0.0, 0.0, 0.5, -0.4])
            .unwrap();
        r.base().unwrap().set_vel(0.2, 0.0, 0.5).unwrap();
        r.wait(0.4).unwrap();
    });
    vec![
        Demonstration {
            path: a,
            task: "reach and grasp".into(),
        },
        Demonstration {
            path: b,
            task: "push with the wrist".into(),
        },
    ]
}

#[test]
fn demonstrations_export_to_a_lerobot_dataset_that_reads_back_to_the_recorded_values() {
    let Some(py) = python() else { return };
    let dir = crate::scratch("lerobot-export");
    let demos = demonstrations(&dir);
    let out = dir.join("dataset");
    let opts = ExportOptions {
        robot_type: Some("locobot".into()),
        ..Default::default()
    };
    let stats = export(&demos, &out, &opts).unwrap();
    println!("{stats:?}");
    assert_eq!((stats.episodes, stats.tasks, stats.images), (2, 2, true));
    assert!(stats.frames > 60, "{stats:?}");

    let checker = Path::new(env!("CARGO_MANIFEST_DIR")).join("peer/check_lerobot_export.py");
    let mut cmd = Command::new(py);
    cmd.arg(&checker)
        .arg(&out)
        .arg("30")
        .arg("reach and grasp,push with the wrist");
    cmd.args(demos.iter().map(|d| &d.path));
    let run = cmd.output().unwrap();
    let said = String::from_utf8_lossy(&run.stdout);
    println!("{said}{}", String::from_utf8_lossy(&run.stderr));
    assert!(
        run.status.success(),
        "the export does not read back: {said}"
    );

    // An existing dataset is never written into; a bad rate or a missing task is refused
    // before anything is read or written.
    let info = std::fs::read(out.join("meta/info.json")).unwrap();
    let again = export(&demos, &out, &opts).unwrap_err();
    assert!(matches!(again, RecordError::Io { .. }), "{again}");
    assert_eq!(std::fs::read(out.join("meta/info.json")).unwrap(), info);
    for fps in [0, 1001] {
        let bad = ExportOptions {
            fps,
            ..opts.clone()
        };
        let e = export(&demos, &dir.join("never"), &bad).unwrap_err();
        assert!(
            matches!(e, RecordError::OutOfRange { what: "fps", .. }),
            "{e}"
        );
    }
    let untitled = [Demonstration {
        task: " ".into(),
        ..demos[0].clone()
    }];
    assert!(export(&untitled, &dir.join("never"), &opts).is_err());
    assert!(!dir.join("never").exists());
}
