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
//! ferrobot base-move locobot --relative 1 1 1.5708 --controller lqr --smooth --json
//! ferrobot bench base --robot locobot --trials 5 --seed 1
//! ```

use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use ferrobot::config::BaseController;
use ferrobot::kinematics::ik::{IkOptions, IkSolver, NumericalIk};
use ferrobot::kinematics::locobot_ik::LocobotIk;
use ferrobot::kinematics::Chain;
use ferrobot::validate;
use ferrobot::{config::IkKind, GoalOptions, Orientation, Pose, Robot, RobotConfig};
use nalgebra::{Isometry3, Translation3};
use serde_json::json;

/// Most trials per target of `bench base`.
const MAX_TRIALS: usize = 100;

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
    /// Serve a simulated robot's firmware core (with its plants, in real time) on a PTY behind
    /// the symlink LINK, for the Serial backend and outside tools. Prints one JSON line; reads
    /// `unplug` and `plug` lines on standard input to drop and restore the link; exits when
    /// standard input closes.
    SimFirmware {
        /// Robot name or configuration path.
        robot: String,
        /// Path of the symlink to create.
        #[arg(long)]
        link: std::path::PathBuf,
        /// Seed of the plants' noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
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

/// The error of any layer as the API's, with whether to print it as JSON.
fn with<E: Into<ferrobot::Error>>(json: bool) -> impl Fn(E) -> (ferrobot::Error, bool) {
    move |e| (e.into(), json)
}

fn load(robot: &str) -> ferrobot::Result<RobotConfig> {
    Ok(if robot.ends_with(".toml") || robot.contains('/') {
        RobotConfig::from_file(robot)?
    } else {
        RobotConfig::bundled(robot)?
    })
}

fn arm_chain(cfg: &RobotConfig) -> ferrobot::Result<Chain> {
    cfg.arm_chain
        .clone()
        .ok_or_else(|| ferrobot::Error::NoComponent {
            robot: cfg.name.clone(),
            component: "arm",
        })
}

/// Joint angles for `chain`: its count, each finite and within ±`validate::MAX_ANGLE`.
fn check_q(chain: &Chain, q: &[f64]) -> ferrobot::Result<()> {
    if q.len() != chain.dof() {
        return Err(ferrobot::Error::JointCount {
            what: "joint angles",
            expected: chain.dof(),
            got: q.len(),
        });
    }
    Ok(validate::angles("joint angles", q)?)
}

fn pose_json(p: &Pose) -> serde_json::Value {
    json!({"position": p.position, "rotation": p.rotation, "quaternion": p.quaternion})
}

fn run(cli: Cli) -> Result<(), (ferrobot::Error, bool)> {
    match cli.cmd {
        Cmd::Robots { json } => {
            if json {
                println!("{}", json!({"robots": ferrobot::config::BUNDLED}));
            } else {
                for r in ferrobot::config::BUNDLED {
                    println!("{r}");
                }
            }
        }
        Cmd::Info { robot, json } => {
            let cfg = load(&robot).map_err(with(json))?;
            let joints: Vec<_> = cfg
                .joints
                .iter()
                .map(|j| {
                    json!({"name": j.name.as_str(), "kind": format!("{:?}", j.kind).to_lowercase(), "servo_id": j.servo_id,
                           "twin_id": j.twin_id, "min": j.limits.min, "max": j.limits.max,
                           "velocity": j.limits.velocity, "effort": j.limits.effort})
                })
                .collect();
            let arm = cfg.arm.as_ref().map(|a| json!({"joints": a.joints, "base_frame": a.base_frame, "ee_frame": a.ee_frame, "home": a.home, "ik": format!("{:?}", a.ik)}));
            let base = cfg.base.as_ref().map(|b| json!({"kind": format!("{:?}", b.kind), "wheel_radius": b.wheel_radius, "track": b.track}));
            let v = json!({"robot": cfg.name, "file": cfg.file.display().to_string(), "arm": arm, "gripper": cfg.gripper.as_ref().map(|g| &g.joint),
                           "camera": cfg.camera.as_ref().map(|c| json!({"pan": c.pan_joint, "tilt": c.tilt_joint, "frame": c.frame, "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy})),
                           "base": base, "joints": joints});
            if json {
                println!("{v}");
            } else {
                println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
            }
        }
        Cmd::Fk {
            robot,
            q,
            frame,
            json,
        } => {
            let cfg = load(&robot).map_err(with(json))?;
            let arm = arm_chain(&cfg).map_err(with(json))?;
            check_q(&arm, &q).map_err(with(json))?;
            let chain = match &frame {
                Some(f) => Chain::from_urdf(&cfg.urdf, &arm.base, f).map_err(with(json))?,
                None => arm.clone(),
            };
            let sub: Vec<f64> = chain
                .joints
                .iter()
                .filter_map(|j| {
                    arm.joints
                        .iter()
                        .position(|a| a.name == j.name)
                        .map(|k| q[k])
                })
                .collect();
            if sub.len() != chain.dof() {
                return Err((
                    ferrobot::Error::UnknownName {
                        what: "frame of the arm's chain",
                        name: frame.unwrap_or_default(),
                    },
                    json,
                ));
            }
            let p: Pose = chain.fk(&sub).into();
            if json {
                println!("{}", pose_json(&p));
            } else {
                println!("frame {} in {}", chain.tip, chain.base);
                println!(
                    "position   {:.6} {:.6} {:.6}",
                    p.position[0], p.position[1], p.position[2]
                );
                println!(
                    "quaternion {:.6} {:.6} {:.6} {:.6}  [x y z w]",
                    p.quaternion[0], p.quaternion[1], p.quaternion[2], p.quaternion[3]
                );
                for r in p.rotation {
                    println!("rotation   {:.6} {:.6} {:.6}", r[0], r[1], r[2]);
                }
            }
        }
        Cmd::Jacobian { robot, q, json } => {
            let cfg = load(&robot).map_err(with(json))?;
            let arm = arm_chain(&cfg).map_err(with(json))?;
            check_q(&arm, &q).map_err(with(json))?;
            let j = arm.jacobian(&q);
            let rows: Vec<Vec<f64>> = (0..6)
                .map(|r| (0..arm.dof()).map(|c| j[(r, c)]).collect())
                .collect();
            if json {
                println!("{}", json!({"jacobian": rows}));
            } else {
                for (name, r) in ["vx", "vy", "vz", "wx", "wy", "wz"].iter().zip(rows) {
                    println!(
                        "{name} {}",
                        r.iter()
                            .map(|v| format!("{v:>10.6}"))
                            .collect::<Vec<_>>()
                            .join(" ")
                    );
                }
            }
        }
        Cmd::Ik(a) => {
            let json = a.json;
            let cfg = load(&a.robot).map_err(with(json))?;
            let chain = arm_chain(&cfg).map_err(with(json))?;
            if let Some(s) = &a.seed {
                check_q(&chain, s).map_err(with(json))?;
            }
            let p = validate::arm_point("position", [a.position[0], a.position[1], a.position[2]])
                .map_err(with(json))?;
            validate::angles(
                "pitch and roll",
                &[a.pitch, a.roll].into_iter().flatten().collect::<Vec<_>>(),
            )
            .map_err(with(json))?;
            let ac = cfg
                .arm
                .as_ref()
                .map(|x| (x.ik_position_tolerance, x.ik_orientation_tolerance, x.ik))
                .unwrap_or((1e-5, 1e-5, IkKind::Numerical));
            let opts = IkOptions {
                position_tolerance: ac.0,
                orientation_tolerance: ac.1,
                ..Default::default()
            };
            let result = if let Some(pitch) = a.pitch {
                LocobotIk::from_chain(&chain)
                    .and_then(|s| {
                        s.solve_pitch_roll(
                            &chain,
                            &p,
                            pitch,
                            a.roll.unwrap_or(0.0),
                            a.seed.as_deref(),
                        )
                    })
                    .map_err(ferrobot::Error::from)
            } else {
                let o = match (&a.quaternion, &a.rpy) {
                    (Some(q), _) => Orientation::Quaternion([q[0], q[1], q[2], q[3]]),
                    (None, Some(r)) => Orientation::YawPitchRoll([r[2], r[1], r[0]]),
                    (None, None) => {
                        return Err((
                            ferrobot::Error::Usage(
                                "give an orientation: --quaternion, --rpy or --pitch".into(),
                            ),
                            json,
                        ))
                    }
                };
                o.to_quaternion().and_then(|rot| {
                    let target = Isometry3::from_parts(Translation3::from(p), rot);
                    let solver: Box<dyn IkSolver> = match ac.2 {
                        IkKind::LocobotPitchRoll => Box::new(LocobotIk::from_chain(&chain)?),
                        IkKind::Numerical => Box::new(NumericalIk),
                    };
                    Ok(solver.solve(&chain, &target, a.seed.as_deref(), &opts)?)
                })
            };
            let q = result.map_err(with(json))?;
            if json {
                println!("{}", json!({"success": true, "joints": q}));
            } else {
                println!(
                    "{}",
                    q.iter()
                        .map(|v| format!("{v:.6}"))
                        .collect::<Vec<_>>()
                        .join(" ")
                );
            }
        }
        Cmd::Demo { robot } => demo(&robot).map_err(|e| (e, false))?,
        Cmd::BaseMove {
            robot,
            relative,
            controller,
            smooth,
            open_loop,
            seed,
            json,
        } => base_move(
            &robot,
            [relative[0], relative[1], relative[2]],
            controller.as_deref(),
            smooth,
            open_loop,
            seed,
            json,
        )
        .map_err(with(json))?,
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
        } => {
            validate::count("trials", trials, 1..=MAX_TRIALS).map_err(with(json))?;
            bench_base(robot, trials, seed, json, &plot_dir, calibrate).map_err(with(json))?
        }
        Cmd::CalibrateOdometry { robot, seed, json } => {
            calibrate_odometry(&robot, seed, json).map_err(with(json))?
        }
        Cmd::SimFirmware { robot, link, seed } => {
            let cfg = load(&robot).map_err(|e| (e, true))?;
            let sim = ferrobot_sim::LockstepSim::with(
                ferrobot::backend::sim::sim_robot(&cfg),
                cfg.firmware_profile(),
                seed,
            );
            ferrobot_sim::serve::run_firmware_server(sim, &cfg.name, link).map_err(|e| {
                let e = match e {
                    ferrobot_sim::serve::ServeError::LinkExists(path) => {
                        ferrobot::Error::PathExists { path }
                    }
                    e => ferrobot::Error::Link(e.to_string()),
                };
                (e, true)
            })?;
        }
    }
    Ok(())
}

fn base_move(
    robot: &str,
    target: [f64; 3],
    controller: Option<&str>,
    smooth: bool,
    open_loop: bool,
    seed: u64,
    json: bool,
) -> ferrobot::Result<()> {
    let controller = controller.map(str::parse::<BaseController>).transpose()?;
    let bot = ferrobot_cli::bench_base::base_robot(robot, seed, None)?;
    let opts = GoalOptions {
        controller,
        smooth,
        close_loop: !open_loop,
        ..Default::default()
    };
    let r = bot.base()?.go_to_relative_with(target, opts)?.wait();
    let odometry = bot.base()?.get_state()?;
    let truth = bot
        .simulator()
        .and_then(|s| s.base_truth())
        .unwrap_or([f64::NAN; 3]);
    if json {
        let mut o = json!({
            "success": r.is_ok(),
            "target": target,
            "odometry": odometry,
            "ground_truth": truth,
        });
        if let Err(e) = &r {
            o["error"] = json!(e.to_string());
        }
        println!("{o}");
        return Ok(());
    }
    println!("target       {:?}", round(&target));
    println!("odometry     {:?}", round(&odometry));
    println!("ground truth {:?}", round(&truth));
    r
}

/// The calibration as JSON.
fn calibration_json(c: &ferrobot_cli::bench_base::OdometryCalibration) -> serde_json::Value {
    let g = |g: &ferrobot::odometry_calibration::WheelGeometry| json!({"left_radius": g.left_radius, "right_radius": g.right_radius, "track": g.track});
    json!({
        "nominal": g(&c.nominal),
        "estimate": g(&c.estimate),
        "runs": c.runs,
        "residual_nominal": {"position_m": c.residual_nominal.0, "heading_rad": c.residual_nominal.1},
        "residual": {"position_m": c.residual.0, "heading_rad": c.residual.1},
    })
}

/// The calibration as text, ending with the configuration line.
fn calibration_text(c: &ferrobot_cli::bench_base::OdometryCalibration) -> String {
    let (n, e) = (&c.nominal, &c.estimate);
    let pct = |x: f64, y: f64| 100.0 * (x / y - 1.0);
    format!(
        "odometry calibration from {} runs measured by ground truth:\n\
         - left radius  {:.5} m ({:+.2} % of nominal {:.5})\n\
         - right radius {:.5} m ({:+.2} % of nominal {:.5})\n\
         - track        {:.5} m ({:+.2} % of nominal {:.5})\n\
         - RMS misfit per run: nominal {:.1} mm / {:.2} deg, calibrated {:.1} mm / {:.2} deg\n\
         [base] line: odometry = {{ left_radius = {:.6}, right_radius = {:.6}, track = {:.6} }}",
        c.runs,
        e.left_radius,
        pct(e.left_radius, n.left_radius),
        n.left_radius,
        e.right_radius,
        pct(e.right_radius, n.right_radius),
        n.right_radius,
        e.track,
        pct(e.track, n.track),
        n.track,
        c.residual_nominal.0 * 1000.0,
        c.residual_nominal.1.to_degrees(),
        c.residual.0 * 1000.0,
        c.residual.1.to_degrees(),
        e.left_radius,
        e.right_radius,
        e.track
    )
}

fn calibrate_odometry(robot: &str, seed: u64, json: bool) -> ferrobot::Result<()> {
    let c = ferrobot_cli::bench_base::calibrate_odometry(robot, seed)?;
    if json {
        let mut o = calibration_json(&c);
        o["robot"] = json!(robot);
        o["seed"] = json!(seed);
        println!("{o}");
    } else {
        println!("{robot}, seed {seed}: {}", calibration_text(&c));
    }
    Ok(())
}

fn bench_base(
    robots: Vec<String>,
    trials: usize,
    seed: u64,
    json: bool,
    plot_dir: &std::path::Path,
    calibrate: bool,
) -> ferrobot::Result<()> {
    use ferrobot_cli::bench_base::{self as bb, Category, CircleRun};
    use ferrobot_cli::plot::{Canvas, COLOURS};
    let robots = if robots.is_empty() {
        vec!["locobot".to_string(), "locobot_lite".to_string()]
    } else {
        robots
    };
    std::fs::create_dir_all(plot_dir)?;
    for robot in robots {
        let calibration = if calibrate {
            Some(bb::calibrate_odometry(&robot, seed + 1000)?)
        } else {
            None
        };
        let geometry = calibration.as_ref().map(|c| c.estimate);
        // Every (controller, category, target, trial), run on all cores; each is seeded, so
        // the order of execution does not change the results.
        let mut jobs = Vec::new();
        for c in BaseController::ALL {
            for cat in Category::ALL {
                for target in cat.targets() {
                    for k in 0..trials {
                        jobs.push((c, cat, target, seed + k as u64));
                    }
                }
            }
        }
        let bar = indicatif::ProgressBar::new(jobs.len() as u64 + CircleRun::ALL.len() as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{msg:>14} [{bar:40}] {pos}/{len} {elapsed}")
                .expect("template")
                .progress_chars("=> "),
        );
        bar.set_message(robot.clone());
        let next = std::sync::atomic::AtomicUsize::new(0);
        let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
        let results: Vec<ferrobot::Result<bb::Trial>> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..threads)
                .map(|_| {
                    s.spawn(|| {
                        let mut out = Vec::new();
                        loop {
                            let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let Some(&(c, cat, target, sd)) = jobs.get(i) else {
                                break;
                            };
                            out.push((
                                i,
                                bb::run_trial(
                                    &robot,
                                    c,
                                    cat,
                                    target,
                                    GoalOptions::default(),
                                    sd,
                                    geometry,
                                ),
                            ));
                            bar.inc(1);
                        }
                        out
                    })
                })
                .collect();
            let mut all: Vec<_> = handles
                .into_iter()
                .flat_map(|h| h.join().expect("trial thread"))
                .collect();
            all.sort_by_key(|(i, _)| *i);
            all.into_iter().map(|(_, r)| r).collect()
        });
        let trials_done = results.into_iter().collect::<ferrobot::Result<Vec<_>>>()?;
        let rows = bb::summarize(&trials_done);
        // The circle comparison: the whole lap, and a zoom on its end (±6 cm).
        let reference: Vec<[f64; 2]> = bb::paper_circle()
            .states
            .iter()
            .map(|s| [s[0], s[1]])
            .collect();
        let end_ref = reference.last().copied().unwrap_or([0.0; 2]);
        let mut canvas = Canvas::new(800, [0.0, 0.4], 1.2, 0.1)?;
        let mut zoom = Canvas::new(800, end_ref, 0.12, 0.01)?;
        let mut entries = vec![(COLOURS[0].1, "reference circle (r = 0.4 m)".to_string())];
        let mut legend = vec![format!("{}: reference circle (r = 0.4 m)", COLOURS[0].0)];
        let mut ends = Vec::new();
        let runs = CircleRun::ALL.len();
        for (k, run) in CircleRun::ALL.into_iter().enumerate() {
            let (path, end) = bb::circle_path(&robot, run, seed, geometry)?;
            // Earlier series wider, so that identical paths stay visible.
            let width = 2 + 2 * (runs - 1 - k);
            canvas.polyline(&path, COLOURS[k + 1].1, width);
            zoom.polyline(&path, COLOURS[k + 1].1, 2 * width);
            let label = format!(
                "{}: ends {:.1} mm from the reference end",
                run.name(),
                end * 1000.0
            );
            legend.push(format!("{}: {label}", COLOURS[k + 1].0));
            entries.push((COLOURS[k + 1].1, label));
            ends.push((run.name(), end));
            bar.inc(1);
        }
        // The reference last, thin, on top.
        canvas.polyline(&reference, COLOURS[0].1, 1);
        zoom.polyline(&reference, COLOURS[0].1, 2);
        let what = if calibrate {
            ", calibrated odometry"
        } else {
            ""
        };
        canvas.legend(&entries);
        canvas.caption(&format!(
            "{robot}{what}: circle tracking, ground truth; grid 0.1 m"
        ));
        zoom.legend(&entries);
        zoom.caption(&format!("{robot}{what}: the end of the lap; grid 1 cm"));
        let suffix = if calibrate { "_calibrated" } else { "" };
        let png = plot_dir.join(format!("circle_{robot}{suffix}.png"));
        let png_zoom = plot_dir.join(format!("circle_{robot}{suffix}_end.png"));
        canvas.save(&png)?;
        zoom.save(&png_zoom)?;
        bar.finish_and_clear();
        if json {
            let mut o = bb::json(&robot, &rows);
            o["circle_plot"] = json!(png.display().to_string());
            o["circle_plot_end"] = json!(png_zoom.display().to_string());
            o["circle_end_error_m"] = json!(ends
                .iter()
                .map(|(n, e)| json!({"run": n, "error": e}))
                .collect::<Vec<_>>());
            o["seed"] = json!(seed);
            o["trials_per_target"] = json!(trials);
            if let Some(c) = &calibration {
                o["odometry_calibration"] = calibration_json(c);
            }
            println!("{o}");
        } else {
            if let Some(c) = &calibration {
                println!("{robot}, seed {}: {}\n", seed + 1000, calibration_text(c));
            }
            println!("{}", bb::markdown(&robot, trials, seed, &rows));
            println!(
                "Circle tracking, ground truth, in {} (the end zoomed in {}):",
                png.display(),
                png_zoom.display()
            );
            for l in legend {
                println!("- {l}");
            }
            println!();
        }
    }
    Ok(())
}

/// The quickstart, narrated.
fn demo(robot: &str) -> ferrobot::Result<()> {
    let wall = std::time::Instant::now();
    let bot = Robot::new(robot)?; // the in-process simulator
    println!("Ferrobot demo: simulated {robot} (firmware core and simulated plants in lockstep)");
    let arm = bot.arm()?;
    arm.set_joint_positions(&[0.4, 0.3, -0.5, 0.6, -0.3])?;
    println!("arm     joints {:?}", round(&arm.get_joint_angles()?));
    arm.set_ee_pose_pitch_roll([0.35, 0.0, 0.15], std::f64::consts::FRAC_PI_2, Some(0.0))?;
    let p = arm.get_ee_pose()?;
    println!(
        "arm     gripper pointing down at {:?} m",
        round(&p.position)
    );
    arm.move_ee_xyz([0.0, 0.0, 0.1], 0.01)?;
    println!(
        "arm     straight up 10 cm, now at {:?} m",
        round(&arm.get_ee_pose()?.position)
    );
    let gripper = bot.gripper()?;
    println!("gripper close -> {:?}", gripper.close()?);
    gripper.open()?;
    println!("gripper open  -> {:?}", gripper.get_state()?);
    let camera = bot.camera()?;
    camera.set_pan_tilt(0.5, 0.3)?;
    println!("camera  pan/tilt {:?} rad", round(&camera.get_state()?));
    bot.arm()?.go_home()?;
    bot.base()?.go_to_absolute([1.0, 1.0, 0.0])?;
    let odom = bot.base()?.get_state()?;
    let truth = bot
        .simulator()
        .and_then(|s| s.base_truth())
        .unwrap_or([f64::NAN; 3]);
    println!(
        "base    go_to_absolute([1, 1, 0]): odometry {:?}, ground truth {:?}",
        round(&odom),
        round(&truth)
    );
    let t = bot.time();
    println!(
        "done: {t:.1} s simulated in {:.2} s",
        wall.elapsed().as_secs_f64()
    );
    Ok(())
}

fn round(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| (x * 1000.0).round() / 1000.0).collect()
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
                println!(
                    "{}",
                    json!({"success": false, "error": msg, "input_error": true})
                );
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
                println!(
                    "{}",
                    json!({"success": false, "error": e.to_string(), "input_error": input})
                );
            } else {
                eprintln!("error: {e}");
            }
            ExitCode::from(if input { 2 } else { 1 })
        }
    }
}
