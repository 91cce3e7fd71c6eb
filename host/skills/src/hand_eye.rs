//! Hand-eye calibration of the head camera, as PyRobot's `locobot_calibration`: the arm holds
//! the marker of the description (`[camera.marker]`) at a few poses, the head looks at it from
//! a grid of pan and tilt angles around it, the marker's corners are found in each colour
//! image ([`ferrobot_perception::marker`]) and the camera's mount
//! (`head_tilt_link -> camera_link`) is fitted to them ([`ferrobot_perception::hand_eye`]).
//! The result is a [`CameraCalibration`] to save and to build robots with
//! ([`ferrobot::RobotBuilder::camera_calibration`]).

use ferrobot::config::{CameraCalibration, RobotConfig};
use ferrobot_perception::{HandEyeProblem, MarkerView, PerceptionError};
use nalgebra::{Isometry3, Point3};

use ferrobot::validate;
use ferrobot::{Error, Result, Robot};

/// How the calibration moves the robot and judges the images.
#[derive(Debug, Clone, PartialEq)]
pub struct HandEyeOptions {
    /// Arm joint positions (rad) holding the marker in the camera's view.
    pub arm_poses: Vec<Vec<f64>>,
    /// Pan angles (rad) added to the pan that centres the marker.
    pub pan_offsets: Vec<f64>,
    /// Tilt angles (rad) added to the tilt that centres the marker.
    pub tilt_offsets: Vec<f64>,
    /// An image whose corners lie farther than this from the fit's prediction is dropped, px
    /// (PyRobot: 20).
    pub inlier_px: f64,
    /// How far from the nominal mount's prediction the marker is looked for, px.
    pub search_px: f64,
    /// Fewest images of the marker the fit needs.
    pub min_images: usize,
}

/// Six arm poses holding the marker before the robot at different heights, sides and angles
/// (the LoCoBot's joints 1-5, rad).
pub const LOCOBOT_ARM_POSES: [[f64; 5]; 6] = [
    [0.0, 0.3, 0.3, -0.9, 0.0],
    [0.35, 0.2, 0.5, -1.0, 0.3],
    [-0.35, 0.2, 0.5, -1.0, -0.3],
    [0.2, 0.5, 0.1, -0.9, -0.2],
    [-0.2, 0.5, 0.1, -0.9, 0.2],
    [0.0, 0.1, 0.7, -1.2, 0.0],
];

impl Default for HandEyeOptions {
    /// PyRobot's procedure on the LoCoBot: 6 arm poses times a 3 x 3 head grid of ±0.35 rad
    /// (20°) pan and ±0.2 rad tilt (PyRobot's ±30° would put the tag outside the D435's
    /// ±21° vertical view), 20 px inliers.
    fn default() -> Self {
        HandEyeOptions {
            arm_poses: LOCOBOT_ARM_POSES.iter().map(|q| q.to_vec()).collect(),
            pan_offsets: vec![-0.35, 0.0, 0.35],
            tilt_offsets: vec![-0.2, 0.0, 0.2],
            inlier_px: 20.0,
            search_px: 80.0,
            min_images: 3,
        }
    }
}

impl HandEyeOptions {
    /// The first `arm_poses` of the default poses and a `grid` x `grid` head grid spanning
    /// the default's offsets (`grid` 1: the marker centred only).
    pub fn with_counts(arm_poses: usize, grid: usize) -> Result<Self> {
        let d = HandEyeOptions::default();
        validate::in_range("arm poses", arm_poses as f64, 1.0, d.arm_poses.len() as f64)?;
        validate::in_range("head grid", grid as f64, 1.0, 5.0)?;
        let spread = |max: f64| -> Vec<f64> {
            if grid == 1 {
                vec![0.0]
            } else {
                (0..grid)
                    .map(|i| -max + 2.0 * max * i as f64 / (grid - 1) as f64)
                    .collect()
            }
        };
        Ok(HandEyeOptions {
            arm_poses: d.arm_poses[..arm_poses].to_vec(),
            pan_offsets: spread(0.35),
            tilt_offsets: spread(0.2),
            ..d
        })
    }

    fn check(&self) -> Result<()> {
        validate::in_range("arm poses", self.arm_poses.len() as f64, 1.0, 100.0)?;
        for (what, v) in [
            ("pan offsets", &self.pan_offsets),
            ("tilt offsets", &self.tilt_offsets),
        ] {
            validate::in_range(what, v.len() as f64, 1.0, 20.0)?;
            validate::all_in_range(what, v, -1.0, 1.0)?;
        }
        validate::in_range("inlier threshold (px)", self.inlier_px, 0.1, 1000.0)?;
        validate::in_range("marker search radius (px)", self.search_px, 1.0, 1000.0)?;
        validate::in_range("fewest images", self.min_images as f64, 1.0, 10_000.0)?;
        Ok(())
    }
}

/// Least change of the marker corners, px (root-sum-square over all corners), for 1 mm or
/// 1 mrad of the mount along its worst-observed direction: corners found to 0.1 px then pin
/// every direction of the mount within about 1 mm or 1 mrad.
pub const MIN_SENSITIVITY: f64 = 0.1;

/// What a calibration measured.
#[derive(Debug, Clone, PartialEq)]
pub struct HandEyeReport {
    /// The camera's mount as fitted, ready to save.
    pub calibration: CameraCalibration,
    /// Images taken.
    pub captured: usize,
    /// Images in which the marker was found.
    pub seen: usize,
    /// Why the marker was not found in each of the other images.
    pub missed: Vec<String>,
    /// Images the fit kept (within the inlier threshold).
    pub used: usize,
    /// Root-mean-square reprojection error of the kept images' corners, px.
    pub rms_px: f64,
}

/// The fixed facts of the calibration, from the description.
struct Setup {
    marker_link: String,
    corners: [Point3<f64>; 4],
    parent: String,
    nominal: Isometry3<f64>,
    link_to_optical: Isometry3<f64>,
    mount: ferrobot::config::CameraMount,
}

fn setup(cfg: &RobotConfig) -> Result<Setup> {
    let bad = |problem: &str| Error::Config {
        file: cfg.file.clone(),
        key: "camera".into(),
        problem: problem.into(),
    };
    let camera = cfg
        .camera
        .as_ref()
        .ok_or_else(|| bad("the robot has no camera to calibrate"))?;
    let marker = camera
        .marker
        .as_ref()
        .ok_or_else(|| bad("the description has no [camera.marker] to calibrate against"))?;
    let mount = cfg
        .camera_mount()
        .ok_or_else(|| bad("the optical frame hangs from no camera link"))?;
    let optical_joint = cfg
        .urdf
        .joints
        .iter()
        .find(|j| j.child.link == camera.frame)
        .ok_or_else(|| bad("the optical frame hangs from no joint"))?;
    Ok(Setup {
        marker_link: marker.link.clone(),
        corners: marker.corners().map(|[x, y, z]| Point3::new(x, y, z)),
        parent: mount.parent.clone(),
        nominal: mount.pose,
        link_to_optical: ferrobot::kinematics::pose_from_urdf(&optical_joint.origin),
        mount,
    })
}

/// Joints count as still when two reports [`SETTLE_STEP`] apart differ by less than this,
/// rad (about one encoder tick).
const STILL: f32 = 2e-3;
/// Time between the reports [`Robot::settle`] compares, s.
const SETTLE_STEP: f64 = 0.05;
/// Longest wait for the joints to come to rest, s.
const SETTLE_LIMIT: f64 = 3.0;

/// The skill's steps, on the robot it drives.
struct Calibration<'a>(&'a Robot);

impl std::ops::Deref for Calibration<'_> {
    type Target = Robot;
    fn deref(&self) -> &Robot {
        self.0
    }
}

impl Calibration<'_> {
    /// Wait until every joint has come to rest (two reports [`SETTLE_STEP`] apart within
    /// [`STILL`]), at most [`SETTLE_LIMIT`]: a motion ends within its tolerance while the
    /// joints still creep, and a view must be taken of joints that stay where they were
    /// measured.
    fn settle(&self) -> Result<()> {
        let mut last = self.telemetry()?;
        let mut waited = 0.0;
        while waited < SETTLE_LIMIT {
            self.wait(SETTLE_STEP)?;
            waited += SETTLE_STEP;
            let now = self.telemetry()?;
            let still = now
                .joints
                .iter()
                .zip(last.joints.iter())
                .all(|(a, b)| (a.position - b.position).abs() < STILL);
            if still {
                return Ok(());
            }
            last = now;
        }
        Ok(())
    }

    /// Calibrate the camera's mount against the description's marker (see the module's
    /// documentation; a simulated robot shows it when built with
    /// [`ferrobot::RobotBuilder::calibration_marker`]): moves the arm and the head, so the arm's workspace before the robot
    /// must be clear. The host's current belief about the mount (the URDF's, or a
    /// calibration the robot was built with) is where the search starts.
    ///
    /// Errors: [`Error::Perception`] with [`PerceptionError::MarkerNotSeen`] when no image
    /// shows the marker, [`PerceptionError::HandEye`] when too few do or they leave the mount
    /// poorly observed; [`Error::Config`] for a robot without a camera or a marker; value
    /// errors for options out of range; the arm's and head's errors as they come.
    fn calibrate_camera(&self, opts: &HandEyeOptions) -> Result<HandEyeReport> {
        opts.check()?;
        let s = setup(self.config())?;
        let arm = self.arm()?;
        let head = self.head()?;
        let camera = self.camera()?;
        let frames = self.frames()?;
        let index = |name: &str| {
            frames.link_index(name).ok_or_else(|| Error::UnknownName {
                what: "frame",
                name: name.to_string(),
            })
        };
        let (parent, marker_link) = (index(&s.parent)?, index(&s.marker_link)?);
        let mut views = Vec::new();
        let (mut captured, mut misses) = (0usize, Vec::new());
        for q in &opts.arm_poses {
            arm.set_joint_positions(q)?;
            // Pan and tilt that centre the marker, seen from the tilt link's origin (on both
            // axes).
            let poses = frames.poses_in(&self.telemetry()?, ferrobot::frames::BASE_FRAME)?;
            let d = poses[marker_link].translation.vector - poses[parent].translation.vector;
            let pan = d.y.atan2(d.x);
            let tilt = (-d.z).atan2(d.xy().norm());
            for dp in &opts.pan_offsets {
                for dt in &opts.tilt_offsets {
                    // The views are placed by the measured joints: a head that stops short
                    // of its target still gives one.
                    match head.set_pan_tilt(pan + dp, tilt + dt) {
                        Ok(()) | Err(Error::Stalled { .. }) => {}
                        Err(e) => return Err(e),
                    }
                    self.settle()?;
                    let (frame, tel) = camera.frame_with_telemetry()?;
                    captured += 1;
                    let poses = frames.poses_in(&tel, ferrobot::frames::BASE_FRAME)?;
                    let (hp, mp) = (poses[parent], poses[marker_link]);
                    // Where the current belief puts the corners.
                    let to_cam = frame.camera_pose.inverse() * mp;
                    let predicted: Option<Vec<[f64; 2]>> = s
                        .corners
                        .iter()
                        .map(|c| frame.intrinsics.project(&(to_cam * c)).map(|(u, v)| [u, v]))
                        .collect();
                    let Some(predicted) = predicted else {
                        misses.push("behind the camera".to_string());
                        continue;
                    };
                    let predicted = [predicted[0], predicted[1], predicted[2], predicted[3]];
                    match ferrobot_perception::detect_square(&frame.rgb, &predicted, opts.search_px)
                    {
                        Ok(d) => views.push(MarkerView {
                            head: hp,
                            marker: mp,
                            corners: d.corners,
                        }),
                        Err(PerceptionError::MarkerNotSeen(why)) => misses.push(format!(
                            "arm {q:?}, pan {:.3}, tilt {:.3}: {why}",
                            pan + dp,
                            tilt + dt
                        )),
                        Err(e) => return Err(Error::Perception(e)),
                    }
                }
            }
        }
        if views.is_empty() {
            return Err(Error::Perception(PerceptionError::MarkerNotSeen(format!(
                "in none of {captured} images ({}; a simulated robot shows its marker when built \
                 with RobotBuilder::calibration_marker(true))",
                misses.first().map_or("", String::as_str)
            ))));
        }
        let seen = views.len();
        let problem = HandEyeProblem {
            intrinsics: camera.intrinsics()?,
            link_to_optical: s.link_to_optical,
            corners: s.corners,
            views,
            initial: s.nominal,
            inlier_px: opts.inlier_px,
            min_views: opts.min_images,
            min_sensitivity: MIN_SENSITIVITY,
        };
        let fit = problem.solve().map_err(Error::Perception)?;
        let mut calibration = CameraCalibration::new(&self.config().name, &s.mount, &fit.mount);
        calibration.reprojection_rms_px = fit.rms_px;
        calibration.images = fit.views;
        Ok(HandEyeReport {
            calibration,
            captured,
            seen,
            missed: misses,
            used: fit.views,
            rms_px: fit.rms_px,
        })
    }
}

/// Calibrates `robot`'s head camera mount against the marker its gripper carries (see the
/// module's documentation): the fitted mount and how well the images pin it.
pub fn calibrate_camera(robot: &Robot, opts: &HandEyeOptions) -> Result<HandEyeReport> {
    Calibration(robot).calibrate_camera(opts)
}
