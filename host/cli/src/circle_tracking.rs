//! The circle-tracking comparison of the base benchmark: the paper's circle (radius 0.4 m)
//! driven open loop, by LQR and by LQR on the ILQR-optimised reference on a simulated base,
//! the executed path taken from the simulator's ground truth (m).

use ferrobot::base_control::Reference;
use ferrobot::error::{Error, Result};
use ferrobot::odometry_calibration::WheelGeometry;

use crate::base_trials::base_robot;

/// How the circle is executed in the tracking comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CircleRun {
    /// The reference's controls played open loop.
    OpenLoop,
    /// LQR closed loop on the reference.
    Lqr,
    /// LQR closed loop on the ILQR-optimised reference.
    Ilqr,
}

impl CircleRun {
    /// Every run, in the plot's order.
    pub const ALL: [CircleRun; 3] = [CircleRun::OpenLoop, CircleRun::Lqr, CircleRun::Ilqr];

    /// Name in legends.
    pub fn name(self) -> &'static str {
        match self {
            CircleRun::OpenLoop => "open loop",
            CircleRun::Lqr => "LQR",
            CircleRun::Ilqr => "ILQR + LQR",
        }
    }
}

/// The paper's circle: radius 0.4 m at 0.1 m/s and 0.25 rad/s for one lap, dt 0.1 s.
pub fn paper_circle() -> Reference {
    Reference::circle([0.0; 3], 0.1, 0.25, std::f64::consts::TAU / 0.25, 0.1)
        .expect("the paper's circle is a valid reference")
}

/// The executed ground-truth path `[x, y]` (m) of `run` on the circle, and its final
/// distance from the reference's end (m).
pub fn circle_path(
    robot: &str,
    run: CircleRun,
    seed: u64,
    geometry: Option<WheelGeometry>,
) -> Result<(Vec<[f64; 2]>, f64)> {
    let bot = base_robot(robot, seed, geometry)?;
    let mut r = paper_circle();
    if run == CircleRun::Ilqr {
        let lim = ferrobot::base_control::Limits::TRACKING;
        r = ferrobot::base_control::ilqr([0.0; 3], &r, [3.0, 3.0, 4.0], 0.2, &lim)?.reference;
    }
    let end = r.end();
    if let Some(b) = bot
        .simulator()
        .as_deref_mut()
        .and_then(|s| s.hw.base.as_mut())
    {
        b.drive.trace = Some(Vec::new());
    }
    bot.base()?
        .track_trajectory(r, run != CircleRun::OpenLoop)?;
    let trace = bot
        .simulator()
        .as_deref_mut()
        .and_then(|s| s.hw.base.as_mut())
        .and_then(|b| b.drive.trace.take())
        .ok_or_else(|| Error::Link("the circle plot needs the simulated backend".into()))?;
    let last = trace.last().copied().unwrap_or([0.0; 3]);
    let path = trace.iter().step_by(20).map(|p| [p[0], p[1]]).collect();
    Ok((path, (last[0] - end[0]).hypot(last[1] - end[1])))
}
