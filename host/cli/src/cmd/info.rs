//! `ferrobot info`: a robot's joints, limits and components.

use ferrobot::RobotConfig;
use serde::Serialize;

use super::common::{load, print_json};

/// `info`: the robot, as one JSON line or indented. Fields in alphabetical order, here and
/// below (see [`print_json`]).
#[derive(Serialize)]
struct InfoJson<'a> {
    /// The arm, if any.
    arm: Option<ArmJson<'a>>,
    /// The mobile base, if any.
    base: Option<BaseJson>,
    /// The camera, if any.
    camera: Option<CameraJson<'a>>,
    /// The configuration file (`<bundled>/NAME.toml` for a bundled robot).
    file: String,
    /// The gripper's joint, if any.
    gripper: Option<&'a str>,
    /// Every joint, in the configuration's order.
    joints: Vec<JointJson<'a>>,
    /// The robot's name.
    robot: &'a str,
}

/// An arm of `info`.
#[derive(Serialize)]
struct ArmJson<'a> {
    /// The chain's root link.
    base_frame: &'a str,
    /// The end-effector link.
    ee_frame: &'a str,
    /// Home joint angles, rad.
    home: &'a [f64],
    /// The IK solver (its `Debug` name).
    ik: String,
    /// The arm's joints, in order.
    joints: &'a [String],
}

/// A base of `info`.
#[derive(Serialize)]
struct BaseJson {
    /// The base model (its `Debug` name).
    kind: String,
    /// Wheel separation, m.
    track: f64,
    /// Wheel radius, m.
    wheel_radius: f64,
}

/// A camera of `info`.
#[derive(Serialize)]
struct CameraJson<'a> {
    /// Principal point x, px.
    cx: f64,
    /// Principal point y, px.
    cy: f64,
    /// The optical frame.
    frame: &'a str,
    /// Focal length x, px.
    fx: f64,
    /// Focal length y, px.
    fy: f64,
    /// The pan joint.
    pan: &'a str,
    /// The tilt joint.
    tilt: &'a str,
}

/// A joint of `info`. The limits are the firmware's `f32`, printed widened to `f64` (as
/// `1.5700000524520874` for 1.57) as they always were.
#[derive(Serialize)]
struct JointJson<'a> {
    /// Effort limit, N·m.
    effort: f64,
    /// What the joint is (its `Debug` name, lower case).
    kind: String,
    /// Upper position limit, rad.
    max: f64,
    /// Lower position limit, rad.
    min: f64,
    /// The joint's name.
    name: &'a str,
    /// Dynamixel ID of its servo.
    servo_id: u8,
    /// Dynamixel ID of a mirrored twin servo, if any.
    twin_id: Option<u8>,
    /// Velocity limit, rad/s.
    velocity: f64,
}

impl<'a> InfoJson<'a> {
    /// The description of `cfg`.
    fn new(cfg: &'a RobotConfig) -> Self {
        let joints = cfg
            .joints
            .iter()
            .map(|j| JointJson {
                effort: f64::from(j.limits.effort),
                kind: format!("{:?}", j.kind).to_lowercase(),
                max: f64::from(j.limits.max),
                min: f64::from(j.limits.min),
                name: j.name.as_str(),
                servo_id: j.servo_id,
                twin_id: j.twin_id,
                velocity: f64::from(j.limits.velocity),
            })
            .collect();
        InfoJson {
            arm: cfg.arm.as_ref().map(|a| ArmJson {
                base_frame: &a.base_frame,
                ee_frame: &a.ee_frame,
                home: &a.home,
                ik: format!("{:?}", a.ik),
                joints: &a.joints,
            }),
            base: cfg.base.as_ref().map(|b| BaseJson {
                kind: format!("{:?}", b.kind),
                track: b.track,
                wheel_radius: b.wheel_radius,
            }),
            camera: cfg.camera.as_ref().map(|c| CameraJson {
                cx: c.cx,
                cy: c.cy,
                frame: &c.frame,
                fx: c.fx,
                fy: c.fy,
                pan: &c.pan_joint,
                tilt: &c.tilt_joint,
            }),
            file: cfg.file.display().to_string(),
            gripper: cfg.gripper.as_ref().map(|g| g.joint.as_str()),
            joints,
            robot: &cfg.name,
        }
    }
}

/// `ferrobot info`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name, or a path to a TOML configuration.
    pub robot: String,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Describe the robot as one JSON line, or as indented JSON without `--json`.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let cfg = load(&a.robot)?;
    let info = InfoJson::new(&cfg);
    if a.json {
        print_json(&info);
    } else {
        say!(
            "{}",
            serde_json::to_string_pretty(&info).unwrap_or_default()
        );
    }
    Ok(())
}
