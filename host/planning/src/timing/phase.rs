//! The phase plane of one piece of the path: points `(s, x = ṡ²)` of the profile, the
//! integration's state over a piece (its limits, time step and step budget), and the driver
//! that alternates forward and backward integration between switching points.

use super::path::{Path, Piece};
use super::{failed, too_many_steps, REL};
use crate::Result;

/// A point of the profile: arc length `s` (rad) and squared path speed `x = ṡ²` (rad²/s²).
#[derive(Debug, Clone, Copy)]
pub(super) struct Pt {
    pub(super) s: f64,
    pub(super) x: f64,
}

/// A switching point: where a backward integration starts and the forward one resumes.
#[derive(Debug, Clone, Copy)]
pub(super) struct Switch {
    pub(super) s: f64,
    pub(super) x: f64,
}

/// Outcome of a step along the velocity limit curve.
#[derive(Debug, Clone, Copy)]
pub(super) enum Follow {
    /// The next knot.
    To(Pt),
    /// The curve falls faster than the profile may: stop before here.
    Unfollowable,
    /// The curve rises faster than the profile may: accelerate under it instead.
    Rises,
}

/// A point of the forward integration: segment `k`, arc length `s`, squared speed `x`, the
/// next break `nb`, the velocity limit curve `xv` and its slope (going forward), and the
/// range `lo..hi` of path accelerations.
#[derive(Debug, Clone, Copy)]
pub(super) struct At {
    pub(super) k: usize,
    pub(super) s: f64,
    pub(super) x: f64,
    pub(super) nb: f64,
    pub(super) xv: f64,
    pub(super) slope: f64,
    pub(super) lo: f64,
    pub(super) hi: f64,
}

/// What a pass of the forward integration did.
#[derive(Debug, Clone, Copy)]
pub(super) enum Pass {
    /// Put a knot on (or just under) the velocity limit curve: follow it next.
    OnCurve,
    /// Put a knot under the limit curves.
    Under,
    /// Stopped.
    Stop(Stop),
}

/// How far the acceleration range at the end of a trial step misses the trial acceleration
/// (on the side the extreme pushes against, and on the other; `None` above the acceleration
/// limit curve), and the step's end `(s, x)`.
pub(super) type Miss = (Option<(f64, f64)>, f64, f64);

/// Why a forward integration stopped before the end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Stop {
    /// At the end of the piece.
    End,
    /// At the acceleration limit curve.
    AccelLimit,
    /// On the velocity limit curve where it falls faster than the profile may.
    VelocityLimit,
}

pub(super) struct Phase<'a> {
    pub(super) path: &'a Path,
    pub(super) piece: &'a Piece,
    pub(super) vmax: &'a [f64],
    pub(super) amax: &'a [f64],
    pub(super) dt: f64,
    /// Tangent and curvature at the point last loaded.
    pub(super) t: Vec<f64>,
    pub(super) c: Vec<f64>,
    /// Segment and arc length of the point loaded in `t`, `c`.
    pub(super) loaded: Option<(usize, f64)>,
    pub(super) budget: &'a mut usize,
}

pub(super) fn tol(a: f64) -> f64 {
    REL * (1.0 + a.abs())
}

impl Phase<'_> {
    pub(super) fn spend(&mut self) -> Result<()> {
        if *self.budget == 0 {
            return Err(too_many_steps());
        }
        *self.budget -= 1;
        Ok(())
    }

    /// The piece's segment at `s` seen going forward (the one starting at a boundary).
    pub(super) fn seg_fwd(&self, s: f64) -> usize {
        let r = &self.piece.segs;
        r.start
            + self.path.segs[r.clone()]
                .partition_point(|g| g.start <= s)
                .saturating_sub(1)
    }

    /// The piece's segment at `s` seen going backward (the one ending at a boundary).
    pub(super) fn seg_bwd(&self, s: f64) -> usize {
        let r = &self.piece.segs;
        r.start
            + self.path.segs[r.clone()]
                .partition_point(|g| g.start < s)
                .saturating_sub(1)
    }

    pub(super) fn next_break(&self, s: f64) -> f64 {
        let b = &self.path.breaks;
        b.get(b.partition_point(|&x| x <= s))
            .map_or(self.piece.s1, |&x| x.min(self.piece.s1))
    }

    pub(super) fn prev_break(&self, s: f64) -> f64 {
        let b = &self.path.breaks;
        match b.partition_point(|&x| x < s) {
            0 => self.piece.s0,
            i => b[i - 1].max(self.piece.s0),
        }
    }

    pub(super) fn load(&mut self, k: usize, s: f64) {
        if self.loaded == Some((k, s)) {
            return;
        }
        let path = self.path;
        path.segs[k].derivatives(s, &mut self.t, &mut self.c);
        self.loaded = Some((k, s));
    }

    /// The profile of the piece, from rest at its start to rest at its end.
    pub(super) fn run(&mut self) -> Result<Vec<Pt>> {
        let (s0, s1) = (self.piece.s0, self.piece.s1);
        let mut switches = self.accel_switches();
        switches.extend(self.scan_switches(s0, s1, false)?);
        switches.sort_by(|a, b| a.s.total_cmp(&b.s).then(a.x.total_cmp(&b.x)));
        let mut prof = vec![Pt { s: s0, x: 0.0 }];
        let mut last_switch = f64::NEG_INFINITY;
        let most_rounds = 2 * switches.len() + 1000;
        for _ in 0..most_rounds {
            let stop = self.forward(&mut prof)?;
            if stop == Stop::End {
                self.backward(&mut prof, Pt { s: s1, x: 0.0 })?;
                return Ok(prof);
            }
            let s_last = prof.last().map_or(s0, |p| p.s);
            let mut next = switches
                .iter()
                .find(|p| p.s > last_switch && p.s >= s_last - tol(s_last))
                .copied();
            if stop == Stop::VelocityLimit {
                // Where exactly the curve becomes followable again, from here.
                let until = next.map_or(s1, |p| p.s);
                let found = self.scan_switches(s_last.max(last_switch), until, true)?;
                if let Some(sw) = found.first().filter(|p| p.s > last_switch) {
                    if next.is_none_or(|n| sw.s < n.s) {
                        next = Some(*sw);
                    }
                }
            }
            let Some(sw) = next else {
                self.backward(&mut prof, Pt { s: s1, x: 0.0 })?;
                return Ok(prof);
            };
            last_switch = sw.s;
            self.backward(&mut prof, Pt { s: sw.s, x: sw.x })?;
        }
        Err(failed("too many switching points"))
    }
}
