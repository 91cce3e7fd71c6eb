//! The camera's pan-tilt head: two position-controlled joints.

use crate::error::{check_finite, Error, Result};
use crate::motion::{Goal, Motion};
use crate::robot::Robot;

/// The pan-tilt head of a [`Robot`]'s camera. Angles in rad; pan about the head's z axis
/// (positive left), tilt about its y axis (positive down).
pub struct PanTilt<'r> {
    robot: &'r mut Robot,
}

impl<'r> PanTilt<'r> {
    pub(crate) fn new(robot: &'r mut Robot) -> Self {
        PanTilt { robot }
    }

    fn joints(&self) -> Result<(usize, usize)> {
        let c = self
            .robot
            .cfg
            .camera
            .as_ref()
            .ok_or_else(|| self.robot.missing("camera"))?;
        let find = |n: &str| {
            self.robot
                .cfg
                .joint_index(n)
                .ok_or_else(|| Error::UnknownName {
                    what: "joint",
                    name: n.into(),
                })
        };
        Ok((find(&c.pan_joint)?, find(&c.tilt_joint)?))
    }

    /// Start moving the selected joints to their targets.
    fn move_to(&mut self, targets: &[(usize, f64)]) -> Result<Motion<'_>> {
        let mut t = 0.2f64;
        let tel = self.robot.link.telemetry()?;
        for &(j, v) in targets {
            check_finite("pan/tilt angle", &[v])?;
            let c = &self.robot.cfg.joints[j];
            let (lo, hi) = (c.limits.min as f64, c.limits.max as f64);
            if v < lo || v > hi {
                return Err(Error::OutOfLimits {
                    joint: c.name.to_string(),
                    value: v,
                    min: lo,
                    max: hi,
                });
            }
            let now = tel.joints.get(j).map(|s| s.position as f64).unwrap_or(v);
            t = t.max(1.5 * (v - now).abs() / (0.9 * c.limits.velocity as f64));
        }
        let mut sorted = targets.to_vec();
        sorted.sort_by_key(|(j, _)| *j);
        let mask = sorted.iter().fold(0u16, |m, (j, _)| m | (1 << j));
        self.robot
            .send_rest_waypoint(mask, sorted.iter().map(|(_, v)| *v), t, "pan/tilt")?;
        Ok(Motion::new(
            self.robot,
            Goal::Joints {
                idx: sorted.iter().map(|(j, _)| *j).collect(),
                target: sorted.iter().map(|(_, v)| *v).collect(),
                tolerance: 0.01,
                stall_since: None,
            },
            "pan/tilt motion",
            std::time::Duration::from_secs_f64(t + 5.0),
        ))
    }

    /// Pan to `angle` and wait.
    pub fn set_pan(&mut self, angle: f64) -> Result<()> {
        let (p, _) = self.joints()?;
        self.move_to(&[(p, angle)])?.wait()
    }

    /// Tilt to `angle` and wait.
    pub fn set_tilt(&mut self, angle: f64) -> Result<()> {
        let (_, t) = self.joints()?;
        self.move_to(&[(t, angle)])?.wait()
    }

    /// Pan and tilt together and wait.
    pub fn set_pan_tilt(&mut self, pan: f64, tilt: f64) -> Result<()> {
        let (p, t) = self.joints()?;
        self.move_to(&[(p, pan), (t, tilt)])?.wait()
    }

    /// Start panning and tilting; returns the motion under way.
    pub fn set_pan_tilt_async(&mut self, pan: f64, tilt: f64) -> Result<Motion<'_>> {
        let (p, t) = self.joints()?;
        self.move_to(&[(p, pan), (t, tilt)])
    }

    /// Measured `[pan, tilt]`, rad.
    pub fn get_state(&mut self) -> Result<[f64; 2]> {
        let (p, t) = self.joints()?;
        let tel = self.robot.link.telemetry()?;
        let at = |j: usize| tel.joints.get(j).map(|s| s.position as f64).unwrap_or(0.0);
        Ok([at(p), at(t)])
    }

    /// Back to pan 0, tilt 0.
    pub fn reset(&mut self) -> Result<()> {
        self.set_pan_tilt(0.0, 0.0)
    }
}
