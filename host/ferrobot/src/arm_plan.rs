//! The arm's planning: its planning scene (PyRobot's MoveIt object API), collision-aware
//! joint, pose and Cartesian goals, and time-optimal trajectories streamed to the firmware.

use std::time::Duration;

use ferrobot_planning::timing::{self, Limits, TimingOptions, Trajectory};
use ferrobot_planning::{Checker, PlanOptions, Planner, RrtConnect};
use ferrobot_protocol::JointPoint;

use crate::arm::{Arm, Orientation};
use crate::error::{Error, Result};
use crate::goals::Claim;
use crate::hub::Hub;
use crate::joints_goal::JointsGoal;
use crate::motion::Motion;

/// Knots of a planned trajectory sent to the firmware at once (its queue holds 16 per joint).
const MAX_KNOTS: usize = 14;
/// Time the servos are given after the trajectory's end before arrival is judged, s.
const SETTLE_S: f64 = 0.25;
/// Shortest time between knots, s.
const MIN_KNOT_DT: f64 = 0.05;
/// A measured start held to the limits, a checker from it, and the pairs of the robot's own
/// links it is allowed to touch.
type StartChecker = (Vec<f64>, Checker, Vec<(String, String)>);

/// Largest difference of any joint between a trajectory's start and the arm's joints when it
/// is executed, rad: the motion from where the arm is to the plan's start was never checked.
/// Twice the arms' arrival tolerance (0.01 rad), for a start measured while the last motion
/// settled.
pub const STALE_START: f64 = 0.02;
/// Times a planned move is planned again when the arm moved while it was planned.
const REPLANS: usize = 2;
/// Joint speed under which a halted arm counts as at rest, rad/s (two of a Dynamixel's
/// velocity units).
const REST_SPEED: f64 = 0.05;
/// Longest a halted arm is given to come to rest before it is planned from again, s.
const REST_WAIT: f64 = 1.0;
/// Longest trajectory [`Arm::execute`] runs, s.
const MAX_DURATION: f64 = 3600.0;
/// Joint-space step of the blended path's collision check, rad.
const BLEND_CHECK_STEP: f64 = 0.01;

/// A planned arm motion: the collision-free path and its time-optimal trajectory.
#[derive(Debug, Clone)]
pub struct ArmTrajectory {
    /// Joint names, in the order of every configuration below.
    pub joints: Vec<String>,
    /// The path's waypoints, rad; consecutive ones joined by collision-free straight edges.
    pub path: Vec<Vec<f64>>,
    /// The trajectory along the path (blended at the waypoints within a checked deviation).
    pub trajectory: Trajectory,
    /// Time spent planning.
    pub planning_time: Duration,
    /// Room kept between the arm and the scene's objects along the path, m
    /// ([`PlanningOptions::padding`], less where an end is nearer).
    pub padding: f64,
}

impl ArmTrajectory {
    /// Duration of the motion, s.
    pub fn duration(&self) -> f64 {
        self.trajectory.duration()
    }
}

/// [`PlanningOptions::padding`] by default, m: the arm's executed motion follows its
/// trajectory to within a few millimetres (the tracking tests' bound is 1 cm at the end
/// effector); without room, a path that grazes an object touched it in the physics engine
/// when executed (`ferrobot arm-plan`, BENCHMARKS.md).
pub const DEFAULT_PADDING: f64 = 0.01;

/// Options of a planned motion.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanningOptions {
    /// Planner options (time limit, seed, range, shortcutting).
    pub plan: PlanOptions,
    /// Use Informed RRT* (path quality) instead of RRT-Connect.
    pub optimise: bool,
    /// Largest deviation of the blended trajectory from the path's corners, rad (blends are
    /// checked for collision and shrunk when they touch).
    pub max_deviation: f64,
    /// Room kept between the arm and the scene's objects along the motion, m, for the arm's
    /// tracking error when it runs (at most [`ferrobot_planning::MAX_PADDING`]). Where the
    /// start or the goal is closer to an object than twice this, half that end's gap is kept
    /// instead, so that both ends stay valid.
    pub padding: f64,
}

impl Default for PlanningOptions {
    fn default() -> Self {
        PlanningOptions {
            plan: PlanOptions::default(),
            optimise: false,
            max_deviation: 0.05,
            padding: DEFAULT_PADDING,
        }
    }
}

impl Arm {
    /// Plans a collision-free, time-optimal motion from the current joints to `q` (rad)
    /// without moving.
    pub fn make_plan_joint_positions(&self, q: &[f64]) -> Result<ArmTrajectory> {
        self.plan_to(q, &PlanningOptions::default())
    }

    /// Plans to a pose (`position` m, `orientation`, base frame) without moving: IK from
    /// several seeds, the collision-free solution nearest the current joints.
    pub fn make_plan_pose(
        &self,
        position: [f64; 3],
        orientation: Orientation,
    ) -> Result<ArmTrajectory> {
        let q = self.free_ik(position, orientation)?;
        self.plan_to(&q, &PlanningOptions::default())
    }

    /// A collision-free IK solution of the pose, nearest the current joints.
    pub(crate) fn free_ik(&self, position: [f64; 3], orientation: Orientation) -> Result<Vec<f64>> {
        let now = self.get_joint_angles()?;
        let checker = self.checker()?;
        let mut seeds = vec![now.clone(), self.cfg_arm().home.clone()];
        let limits = checker.model().limits().to_vec();
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for _ in 0..8 {
            seeds.push(
                limits
                    .iter()
                    .map(|&(lo, hi)| rng.random_range(lo..=hi))
                    .collect(),
            );
        }
        let mut best: Option<(f64, Vec<f64>)> = None;
        let mut first_err = None;
        let mut hit = None;
        for seed in &seeds {
            match self.compute_ik(position, orientation, Some(seed)) {
                Ok(q) => {
                    if let Some(c) = checker.contact(&q) {
                        hit.get_or_insert(c);
                        continue;
                    }
                    let d: f64 = q.iter().zip(&now).map(|(a, b)| (a - b).abs()).sum();
                    if best.as_ref().is_none_or(|(bd, _)| d < *bd) {
                        best = Some((d, q));
                    }
                }
                Err(e) => {
                    first_err.get_or_insert(e);
                }
            }
        }
        match (best, hit, first_err) {
            (Some((_, q)), _, _) => Ok(q),
            (None, Some(c), _) => Err(ferrobot_planning::Error::NoFreeIk {
                why: format!(
                    "every solution from {} seeds is in collision ({} touches {})",
                    seeds.len(),
                    c.a,
                    c.b
                ),
            }
            .into()),
            (None, None, Some(e)) => Err(e),
            (None, None, None) => Err(ferrobot_planning::Error::NoFreeIk {
                why: "no solution".into(),
            }
            .into()),
        }
    }

    /// Plans from the current joints to `goal`.
    pub fn plan_to(&self, goal: &[f64], opts: &PlanningOptions) -> Result<ArmTrajectory> {
        self.check_goal(goal)?;
        crate::validate::in_range(
            "planning padding (m)",
            opts.padding,
            0.0,
            ferrobot_planning::MAX_PADDING,
        )?;
        let start = self.get_joint_angles()?;
        let (start, mut checker, allowed) = self.start_checker(&start)?;
        // The pairs a start in self-contact was allowed may not touch at the goal.
        if !allowed.is_empty() {
            if let Some(c) = self.checker()?.contact(goal) {
                return Err(ferrobot_planning::Error::GoalInCollision { a: c.a, b: c.b }.into());
            }
        }
        let mut padding = 0.0;
        if opts.padding > 0.0 && checker.contact(&start).is_none() {
            let gap = checker
                .world_gap(&start, 2.0 * opts.padding)
                .min(checker.world_gap(goal, 2.0 * opts.padding));
            let pad = opts.padding.min(0.5 * gap);
            if pad > 0.0 {
                checker.set_padding(pad)?;
                // Gaps are lower bounds of more than one kind: should one put an end within the
                // padding after all, plan without it rather than refuse the end.
                if checker.contact(&start).is_none() && checker.contact(goal).is_none() {
                    padding = pad;
                } else {
                    checker.set_padding(0.0)?;
                }
            }
        }
        // The arm's own extension step unless the caller gave one.
        let mut plan_opts = opts.plan.clone();
        plan_opts.range = plan_opts.range.or(self.cfg_arm().planning_range);
        let plan = if opts.optimise {
            ferrobot_planning::InformedRrtStar.plan(&checker, &start, goal, &plan_opts)?
        } else {
            RrtConnect.plan(&checker, &start, goal, &plan_opts)?
        };
        let trajectory = self.time_path(&checker, &plan.path, opts.max_deviation)?;
        let planned = ArmTrajectory {
            joints: self.joint_names(),
            path: plan.path,
            trajectory,
            planning_time: plan.time,
            padding,
        };
        self.announce(&planned);
        Ok(planned)
    }

    /// The measured `start` held to the limits, a checker for planning from it, and the pairs
    /// of the robot's own links it allows. A start where two of them already touch (an arm
    /// that sagged while its servos were off) could never be left: those pairs go unchecked
    /// (at most 8), as MoveIt's start-state fixing would move out of them; the goal must be
    /// free of them ([`Arm::plan_to`]). Contacts with objects stay errors.
    fn start_checker(&self, start: &[f64]) -> Result<StartChecker> {
        let mut checker = self.checker()?;
        // Measured angles may sit a hair outside a limit.
        let start: Vec<f64> = start
            .iter()
            .zip(checker.model().limits())
            .map(|(v, (lo, hi))| v.clamp(*lo, *hi))
            .collect();
        let mut allowed: Vec<(String, String)> = Vec::new();
        let model = self.model()?;
        while let Some(c) = checker.contact(&start) {
            let own = model.link_index(&c.a).is_some() && model.link_index(&c.b).is_some();
            if !own || allowed.len() >= 8 || allowed.contains(&(c.a.clone(), c.b.clone())) {
                break;
            }
            allowed.push((c.a, c.b));
            checker = self.checker_allowing(&allowed)?;
        }
        Ok((start, checker, allowed))
    }

    /// Whether `traj` may run now: its joints the arm's, its path and trajectory well formed
    /// and ending alike, its start within [`STALE_START`] of the arm's joints, and its motion
    /// free in the scene as it is now (checked as planning checked it).
    fn check_trajectory(&self, traj: &ArmTrajectory) -> Result<()> {
        let invalid = |why: String| -> Error {
            ferrobot_planning::Error::Invalid {
                what: "trajectory".into(),
                why,
            }
            .into()
        };
        let names = self.joint_names();
        if traj.joints != names {
            return Err(invalid(format!(
                "its joints {:?} are not the arm's {names:?}",
                traj.joints
            )));
        }
        let (Some(first), Some(last)) = (traj.path.first(), traj.path.last()) else {
            return Err(invalid("its path is empty".into()));
        };
        for q in &traj.path {
            self.check_goal(q)?;
        }
        let t = &traj.trajectory;
        let total = t.duration();
        if t.dof() != names.len() || !(0.0..=MAX_DURATION).contains(&total) {
            return Err(invalid(format!(
                "{} joints over {total} s (the arm has {}; at most {MAX_DURATION} s)",
                t.dof(),
                names.len()
            )));
        }
        let off = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(
                    0.0f64,
                    |m, d| if d.is_nan() { f64::INFINITY } else { m.max(d) },
                )
        };
        if off(&t.sample(0.0).position, first) > 1e-6 || off(&t.sample(total).position, last) > 1e-6
        {
            return Err(invalid(
                "its trajectory does not start and end where its path does".into(),
            ));
        }
        let here = self.get_joint_angles()?;
        let gap = off(&here, first);
        if gap > STALE_START {
            return Err(Error::StalePlan {
                why: format!(
                    "it starts {gap:.3} rad from the arm's joints (at most {STALE_START} rad)"
                ),
            });
        }
        let (_, checker, _) = self.start_checker(&here)?;
        if !blends_free(&checker, t) {
            return Err(Error::StalePlan {
                why: "its motion touches something in the scene as it is now".into(),
            });
        }
        Ok(())
    }

    /// The joints' speed and acceleration limits.
    fn limits(&self) -> Limits {
        let cfg = self.robot.cfg();
        Limits {
            velocity: self
                .parts_joints()
                .iter()
                .map(|&j| f64::from(cfg.joints[j].limits.velocity) * 0.9)
                .collect(),
            acceleration: self.cfg_arm().acceleration.clone(),
        }
    }

    /// The time-optimal trajectory along `path`, its blends checked for collision (shrunk,
    /// and at last dropped, when they touch).
    fn time_path(
        &self,
        checker: &Checker,
        path: &[Vec<f64>],
        deviation: f64,
    ) -> Result<Trajectory> {
        let limits = self.limits();
        let mut dev = deviation;
        loop {
            let t = timing::time_optimal(
                path,
                &limits,
                &TimingOptions {
                    max_deviation: dev,
                    ..TimingOptions::default()
                },
            )?;
            if dev == 0.0 || blends_free(checker, &t) {
                return Ok(t);
            }
            dev = if dev > 0.002 { dev / 4.0 } else { 0.0 };
        }
    }

    /// Plans from the current joints to `goal` and starts the motion. Time passes while a plan
    /// is made (on a real robot always; on the simulator while another thread waits): should
    /// the arm have moved more than [`STALE_START`] from the plan's start meanwhile (an older
    /// motion drove it, or it was settling), or the scene changed, its older motions are
    /// halted (they end [`Error::Preempted`], as the new motion would end them), the arm is
    /// given up to [`REST_WAIT`] to come to rest, and the plan is made again from there, at
    /// most [`REPLANS`] times.
    pub(crate) fn plan_and_execute(
        &self,
        goal: &[f64],
        tolerance: f64,
        timeout: Option<Duration>,
    ) -> Result<Motion> {
        let opts = PlanningOptions::default();
        let mut replans = 0;
        loop {
            let traj = self.plan_to(goal, &opts)?;
            match self.execute_with(&traj, tolerance, timeout) {
                Err(Error::StalePlan { .. }) if replans < REPLANS => {
                    replans += 1;
                    self.come_to_rest()?;
                }
                done => return done,
            }
        }
    }

    /// Halt the arm's motions under way and wait (the backend's time) until every joint is
    /// slower than [`REST_SPEED`], or [`REST_WAIT`] has passed.
    fn come_to_rest(&self) -> Result<()> {
        let claim = Claim {
            joints: self.parts().mask(),
            ..Claim::default()
        };
        let cfg = self.robot.cfg();
        let end = {
            let mut io = self.robot.lock_hub();
            io.prepare(cfg, claim);
            io.link
                .now()
                .saturating_add(Duration::from_secs_f64(REST_WAIT))
        };
        loop {
            let still = self
                .get_joint_velocities()?
                .iter()
                .all(|v| v.abs() < REST_SPEED);
            let now = self.robot.lock_hub().link.now();
            if still || now >= end {
                return Ok(());
            }
            self.robot.wait_for(crate::goals::POLL);
            // A clock that does not move (a link that lost its firmware): the next plan's
            // execution reports the link's state.
            if self.robot.lock_hub().link.now() <= now {
                return Ok(());
            }
        }
    }

    /// Starts executing a planned trajectory: knots (position and velocity, at most 14, at
    /// least 0.05 s apart) sent at once, which the firmware joins by cubic Hermite curves.
    /// Checked first: a malformed trajectory is an error, and one that starts more than
    /// [`STALE_START`] from the arm's joints or touches something in the scene as it is now
    /// (objects added, the gripper moved since planning) is [`Error::StalePlan`].
    pub fn execute(&self, traj: &ArmTrajectory) -> Result<Motion> {
        self.execute_with(traj, self.cfg_arm().joint_tolerance, None)
    }

    /// [`Arm::execute`] with an arrival tolerance (rad) and a timeout (the configuration's
    /// or the motion's duration and 5 s, whichever is longer, when `None`).
    pub(crate) fn execute_with(
        &self,
        traj: &ArmTrajectory,
        tolerance: f64,
        timeout: Option<Duration>,
    ) -> Result<Motion> {
        self.check_trajectory(traj)?;
        let total = traj.trajectory.duration();
        let n = ((total / MIN_KNOT_DT).ceil() as usize).clamp(1, MAX_KNOTS);
        let dt = total / n as f64;
        let idx = self.parts_joints().to_vec();
        let mask = self.parts().mask();
        let target = traj.path.last().cloned().unwrap_or_default();
        let timeout = timeout
            .unwrap_or_else(|| Duration::from_secs_f64(self.cfg_arm().timeout.max(total + 5.0)));
        let claim = Claim {
            joints: mask,
            ..Claim::default()
        };
        self.robot
            .start_motion(claim, "planned arm motion", |io: &mut Hub| {
                self.ensure_position_mode(io)?;
                // The knots as sent, from the start: what the joints follow.
                let mut reference = vec![(0.0, traj.trajectory.sample(0.0).position)];
                for k in 1..=n {
                    let p = traj.trajectory.sample(dt * k as f64);
                    reference.push((dt * k as f64, p.position.clone()));
                    let points = p
                        .position
                        .iter()
                        .zip(&p.velocity)
                        .map(|(&x, &v)| JointPoint {
                            position: x as f32,
                            velocity: if k == n { 0.0 } else { v as f32 },
                            effort: 0.0,
                        })
                        .collect();
                    io.link.command(
                        &ferrobot_protocol::HostMsg::Waypoint {
                            joints: mask,
                            duration_us: (dt * 1e6) as u32,
                            points,
                        },
                        "planned trajectory knot",
                    )?;
                }
                let started = io.link.now();
                // The servos lag the reference: give them time to settle at the end.
                let goal = JointsGoal::new(
                    idx,
                    target,
                    tolerance,
                    started,
                    started + Duration::from_secs_f64(total + SETTLE_S),
                )
                .following(reference);
                Ok((Box::new(goal) as Box<dyn crate::goals::Goal>, timeout))
            })
    }

    /// Joint positions along a straight line of the end effector, checked: each step free of
    /// collision (proven at the checker's resolution) and without joint jumps.
    pub(crate) fn check_cartesian(
        &self,
        start: &[f64],
        path: &[Vec<f64>],
        step: f64,
    ) -> Result<()> {
        let checker = self.checker()?;
        let mut prev = start.to_vec();
        // A joint moving more than this for one step is a jump (a branch switch of the IK):
        // far more than any joint needs for a step of `step` m at the arm's reach.
        let jump = (step * 40.0).max(0.2);
        for (i, q) in path.iter().enumerate() {
            if let Some((j, d)) = q
                .iter()
                .zip(&prev)
                .map(|(a, b)| (a - b).abs())
                .enumerate()
                .find(|(_, d)| *d > jump)
            {
                return Err(ferrobot_planning::Error::Cartesian {
                    why: format!(
                        "joint {} jumps {d:.3} rad at step {} of {} (more than {jump:.3} rad)",
                        self.joint_names()[j],
                        i + 1,
                        path.len()
                    ),
                }
                .into());
            }
            if let Some(c) = checker.contact(q) {
                return Err(ferrobot_planning::Error::Cartesian {
                    why: format!("step {} of {}: {} touches {}", i + 1, path.len(), c.a, c.b),
                }
                .into());
            }
            if !checker.motion_proven(&prev, q) {
                return Err(ferrobot_planning::Error::Cartesian {
                    why: format!(
                        "the motion to step {} of {} touches something",
                        i + 1,
                        path.len()
                    ),
                }
                .into());
            }
            prev = q.clone();
        }
        Ok(())
    }
}

/// Whether the blended path of `t` is free: the chord of each of [`blend_spans`] proven free.
fn blends_free(checker: &Checker, t: &Trajectory) -> bool {
    blend_spans(t)
        .iter()
        .all(|&(s0, s1)| checker.motion_proven(&t.path_position(s0), &t.path_position(s1)))
}

/// Largest joint-space distance (rad) of the blended path from the chords that stand for it in
/// [`blends_free`]: 10 µrad, a few micrometres of link motion.
const CHORD_SAG: f64 = 1e-5;

/// Spans of arc length (rad) along the blended path of `t`, from its start to its end, whose
/// chords stand for it: at most [`BLEND_CHECK_STEP`] rad each, halved while the path at a
/// span's quarters or middle is more than [`CHORD_SAG`] from its chord. On a blend's arc a
/// chord of fixed length could cut across the whole arc (a small blend), leaving the path
/// between unchecked; a circular arc's sag falls fourfold with each halving. At most 16
/// halvings.
fn blend_spans(t: &Trajectory) -> Vec<(f64, f64)> {
    let len = t.path_length();
    let n = ((len / BLEND_CHECK_STEP).ceil() as usize).max(1);
    let mut out = Vec::with_capacity(n);
    let mut stack: Vec<(f64, f64, u32)> = Vec::new();
    for k in (0..n).rev() {
        stack.push((
            len * k as f64 / n as f64,
            len * (k + 1) as f64 / n as f64,
            0,
        ));
    }
    while let Some((s0, s1, depth)) = stack.pop() {
        if depth < 16 && chord_sag(t, s0, s1, &[0.25, 0.5, 0.75]) > CHORD_SAG {
            let mid = 0.5 * (s0 + s1);
            stack.push((mid, s1, depth + 1));
            stack.push((s0, mid, depth + 1));
        } else {
            out.push((s0, s1));
        }
    }
    out
}

/// The largest distance (rad) of the path of `t` at fractions `at` of the span `[s0, s1]` (arc
/// length, rad) from the chord's point at the same fraction.
fn chord_sag(t: &Trajectory, s0: f64, s1: f64, at: &[f64]) -> f64 {
    let (a, b) = (t.path_position(s0), t.path_position(s1));
    at.iter()
        .map(|&f| {
            let m = t.path_position(s0 + f * (s1 - s0));
            a.iter()
                .zip(&b)
                .zip(&m)
                .map(|((x, y), z)| (x + f * (y - x) - z).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0f64, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a path with small blends, the spans' chords stand for the path within [`CHORD_SAG`]
    /// (each checked at 199 inner points, against the chord's point at the same fraction, a
    /// bound on the distance from the chord), where chords of [`BLEND_CHECK_STEP`] alone cut
    /// across the arcs by more than a hundred times that; the spans tile the path.
    #[test]
    fn chords_follow_small_blends() {
        let path = vec![
            vec![0.0, 0.0, 0.0],
            vec![0.5, 0.0, 0.0],
            vec![0.5, 0.5, 0.0],
            vec![0.5, 0.5, 0.5],
            vec![0.0, 0.5, 0.5],
        ];
        let t = timing::time_optimal(
            &path,
            &Limits::uniform(3, 1.0, 2.0),
            &TimingOptions {
                max_deviation: 0.003,
                ..TimingOptions::default()
            },
        )
        .expect("timed");
        let fine: Vec<f64> = (1..200).map(|i| f64::from(i) / 200.0).collect();
        let spans = blend_spans(&t);
        assert_eq!(spans[0].0, 0.0);
        assert_eq!(spans.last().expect("spans").1, t.path_length());
        for w in spans.windows(2) {
            assert_eq!(w[0].1, w[1].0, "spans tile the path");
        }
        let sag = spans
            .iter()
            .map(|&(a, b)| chord_sag(&t, a, b, &fine))
            .fold(0.0f64, f64::max);
        assert!(sag <= 1.5 * CHORD_SAG, "{sag} rad from the chords");
        let l = t.path_length();
        let n = (l / BLEND_CHECK_STEP).ceil() as usize;
        let coarse = (0..n)
            .map(|k| {
                chord_sag(
                    &t,
                    l * k as f64 / n as f64,
                    l * (k + 1) as f64 / n as f64,
                    &fine,
                )
            })
            .fold(0.0f64, f64::max);
        assert!(coarse > 100.0 * CHORD_SAG, "{coarse} rad");
        eprintln!(
            "{} spans, sag {sag:.2e} rad; fixed chords {n}, sag {coarse:.2e} rad",
            spans.len()
        );
    }
}
