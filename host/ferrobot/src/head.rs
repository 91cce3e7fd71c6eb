//! The pan-tilt head that carries the camera: two position-controlled joints.

use std::time::Duration;

use crate::error::{check_finite, Error, Result};
use crate::goals::{Claim, Goal};
use crate::hub::Hub;
use crate::joints_goal::JointsGoal;
use crate::motion::Motion;
use crate::robot::Robot;

/// The pan-tilt head of a [`Robot`]'s camera: a handle (clone of the robot's). Angles in rad;
/// pan about the head's z axis (positive left), tilt about its y axis (positive down).
#[derive(Clone, Debug)]
pub struct Head {
    robot: Robot,
    /// Firmware indices of the pan and tilt joints.
    pan: usize,
    tilt: usize,
}

impl Head {
    pub(crate) fn new(robot: Robot) -> Result<Self> {
        let cfg = robot.cfg();
        let c = cfg.camera.as_ref().ok_or_else(|| robot.missing("camera"))?;
        let find = |n: &str| {
            cfg.joint_index(n).ok_or_else(|| Error::UnknownName {
                what: "joint",
                name: n.into(),
            })
        };
        let (pan, tilt) = (find(&c.pan_joint)?, find(&c.tilt_joint)?);
        Ok(Head { robot, pan, tilt })
    }

    fn joints(&self) -> Result<(usize, usize)> {
        Ok((self.pan, self.tilt))
    }

    /// Start moving the selected joints to their targets; a head motion of the same joints
    /// still under way is preempted.
    fn move_to(&self, targets: &[(usize, f64)]) -> Result<Motion> {
        let cfg = self.robot.cfg();
        for &(j, v) in targets {
            check_finite("pan/tilt angle", &[v])?;
            let c = &cfg.joints[j];
            let (lo, hi) = (c.limits.min as f64, c.limits.max as f64);
            if v < lo || v > hi {
                return Err(Error::OutOfLimits {
                    joint: c.name.to_string(),
                    value: v,
                    min: lo,
                    max: hi,
                });
            }
        }
        let mut sorted = targets.to_vec();
        sorted.sort_by_key(|(j, _)| *j);
        let mask = crate::goals::joint_mask(sorted.iter().map(|(j, _)| *j));
        let claim = Claim {
            joints: mask,
            ..Claim::default()
        };
        self.robot
            .start_motion(claim, "pan/tilt motion", |io: &mut Hub| {
                let tel = io.link.telemetry()?;
                let mut t = 0.2f64;
                for &(j, v) in &sorted {
                    // A reported angle that is not a number within 0.1 rad of the joint's range
                    // (hostile telemetry) is taken as the far end of the range from the target:
                    // the slowest move, never an infinite duration.
                    let c = &cfg.joints[j];
                    let (lo, hi) = (c.limits.min as f64, c.limits.max as f64);
                    let now = tel
                        .joints
                        .get(j)
                        .map(|s| s.position as f64)
                        .filter(|p| p.is_finite() && (lo - 0.1..=hi + 0.1).contains(p))
                        .unwrap_or(if v - lo > hi - v { lo } else { hi });
                    t = t.max(1.5 * (v - now).abs() / (0.9 * c.limits.velocity as f64));
                }
                io.send_rest_waypoint(mask, sorted.iter().map(|(_, v)| *v), t, "pan/tilt")?;
                let started = io.link.now();
                let goal = JointsGoal::new(
                    sorted.iter().map(|(j, _)| *j).collect(),
                    sorted.iter().map(|(_, v)| *v).collect(),
                    0.01,
                    started,
                    started + Duration::from_secs_f64(t),
                );
                Ok((
                    Box::new(goal) as Box<dyn Goal>,
                    Duration::from_secs_f64(t + 5.0),
                ))
            })
    }

    /// Pan to `angle` and wait.
    pub fn set_pan(&self, angle: f64) -> Result<()> {
        let (p, _) = self.joints()?;
        self.move_to(&[(p, angle)])?.wait()
    }

    /// Tilt to `angle` and wait.
    pub fn set_tilt(&self, angle: f64) -> Result<()> {
        let (_, t) = self.joints()?;
        self.move_to(&[(t, angle)])?.wait()
    }

    /// Pan and tilt together and wait.
    pub fn set_pan_tilt(&self, pan: f64, tilt: f64) -> Result<()> {
        let (p, t) = self.joints()?;
        self.move_to(&[(p, pan), (t, tilt)])?.wait()
    }

    /// Start panning and tilting; returns the motion under way.
    pub fn set_pan_tilt_async(&self, pan: f64, tilt: f64) -> Result<Motion> {
        let (p, t) = self.joints()?;
        self.move_to(&[(p, pan), (t, tilt)])
    }

    /// Measured `[pan, tilt]`, rad.
    pub fn get_state(&self) -> Result<[f64; 2]> {
        let (p, t) = self.joints()?;
        let tel = self.robot.telemetry()?;
        let at = |j: usize| tel.joints.get(j).map(|s| s.position as f64).unwrap_or(0.0);
        Ok([at(p), at(t)])
    }

    /// Back to pan 0, tilt 0.
    pub fn reset(&self) -> Result<()> {
        self.set_pan_tilt(0.0, 0.0)
    }
}
