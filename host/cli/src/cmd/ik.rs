//! `ferrobot ik`: inverse kinematics of the end effector.

use ferrobot::config::IkKind;
use ferrobot::kinematics::ik::{IkOptions, IkSolver, NumericalIk};
use ferrobot::kinematics::locobot_ik::LocobotIk;
use ferrobot::{validate, Orientation};
use nalgebra::{Isometry3, Translation3};
use serde::Serialize;

use super::common::{arm_chain, check_q, load, print_json};

/// `ferrobot ik`'s arguments: the target, its orientation one of three ways, and a seed.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Target position X Y Z, m, in the root link.
    #[arg(long, num_args = 3, allow_negative_numbers = true, required = true, value_names = ["X", "Y", "Z"])]
    pub position: Vec<f64>,
    /// Orientation as a quaternion X Y Z W.
    #[arg(long, num_args = 4, allow_negative_numbers = true, value_names = ["X", "Y", "Z", "W"], conflicts_with_all = ["rpy", "pitch"])]
    pub quaternion: Option<Vec<f64>>,
    /// Orientation as roll, pitch, yaw (R = Rz(yaw)·Ry(pitch)·Rx(roll)), rad.
    #[arg(long, num_args = 3, allow_negative_numbers = true, value_names = ["R", "P", "Y"], conflicts_with = "pitch")]
    pub rpy: Option<Vec<f64>>,
    /// 5-DOF arms: gripper pitch below horizontal, rad.
    #[arg(long, allow_negative_numbers = true)]
    pub pitch: Option<f64>,
    /// 5-DOF arms: gripper roll, rad (with --pitch; default 0).
    #[arg(long, allow_negative_numbers = true, requires = "pitch")]
    pub roll: Option<f64>,
    /// Seed joint angles, rad.
    #[arg(long, num_args = 1.., allow_negative_numbers = true)]
    pub seed: Option<Vec<f64>>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `ik --json` when solved (a failure is `main`'s error object), fields in alphabetical
/// order (see [`print_json`]).
#[derive(Serialize)]
struct IkJson {
    /// The arm's joint angles, rad.
    joints: Vec<f64>,
    /// Always true.
    success: bool,
}

/// Solve for the joint angles (rad) that put the end effector at the target of `a`: the
/// pitch-roll solver with `--pitch`, else the robot's solver for a full orientation.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let cfg = load(&a.robot)?;
    let chain = arm_chain(&cfg)?;
    if let Some(s) = &a.seed {
        check_q(&chain, s)?;
    }
    let p = validate::arm_point("position", [a.position[0], a.position[1], a.position[2]])?;
    validate::angles(
        "pitch and roll",
        &[a.pitch, a.roll].into_iter().flatten().collect::<Vec<_>>(),
    )?;
    let ac = cfg
        .arm
        .as_ref()
        .map(|x| (x.ik_position_tolerance, x.ik_orientation_tolerance, x.ik))
        .unwrap_or((1e-5, 1e-5, IkKind::Numerical));
    let opts = IkOptions {
        position_tolerance: ac.0,
        orientation_tolerance: ac.1,
        ..Default::default()
    };
    let result = if let Some(pitch) = a.pitch {
        LocobotIk::from_chain(&chain)
            .and_then(|s| {
                s.solve_pitch_roll(&chain, &p, pitch, a.roll.unwrap_or(0.0), a.seed.as_deref())
            })
            .map_err(ferrobot::Error::from)
    } else {
        let o = match (&a.quaternion, &a.rpy) {
            (Some(q), _) => Orientation::Quaternion([q[0], q[1], q[2], q[3]]),
            (None, Some(r)) => Orientation::YawPitchRoll([r[2], r[1], r[0]]),
            (None, None) => {
                return Err(ferrobot::Error::Usage(
                    "give an orientation: --quaternion, --rpy or --pitch".into(),
                ))
            }
        };
        o.to_quaternion().and_then(|rot| {
            let target = Isometry3::from_parts(Translation3::from(p), rot);
            let solver: Box<dyn IkSolver> = match ac.2 {
                IkKind::LocobotPitchRoll => Box::new(LocobotIk::from_chain(&chain)?),
                IkKind::Numerical => Box::new(NumericalIk),
            };
            Ok(solver.solve(&chain, &target, a.seed.as_deref(), &opts)?)
        })
    };
    let q = result?;
    if a.json {
        print_json(&IkJson {
            joints: q,
            success: true,
        });
    } else {
        say!(
            "{}",
            q.iter()
                .map(|v| format!("{v:.6}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    Ok(())
}
