//! What a description is checked against besides itself (the wire's ranges, the firmware, the
//! arm's kinematic chain), which this crate does not know: `ferrobot-profile` implements
//! [`Checks`]. Each check is called at its place among the description's own, so that the
//! first error a robot's configuration meets is the same whichever checks run.

use std::path::Path;

use crate::base::BaseSection;
use crate::error::Result;
use crate::joints::{Joint, JointSection};
use crate::sections::{ArmConfig, BusSection};

/// One `[[joint]]` entry as the checks see it: as written, its limits resolved (before the
/// table's `f32`), and the table's row made of it.
#[derive(Debug, Clone, Copy)]
pub struct JointEntry<'a> {
    /// Its index in the table.
    pub index: usize,
    /// As written.
    pub section: &'a JointSection,
    /// Lower position limit (the URDF's, or the override), rad or m.
    pub min: f64,
    /// Upper position limit, rad or m.
    pub max: f64,
    /// Speed limit, rad/s or m/s.
    pub velocity: f64,
    /// The table's row.
    pub joint: &'a Joint,
}

/// The checks of a description beyond its own, each returning the error of the key concerned
/// ([`crate::config_error`]). Every method checks nothing by default.
pub trait Checks {
    /// The URDF as parsed, before the configuration is checked against it.
    fn urdf(&self, _file: &Path, _urdf: &urdf_rs::Robot) -> Result<()> {
        Ok(())
    }
    /// The joint table as written, before any of its entries is checked.
    fn table(&self, _file: &Path, _joints: &[JointSection]) -> Result<()> {
        Ok(())
    }
    /// One entry, after the description's checks of it (its name, servo and URDF joint).
    fn joint(&self, _file: &Path, _entry: &JointEntry) -> Result<()> {
        Ok(())
    }
    /// The whole table, after every entry.
    fn joints(&self, _file: &Path, _joints: &[Joint]) -> Result<()> {
        Ok(())
    }
    /// The arm, after the description's checks of its poses, tolerances, accelerations and
    /// planning range (its acceleration defaults filled in), before that of its IK solver.
    fn arm(
        &self,
        _file: &Path,
        _urdf: &urdf_rs::Robot,
        _arm: &ArmConfig,
        _joints: &[Joint],
    ) -> Result<()> {
        Ok(())
    }
    /// The base's speed limits (`max_linear`, `max_angular`), after its geometry and before
    /// its tolerances.
    fn base_speeds(&self, _file: &Path, _base: &BaseSection) -> Result<()> {
        Ok(())
    }
    /// The base's calibrated odometry, after the rest of the base.
    fn base_odometry(&self, _file: &Path, _base: &BaseSection) -> Result<()> {
        Ok(())
    }
    /// The bus's servo-loop period, after its bit rate.
    fn bus(&self, _file: &Path, _bus: &BusSection) -> Result<()> {
        Ok(())
    }
}

/// The description's own checks and no more: what [`crate::RobotConfig::load`] and its
/// siblings run. A robot that is to run is loaded with `ferrobot-profile`'s checks too.
#[derive(Debug, Clone, Copy, Default)]
pub struct DescriptionOnly;

impl Checks for DescriptionOnly {}
