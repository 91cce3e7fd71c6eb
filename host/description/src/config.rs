//! A loaded robot configuration ([`RobotConfig`]): where it comes from, the TOML with dotted
//! overrides applied, its URDF read and parsed, and the whole checked before it is returned.

use std::path::{Path, PathBuf};

use crate::base::BaseSection;
use crate::checks::{Checks, DescriptionOnly};
use crate::error::{config_error as cfg_err, Error, Result};
use crate::files::{bundled_files, read_text, BUNDLED, MAX_CONFIG_BYTES, MAX_URDF_BYTES};
use crate::joints::Joint;
use crate::sections::{
    ArmConfig, BusSection, CameraSection, CollisionSection, ConfigFile, GripperSection,
};

/// A loaded, validated robot configuration.
#[derive(Debug, Clone)]
pub struct RobotConfig {
    /// Robot name.
    pub name: String,
    /// Where it came from (`<bundled>/NAME.toml` for bundled robots).
    pub file: PathBuf,
    /// The firmware's built-in profile a board runs for this robot, if it has one
    /// (`ferrobot_firmware::config::by_name`).
    pub board_profile: Option<String>,
    /// `[bus]`.
    pub bus: BusSection,
    /// `[direct]`: the stock robot's own cables, for the host-run firmware.
    pub direct: Option<crate::direct::DirectSection>,
    /// The parsed URDF.
    pub urdf: urdf_rs::Robot,
    /// The URDF's file name as the configuration gives it (relative to the configuration).
    pub urdf_file: String,
    /// `[collision]`.
    pub collision: Option<CollisionSection>,
    /// `[arm]`.
    pub arm: Option<ArmConfig>,
    /// `[gripper]`.
    pub gripper: Option<GripperSection>,
    /// `[camera]`.
    pub camera: Option<CameraSection>,
    /// `[base]`.
    pub base: Option<BaseSection>,
    /// The joint table, with limits resolved against the URDF.
    pub joints: Vec<Joint>,
    /// Gravity in simulation.
    pub sim_gravity: bool,
}

/// Where a configuration comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigSource {
    /// A bundled robot by name.
    Bundled(String),
    /// A TOML file on disk; its `urdf` path is relative to it.
    File(PathBuf),
}

/// Set dotted `key`s of a TOML document to values.
fn apply_overrides(text: &str, file: &Path, overrides: &[(String, toml::Value)]) -> Result<String> {
    let mut doc: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| cfg_err(file, "-", e.message().to_string()))?;
    for (key, value) in overrides {
        let mut parts = key.split('.').peekable();
        let mut table = &mut doc;
        while let Some(p) = parts.next() {
            if parts.peek().is_none() {
                table.insert(p.to_string(), value.clone());
            } else {
                table = table
                    .entry(p.to_string())
                    .or_insert_with(|| toml::Value::Table(Default::default()))
                    .as_table_mut()
                    .ok_or_else(|| cfg_err(file, key.clone(), format!("{p:?} is not a table")))?;
            }
        }
    }
    Ok(doc.to_string())
}

impl RobotConfig {
    /// Load from `source` with `overrides` (dotted keys, e.g. `("arm.joint_tolerance", 0.005)`)
    /// applied to the TOML before it is validated, so an override is checked like the file.
    /// The description's own checks ([`DescriptionOnly`]); see [`RobotConfig::load_with`].
    pub fn load(source: &ConfigSource, overrides: &[(String, toml::Value)]) -> Result<Self> {
        Self::load_with(source, overrides, &DescriptionOnly)
    }

    /// [`RobotConfig::load`] with `checks` run at their places among the description's own.
    pub fn load_with(
        source: &ConfigSource,
        overrides: &[(String, toml::Value)],
        checks: &dyn Checks,
    ) -> Result<Self> {
        let with_overrides = |text: &str, file: &Path| -> Result<String> {
            if overrides.is_empty() {
                Ok(text.to_string())
            } else {
                apply_overrides(text, file, overrides)
            }
        };
        match source {
            ConfigSource::Bundled(n) => {
                let (toml, urdf) = bundled_files(n).ok_or_else(|| Error::UnknownRobot {
                    name: n.to_string(),
                    known: BUNDLED.join(", "),
                })?;
                let file = PathBuf::from(format!("<bundled>/{n}.toml"));
                let text = with_overrides(toml, &file)?;
                Self::parse_with(&text, &file, |_| Ok(urdf.to_string()), checks)
            }
            ConfigSource::File(p) => {
                let text = read_text(p, MAX_CONFIG_BYTES)
                    .map_err(|e| cfg_err(p, "-", format!("cannot read: {e}")))?;
                let text = with_overrides(&text, p)?;
                let dir = p.parent().map(Path::to_path_buf).unwrap_or_default();
                Self::parse_with(
                    &text,
                    p,
                    |u| {
                        let up = dir.join(u);
                        read_text(&up, MAX_URDF_BYTES).map_err(|e| {
                            cfg_err(p, "urdf", format!("cannot read {}: {e}", up.display()))
                        })
                    },
                    checks,
                )
            }
        }
    }

    /// Load a bundled robot by name.
    pub fn bundled(name: &str) -> Result<Self> {
        Self::load(&ConfigSource::Bundled(name.to_string()), &[])
    }

    /// Load a robot from a TOML file; its `urdf` path is relative to the file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self> {
        Self::load(&ConfigSource::File(path.as_ref().to_path_buf()), &[])
    }

    /// Parse TOML text (named `file` in errors); `read_urdf` fetches the URDF it names. The
    /// description's own checks ([`DescriptionOnly`]).
    pub fn parse(
        text: &str,
        file: &Path,
        read_urdf: impl FnOnce(&str) -> Result<String>,
    ) -> Result<Self> {
        Self::parse_with(text, file, read_urdf, &DescriptionOnly)
    }

    /// [`RobotConfig::parse`] with `checks` run at their places among the description's own.
    pub fn parse_with(
        text: &str,
        file: &Path,
        read_urdf: impl FnOnce(&str) -> Result<String>,
        checks: &dyn Checks,
    ) -> Result<Self> {
        let de = toml::Deserializer::parse(text)
            .map_err(|e| cfg_err(file, "-", e.message().to_string()))?;
        let raw: ConfigFile = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            cfg_err(
                file,
                if key.is_empty() || key == "." {
                    "-".to_string()
                } else {
                    key
                },
                e.inner().message().to_string(),
            )
        })?;
        let urdf_text = read_urdf(&raw.urdf)?;
        let urdf = urdf_rs::read_from_string(&urdf_text)
            .map_err(|e| cfg_err(file, "urdf", format!("invalid URDF: {e}")))?;
        // The checks' view of the URDF (for `ferrobot-profile`: names, links, axes and
        // origins, then the tree: one root, no cycle, every link on it).
        checks.urdf(file, &urdf)?;
        crate::validate::validate(raw, urdf, file, checks)
    }

    /// The configuration as the host-run firmware runs it (`[direct]`'s bus in place of
    /// `[bus]`), or `None` for a robot without a `[direct]` section.
    pub fn direct_config(&self) -> Option<RobotConfig> {
        let direct = self.direct.as_ref()?;
        Some(RobotConfig {
            bus: direct.bus(),
            ..self.clone()
        })
    }

    /// Index of a joint in the firmware's table.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name.as_str() == name)
    }
}
