//! `ferrobot`: robots, kinematics from the command line, and the simulated demo.
//!
//! ```text
//! ferrobot robots
//! ferrobot info locobot
//! ferrobot fk locobot 0.1 -0.2 0.3 0 0 --json
//! ferrobot jacobian sawyer 0 -1.18 0 2.18 0 0.57 3.32
//! ferrobot ik locobot --position 0.35 0 0.15 --pitch 1.5708 --roll 0
//! ferrobot ik sawyer --position 0.6 0.1 0.4 --quaternion 0 1 0 0 --seed 0 -1 0 2 0 0.5 3
//! ferrobot demo
//! ferrobot serve locobot --scene tabletop --namespace /locobot
//! ferrobot scene tabletop --json
//! ferrobot snapshot locobot --scene tabletop --tilt 0.8 --out target/snapshot
//! ferrobot base-move locobot --relative 1 1 1.5708 --controller lqr --smooth --json
//! ferrobot bench base --robot locobot --trials 5 --seed 1
//! ferrobot bench camera --scene apartment --seconds 10
//! ferrobot bench plan --robot locobot --scene tabletop --problems 100 --seed 1 --ompl
//! ferrobot bench arm locobot --cycles 30 --out target/bench-arm --json
//! ferrobot bench push locobot --scene tabletop --trials 100 --seed 1 --json
//! ferrobot collision-matrix sawyer --samples 10000 --seed 1
//! ferrobot nav-plan --map map.yaml --from 1 1 --to 3 2 --radius 0.2 --json
//! ferrobot cluster --in cloud.ply --eps 0.02 --min-samples 15 --json
//! ferrobot teleop locobot --scene tabletop
//! ferrobot bench grasp locobot --scene tabletop --trials 100 --seed 1 --json
//! ferrobot bench push locobot --scene tabletop --trials 100 --seed 1 --json
//! ferrobot bench arm locobot --out target/bench-arm --json
//! ferrobot calibrate-camera locobot --perturb 0.02 0 0 0 0.0524 0 --seed 1 --json
//! ```

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use serde::Serialize;

use cmd::common::print_json;

/// `println!` for the subcommands, through [`cmd::common::say`]: a closed pipe ends the program
/// quietly instead of a panic.
macro_rules! say {
    ($($t:tt)*) => {
        $crate::cmd::common::say(format_args!($($t)*))
    };
}

mod cmd;

#[derive(Parser)]
#[command(
    name = "ferrobot",
    version,
    about = "Ferrobot: robots, kinematics and the simulated demo"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the bundled robots.
    Robots(cmd::robots::Args),
    /// Describe a robot: joints, limits, components.
    Info(cmd::info::Args),
    /// Pose of the end-effector frame (or --frame) in the robot's root link at joint angles Q.
    Fk(cmd::fk::Args),
    /// Geometric Jacobian (rows vx vy vz wx wy wz, root frame, at the end effector's origin).
    Jacobian(cmd::jacobian::Args),
    /// Inverse kinematics of the end effector.
    Ik(cmd::ik::Args),
    /// Serve a simulated robot's firmware core (with its plants, in real time, in a scene) on a
    /// PTY behind the symlink LINK, and its camera on the Unix socket LINK.camera, for the
    /// Serial backend and outside tools. Prints one JSON line, then reads control lines on
    /// standard input until it closes: `unplug` and `plug` drop and restore the link (`unplug
    /// MS` restores it after MS of the firmware's time), `mute` and `unmute` drop and restore
    /// its telemetry (a stopped control loop), `freeze` and `thaw` stop and restart the
    /// world's clock (the firmware still answers), `stall MS` stops the server for MS.
    SimFirmware(cmd::sim_firmware::Args),
    /// Serve a robot on zenoh: its topics as a ROS 2 node publishes them (rmw_zenoh's layout:
    /// joint states, transforms, odometry, camera, URDF), `/cmd_vel` to drive its base, and the
    /// remote backend for programs on other machines. Listens on loopback unless told
    /// otherwise; beyond it, --credentials is required. Prints one JSON line, then serves
    /// until standard input closes or a signal ends it.
    Serve(cmd::serve::Args),
    /// Serve the host-run firmware of a stock robot (the firmware core on this computer, the
    /// servo bus and the base on the robot's own USB cables: a U2D2, the base's cable) on a
    /// PTY behind the symlink LINK, for the serial backend, after the hardware check has
    /// passed. Prints one JSON line (the link and the check's report) and serves until
    /// standard input closes.
    Drive(cmd::drive::Args),
    /// The robot's own hardware.
    Hardware {
        #[command(subcommand)]
        which: HardwareCommand,
    },
    /// One base motion on the simulated robot, from rest at the origin.
    BaseMove(cmd::base_move::Args),
    /// Calibrate the simulated base's odometry (UMBmark squares both ways and a 2 m line,
    /// measured by ground truth, fitted by least squares); prints the `[base] odometry` line.
    CalibrateOdometry(cmd::calibrate_odometry::Args),
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        which: BenchCommand,
    },
    /// The self-collision matrix of a robot's arm by sampling (link pairs adjacent, touching
    /// at the default pose, in nearly every or in no random configuration), printed as the
    /// `[collision]` section of its configuration.
    CollisionMatrix(cmd::collision_matrix::Args),
    /// The global planner alone on a map in ROS map_server's format (YAML + PNG): a
    /// collision-free path for a round robot, or a typed error.
    NavPlan(cmd::nav_plan::Args),
    /// DBSCAN on a point cloud (a PLY file, metres), with scikit-learn's semantics and labels
    /// (a point is core with at least MIN_SAMPLES neighbours within EPS, itself included;
    /// noise is -1); a summary, or with --json one label per point in the file's order.
    Cluster(cmd::cluster::Args),
    /// Visual SLAM on a scripted drive or a recorded sequence. A drive: the simulated robot
    /// follows a route of the scene while SLAM runs on its camera and odometry; writes
    /// estimate.tum, ground_truth.tum, odometry.tum, map.yaml + map.png, cloud.ply and
    /// trajectory.png to --out. A sequence (--dataset DIR, the TUM RGB-D layout): writes
    /// estimate.tum (camera poses) and cloud.ply to --out, if given.
    Slam(cmd::slam::Args),
    /// Record a simulated drive along a scene's route as an RGB-D sequence in the TUM RGB-D
    /// layout (rgb/, depth/ at 5000 units per metre, rgb.txt, depth.txt, groundtruth.txt of
    /// the camera, camera.yaml).
    RecordRgbd(cmd::record_rgbd::Args),
    /// What a scene holds (bundled name or scene file): its bodies in the world frame (z up,
    /// metres) and the robot's start pose.
    Scene(cmd::scene::Args),
    /// One RGB-D frame of the simulated robot in a scene: writes rgb.png, depth.png (16-bit
    /// mm, 0 invalid), cloud.ply (world frame) and snapshot.png (colour | depth) to --out.
    Snapshot(cmd::snapshot::Args),
    /// Plan an arm motion around a scene's objects on the simulator and execute it: prints
    /// the plan (time, waypoints, length, duration) and the executed motion's contacts in the
    /// physics engine; --png draws the motion seen from beside the robot.
    ArmPlan(cmd::arm_plan::Args),
    /// Drive a robot from the keyboard in a terminal, with PyRobot's key map and steps: the
    /// end effector, the wrist, the gripper, the camera's pan and tilt, and the base while an
    /// arrow is held; the robot's state shown live. q, Esc or Ctrl-C quits with the base
    /// stopped and the arm holding.
    Teleop(cmd::teleop::Args),
    /// Hand-eye calibration of the head camera against the marker on the gripper (PyRobot's
    /// locobot_calibration), the simulated camera mounted off nominal by --perturb: prints
    /// the fitted mount's error against the true one; --out writes the calibration file.
    CalibrateCamera(cmd::calibrate_camera::Args),
    /// Run the quickstart on the simulated LoCoBot.
    Demo(cmd::demo::Args),
    /// Record a robot for --seconds of its time into an MCAP file with ROS 2 schemas (joint
    /// states, odometry, transforms, the gripper, commands, faults, the camera, SLAM's pose,
    /// the URDF), readable by Foxglove, rosbag2 and rosbags; the robot is moved by whatever
    /// moves it meanwhile (a hand in teach mode, another program through `ferrobot drive`).
    Record(cmd::record::Args),
    /// Feed a recording back: its commands to a robot at their recorded instants (the
    /// simulator by default; a real robot after a confirmation), or its frames and odometry to
    /// SLAM offline at any speed.
    Replay(cmd::replay::Args),
    /// Export recordings as one LeRobot dataset (format v3.0): each recording an episode with
    /// its task, observation.state, action and the camera's frames at --fps.
    ExportLerobot(cmd::export_lerobot::Args),
}

#[derive(Subcommand)]
enum HardwareCommand {
    /// Before anything moves: find the devices of the robot's `[direct]` section (by path,
    /// udev link or USB IDs), ping every servo the description names and read its model,
    /// firmware, baud, mode, voltage and temperature, hear the base and its battery, and
    /// print a table of what is wrong and how to fix it. Fails when a row is a fault.
    Check(cmd::hardware::Args),
}

#[derive(Subcommand)]
enum BenchCommand {
    /// PyRobot's base accuracy trials (Table 1) for every controller, against ground truth
    /// and odometry, plus the circle-tracking plot per base.
    Base(cmd::bench_base::Args),
    /// The simulator's real-time factor for the LoCoBot with its camera streaming at 30 Hz
    /// while the base drives a circle, per scene, beside the same run without frames.
    Camera(cmd::bench_camera::Args),
    /// Arm planning on a fixed, seeded set of problems in a scene (or a problems file):
    /// success rate, time, path length, collision checks per second; with --ompl, OMPL's
    /// RRTConnect on the same problems in the same run.
    Plan(cmd::bench_plan::Args),
    /// The arm in the manner of ISO 9283: pose accuracy and repeatability over five poses in
    /// a cube (by ground truth), and the joint tracking of a streamed trajectory, with plots.
    Arm(cmd::bench_arm::Args),
    /// PyRobot's pushing example, measured by ground truth: objects placed at random on the
    /// table per trial (seed SEED + k), one object pushed; how far it moved along the push
    /// and whether any other object moved more than 1 cm.
    Push(cmd::bench_push::Args),
    /// PyRobot's grasping example as a benchmark: each trial places the scene's graspable
    /// objects at random on the table (seed SEED + trial), looks, grasps, lifts; success is an
    /// object lifted at least 5 cm and held 2 s, from the simulator's ground truth.
    Grasp(cmd::bench_grasp::Args),
    /// The host-run firmware's servo loop on the wall clock against the plants served in real
    /// time, the arm moving: tick interval and jitter, the firmware's overruns and servo
    /// timeouts, and the wire's budget per tick on a U2D2.
    HostLoop(cmd::bench_host_loop::Args),
    /// What recording costs: the simulated LoCoBot with its camera, with and without the
    /// recorder (real-time factor, the recorder's CPU time, MB/s, drops, loop overruns).
    Record(cmd::bench_record::Args),
    /// What driving a robot over zenoh costs: command round trips and joint states' age and
    /// rate, in-process against the remote backend with one and two served robots.
    Remote(cmd::bench_remote::Args),
    /// Navigation on the scene's ground-truth floor plan: the simulated robot drives to N
    /// random reachable goals; success rate, bumper hits, path length against the shortest
    /// path, time per goal.
    Nav(cmd::bench_nav::Args),
}

/// Run the subcommand; its error comes with whether to print it as JSON.
fn run(cli: Cli) -> Result<(), (ferrobot::Error, bool)> {
    let (result, json) = match cli.cmd {
        Command::Robots(a) => (cmd::robots::run(&a), a.json),
        Command::Info(a) => (cmd::info::run(&a), a.json),
        Command::Fk(a) => (cmd::fk::run(&a), a.json),
        Command::Jacobian(a) => (cmd::jacobian::run(&a), a.json),
        Command::Ik(a) => (cmd::ik::run(&a), a.json),
        // Its one line on standard output is JSON, and so are its errors.
        Command::SimFirmware(a) => (cmd::sim_firmware::run(&a), true),
        Command::Serve(a) => (cmd::serve::run(&a), true),
        Command::Drive(a) => (cmd::drive::run(&a), true),
        Command::Hardware {
            which: HardwareCommand::Check(a),
        } => (cmd::hardware::run(&a), a.json),
        Command::BaseMove(a) => (cmd::base_move::run(&a), a.json),
        Command::CalibrateOdometry(a) => (cmd::calibrate_odometry::run(&a), a.json),
        Command::Bench { which } => run_bench(which),
        Command::CollisionMatrix(a) => (cmd::collision_matrix::run(&a), false),
        Command::NavPlan(a) => (cmd::nav_plan::run(&a), a.json),
        Command::Cluster(a) => (cmd::cluster::run(&a), a.json),
        Command::Slam(a) => (cmd::slam::run(&a), a.json),
        Command::RecordRgbd(a) => (cmd::record_rgbd::run(&a), false),
        Command::Scene(a) => (cmd::scene::run(&a), a.json),
        Command::Snapshot(a) => (cmd::snapshot::run(&a), a.json),
        Command::ArmPlan(a) => (cmd::arm_plan::run(&a), a.json),
        Command::Teleop(a) => (cmd::teleop::run(&a), false),
        Command::CalibrateCamera(a) => (cmd::calibrate_camera::run(&a), a.json),
        Command::Demo(a) => (cmd::demo::run(&a), false),
        Command::Record(a) => (cmd::record::run(&a), a.json),
        Command::Replay(a) => (cmd::replay::run(&a), a.json),
        Command::ExportLerobot(a) => (cmd::export_lerobot::run(&a), a.json),
    };
    result.map_err(|e| (e, json))
}

/// Run the benchmark; its result comes with whether an error prints as JSON.
fn run_bench(which: BenchCommand) -> (ferrobot::Result<()>, bool) {
    match which {
        BenchCommand::Base(a) => (cmd::bench_base::run(&a), a.json),
        BenchCommand::Camera(a) => (cmd::bench_camera::run(&a), a.json),
        BenchCommand::Plan(a) => (cmd::bench_plan::run(&a), a.json),
        BenchCommand::Arm(a) => (cmd::bench_arm::run(&a), a.json),
        BenchCommand::Push(a) => (cmd::bench_push::run(&a), a.json),
        BenchCommand::Grasp(a) => (cmd::bench_grasp::run(&a), a.json),
        BenchCommand::Nav(a) => (cmd::bench_nav::run(&a), a.json),
        BenchCommand::HostLoop(a) => (cmd::bench_host_loop::run(&a), a.json),
        BenchCommand::Record(a) => (cmd::bench_record::run(&a), a.json),
        BenchCommand::Remote(a) => (cmd::bench_remote::run(&a), a.json),
    }
}

/// The error object of `--json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct ErrorJson {
    /// What went wrong.
    error: String,
    /// Whether the input was at fault (exit code 2) rather than the robot or the world (1).
    input_error: bool,
    /// Always false.
    success: bool,
}

/// Exit codes: 0 success, 1 the robot or the world failed (unreachable, timeout, fault), 2
/// the input was wrong (arguments, values, names, files). With `--json`, an error is one
/// object `{"success": false, "error": "...", "input_error": bool}` on standard output.
fn main() -> ExitCode {
    let json_wanted = std::env::args_os().any(|a| a == "--json");
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            if json_wanted && e.use_stderr() {
                let text = e.to_string();
                let first = text.lines().next().unwrap_or_default();
                let msg = first.strip_prefix("error: ").unwrap_or(first).to_string();
                print_json(&ErrorJson {
                    error: msg,
                    input_error: true,
                    success: false,
                });
                return ExitCode::from(2);
            }
            // Help and version print and succeed; usage errors exit with code 2.
            e.exit();
        }
    };
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err((e, json)) => {
            let input = e.is_input();
            if json {
                print_json(&ErrorJson {
                    error: e.to_string(),
                    input_error: input,
                    success: false,
                });
            } else {
                eprintln!("error: {e}");
            }
            ExitCode::from(if input { 2 } else { 1 })
        }
    }
}
