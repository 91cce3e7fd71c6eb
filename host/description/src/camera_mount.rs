//! The camera's mount on the robot and its calibration file.
//!
//! The mount is the URDF joint that carries the camera's body: the parent of the optical
//! frame's link is the camera's link (`camera_link` on the LoCoBot), and the joint into that
//! link from the head (`head_tilt_link -> camera_link`) is what hand-eye calibration
//! estimates. A calibration file holds that transform; [`RobotConfig::set_camera_mount`]
//! puts it into the description's URDF, so that every frame the host computes (the camera's
//! pose, its clouds in `base_link`) uses it.
//!
//! The file is TOML:
//!
//! ```toml
//! robot = "locobot"
//! parent = "head_tilt_link"
//! child = "camera_link"
//! xyz = [0.067, 0.0, -0.004]                 # m, the child's origin in the parent's frame
//! quaternion = [0.0, 0.0, 0.0, 1.0]          # [x, y, z, w], the child's orientation
//! reprojection_rms_px = 0.1                  # how well it fitted (informative)
//! images = 54
//! ```

use std::path::Path;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

use crate::error::{config_error as cfg_err, Result};
use crate::files::read_text;
use crate::RobotConfig;

/// Largest calibration file read, bytes.
pub const MAX_CALIBRATION_BYTES: u64 = 64 << 10;

/// The URDF joint carrying the camera: `parent -> child` through `joint`.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraMount {
    /// The fixed joint's name (`camera_joint` on the LoCoBot).
    pub joint: String,
    /// The link the camera is mounted on (`head_tilt_link`).
    pub parent: String,
    /// The camera's link (`camera_link`), parent of the optical frame.
    pub child: String,
    /// The child's pose in the parent's frame (the joint's origin), m and rad.
    pub pose: Isometry3<f64>,
}

/// A hand-eye calibration's result: the camera's mount as measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraCalibration {
    /// The robot it was measured on (its description's name).
    pub robot: String,
    /// The link the camera is mounted on.
    pub parent: String,
    /// The camera's link.
    pub child: String,
    /// The child's origin in the parent's frame, m.
    pub xyz: [f64; 3],
    /// The child's orientation in the parent's frame, [x, y, z, w].
    pub quaternion: [f64; 4],
    /// Root-mean-square reprojection error of the fit, px.
    #[serde(default)]
    pub reprojection_rms_px: f64,
    /// Images the fit used.
    #[serde(default)]
    pub images: usize,
}

impl CameraCalibration {
    /// The mount's pose (child in parent), m and rad.
    pub fn pose(&self) -> Isometry3<f64> {
        let [x, y, z, w] = self.quaternion;
        Isometry3::from_parts(
            Translation3::new(self.xyz[0], self.xyz[1], self.xyz[2]),
            UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)),
        )
    }

    /// A calibration of `robot`'s `mount` at `pose` (child in parent).
    pub fn new(robot: &str, mount: &CameraMount, pose: &Isometry3<f64>) -> Self {
        let q = pose.rotation.coords;
        let t = pose.translation.vector;
        CameraCalibration {
            robot: robot.to_string(),
            parent: mount.parent.clone(),
            child: mount.child.clone(),
            xyz: [t.x, t.y, t.z],
            quaternion: [q.x, q.y, q.z, q.w],
            reprojection_rms_px: 0.0,
            images: 0,
        }
    }

    /// Read and check a calibration file: finite numbers, a unit quaternion (within 1e-6),
    /// a translation under 1 m.
    pub fn load(path: &Path) -> Result<Self> {
        let text = read_text(path, MAX_CALIBRATION_BYTES)
            .map_err(|e| cfg_err(path, "-", format!("cannot read: {e}")))?;
        let c: CameraCalibration =
            toml::from_str(&text).map_err(|e| cfg_err(path, "-", e.message().to_string()))?;
        if !c.xyz.iter().all(|v| v.is_finite() && v.abs() <= 1.0) {
            return Err(cfg_err(
                path,
                "xyz",
                format!("{:?} m: need finite values within 1 m", c.xyz),
            ));
        }
        let n = c.quaternion.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !n.is_finite() || (n - 1.0).abs() > 1e-6 {
            return Err(cfg_err(
                path,
                "quaternion",
                format!("{:?} is not a unit quaternion [x, y, z, w]", c.quaternion),
            ));
        }
        Ok(c)
    }

    /// Write the file (TOML) at `path`.
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        let text = toml::to_string(self).map_err(std::io::Error::other)?;
        std::fs::write(path, text)
    }
}

impl RobotConfig {
    /// The camera's mount: the URDF joint into the optical frame's parent link. `None`
    /// without a camera, or when the optical frame or its link hangs from no joint.
    pub fn camera_mount(&self) -> Option<CameraMount> {
        let frame = &self.camera.as_ref()?.frame;
        let into = |link: &str| self.urdf.joints.iter().find(|j| j.child.link == link);
        let child = into(frame)?.parent.link.clone();
        let joint = into(&child)?;
        Some(CameraMount {
            joint: joint.name.clone(),
            parent: joint.parent.link.clone(),
            child,
            pose: pose_from_urdf(&joint.origin),
        })
    }

    /// Mount the camera at `calibration`: its pose becomes the mount joint's origin in the
    /// URDF (so every frame computed from this description uses it). An error if the
    /// calibration is of another robot or another mount.
    pub fn set_camera_mount(&mut self, calibration: &CameraCalibration, file: &Path) -> Result<()> {
        let mount = self.camera_mount().ok_or_else(|| {
            cfg_err(
                file,
                "-",
                format!("robot {:?} has no camera mount", self.name),
            )
        })?;
        if calibration.robot != self.name {
            return Err(cfg_err(
                file,
                "robot",
                format!(
                    "the calibration is of {:?}, not {:?}",
                    calibration.robot, self.name
                ),
            ));
        }
        if (calibration.parent.as_str(), calibration.child.as_str())
            != (mount.parent.as_str(), mount.child.as_str())
        {
            return Err(cfg_err(
                file,
                "parent",
                format!(
                    "the calibration is of {} -> {}, the camera's mount is {} -> {}",
                    calibration.parent, calibration.child, mount.parent, mount.child
                ),
            ));
        }
        let pose = calibration.pose();
        let (roll, pitch, yaw) = pose.rotation.euler_angles();
        let t = pose.translation.vector;
        if let Some(j) = self.urdf.joints.iter_mut().find(|j| j.name == mount.joint) {
            j.origin.xyz = urdf_rs::Vec3([t.x, t.y, t.z]);
            j.origin.rpy = urdf_rs::Vec3([roll, pitch, yaw]);
        }
        Ok(())
    }
}

/// The pose a URDF origin gives (translation, then roll-pitch-yaw), m and rad: the same as
/// `ferrobot_kinematics::pose_from_urdf`, which this crate does not depend on.
fn pose_from_urdf(p: &urdf_rs::Pose) -> Isometry3<f64> {
    let r = UnitQuaternion::from_euler_angles(p.rpy[0], p.rpy[1], p.rpy[2]);
    Isometry3::from_parts(Translation3::new(p.xyz[0], p.xyz[1], p.xyz[2]), r)
}
