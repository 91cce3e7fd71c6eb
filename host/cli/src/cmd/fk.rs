//! `ferrobot fk`: forward kinematics of the arm's chain.

use ferrobot::kinematics::Chain;
use ferrobot::Pose;
use serde::Serialize;

use super::common::{arm_chain, check_q, load, print_json};

/// `fk --json`: the pose, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct PoseJson {
    /// Position, m.
    position: [f64; 3],
    /// Unit quaternion `[x, y, z, w]`.
    quaternion: [f64; 4],
    /// Rotation matrix, rows.
    rotation: [[f64; 3]; 3],
}

/// `ferrobot fk`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Joint angles, rad, in arm order.
    #[arg(allow_negative_numbers = true, required = true)]
    pub q: Vec<f64>,
    /// Frame of the arm's chain (default: the end effector).
    #[arg(long)]
    pub frame: Option<String>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Print the pose of the end effector (or of `--frame`, a link of the arm's chain) in the
/// robot's root link at the arm's joint angles `q` (rad).
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let (q, frame) = (a.q.as_slice(), a.frame.as_deref());
    let cfg = load(&a.robot)?;
    let arm = arm_chain(&cfg)?;
    check_q(&arm, q)?;
    let chain = match frame {
        Some(f) => Chain::from_urdf(&cfg.urdf, &arm.base, f)?,
        None => arm.clone(),
    };
    let sub: Vec<f64> = chain
        .joints
        .iter()
        .filter_map(|j| {
            arm.joints
                .iter()
                .position(|a| a.name == j.name)
                .map(|k| q[k])
        })
        .collect();
    if sub.len() != chain.dof() {
        return Err(ferrobot::Error::UnknownName {
            what: "frame of the arm's chain",
            name: frame.unwrap_or_default().to_string(),
        });
    }
    let p: Pose = chain.fk(&sub).into();
    if a.json {
        print_json(&PoseJson {
            position: p.position,
            quaternion: p.quaternion,
            rotation: p.rotation,
        });
    } else {
        say!("frame {} in {}", chain.tip, chain.base);
        say!(
            "position   {:.6} {:.6} {:.6}",
            p.position[0],
            p.position[1],
            p.position[2]
        );
        say!(
            "quaternion {:.6} {:.6} {:.6} {:.6}  [x y z w]",
            p.quaternion[0],
            p.quaternion[1],
            p.quaternion[2],
            p.quaternion[3]
        );
        for r in p.rotation {
            say!("rotation   {:.6} {:.6} {:.6}", r[0], r[1], r[2]);
        }
    }
    Ok(())
}
