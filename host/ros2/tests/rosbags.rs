//! Our message definitions and their RIHS01 hashes against rosbags (a peer from PyPI): every
//! type ROS 2 Jazzy defines must hash in rosbags' own Jazzy store (ROS's definitions, not ours)
//! as we hash it, and our own schema text, parsed by rosbags, must hash the same
//! (host/ros2/peer/check_types.py).

use std::path::Path;
use std::process::Command;

use ferrobot_ros2::{schemas, type_hash};

#[test]
fn every_type_we_speak_hashes_as_rosbags_and_ros_2_jazzy_do() {
    let Some(py) = ferrobot_peers::for_test("rosbags.typesys", "scripts/python-env.sh record")
    else {
        return;
    };
    let entries: Vec<String> = schemas::ALL
        .iter()
        .map(|t| {
            let hash = type_hash::rihs01(t).unwrap();
            format!(
                "{{\"name\": {:?}, \"schema\": {:?}, \"rihs01\": {:?}}}",
                t.name,
                t.schema(),
                hash
            )
        })
        .collect();
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    let file = dir.join("types.json");
    std::fs::write(&file, format!("[{}]", entries.join(", "))).unwrap();
    let checker = Path::new(env!("CARGO_MANIFEST_DIR")).join("peer/check_types.py");
    let out = Command::new(py).arg(&checker).arg(&file).output().unwrap();
    let said = String::from_utf8_lossy(&out.stdout);
    println!("{said}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "rosbags disagrees: {said}");
    assert_eq!(
        said.lines().filter(|l| l.starts_with("ok ")).count(),
        schemas::ALL.len()
    );
}
