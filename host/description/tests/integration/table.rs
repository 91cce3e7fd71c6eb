//! The joint table's own checks: an entry given twice is refused with its key and a message
//! naming the joint.

use std::path::Path;

use ferrobot_description::{bundled_files, Error, RobotConfig};

/// The LoCoBot's configuration with `toml` and `urdf` edited.
fn load(
    edit_toml: impl Fn(&str) -> String,
    edit_urdf: impl Fn(&str) -> String,
) -> Result<RobotConfig, Error> {
    let (toml, urdf) = bundled_files("locobot").expect("bundled");
    let urdf = edit_urdf(urdf);
    RobotConfig::parse(&edit_toml(toml), Path::new("locobot.toml"), |_| {
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
fn a_joint_table_entry_given_twice_is_refused() {
    let edit = |t: &str| t.replacen("name = \"joint_2\"", "name = \"joint_1\"", 1);
    refused(
        load(edit, |t: &str| t.to_string()),
        "joint[1].name",
        "two [[joint]] entries",
    );
}
