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

use clap::{Args, Parser, Subcommand};
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
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// List the bundled robots.
    Robots {
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Describe a robot: joints, limits, components.
    Info {
        /// Robot name, or a path to a TOML configuration.
        robot: String,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Pose of the end-effector frame (or --frame) in the robot's root link at joint angles Q.
    Fk {
        /// Robot name or configuration path.
        robot: String,
        /// Joint angles, rad, in arm order.
        #[arg(allow_negative_numbers = true, required = true)]
        q: Vec<f64>,
        /// Frame of the arm's chain (default: the end effector).
        #[arg(long)]
        frame: Option<String>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Geometric Jacobian (rows vx vy vz wx wy wz, root frame, at the end effector's origin).
    Jacobian {
        /// Robot name or configuration path.
        robot: String,
        /// Joint angles, rad.
        #[arg(allow_negative_numbers = true, required = true)]
        q: Vec<f64>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Inverse kinematics of the end effector.
    Ik(IkArgs),
    /// Serve a simulated robot's firmware core (with its plants, in real time, in a scene) on a
    /// PTY behind the symlink LINK, and its camera on the Unix socket LINK.camera, for the
    /// Serial backend and outside tools. Prints one JSON line, then reads control lines on
    /// standard input until it closes: `unplug` and `plug` drop and restore the link (`unplug
    /// MS` restores it after MS of the firmware's time), `mute` and `unmute` drop and restore
    /// its telemetry (a stopped control loop), `freeze` and `thaw` stop and restart the
    /// world's clock (the firmware still answers), `stall MS` stops the server for MS.
    SimFirmware {
        /// Robot name or configuration path.
        robot: String,
        /// Path of the symlink to create.
        #[arg(long)]
        link: std::path::PathBuf,
        /// Seed of the plants' noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// The world: a bundled scene or a scene file (default: empty).
        #[arg(long, default_value = "empty")]
        scene: String,
        /// Exact depth from the camera (no stereo noise).
        #[arg(long)]
        no_noise: bool,
    },
    /// One base motion on the simulated robot, from rest at the origin.
    BaseMove {
        /// Robot name or configuration path.
        robot: String,
        /// Relative target X Y THETA (m, m, rad) in the start pose's frame.
        #[arg(long, num_args = 3, allow_negative_numbers = true, required = true, value_names = ["X", "Y", "THETA"])]
        relative: Vec<f64>,
        /// proportional, lqr, ilqr or dwa (default: the configuration's).
        #[arg(long)]
        controller: Option<String>,
        /// LQR/ILQR: a smooth (Bézier) reference.
        #[arg(long)]
        smooth: bool,
        /// LQR/ILQR: play the reference open loop.
        #[arg(long)]
        open_loop: bool,
        /// Seed of the plants' noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Calibrate the simulated base's odometry (UMBmark squares both ways and a 2 m line,
    /// measured by ground truth, fitted by least squares); prints the `[base] odometry` line.
    CalibrateOdometry {
        /// Robot name or configuration path.
        robot: String,
        /// Seed of the plants' noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        which: BenchCmd,
    },
    /// The self-collision matrix of a robot's arm by sampling (link pairs adjacent, touching
    /// at the default pose, in nearly every or in no random configuration), printed as the
    /// `[collision]` section of its configuration.
    CollisionMatrix {
        /// Robot name or configuration path.
        robot: String,
        /// Random configurations of every movable joint.
        #[arg(long, default_value_t = ferrobot::planning::acm::DEFAULT_SAMPLES)]
        samples: usize,
        /// Seed of the sampler.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// The global planner alone on a map in ROS map_server's format (YAML + PNG): a
    /// collision-free path for a round robot, or a typed error.
    NavPlan {
        /// The map's YAML file.
        #[arg(long)]
        map: std::path::PathBuf,
        /// Start x y, m (map frame).
        #[arg(long, num_args = 2, allow_negative_numbers = true, value_names = ["X", "Y"], required = true)]
        from: Vec<f64>,
        /// Goal x y, m (map frame).
        #[arg(long, num_args = 2, allow_negative_numbers = true, value_names = ["X", "Y"], required = true)]
        to: Vec<f64>,
        /// Robot radius, m.
        #[arg(long, allow_negative_numbers = true)]
        radius: f64,
        /// Treat unknown cells as free (default: occupied).
        #[arg(long)]
        unknown_free: bool,
        /// Also draw the map and the path into this PNG file.
        #[arg(long)]
        plot: Option<std::path::PathBuf>,
        /// Print one JSON object: `{"length_m", "path": [[x, y], ...]}`.
        #[arg(long)]
        json: bool,
    },
    /// DBSCAN on a point cloud (a PLY file, metres), with scikit-learn's semantics and labels
    /// (a point is core with at least MIN_SAMPLES neighbours within EPS, itself included;
    /// noise is -1); a summary, or with --json one label per point in the file's order.
    Cluster {
        /// The cloud: a PLY file (ASCII or binary little-endian, vertices with x y z).
        #[arg(long = "in", value_name = "CLOUD.ply")]
        input: std::path::PathBuf,
        /// Neighbourhood radius, m (finite, in (0, 100]).
        #[arg(long, allow_negative_numbers = true)]
        eps: f64,
        /// Neighbours (the point itself included) that make a point core (1 to 1,000,000).
        #[arg(long)]
        min_samples: usize,
        /// Print one JSON object: `{"labels": [...]}`, one label per point, -1 for noise.
        #[arg(long)]
        json: bool,
    },
    /// Visual SLAM on a scripted drive or a recorded sequence. A drive: the simulated robot
    /// follows a route of the scene while SLAM runs on its camera and odometry; writes
    /// estimate.tum, ground_truth.tum, odometry.tum, map.yaml + map.png, cloud.ply and
    /// trajectory.png to --out. A sequence (--dataset DIR, the TUM RGB-D layout): writes
    /// estimate.tum (camera poses) and cloud.ply to --out, if given.
    Slam {
        /// Robot name or configuration path (not with --dataset).
        #[arg(required_unless_present = "dataset", conflicts_with = "dataset")]
        robot: Option<String>,
        /// A recorded RGB-D sequence in the TUM RGB-D layout (rgb.txt, depth.txt, PNGs,
        /// camera.yaml, groundtruth.txt when present).
        #[arg(long)]
        dataset: Option<std::path::PathBuf>,
        /// Scene name or path.
        #[arg(long, default_value = "apartment", conflicts_with = "dataset")]
        scene: String,
        /// Route of the scene to drive.
        #[arg(long, default_value = "loop", conflicts_with = "dataset")]
        route: String,
        /// Seed of the plants' and the camera's noise.
        #[arg(long, default_value_t = 1, conflicts_with = "dataset")]
        seed: u64,
        /// Localise in this saved SLAM map (an earlier drive's map.slam) from a start SLAM is
        /// not told.
        #[arg(long, conflicts_with = "dataset")]
        map: Option<std::path::PathBuf>,
        /// Output directory (created if missing).
        #[arg(long)]
        out: Option<std::path::PathBuf>,
        /// Print one JSON object: `{"ate_rmse_m", "frames", "ms_per_frame": {"mean", "p95"},
        /// "occupancy_iou", ...}`.
        #[arg(long)]
        json: bool,
    },
    /// Record a simulated drive along a scene's route as an RGB-D sequence in the TUM RGB-D
    /// layout (rgb/, depth/ at 5000 units per metre, rgb.txt, depth.txt, groundtruth.txt of
    /// the camera, camera.yaml).
    RecordRgbd {
        /// Robot name or configuration path.
        robot: String,
        /// Scene name or path.
        #[arg(long, default_value = "apartment")]
        scene: String,
        /// Route of the scene to drive.
        #[arg(long)]
        route: String,
        /// Seed of the plants' and the camera's noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output directory (must be missing or empty).
        #[arg(long)]
        out: std::path::PathBuf,
    },
    /// What a scene holds (bundled name or scene file): its bodies in the world frame (z up,
    /// metres) and the robot's start pose.
    Scene {
        /// `empty`, `tabletop`, `apartment`, `shelf`, `clutter`, or a scene file's path.
        name: String,
        /// Also write the scene's ground-truth floor plan here (map_server's YAML, and a PNG
        /// of the same name beside it): obstacles 0.1–0.8 m above the floor, as PyRobot maps.
        #[arg(long)]
        map: Option<std::path::PathBuf>,
        /// Cell size of the floor plan, m (PyRobot's 0.02).
        #[arg(long, default_value_t = 0.02)]
        resolution: f64,
        /// Write over an existing map file (and its PNG).
        #[arg(long)]
        force: bool,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// One RGB-D frame of the simulated robot in a scene: writes rgb.png, depth.png (16-bit
    /// mm, 0 invalid), cloud.ply (world frame) and snapshot.png (colour | depth) to --out.
    Snapshot(SnapshotCli),
    /// Plan an arm motion around a scene's objects on the simulator and execute it: prints
    /// the plan (time, waypoints, length, duration) and the executed motion's contacts in the
    /// physics engine; --png draws the motion seen from beside the robot.
    ArmPlan(ArmPlanCli),
    /// Drive a robot from the keyboard in a terminal, with PyRobot's key map and steps: the
    /// end effector, the wrist, the gripper, the camera's pan and tilt, and the base while an
    /// arrow is held; the robot's state shown live. q, Esc or Ctrl-C quits with the base
    /// stopped and the arm holding.
    Teleop(TeleopCli),
    /// Hand-eye calibration of the head camera against the marker on the gripper (PyRobot's
    /// locobot_calibration), the simulated camera mounted off nominal by --perturb: prints
    /// the fitted mount's error against the true one; --out writes the calibration file.
    CalibrateCamera(CalibrateCameraCli),
    /// Run the quickstart on the simulated LoCoBot.
    Demo {
        /// Robot (default locobot).
        #[arg(long, default_value = "locobot")]
        robot: String,
    },
}

#[derive(Subcommand)]
enum BenchCmd {
    /// PyRobot's base accuracy trials (Table 1) for every controller, against ground truth
    /// and odometry, plus the circle-tracking plot per base.
    Base {
        /// Robots (repeatable; default locobot and locobot_lite).
        #[arg(long)]
        robot: Vec<String>,
        /// Trials per target (the paper: 5).
        #[arg(long, default_value_t = 5)]
        trials: usize,
        /// Seed of trial k is SEED + k (the same for every controller).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Print one JSON object per robot, one per line, instead of Markdown.
        #[arg(long)]
        json: bool,
        /// Where the circle plots go.
        #[arg(long, default_value = "target/bench-base")]
        plot_dir: std::path::PathBuf,
        /// First calibrate each base's odometry (as `ferrobot calibrate-odometry` with seed
        /// SEED + 1000) and run every trial with the calibrated geometry.
        #[arg(long)]
        calibrate: bool,
    },
    /// The simulator's real-time factor for the LoCoBot with its camera streaming at 30 Hz
    /// while the base drives a circle, per scene, beside the same run without frames.
    Camera {
        /// Scenes (repeatable; default tabletop and apartment).
        #[arg(long)]
        scene: Vec<String>,
        /// Simulated seconds per run.
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
        /// Print one JSON object per scene, one per line, instead of Markdown.
        #[arg(long)]
        json: bool,
    },
    /// Arm planning on a fixed, seeded set of problems in a scene (or a problems file):
    /// success rate, time, path length, collision checks per second; with --ompl, OMPL's
    /// RRTConnect on the same problems in the same run.
    Plan(BenchPlanCli),
    /// The arm in the manner of ISO 9283: pose accuracy and repeatability over five poses in
    /// a cube (by ground truth), and the joint tracking of a streamed trajectory, with plots.
    Arm {
        /// Robot name or configuration path.
        robot: String,
        /// Cycles through the five poses (ISO 9283: 30).
        #[arg(long, default_value_t = 30)]
        cycles: usize,
        /// Where the robot runs.
        #[command(flatten)]
        backend: cmd::common::BackendArgs,
        /// Write one PNG per joint (commanded and measured angle over time) here.
        #[arg(long)]
        out: Option<std::path::PathBuf>,
        /// Print one JSON object: `{"accuracy_mm_max", "cycles", "poses": [{"accuracy_mm",
        /// "commanded_m", "repeatability_mm"}], "repeatability_mm_max", "tracking": [{"max_rad",
        /// "name", "rms_rad"}], "tracking_duration_s"}`.
        #[arg(long)]
        json: bool,
    },
    /// PyRobot's pushing example, measured by ground truth: objects placed at random on the
    /// table per trial (seed SEED + k), one object pushed; how far it moved along the push
    /// and whether any other object moved more than 1 cm.
    Push {
        /// Robot name or configuration path.
        robot: String,
        /// Scene name or path (movable objects on a static body `table`).
        #[arg(long, default_value = "tabletop")]
        scene: String,
        /// Trials.
        #[arg(long, default_value_t = 10)]
        trials: usize,
        /// Where the robot runs; --seed is the first trial's (placement and plants).
        #[command(flatten)]
        backend: cmd::common::BackendArgs,
        /// Print one JSON object: `{"others_moved", "per_trial": [...], "pushes",
        /// "success_rate", "success_rate_of_pushes", "target_moved_m": {"median", "min"},
        /// "time_s": {"median"}, "trials"}`.
        #[arg(long)]
        json: bool,
    },
    /// PyRobot's grasping example as a benchmark: each trial places the scene's graspable
    /// objects at random on the table (seed SEED + trial), looks, grasps, lifts; success is an
    /// object lifted at least 5 cm and held 2 s, from the simulator's ground truth.
    Grasp {
        /// Robot name or configuration path.
        robot: String,
        /// Scene name or path (with a fixed body `table`).
        #[arg(long, default_value = "tabletop")]
        scene: String,
        /// Trials.
        #[arg(long, default_value_t = 10)]
        trials: usize,
        /// The backend; --seed seeds the placements (and the plants' noise on the sim).
        #[command(flatten)]
        backend: cmd::common::BackendArgs,
        /// Print one JSON object: `{"failures", "objects", "success_rate", "time_s":
        /// {"median"}, "trials"}` (the failures' reasons, the objects placed).
        #[arg(long)]
        json: bool,
    },
    /// Navigation on the scene's ground-truth floor plan: the simulated robot drives to N
    /// random reachable goals; success rate, bumper hits, path length against the shortest
    /// path, time per goal.
    Nav {
        /// Robot name or configuration path.
        robot: String,
        /// Scene name or path.
        #[arg(long, default_value = "apartment")]
        scene: String,
        /// Goals.
        #[arg(long, default_value_t = 50)]
        goals: usize,
        /// Seed of the goals and the plants' noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Where the base's pose comes from: `slam` (SLAM beside the robot, started at the
        /// true start on the floor plan's frame) or `odometry` (the wheels alone).
        #[arg(long, default_value = "slam")]
        localise: String,
        /// One line per goal on standard error.
        #[arg(long)]
        trace: bool,
        /// Explore the scene first (SLAM, frontiers), then drive to the goals on SLAM's map;
        /// the JSON gains `exploration`: `{"bumper_hits", "distance_m", "occupancy_iou",
        /// "occupancy_iou_free", "occupancy_iou_occupied", "time_s"}`.
        #[arg(long)]
        explore: bool,
        /// With --explore: write the explored map (`map.yaml`, `map.png`), the part of the
        /// floor plan it is judged against (`truth.yaml`, `truth.png`) and a picture of the
        /// map with the SLAM, true and wheel-odometry paths (`exploration.png`) here.
        #[arg(long)]
        out: Option<std::path::PathBuf>,
        /// Print one JSON object: `{"bumper_hits", "goals", "path_length_ratio": {"median"},
        /// "success_rate", "time_s": {"median"}}`.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Args)]
struct BenchPlanCli {
    /// Robot name or configuration path.
    #[arg(long, required_unless_present = "config", conflicts_with = "config")]
    robot: Option<String>,
    /// Robot configuration file (the same as --robot PATH).
    #[arg(long)]
    config: Option<String>,
    /// Scene name or path: generated problems (collision-free starts and goals whose
    /// straight line collides, both near an object when the scene has any besides floor
    /// and walls).
    #[arg(
        long,
        required_unless_present = "problems_file",
        conflicts_with = "problems_file"
    )]
    scene: Option<String>,
    /// Problems file (JSON: joints, objects, problems with start and goal; an export is
    /// one) instead of generated problems.
    #[arg(long)]
    problems_file: Option<std::path::PathBuf>,
    /// Generated problems.
    #[arg(long, default_value_t = 100)]
    problems: usize,
    /// Seed of the problem set and of the planner (problem k: SEED + k).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// rrt-connect or informed-rrt-star.
    #[arg(long, default_value = "rrt-connect")]
    planner: String,
    /// Time limit per problem, s (OMPL's too).
    #[arg(long, default_value_t = 1.0)]
    time_limit: f64,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
    /// Write robot, scene, problems and paths here (JSON, as host/planning/peer/plan_peer.py
    /// reads it; a bundled robot's URDF and the scene's meshes go beside it).
    #[arg(long)]
    export: Option<std::path::PathBuf>,
    /// Also plan the problems with OMPL's RRTConnect (simplified) through the Python peer
    /// and compare (needs `scripts/python-env.sh plan`).
    #[arg(long)]
    ompl: bool,
    /// OMPL's time limit per problem, s (default: --time-limit; its Python state checks are
    /// about 0.25 ms each).
    #[arg(long, requires = "ompl")]
    ompl_time_limit: Option<f64>,
}

#[derive(Args)]
struct TeleopCli {
    /// Robot name or configuration path.
    robot: String,
    /// Scene name or path (the simulated world).
    #[arg(long, default_value = "empty")]
    scene: String,
    #[command(flatten)]
    backend: cmd::common::BackendArgs,
    /// Simulator only: advance simulated time by this many ms per turn of the loop, each turn
    /// reading keys for as long of wall time, never catching up (default: real time).
    #[arg(long, allow_negative_numbers = true)]
    step_ms: Option<f64>,
    /// The terminal's auto-repeat delay, s (0.05-2): how long a first press of an arrow
    /// drives the base when the terminal does not report key releases.
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    repeat_delay: f64,
    /// Write one JSON line per turn (time, keys, commands, state) to this new file.
    #[arg(long)]
    trace: Option<std::path::PathBuf>,
}

#[derive(Args)]
struct CalibrateCameraCli {
    /// Robot name or configuration path.
    robot: String,
    /// The simulated camera's mount error DX DY DZ DROLL DPITCH DYAW (m and rad, in the camera
    /// link's frame; each within 0.1 m and 0.5 rad).
    #[arg(long, num_args = 6, allow_negative_numbers = true,
          value_names = ["DX", "DY", "DZ", "DROLL", "DPITCH", "DYAW"])]
    perturb: Option<Vec<f64>>,
    /// Arm poses holding the marker (1-6).
    #[arg(long, default_value_t = 6)]
    poses: usize,
    /// Head grid side: GRID x GRID pan/tilt views per arm pose (1-5).
    #[arg(long, default_value_t = 3)]
    grid: usize,
    /// Scene name or path.
    #[arg(long, default_value = "empty")]
    scene: String,
    #[command(flatten)]
    backend: cmd::common::BackendArgs,
    /// Write the calibration (TOML) here, for `RobotBuilder::camera_calibration`.
    #[arg(long)]
    out: Option<std::path::PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct SnapshotCli {
    /// Robot name or configuration path.
    robot: String,
    /// Scene name or path.
    #[arg(long, default_value = "tabletop")]
    scene: String,
    /// Head pan, rad (positive left).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pan: f64,
    /// Head tilt, rad (positive down; PyRobot's grasping view is 0.8).
    #[arg(long, default_value_t = 0.8, allow_negative_numbers = true)]
    tilt: f64,
    /// Arm joint angles, rad (default: as the robot starts).
    #[arg(long, num_args = 1.., allow_negative_numbers = true)]
    joints: Option<Vec<f64>>,
    /// Base start pose X Y THETA in the world (default: the scene's).
    #[arg(long, num_args = 3, allow_negative_numbers = true, value_names = ["X", "Y", "THETA"])]
    base: Option<Vec<f64>>,
    /// Exact depth (no stereo noise).
    #[arg(long)]
    no_noise: bool,
    /// Depth range of the cloud MIN MAX, m (default: the description's).
    #[arg(long, num_args = 2, value_names = ["MIN", "MAX"])]
    depth_range: Option<Vec<f64>>,
    /// Output directory (created if missing).
    #[arg(long)]
    out: std::path::PathBuf,
    /// Seed of the plants' and the camera's noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct ArmPlanCli {
    /// Robot name or configuration path.
    robot: String,
    /// Scene name or path.
    #[arg(long, default_value = "tabletop")]
    scene: String,
    /// Start configuration, rad (reached first by a planned motion; default: as the robot
    /// starts).
    #[arg(long, num_args = 1.., allow_negative_numbers = true)]
    from: Option<Vec<f64>>,
    /// Goal configuration, rad.
    #[arg(long, num_args = 1.., allow_negative_numbers = true, required = true)]
    to: Vec<f64>,
    /// Room kept between the arm and the scene's objects along the motion, m.
    #[arg(long, default_value_t = ferrobot::arm_plan::DEFAULT_PADDING)]
    padding: f64,
    /// Seed of the plants.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Draw the executed motion into this PNG.
    #[arg(long)]
    png: Option<std::path::PathBuf>,
    /// Print one JSON object: `{"contacts", "duration_s", "final_error_rad", "joints",
    /// "padding_m", "path", "path_length_rad", "planning_ms", "scene_objects"}`.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct IkArgs {
    /// Robot name or configuration path.
    robot: String,
    /// Target position X Y Z, m, in the root link.
    #[arg(long, num_args = 3, allow_negative_numbers = true, required = true, value_names = ["X", "Y", "Z"])]
    position: Vec<f64>,
    /// Orientation as a quaternion X Y Z W.
    #[arg(long, num_args = 4, allow_negative_numbers = true, value_names = ["X", "Y", "Z", "W"], conflicts_with_all = ["rpy", "pitch"])]
    quaternion: Option<Vec<f64>>,
    /// Orientation as roll, pitch, yaw (R = Rz(yaw)·Ry(pitch)·Rx(roll)), rad.
    #[arg(long, num_args = 3, allow_negative_numbers = true, value_names = ["R", "P", "Y"], conflicts_with = "pitch")]
    rpy: Option<Vec<f64>>,
    /// 5-DOF arms: gripper pitch below horizontal, rad.
    #[arg(long, allow_negative_numbers = true)]
    pitch: Option<f64>,
    /// 5-DOF arms: gripper roll, rad (with --pitch; default 0).
    #[arg(long, allow_negative_numbers = true, requires = "pitch")]
    roll: Option<f64>,
    /// Seed joint angles, rad.
    #[arg(long, num_args = 1.., allow_negative_numbers = true)]
    seed: Option<Vec<f64>>,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// Run the subcommand; its error comes with whether to print it as JSON.
fn run(cli: Cli) -> Result<(), (ferrobot::Error, bool)> {
    let (result, json) = match cli.cmd {
        Cmd::Robots { json } => (cmd::robots::run(json), json),
        Cmd::Info { robot, json } => (cmd::info::run(&robot, json), json),
        Cmd::Fk {
            robot,
            q,
            frame,
            json,
        } => (cmd::fk::run(&robot, &q, frame.as_deref(), json), json),
        Cmd::Jacobian { robot, q, json } => (cmd::jacobian::run(&robot, &q, json), json),
        Cmd::Ik(a) => (cmd::ik::run(&a), a.json),
        Cmd::Demo { robot } => (cmd::demo::run(&robot), false),
        Cmd::Teleop(a) => (
            cmd::teleop::run(&cmd::teleop::Args {
                robot: &a.robot,
                scene: &a.scene,
                backend: &a.backend,
                step_ms: a.step_ms,
                repeat_delay: a.repeat_delay,
                trace: a.trace.as_deref(),
            }),
            false,
        ),
        Cmd::Scene {
            name,
            map,
            resolution,
            force,
            json,
        } => (
            cmd::scene::run(&name, json, map.as_deref(), resolution, force),
            json,
        ),
        Cmd::Snapshot(a) => (
            cmd::snapshot::run(&cmd::snapshot::SnapshotArgs {
                robot: &a.robot,
                scene: &a.scene,
                pan: a.pan,
                tilt: a.tilt,
                joints: a.joints.as_deref(),
                base: a.base.as_ref().map(|b| [b[0], b[1], b[2]]),
                no_noise: a.no_noise,
                depth_range: a.depth_range.as_ref().map(|r| [r[0], r[1]]),
                out: &a.out,
                seed: a.seed,
                json: a.json,
            }),
            a.json,
        ),
        Cmd::ArmPlan(a) => (
            cmd::arm_plan::run(&cmd::arm_plan::ArmPlanArgs {
                robot: &a.robot,
                scene: &a.scene,
                from: a.from.as_deref(),
                to: &a.to,
                padding: a.padding,
                seed: a.seed,
                png: a.png.as_deref(),
                json: a.json,
            }),
            a.json,
        ),
        Cmd::CalibrateCamera(a) => {
            let p = a.perturb.as_deref().unwrap_or(&[0.0; 6]);
            (
                cmd::calibrate_camera::run(&cmd::calibrate_camera::CalibrateArgs {
                    robot: &a.robot,
                    perturb: [p[0], p[1], p[2], p[3], p[4], p[5]],
                    poses: a.poses,
                    grid: a.grid,
                    scene: &a.scene,
                    backend: &a.backend,
                    out: a.out.as_deref(),
                    json: a.json,
                }),
                a.json,
            )
        }
        Cmd::BaseMove {
            robot,
            relative,
            controller,
            smooth,
            open_loop,
            seed,
            json,
        } => (
            cmd::base_move::run(
                &robot,
                [relative[0], relative[1], relative[2]],
                controller.as_deref(),
                smooth,
                open_loop,
                seed,
                json,
            ),
            json,
        ),
        Cmd::Bench {
            which:
                BenchCmd::Base {
                    robot,
                    trials,
                    seed,
                    json,
                    plot_dir,
                    calibrate,
                },
        } => (
            cmd::bench_base::run(robot, trials, seed, json, &plot_dir, calibrate),
            json,
        ),
        Cmd::Bench {
            which:
                BenchCmd::Camera {
                    scene,
                    seconds,
                    json,
                },
        } => {
            let scenes = if scene.is_empty() {
                vec!["tabletop".to_string(), "apartment".to_string()]
            } else {
                scene
            };
            (cmd::bench_camera::run(&scenes, seconds, json), json)
        }
        Cmd::Bench {
            which:
                BenchCmd::Nav {
                    robot,
                    scene,
                    goals,
                    seed,
                    localise,
                    trace,
                    explore,
                    out,
                    json,
                },
        } => (
            cmd::bench_nav::run(&cmd::bench_nav::NavArgs {
                robot: &robot,
                scene: &scene,
                goals,
                seed,
                localise: &localise,
                trace,
                explore,
                out: out.as_deref(),
                json,
            }),
            json,
        ),
        Cmd::Bench {
            which:
                BenchCmd::Arm {
                    robot,
                    cycles,
                    backend,
                    out,
                    json,
                },
        } => (
            cmd::bench_arm::run(&cmd::bench_arm::ArmArgs {
                robot: &robot,
                cycles,
                backend: &backend,
                out: out.as_deref(),
                json,
            }),
            json,
        ),
        Cmd::Bench {
            which:
                BenchCmd::Push {
                    robot,
                    scene,
                    trials,
                    backend,
                    json,
                },
        } => (
            cmd::bench_push::run(&cmd::common::TableTrials {
                robot: &robot,
                scene: &scene,
                trials,
                backend: &backend,
                json,
            }),
            json,
        ),
        Cmd::Bench {
            which:
                BenchCmd::Grasp {
                    robot,
                    scene,
                    trials,
                    backend,
                    json,
                },
        } => (
            cmd::bench_grasp::run(&cmd::common::TableTrials {
                robot: &robot,
                scene: &scene,
                trials,
                backend: &backend,
                json,
            }),
            json,
        ),
        Cmd::Bench {
            which: BenchCmd::Plan(a),
        } => {
            let robot = a
                .robot
                .as_deref()
                .or(a.config.as_deref())
                .unwrap_or_default();
            (
                cmd::bench_plan::run(&cmd::bench_plan::PlanArgs {
                    robot,
                    scene: a.scene.as_deref(),
                    problems_file: a.problems_file.as_deref(),
                    problems: a.problems,
                    seed: a.seed,
                    planner: &a.planner,
                    time_limit: a.time_limit,
                    json: a.json,
                    export: a.export.as_deref(),
                    ompl: a.ompl,
                    ompl_time_limit: a.ompl_time_limit.unwrap_or(a.time_limit),
                }),
                a.json,
            )
        }
        Cmd::CollisionMatrix {
            robot,
            samples,
            seed,
        } => (cmd::collision_matrix::run(&robot, samples, seed), false),
        Cmd::NavPlan {
            map,
            from,
            to,
            radius,
            unknown_free,
            plot,
            json,
        } => (
            cmd::nav_plan::run(&cmd::nav_plan::Args {
                map: &map,
                from: [from[0], from[1]],
                to: [to[0], to[1]],
                radius,
                unknown_free,
                plot: plot.as_deref(),
                json,
            }),
            json,
        ),
        Cmd::Cluster {
            input,
            eps,
            min_samples,
            json,
        } => (cmd::cluster::run(&input, eps, min_samples, json), json),
        Cmd::Slam {
            robot,
            dataset,
            scene,
            route,
            seed,
            map,
            out,
            json,
        } => {
            let source = match (&robot, &dataset) {
                (_, Some(d)) => Ok(cmd::slam::Source::Dataset(d)),
                (Some(r), None) => Ok(cmd::slam::Source::Drive {
                    robot: r,
                    scene: &scene,
                    route: &route,
                    seed,
                    map: map.as_deref(),
                }),
                (None, None) => Err(ferrobot::Error::Usage("name a ROBOT or a --dataset".into())),
            };
            let r = source.and_then(|source| {
                cmd::slam::run(&cmd::slam::Args {
                    source,
                    out: out.as_deref(),
                    json,
                })
            });
            (r, json)
        }
        Cmd::RecordRgbd {
            robot,
            scene,
            route,
            seed,
            out,
        } => (
            cmd::record_rgbd::run(&robot, &scene, &route, seed, &out),
            false,
        ),
        Cmd::CalibrateOdometry { robot, seed, json } => {
            (cmd::calibrate_odometry::run(&robot, seed, json), json)
        }
        // Its one line on standard output is JSON, and so are its errors.
        Cmd::SimFirmware {
            robot,
            link,
            seed,
            scene,
            no_noise,
        } => (
            cmd::sim_firmware::run(&robot, link, seed, &scene, !no_noise),
            true,
        ),
    };
    result.map_err(|e| (e, json))
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
