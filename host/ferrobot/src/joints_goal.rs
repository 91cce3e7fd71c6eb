//! The goal of joints reaching targets within a tolerance, judged stalled when they stop
//! improving: arm moves, Cartesian paths and the pan-tilt head.

use std::time::Duration;

use crate::backend::Link;
use crate::error::{Error, Result};
use crate::goals::{
    joint_mask, Claim, Goal, Step, ARRIVAL_SPEED, STALL_GRACE, STALL_LAG, STALL_PROGRESS,
    STALL_TIME,
};

/// The goal of joints (firmware indices) reaching targets within a tolerance: arm moves,
/// Cartesian paths and the pan-tilt head.
pub(crate) struct JointsGoal {
    /// Firmware joint indices.
    idx: Vec<usize>,
    /// Targets, rad.
    target: Vec<f64>,
    /// Arrival tolerance, rad.
    tolerance: f64,
    /// When the last knot sent for these joints is due (the backend's clock): the goal is not
    /// reached before, even if the joints pass their targets on the way.
    due: Duration,
    /// When the motion started.
    started: Duration,
    /// The timed path the joints follow (s from `started`, positions in `idx` order), when it
    /// is known: while it runs, a stall is judged by the lag behind it, not by the distance
    /// to the target (a planned path may lead away from the target first).
    reference: Vec<(f64, Vec<f64>)>,
    /// Best (smallest) worst-joint error so far, when it was reached, and whether it was a lag
    /// behind the reference.
    stall_since: Option<(f64, Duration, bool)>,
}

impl JointsGoal {
    /// Joints `idx` to reach `target` (rad) within `tolerance`, started at `started`, not
    /// before `due`.
    pub(crate) fn new(
        idx: Vec<usize>,
        target: Vec<f64>,
        tolerance: f64,
        started: Duration,
        due: Duration,
    ) -> Self {
        JointsGoal {
            idx,
            target,
            tolerance,
            due,
            started,
            reference: Vec::new(),
            stall_since: None,
        }
    }

    /// The goal following the timed path `reference` (s from the start, positions in the
    /// joints' order, times increasing).
    pub(crate) fn following(mut self, reference: Vec<(f64, Vec<f64>)>) -> Self {
        self.reference = reference;
        self
    }

    fn mask(&self) -> u16 {
        joint_mask(self.idx.iter().copied())
    }

    /// Where the reference has the joints `t` s after the start (linear between its points);
    /// `None` before its first or after its last point.
    fn reference_at(&self, t: f64) -> Option<Vec<f64>> {
        let k = self.reference.iter().position(|(tk, _)| *tk >= t)?;
        let (t1, q1) = &self.reference[k];
        if k == 0 {
            return (t >= *t1 - 1e-9).then(|| q1.clone());
        }
        let (t0, q0) = &self.reference[k - 1];
        let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 1.0 };
        Some(q0.iter().zip(q1).map(|(a, b)| a + f * (b - a)).collect())
    }
}

impl Goal for JointsGoal {
    fn claim(&self) -> Claim {
        Claim {
            joints: self.mask(),
            ..Claim::default()
        }
    }

    fn step(&mut self, s: &mut Step<'_>) -> Option<Result<()>> {
        let now = s.now;
        let position = |j: usize| {
            s.telemetry
                .joints
                .get(j)
                .copied()
                .unwrap_or_default()
                .position as f64
        };
        let mut worst = (0usize, 0.0f64);
        let mut at_rest = true;
        for (&j, &q) in self.idx.iter().zip(self.target.iter()) {
            let st = s.telemetry.joints.get(j).copied().unwrap_or_default();
            let e = (st.position as f64 - q).abs();
            if e > worst.1 {
                worst = (j, e);
            }
            at_rest &= (st.velocity as f64).abs() < ARRIVAL_SPEED;
        }
        if worst.1 <= self.tolerance && at_rest && now >= self.due {
            return Some(Ok(()));
        }
        // Stalled: past the start of the motion, the largest joint error has not improved by
        // STALL_PROGRESS for STALL_TIME (a blocked joint, or a trajectory that ended short of
        // its target). Progress, not speed readings, so that noise on a joint pressed against
        // an obstacle does not hide the stall. Joints within tolerance of their targets,
        // waiting for the last knot to be due, are not stalled. While a known reference runs,
        // the error is the lag behind it, and a lag within STALL_LAG is no stall.
        let t = now.saturating_sub(self.started).as_secs_f64();
        let lagging = self.reference_at(t).map(|r| {
            self.idx
                .iter()
                .zip(&r)
                .map(|(&j, &q)| (j, (position(j) - q).abs()))
                .fold((0usize, 0.0f64), |w, e| if e.1 > w.1 { e } else { w })
        });
        let (error, tracking) = match lagging {
            Some(lag) if lag.1 <= STALL_LAG => {
                self.stall_since = None;
                return None;
            }
            Some(lag) => (lag, true),
            None => (worst, false),
        };
        let (best, at, _) = match self.stall_since {
            Some(since) if since.2 == tracking => since,
            _ => *self.stall_since.insert((error.1, now, tracking)),
        };
        if error.1 < best - STALL_PROGRESS {
            self.stall_since = Some((error.1, now, tracking));
        } else if error.1 > self.tolerance
            && now > self.started + STALL_GRACE
            && now - at > STALL_TIME
        {
            let joint = s
                .cfg
                .joints
                .get(error.0)
                .map(|j| j.name.to_string())
                .unwrap_or_default();
            return Some(Err(Error::Stalled {
                joint,
                position: position(error.0),
                error: error.1,
            }));
        }
        None
    }

    fn halt(&mut self, link: &mut dyn Link) {
        let _ = link.command(
            &ferrobot_protocol::HostMsg::ClearQueue {
                joints: self.mask(),
            },
            "stop",
        );
    }
}
