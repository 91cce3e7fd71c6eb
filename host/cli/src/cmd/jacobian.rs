//! `ferrobot jacobian`: the arm's geometric Jacobian.

use serde::Serialize;

use super::common::{arm_chain, check_q, load, print_json};

/// `jacobian --json`.
#[derive(Serialize)]
struct JacobianJson {
    /// Six rows (vx vy vz wx wy wz) of one column per joint.
    jacobian: Vec<Vec<f64>>,
}

/// `ferrobot jacobian`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Joint angles, rad.
    #[arg(allow_negative_numbers = true, required = true)]
    pub q: Vec<f64>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Print the geometric Jacobian at joint angles `q` (rad): rows vx vy vz wx wy wz in the root
/// frame, at the end effector's origin.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let q = a.q.as_slice();
    let cfg = load(&a.robot)?;
    let arm = arm_chain(&cfg)?;
    check_q(&arm, q)?;
    let j = arm.jacobian(q);
    let rows: Vec<Vec<f64>> = (0..6)
        .map(|r| (0..arm.dof()).map(|c| j[(r, c)]).collect())
        .collect();
    if a.json {
        print_json(&JacobianJson { jacobian: rows });
    } else {
        for (name, r) in ["vx", "vy", "vz", "wx", "wy", "wz"].iter().zip(rows) {
            say!(
                "{name} {}",
                r.iter()
                    .map(|v| format!("{v:>10.6}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            );
        }
    }
    Ok(())
}
