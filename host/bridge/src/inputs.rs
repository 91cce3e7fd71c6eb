//! A served robot's ROS 2 inputs ([`Inputs`]): `/cmd_vel` drives the base, `/goal_pose`
//! (rviz2's "2D Goal Pose" tool) takes it to a pose, `/arm/joint_trajectory` moves the arm
//! through a trajectory's points. Each message
//! refused (malformed, not finite, beyond the robot's limits, naming joints the arm does not
//! have) is counted with its reason ([`crate::ServeStats`]), and the robot carries on.
//!
//! A documented subset of what ROS 2's controllers do: a trajectory's points are reached in
//! order, each by a planned, collision-free motion timed within the joints' limits; the
//! message's times are not kept. A new trajectory preempts the one under way, as
//! `joint_trajectory_controller` does.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, TryRecvError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use ferrobot::base::GoalOptions;
use ferrobot::slam::Source;
use ferrobot::{MoveOptions, Robot};
use ferrobot_ros2::{decode, topics};
use parking_lot::Mutex;

use crate::error::BridgeError;
use crate::node::{RosNode, RosSubscription};
use crate::serve::ServeStats;

/// The subscriptions to a served robot's inputs; dropped, they end.
pub struct Inputs {
    _cmd_vel: Option<RosSubscription>,
    _goal_pose: Option<RosSubscription>,
    _arm: Option<ArmTrajectories>,
}

impl Inputs {
    /// Subscribes to the inputs `robot` has parts for (the base's with a base, the arm's with
    /// an arm); each `/cmd_vel` message drives the base for `hold` s.
    pub fn subscribe(
        robot: &Robot,
        node: &RosNode,
        hold: f64,
        stats: &Arc<Mutex<ServeStats>>,
    ) -> Result<Inputs, BridgeError> {
        let base = robot.config().base.is_some();
        Ok(Inputs {
            _cmd_vel: base
                .then(|| cmd_vel(robot, node, hold, stats.clone()))
                .transpose()?,
            _goal_pose: base
                .then(|| goal_pose(robot, node, stats.clone()))
                .transpose()?,
            _arm: robot
                .config()
                .arm
                .is_some()
                .then(|| ArmTrajectories::start(robot, node, stats.clone()))
                .transpose()?,
        })
    }
}

/// `/cmd_vel`: each message drives the base at its forward speed (m/s) and yaw rate (rad/s)
/// for `hold` s, or until the next one.
fn cmd_vel(
    robot: &Robot,
    node: &RosNode,
    hold: f64,
    stats: Arc<Mutex<ServeStats>>,
) -> Result<RosSubscription, BridgeError> {
    let base = robot.base()?;
    node.subscription(&topics::CMD_VEL, move |payload, _| {
        let outcome = ferrobot_ros2::decode::twist(payload)
            .map_err(|e| e.to_string())
            .and_then(|[v, w]| base.set_vel_async(v, w, hold).map_err(|e| e.to_string()));
        let mut s = stats.lock();
        match outcome {
            Ok(_motion) => s.cmd_vel_accepted += 1,
            Err(why) => {
                s.cmd_vel_refused += 1;
                s.last_refusal = Some(why);
            }
        }
    })
}

/// Counts an accepted goal, or a refused one with its reason.
fn tally(stats: &Mutex<ServeStats>, outcome: Result<(), String>) {
    let mut s = stats.lock();
    match outcome {
        Ok(()) => s.goals_accepted += 1,
        Err(why) => {
            s.goals_refused += 1;
            s.last_refusal = Some(why);
        }
    }
}

/// `/goal_pose`: the base to the pose's x, y and yaw, in `odom` (or an empty frame), or in
/// `map` while SLAM runs.
pub fn goal_pose(
    robot: &Robot,
    node: &RosNode,
    stats: Arc<Mutex<ServeStats>>,
) -> Result<RosSubscription, BridgeError> {
    let base = robot.base()?;
    node.subscription(&topics::GOAL_POSE, move |payload, _| {
        let outcome = decode::pose_stamped(payload)
            .map_err(|e| e.to_string())
            .and_then(|(_, frame, pose)| {
                let frame = match frame.as_str() {
                    "" | topics::ODOM_FRAME => Source::Odometry,
                    topics::MAP_FRAME => Source::Slam,
                    other => return Err(format!("a goal in {other:?}: odom or map")),
                };
                let yaw = pose.rotation.euler_angles().2;
                let goal = [pose.translation.x, pose.translation.y, yaw];
                let opts = GoalOptions {
                    frame,
                    ..GoalOptions::default()
                };
                base.go_to_absolute_with(goal, opts)
                    .map(|_motion| ())
                    .map_err(|e| e.to_string())
            });
        tally(&stats, outcome);
    })
}

/// The arm's trajectories: the subscription, and the thread that moves the arm through them.
pub struct ArmTrajectories {
    _subscription: RosSubscription,
    stop: Arc<AtomicBool>,
    worker: Option<JoinHandle<()>>,
}

impl ArmTrajectories {
    /// Subscribes to `/arm/joint_trajectory` for `robot`'s arm.
    pub fn start(
        robot: &Robot,
        node: &RosNode,
        stats: Arc<Mutex<ServeStats>>,
    ) -> Result<ArmTrajectories, BridgeError> {
        let arm = robot.arm()?;
        let joints = arm.joint_names();
        let (tx, receiver) = sync_channel::<Vec<Vec<f64>>>(4);
        let stop = Arc::new(AtomicBool::new(false));
        let (theirs, their_stop) = (stats.clone(), stop.clone());
        let worker = std::thread::Builder::new()
            .name("ferrobot-arm-trajectories".into())
            .spawn(move || follow(&arm, &receiver, &theirs, &their_stop))
            .map_err(|e| BridgeError::Usage(format!("starting the arm's goals: {e}")))?;
        let subscription =
            node.subscription(&topics::ARM_JOINT_TRAJECTORY, move |payload, _| {
                let outcome = decode::joint_trajectory(payload)
                    .map_err(|e| e.to_string())
                    .and_then(|(names, points)| ordered(&joints, &names, &points))
                    .and_then(|points| {
                        tx.try_send(points)
                            .map_err(|_| "the arm's goals are queued four deep".to_string())
                    });
                tally(&stats, outcome);
            })?;
        Ok(ArmTrajectories {
            _subscription: subscription,
            stop,
            worker: Some(worker),
        })
    }
}

impl Drop for ArmTrajectories {
    /// Stops following: the arm's motion under way, if any, goes on as its commands do.
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}

/// Each point's positions in the arm's joint order: every arm joint named once, and nothing
/// else; at least one point, each finite (the limits are the arm's to check).
fn ordered(
    joints: &[String],
    names: &[String],
    points: &[(Vec<f64>, Duration)],
) -> Result<Vec<Vec<f64>>, String> {
    let index: Vec<usize> = joints
        .iter()
        .map(|j| {
            let mut at = names.iter().enumerate().filter(|(_, n)| *n == j);
            match (at.next(), at.next()) {
                (Some((k, _)), None) => Ok(k),
                _ => Err(format!(
                    "joint {j} named {} times",
                    names.iter().filter(|n| *n == j).count()
                )),
            }
        })
        .collect::<Result<_, _>>()?;
    if names.len() != joints.len() {
        return Err(format!(
            "{} joints named; the arm's are {joints:?}",
            names.len()
        ));
    }
    if points.is_empty() {
        return Err("a trajectory without points".into());
    }
    points
        .iter()
        .map(|(p, _)| {
            if p.len() != names.len() {
                return Err(format!(
                    "a point of {} positions for {} joints",
                    p.len(),
                    names.len()
                ));
            }
            let q: Vec<f64> = index.iter().map(|&k| p[k]).collect();
            match q.iter().all(|x| x.is_finite()) {
                true => Ok(q),
                false => Err(format!("a point that is not finite: {q:?}")),
            }
        })
        .collect()
}

/// How often the follower looks for a newer trajectory and for its end, wall time.
const LOOK: Duration = Duration::from_millis(20);

/// Moves the arm through each trajectory received, until `stop`; a newer one preempts the one
/// under way.
fn follow(
    arm: &ferrobot::arm::Arm,
    goals: &Receiver<Vec<Vec<f64>>>,
    stats: &Mutex<ServeStats>,
    stop: &AtomicBool,
) {
    let mut next = None;
    while !stop.load(Ordering::SeqCst) {
        let points = match next.take() {
            Some(p) => p,
            None => match goals.recv_timeout(LOOK * 5) {
                Ok(p) => p,
                Err(RecvTimeoutError::Timeout) => continue,
                Err(RecvTimeoutError::Disconnected) => return,
            },
        };
        'points: for q in points {
            let mut motion = match arm.move_joints(&q, MoveOptions::default()) {
                Ok(m) => m,
                Err(e) => {
                    tally(stats, Err(format!("the arm refused a point: {e}")));
                    break;
                }
            };
            // The robot's time passes elsewhere (its clock, or its clients in lockstep).
            while motion.poll().is_none() {
                if stop.load(Ordering::SeqCst) {
                    return;
                }
                match goals.try_recv() {
                    Ok(newer) => {
                        next = Some(newer);
                        break 'points;
                    }
                    Err(TryRecvError::Disconnected) => return,
                    Err(TryRecvError::Empty) => std::thread::sleep(LOOK),
                }
            }
            if let Some(Err(e)) = motion.poll() {
                tally(stats, Err(format!("the arm's motion ended: {e}")));
                break;
            }
        }
    }
}
