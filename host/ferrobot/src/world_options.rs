//! The simulated world a robot is built in, on the sim and emulated backends (cargo feature
//! `sim`): the scene and the robot's start pose in it, the camera's depth noise, how far the
//! simulated camera truly sits off its URDF mount, and the hand-eye marker.

use nalgebra::{Isometry3, Translation3, UnitQuaternion};

use crate::builder::RobotBuilder;
use crate::error::Result;
use ferrobot_sim::scene::{Scene, SceneSource};

/// Largest camera mount error the simulator takes: 0.1 m along each axis, 0.5 rad about each.
pub const MAX_CAMERA_MOUNT_ERROR: [f64; 2] = [0.1, 0.5];

/// What the builder was told of the simulated world.
#[derive(Debug, Clone)]
pub(crate) struct WorldOptions {
    scene: SceneSource,
    /// A scene already loaded (and perhaps changed), used instead of `scene`.
    loaded_scene: Option<Scene>,
    depth_noise: bool,
    start_pose: Option<[f64; 3]>,
    camera_mount_error: [f64; 6],
    marker: bool,
    /// A world shared with other robots, joined instead of a world of the robot's own.
    shared: Option<crate::SharedWorld>,
}

impl Default for WorldOptions {
    fn default() -> Self {
        WorldOptions {
            scene: SceneSource::default(),
            loaded_scene: None,
            depth_noise: true,
            start_pose: None,
            camera_mount_error: [0.0; 6],
            marker: false,
            shared: None,
        }
    }
}

/// The simulated world as the backends build it: the scene (with the start pose), the
/// camera's depth noise, the true camera mount's error and the marker.
pub(crate) struct World {
    pub(crate) scene: std::sync::Arc<Scene>,
    pub(crate) depth_noise: bool,
    pub(crate) mount_error: Isometry3<f64>,
    pub(crate) marker: bool,
    /// The shared world the robot joins, and where in it (`[x, y, θ]`, m and rad).
    pub(crate) shared: Option<(crate::SharedWorld, [f64; 3])>,
}

impl WorldOptions {
    /// The world these options make, checked: the mount error within
    /// [`MAX_CAMERA_MOUNT_ERROR`], the scene loaded, the start pose within the validated range.
    pub(crate) fn world(self) -> Result<World> {
        let e = self.camera_mount_error;
        let [tmax, rmax] = MAX_CAMERA_MOUNT_ERROR;
        crate::validate::all_in_range("camera mount error (m)", &e[..3], -tmax, tmax)?;
        crate::validate::all_in_range("camera mount error (rad)", &e[3..], -rmax, rmax)?;
        let mount_error = mount_error_pose(&e);
        if let Some(p) = self.start_pose {
            let m = crate::validate::MAX_BASE_COORDINATE;
            crate::validate::all_in_range("start position", &p[..2], -m, m)?;
            crate::validate::in_range("start heading", p[2], -m, m)?;
        }
        if let Some(shared) = self.shared {
            let scene = shared.scene();
            let pose = self.start_pose.unwrap_or(scene.robot_pose);
            return Ok(World {
                scene,
                depth_noise: self.depth_noise,
                mount_error,
                marker: self.marker,
                shared: Some((shared, pose)),
            });
        }
        let mut scene = match self.loaded_scene {
            Some(s) => s,
            None => Scene::load(&self.scene)?,
        };
        if let Some(p) = self.start_pose {
            scene.robot_pose = p;
        }
        Ok(World {
            scene: std::sync::Arc::new(scene),
            depth_noise: self.depth_noise,
            mount_error,
            marker: self.marker,
            shared: None,
        })
    }
}

impl RobotBuilder {
    /// Start the simulated robot at `[x, y, θ]` (m, m, rad) in the scene's world frame instead
    /// of the scene's own start pose (in a shared world too: [`RobotBuilder::shared_world`]).
    pub fn start_pose(mut self, pose: [f64; 3]) -> Self {
        self.world.start_pose = Some(pose);
        self
    }
    /// The simulated world the robot lives in: a bundled scene (`empty`, `tabletop`,
    /// `apartment`, `shelf`, `clutter`) or the path of a scene file (default `empty`: an empty
    /// world). The simulator backend renders its camera from this world.
    pub fn scene(mut self, scene: &str) -> Self {
        self.world.scene = SceneSource::from_arg(scene);
        self
    }
    /// Join `world`, a simulated world shared with other robots on one clock
    /// ([`crate::SharedWorld`]), instead of a world of the robot's own: at
    /// [`RobotBuilder::start_pose`] (default the world's scene's start pose), on the simulator
    /// backend ([`Backend::Sim`](crate::Backend::Sim): its seed and pacing); the world's scene
    /// replaces [`RobotBuilder::scene`]'s. Building fails with [`crate::Error::Scene`] where
    /// the robot would overlap a scene body or another robot.
    pub fn shared_world(mut self, world: &crate::SharedWorld) -> Self {
        self.world.shared = Some(world.clone());
        self
    }

    /// The simulated world as a scene already loaded (and perhaps changed: objects placed at
    /// random for a benchmark's trial), instead of [`RobotBuilder::scene`].
    pub fn with_scene(mut self, scene: Scene) -> Self {
        self.world.loaded_scene = Some(scene);
        self
    }

    /// Mount the simulated camera off its URDF pose by `[dx, dy, dz, droll, dpitch, dyaw]`
    /// (m and rad, in the camera link's frame: the true camera link is the URDF's times this
    /// pose, the rotation roll-pitch-yaw as in a URDF) for hand-eye calibration studies; on
    /// the sim and emulated backends. The host keeps believing the URDF (or the calibration
    /// of [`RobotBuilder::camera_calibration`]). Checked by [`RobotBuilder::build`]: finite,
    /// within [`MAX_CAMERA_MOUNT_ERROR`].
    pub fn camera_mount_error(mut self, error: [f64; 6]) -> Self {
        self.world.camera_mount_error = error;
        self
    }

    /// Draw the description's hand-eye marker (`[camera.marker]`) on the simulated robot, on
    /// the sim and emulated backends (default off: with the arm at home its corners sit fixed
    /// in the camera's view and visual SLAM takes them for features of the world; the
    /// hand-eye calibration skill needs it on).
    pub fn calibration_marker(mut self, on: bool) -> Self {
        self.world.marker = on;
        self
    }

    /// Simulate the depth camera's noise (default on: the D435's stereo noise model); off for
    /// exact depth.
    pub fn depth_noise(mut self, on: bool) -> Self {
        self.world.depth_noise = on;
        self
    }
}

/// The pose of a camera mount error `[dx, dy, dz, droll, dpitch, dyaw]` (m and rad; the
/// rotation roll-pitch-yaw as in a URDF): the true camera link is the URDF's times this pose
/// ([`RobotBuilder::camera_mount_error`]).
pub fn mount_error_pose(e: &[f64; 6]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(e[0], e[1], e[2]),
        UnitQuaternion::from_euler_angles(e[3], e[4], e[5]),
    )
}
