//! The arm's gravity model: sent by the host link by link ([`HostMsg::ArmLink`]), checked
//! against the physical ranges, evaluated at the measured pose every tick (the gravity term of
//! recursive Newton-Euler, [`ferrobot_protocol::gravity`]), and trusted only while the joints'
//! measured efforts agree with it.
//!
//! A model is a claim about the arm the firmware cannot take on faith: the host may be wrong
//! (a payload, a bad description) or hostile. So a new model is a *candidate* until the arm
//! *confirms* it, and a trusted model is *refuted* as soon as the arm contradicts it: whenever
//! every loaded joint of a model is held still in position mode, each one's measured effort
//! must be the modelled load within [`AGREE_ABS`] + [`AGREE_SHARE`] of it. Agreeing for
//! [`CONFIRM_TIME`] confirms a candidate, which then replaces the trusted model; one joint
//! disagreeing for [`REFUTE_TIME`] refutes the trusted model, which becomes a candidate again.
//! A host can so neither take a trusted model away nor slip a wrong one in; only the arm's
//! own measurements (or a new joint table) end a model's trust. Without a trusted model the
//! joints run as without one (their load correction carries the load); the handover either
//! way moves no goal (see `JointControl::tick_position`).
//!
//! [`HostMsg::ArmLink`]: ferrobot_protocol::HostMsg::ArmLink

use ferrobot_protocol::gravity::{self, Link, MAX_LINKS};
use ferrobot_protocol::{
    ranges, ArmLink, FaultKind, JointKind, JointMode, RejectReason, MAX_JOINTS,
};
use heapless::Vec;

use crate::time::{Duration, Instant};
use crate::Firmware;

/// A measured effort agrees with the model within this, N·m (static friction, the servos'
/// current sensing) ...
pub const AGREE_ABS: f32 = 0.2;
/// ... plus this share of the modelled load (the description's masses: a model 20 % off the
/// arm is still trusted).
pub const AGREE_SHARE: f32 = 0.3;
/// A joint carries a load worth checking when the model gives it at least this, N·m.
pub const LOADED: f32 = 0.05;
/// A candidate is confirmed only at a pose where it gives at least one joint held still this
/// load, N·m, or more: at a pose where everything is light (the arm upright), a wrong model
/// agrees within the tolerance as well as the right one.
pub const CONFIRM_LOAD: f32 = 0.4;
/// Agreement this long confirms a model.
pub const CONFIRM_TIME: Duration = Duration::from_millis(200);
/// Disagreement of one joint this long refutes a trusted model.
pub const REFUTE_TIME: Duration = Duration::from_millis(300);

/// The gravity model of an arm: a serial chain of revolute joints and, for each link, the row
/// of the joint table it moves.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GravityModel {
    /// The chain, base first.
    pub links: Vec<Link<f32>, MAX_LINKS>,
    /// Joint-table row of each link's joint.
    pub joints: Vec<u8, MAX_LINKS>,
}

/// The trusted model, the candidate, and the one being received.
#[derive(Debug, Clone, Default)]
pub(crate) struct Dynamics {
    /// The model the arm confirmed, in force.
    trusted: Option<GravityModel>,
    /// A model waiting for the arm to confirm it (a new one, or a refuted one).
    candidate: Option<GravityModel>,
    /// Links received so far of the model being sent, and how many it has.
    pending: Option<(u8, GravityModel)>,
    /// Since when every loaded joint has agreed with the candidate.
    agree_since: Option<Instant>,
    /// Since when a joint has disagreed with the trusted model, and which.
    disagree_since: Option<(Instant, u8)>,
    /// Per joint-table row, the largest effort (N·m) the joint was measured giving, held
    /// still, in agreement with the trusted model: the model's load is carried only up to
    /// what the arm has shown (see [`carried`]); a model right where the arm was seen may be
    /// wrong where it was not. 0: never seen; the joint's load correction carries its load.
    borne: [f32; MAX_JOINTS],
}

impl Dynamics {
    /// Whether a model is trusted.
    pub(crate) fn trusted(&self) -> bool {
        self.trusted.is_some()
    }

    /// Whether the trusted model covers joint-table row `j`.
    pub(crate) fn trusted_for(&self, j: usize) -> bool {
        self.trusted
            .as_ref()
            .is_some_and(|m| m.joints.iter().any(|&r| usize::from(r) == j))
    }

    /// Drop every model (the joint table changed under them).
    pub(crate) fn clear(&mut self) {
        *self = Self::default();
    }
}

/// Whether a joint measured giving effort `e` (N·m) bears out a modelled load `t` (what
/// gravity exerts, N·m): `e + t` within [`AGREE_ABS`] + [`AGREE_SHARE`] of the *measured*
/// effort (a tolerance that grew with the claim would let a large wrong claim through).
fn agrees(e: f32, t: f32) -> bool {
    (e + t).abs() <= AGREE_ABS + AGREE_SHARE * e.abs()
}

/// The largest load (N·m) an effort of `e` N·m bears out, with the agreement's tolerance; the
/// tolerance alone for an effort not measured.
pub fn supported(e: f32) -> f32 {
    let e = if e.is_finite() { e.abs() } else { 0.0 };
    AGREE_ABS + (1.0 + AGREE_SHARE) * e
}

/// The load (N·m) a joint carries of its modelled `t`, having been seen bearing out `shown`
/// N·m: none before it was seen; else `t` within what it showed, with the agreement's
/// tolerance.
fn carried(t: f32, shown: f32) -> Option<f32> {
    let cap = supported(shown);
    (shown > 0.0).then_some(t.clamp(-cap, cap))
}

impl Firmware {
    /// Take link `index` of a model of `count` links; once whole it is the candidate, which
    /// replaces the trusted model when the arm confirms it. `count` 0 drops the candidate.
    pub(crate) fn arm_link(
        &mut self,
        index: u8,
        count: u8,
        link: &ArmLink,
    ) -> Result<(), RejectReason> {
        let result = self.take_link(index, count, link);
        if result.is_err() {
            self.dynamics.pending = None;
        }
        if result == Ok(true) {
            let model = self.dynamics.pending.take().map(|(_, m)| m);
            self.dynamics.candidate = model.filter(|m| !m.links.is_empty());
            self.dynamics.agree_since = None;
        }
        result.map(|_| ())
    }

    /// Check and keep one link; `Ok(true)` once the model is whole.
    fn take_link(&mut self, index: u8, count: u8, link: &ArmLink) -> Result<bool, RejectReason> {
        if count == 0 {
            self.dynamics.pending = Some((0, GravityModel::default()));
            return Ok(true);
        }
        if usize::from(count) > MAX_LINKS {
            return Err(RejectReason::InvalidConfig);
        }
        if let Some(e) = ranges::arm_link_error(link) {
            return Err(e);
        }
        let row = self
            .profile
            .joints
            .get(usize::from(link.joint))
            .ok_or(RejectReason::UnknownJoint)?;
        // An arm's joints only: the gripper has its own driver, a camera head no load to speak of.
        if row.kind != JointKind::Arm {
            return Err(RejectReason::InvalidConfig);
        }
        if index == 0 {
            self.dynamics.pending = Some((count, GravityModel::default()));
        }
        let Some((n, m)) = self.dynamics.pending.as_mut() else {
            return Err(RejectReason::InvalidConfig);
        };
        let in_order = *n == count && usize::from(index) == m.links.len();
        if !in_order || m.joints.contains(&link.joint) {
            return Err(RejectReason::InvalidConfig);
        }
        let pushed = m.links.push(link.link()).is_ok() && m.joints.push(link.joint).is_ok();
        if !pushed {
            return Err(RejectReason::InvalidConfig);
        }
        Ok(m.links.len() == usize::from(count))
    }

    /// Joints in teach mode go back to position mode, holding where they are.
    pub(crate) fn leave_teach(&mut self, now: Instant) {
        for j in self.joints.iter_mut() {
            if j.mode == JointMode::Teach {
                j.set_mode(now, JointMode::Position);
            }
        }
        self.apply_modes();
    }

    /// Give every joint the trusted model's gravity load at the measured pose (or none), refute
    /// the trusted model or confirm the candidate against the measured efforts.
    pub(crate) fn model_gravity(&mut self, now: Instant) {
        for j in self.joints.iter_mut() {
            j.gravity = None;
        }
        for j in self.joints.iter_mut() {
            j.model_load = None;
        }
        let mut tau = [0.0f32; MAX_LINKS];
        if self
            .modelled_loads(self.dynamics.trusted.as_ref(), &mut tau)
            .is_some()
        {
            self.bear_out(&tau);
            if let Some(j) = self
                .disagreeing(self.dynamics.trusted.as_ref(), &tau, true)
                .1
            {
                let d = &mut self.dynamics;
                let since = *d.disagree_since.get_or_insert((now, j));
                if now - since.0 >= REFUTE_TIME {
                    d.candidate = d.trusted.take();
                    d.borne = [0.0; MAX_JOINTS];
                    d.disagree_since = None;
                    d.agree_since = None;
                    self.leave_teach(now);
                    self.fault(now, FaultKind::ModelRefuted, Some(since.1), None, 0);
                    return;
                }
            } else {
                self.dynamics.disagree_since = None;
            }
            if let Some(m) = self.dynamics.trusted.as_ref() {
                let borne = self.dynamics.borne;
                for (&j, &t) in m.joints.iter().zip(&tau) {
                    let shown = borne.get(usize::from(j)).copied().unwrap_or(0.0);
                    if let Some(jc) = self.joints.get_mut(usize::from(j)) {
                        jc.model_load = Some(t);
                        jc.gravity = carried(t, shown);
                    }
                }
            }
        }
        self.check_candidate(now);
    }

    /// Confirm the candidate once every loaded joint of it has agreed for [`CONFIRM_TIME`].
    fn check_candidate(&mut self, now: Instant) {
        let mut tau = [0.0f32; MAX_LINKS];
        if self
            .modelled_loads(self.dynamics.candidate.as_ref(), &mut tau)
            .is_none()
        {
            return;
        }
        let agrees =
            self.disagreeing(self.dynamics.candidate.as_ref(), &tau, false) == (true, None);
        let d = &mut self.dynamics;
        d.agree_since = if agrees {
            Some(d.agree_since.unwrap_or(now))
        } else {
            None
        };
        if d.agree_since.is_some_and(|t| now - t >= CONFIRM_TIME) {
            d.trusted = d.candidate.take();
            d.borne = [0.0; MAX_JOINTS];
            d.agree_since = None;
            d.disagree_since = None;
            self.leave_teach(now);
            self.fault(now, FaultKind::ModelConfirmed, None, None, 0);
        }
    }

    /// Model `m`'s gravity torques at the measured pose (N·m, what gravity exerts), in link
    /// order; `None` without a model or with a joint of it unmeasured.
    fn modelled_loads(
        &self,
        m: Option<&GravityModel>,
        tau: &mut [f32; MAX_LINKS],
    ) -> Option<usize> {
        let m = m?;
        let mut q = [0.0f32; MAX_LINKS];
        for (qk, &j) in q.iter_mut().zip(&m.joints) {
            let jc = self.joints.get(usize::from(j))?;
            let p = jc.state.position;
            if !jc.measured || !p.is_finite() {
                return None;
            }
            *qk = p;
        }
        // The torques stop at the chain's last link (`q` and `tau` are longer).
        let n = gravity::torques(&m.links, &q, gravity::G, tau);
        (n == m.links.len() && tau.iter().take(n).all(|t| t.is_finite())).then_some(n)
    }

    /// Note, for each joint of the trusted model (its loads `tau`) held still now and agreeing
    /// with it, the effort it gives.
    fn bear_out(&mut self, tau: &[f32]) {
        let Some(m) = self.dynamics.trusted.as_ref() else {
            return;
        };
        for (&j, &t) in m.joints.iter().zip(tau) {
            let j = usize::from(j);
            let (Some(jc), Some(cfg)) = (self.joints.get(j), self.profile.joints.get(j)) else {
                continue;
            };
            let e = jc.state.effort;
            if jc.holding_still(cfg) && agrees(e, t) {
                if let Some(b) = self.dynamics.borne.get_mut(j) {
                    *b = b.max(e.abs());
                }
            }
        }
    }

    /// Model `m` (its loads `tau`) against the joints held still in position mode: whether
    /// the arm bears it out (every loaded joint checked and agreeing, one of them bearing at
    /// least [`CONFIRM_LOAD`]), and the first joint that disagrees, if any. `refuting` checks
    /// every joint at rest, held back from its command or not: trust is earned only where
    /// nothing else pushes a joint, and lost wherever one rests against the model's claim (a
    /// model that overstates a load holds its joint off its command, beyond a limit even).
    fn disagreeing(
        &self,
        m: Option<&GravityModel>,
        tau: &[f32],
        refuting: bool,
    ) -> (bool, Option<u8>) {
        let Some(m) = m else {
            return (false, None);
        };
        let (mut all_agree, mut telling, mut disagreeing) = (true, false, None);
        for (&j, &t) in m.joints.iter().zip(tau) {
            let (Some(jc), Some(cfg)) = (
                self.joints.get(usize::from(j)),
                self.profile.joints.get(usize::from(j)),
            ) else {
                return (false, None);
            };
            let checked = if refuting {
                jc.at_rest()
            } else {
                jc.holding_still(cfg)
            };
            if !checked {
                all_agree &= t.abs() < LOADED;
                continue;
            }
            let agrees = agrees(jc.state.effort, t);
            all_agree &= agrees;
            telling |= t.abs() >= CONFIRM_LOAD;
            if !agrees && disagreeing.is_none() {
                disagreeing = Some(j);
            }
        }
        (all_agree && telling, disagreeing)
    }
}
