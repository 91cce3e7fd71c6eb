//! Malformed robot descriptions: a URDF or a joint table that would crash, confuse or mislead
//! what loads it later (the kinematic tree, the planner, IK) is refused when the configuration
//! loads, with the key `urdf` or the table's entry and a message naming what is wrong.

use std::path::Path;

use ferrobot_description::{bundled_files, Error, RobotConfig};

/// The LoCoBot's configuration with `toml` and `urdf` edited.
fn load(
    edit_toml: impl Fn(&str) -> String,
    edit_urdf: impl Fn(&str) -> String,
) -> Result<RobotConfig, Error> {
    let (toml, urdf) = bundled_files("locobot").expect("bundled");
    let urdf = edit_urdf(urdf);
    ferrobot_profile::parse(&edit_toml(toml), Path::new("locobot.toml"), |_| {
        Ok(urdf.clone())
    })
}

fn refused(r: Result<RobotConfig, Error>, key: &str, says: &str) {
    match r {
        Err(Error::Config {
            key: k, problem, ..
        }) => {
            assert!(k.starts_with(key), "key {k:?}, not {key:?}: {problem}");
            assert!(problem.contains(says), "{problem:?} does not say {says:?}");
        }
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("accepted; expected an error saying {says:?}"),
    }
}

#[test]
fn malformed_urdfs_are_refused_when_the_configuration_loads() {
    let same = |t: &str| t.to_string();
    load(same, same).expect("the bundled robot loads");
    let cases: [(&str, &str, &str, &str); 6] = [
        (
            "a link defined twice",
            "<link name=\"elbow_link\">",
            "<link name=\"elbow_link\"/>\n  <link name=\"elbow_link\">",
            "defined twice",
        ),
        (
            "a joint defined twice",
            "<joint name=\"joint_2\" type=\"revolute\">",
            "<joint name=\"joint_1\" type=\"revolute\">",
            "defined twice",
        ),
        (
            "a joint whose child link is missing",
            "<child link=\"elbow_link\"/>",
            "<child link=\"nowhere_link\"/>",
            "does not define",
        ),
        (
            "a zero axis",
            "<origin xyz=\"0 0 0.072\" rpy=\"0 0 0\"/>\n    <axis xyz=\"0 0 1\"/>",
            "<origin xyz=\"0 0 0.072\" rpy=\"0 0 0\"/>\n    <axis xyz=\"0 0 0\"/>",
            "axis",
        ),
        (
            "a NaN axis",
            "<origin xyz=\"0 0 0.072\" rpy=\"0 0 0\"/>\n    <axis xyz=\"0 0 1\"/>",
            "<origin xyz=\"0 0 0.072\" rpy=\"0 0 0\"/>\n    <axis xyz=\"0 NaN 1\"/>",
            "axis",
        ),
        (
            "a joint origin that is not finite",
            "<origin xyz=\"0 0 0.072\" rpy=\"0 0 0\"/>",
            "<origin xyz=\"0 0 inf\" rpy=\"0 0 0\"/>",
            "origin",
        ),
    ];
    for (what, from, to, says) in cases {
        let edit = |t: &str| {
            assert!(t.contains(from), "{what}: {from:?} not in the URDF");
            t.replacen(from, to, 1)
        };
        eprintln!("{what}");
        refused(load(same, edit), "urdf", says);
    }
}

/// The arm's chain, which IK searches, has the limits of the joint table (the configuration's
/// overrides), not the URDF's.
#[test]
fn the_arm_chain_has_the_configured_limits() {
    let edit = |t: &str| {
        t.replacen(
            "name = \"joint_1\"\nkind = \"arm\"\n",
            "name = \"joint_1\"\nkind = \"arm\"\nlimits = { min = -1.0, max = 1.57 }\n",
            1,
        )
    };
    let cfg = load(edit, |t: &str| t.to_string()).expect("loads");
    let j = &ferrobot_profile::arm_chain(&cfg).expect("chain").joints[0];
    assert_eq!((j.name.as_str(), j.lower, j.upper), ("joint_1", -1.0, 1.57));
}

/// More servos than the firmware's bus drives (twins count) are refused before anything
/// else: the LoCoBot's nine servos and seven more joints with a twin each are 23, beyond 16.
#[test]
fn more_servos_than_the_bus_drives_are_refused() {
    let edit = |t: &str| {
        let mut t = t.to_string();
        for k in 0..7 {
            t.push_str(&format!(
                "\n[[joint]]\nname = \"extra_{k}\"\nkind = \"head\"\nservo = {{ id = {}, model = \"xl430-w250\", twin = {} }}\neffort_limit = 1.0\nlimits = {{ min = -1.0, max = 1.0, velocity = 1.0 }}\n",
                100 + 2 * k,
                101 + 2 * k
            ));
        }
        t
    };
    match load(edit, |t: &str| t.to_string()) {
        Err(Error::Config { problem, .. }) => assert!(problem.contains("servos"), "{problem}"),
        other => panic!("{other:?}"),
    }
}
