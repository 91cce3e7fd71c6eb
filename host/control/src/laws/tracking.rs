//! Tracking a reference with time-varying LQR ([`LqrTracker`]), its commands bounded and
//! rate-limited by [`Limits`]. Poses `[x, y, θ]` (m, m, rad), commands `(v, ω)` (m/s, rad/s).

use std::time::Duration;

use crate::trajectory::{Limits, LqrTracker};

/// A reference being tracked: the LQR gains, the clock, and the rate limiter of the commands.
#[derive(Debug, Clone)]
pub struct Tracking {
    tracker: LqrTracker,
    closed_loop: bool,
    start: Option<Duration>,
    next: Duration,
    last: (f64, f64),
    limits: Limits,
}

impl Tracking {
    /// At `now`, from the odometry pose `[x, y, θ]` (m, m, rad; the reference's frame): `None`
    /// when finished; `Some(None)` to keep the last command; `Some(Some((v, ω)))` to send.
    pub fn step(&mut self, now: Duration, pose: [f64; 3]) -> Option<Option<(f64, f64)>> {
        let start = *self.start.get_or_insert(now);
        if now < self.next {
            return Some(None);
        }
        let dt = self.tracker.reference.dt;
        // `dt` is validated in `validate::REFERENCE_DT`.
        self.next = now + Duration::from_secs_f64(dt);
        let k = ((now - start).as_secs_f64() / dt).floor() as usize;
        if k >= self.tracker.reference.controls.len() {
            return None;
        }
        let [v, w] = self.tracker.control(k, pose, self.closed_loop);
        // Limits hold on what is commanded: bound, then rate-limit.
        let l = &self.limits;
        let v = v.clamp(-l.v, l.v);
        let w = w.clamp(-l.w, l.w);
        let v = self.last.0 + (v - self.last.0).clamp(-l.accel_v * dt, l.accel_v * dt);
        let w = self.last.1 + (w - self.last.1).clamp(-l.accel_w * dt, l.accel_w * dt);
        self.last = (v, w);
        Some(Some((v, w)))
    }
}

impl Tracking {
    /// Tracks `tracker`'s reference from `now` on, closing the loop on odometry or not,
    /// within `limits`.
    pub fn new(tracker: LqrTracker, closed_loop: bool, now: Duration, limits: Limits) -> Self {
        Tracking {
            tracker,
            closed_loop,
            start: None,
            next: now,
            last: (0.0, 0.0),
            limits,
        }
    }
}
