//! `ferrobot arm-plan`: one planned arm motion on the simulator, around the scene's objects.
//! The arm plans from where it starts (or from `--from`, reached by a planned motion first) to
//! `--to` (rad), executes the trajectory, and the command prints what the planner found and
//! what the executed motion did in the physics engine: contacts between the arm's links and
//! anything, and how far the arm ended from the goal; `--png` draws the motion (its picture:
//! `docs/design/cli.md`).

use ferrobot::arm_plan::PlanningOptions;
use ferrobot::perception::{io, RgbImage};
use ferrobot::Backend;
use ferrobot::Robot;
use ferrobot_cli::plot::{pen_px, segment_px, COLOURS};
use ferrobot_sim::body::RobotBody;
use ferrobot_sim::lockstep::{LockstepSim, Truth};
use ferrobot_sim::render::{PinholeCamera, RenderedImage, Renderer};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use super::common::print_json;

/// Poses of the arm drawn in the picture (the first, the last and evenly between).
pub const POSES: usize = 6;
/// Simulated time between recorded states of the executed motion, s.
const RECORD_DT: f64 = 0.02;
/// Picture size, px.
const WIDTH: u32 = 800;
const HEIGHT: u32 = 600;
/// Opacity of the earlier poses drawn over the last one.
const GHOST: f32 = 0.55;
/// The plots' colours ([`COLOURS`]) of the gripper's path (red), and the tints of the first
/// and the last of the earlier poses (blue, orange).
const PATH: [u8; 3] = COLOURS[1].1;
const TINTS: [[u8; 3]; 2] = [COLOURS[2].1, COLOURS[4].1];

/// `arm-plan --json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct ArmPlanJson {
    /// Contacts of the arm's links recorded by the physics engine during the motion.
    contacts: usize,
    /// Duration of the planned trajectory, s.
    duration_s: f64,
    /// Largest joint error at the end of the executed motion, rad.
    final_error_rad: f64,
    /// The planned joints, in the order of `path`.
    joints: Vec<String>,
    /// Room the path keeps from the scene's objects, m (the padding asked for, less where an
    /// end is nearer).
    padding_m: f64,
    /// Joint-space length of the path, rad.
    path_length_rad: f64,
    /// The path's waypoints, rad.
    path: Vec<Vec<f64>>,
    /// Planning time (search, shortcutting and time parameterisation), ms.
    planning_ms: f64,
    /// Scene objects added to the arm's planning scene.
    scene_objects: usize,
}

/// `ferrobot arm-plan`'s arguments: what to plan.
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Scene name or path.
    #[arg(long, default_value = "tabletop")]
    pub scene: String,
    /// Start configuration, rad (reached first by a planned motion; default: as the robot
    /// starts).
    #[arg(long, num_args = 1.., allow_negative_numbers = true)]
    pub from: Option<Vec<f64>>,
    /// Goal configuration, rad.
    #[arg(long, num_args = 1.., allow_negative_numbers = true, required = true)]
    pub to: Vec<f64>,
    /// Room kept between the arm and the scene's objects along the motion, m.
    #[arg(long, default_value_t = ferrobot::arm_plan::DEFAULT_PADDING)]
    pub padding: f64,
    /// Seed of the plants.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Draw the executed motion into this PNG.
    #[arg(long)]
    pub png: Option<std::path::PathBuf>,
    /// Print one JSON object: `{"contacts", "duration_s", "final_error_rad", "joints",
    /// "padding_m", "path", "path_length_rad", "planning_ms", "scene_objects"}`.
    #[arg(long)]
    pub json: bool,
}

/// The arm's joints (indices in the URDF's tree), the links they move (watched for
/// contacts) and the end effector's link.
struct ArmLinks {
    joints: Vec<usize>,
    watched: Vec<String>,
    ee: usize,
}

/// Plan, execute, report, draw.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    check(a)?;
    let bot = super::common::robot_builder(&a.robot)
        .scene(&a.scene)
        .backend(Backend::Sim {
            seed: a.seed,
            realtime: false,
        })
        .build()?;
    let arm = bot.arm()?;
    let objects = arm.add_scene_objects()?;
    let cfg = bot.config().clone();
    let arm_cfg = cfg
        .arm
        .as_ref()
        .ok_or_else(|| ferrobot::Error::NoComponent {
            robot: cfg.name.clone(),
            component: "arm",
        })?;
    let links = arm_links(&bot, &arm_cfg.joints, &arm_cfg.ee_frame)?;
    simulator(&bot)?
        .hw
        .watch_robot_contacts(&links.watched)
        .map_err(|e| ferrobot::Error::Usage(e.to_string()))?;
    if let Some(q) = a.from.as_deref() {
        arm.set_joint_positions(q)?;
    }
    // Reaching the start is not part of the motion reported.
    simulator(&bot)?.hw.take_robot_contacts();
    let plan = arm.plan_to(
        &a.to,
        &PlanningOptions {
            padding: a.padding,
            ..PlanningOptions::default()
        },
    )?;
    let motion = arm.execute(&plan)?;
    let mut record = record_motion(&bot, plan.duration(), || motion.is_finished())?;
    motion.wait()?;
    record.push(bot.truth()?);
    let contacts: Vec<String> = simulator(&bot)?
        .hw
        .take_robot_contacts()
        .iter()
        .map(|c| {
            format!(
                "  {} touched {} from {:.3} s to {:.3} s, {:.1} mm deep at most",
                c.link,
                c.body,
                c.first_us as f64 * 1e-6,
                c.last_us as f64 * 1e-6,
                c.max_depth * 1e3
            )
        })
        .collect();
    let final_error = largest_error(&links.joints, &a.to, &record);
    if let Some(path) = a.png.as_deref() {
        let sim = simulator(&bot)?;
        let body = body_of(&sim)?;
        let renderer = Renderer::new(sim.scene(), Some(body));
        let img = picture(&renderer, &record, links.ee)?;
        drop(sim);
        io::write_rgb_png(path, &img)?;
    }
    let j = ArmPlanJson {
        contacts: contacts.len(),
        duration_s: plan.duration(),
        final_error_rad: final_error,
        joints: plan.joints.clone(),
        padding_m: plan.padding,
        path_length_rad: ferrobot::planning::planner::path_length(&plan.path),
        path: plan.path.clone(),
        planning_ms: plan.planning_time.as_secs_f64() * 1e3,
        scene_objects: objects,
    };
    report(a, &cfg.name, &j, &contacts);
    Ok(())
}

/// The arguments refused before the simulator starts.
fn check(a: &Args) -> ferrobot::Result<()> {
    ferrobot::validate::in_range(
        "padding (m)",
        a.padding,
        0.0,
        ferrobot::planning::MAX_PADDING,
    )?;
    ferrobot::validate::angles("--to", &a.to)?;
    if let Some(q) = a.from.as_deref() {
        ferrobot::validate::angles("--from", q)?;
    }
    Ok(())
}

/// The arm's joints (`joints`), the links they move and the end effector's link (`ee_frame`)
/// in the simulated body.
fn arm_links(bot: &Robot, joints: &[String], ee_frame: &str) -> ferrobot::Result<ArmLinks> {
    let sim = simulator(bot)?;
    let body = body_of(&sim)?;
    let tree = &body.tree;
    let joints: Vec<usize> = joints
        .iter()
        .map(|j| {
            tree.joint_index(j)
                .ok_or_else(|| ferrobot::Error::Usage(format!("no joint {j} in the URDF")))
        })
        .collect::<ferrobot::Result<_>>()?;
    let names: Vec<String> = tree.links().map(str::to_string).collect();
    let watched: Vec<String> = tree
        .links_moved_by(&joints)
        .into_iter()
        .map(|l| names[l].clone())
        .collect();
    let ee = tree
        .link_index(ee_frame)
        .ok_or_else(|| ferrobot::Error::Usage(format!("no link {ee_frame} in the URDF")))?;
    Ok(ArmLinks {
        joints,
        watched,
        ee,
    })
}

/// The world's ground truth now and every [`RECORD_DT`] until `finished` says so (at most
/// the plan's `duration` and 30 s more).
fn record_motion(
    bot: &Robot,
    duration: f64,
    finished: impl Fn() -> bool,
) -> ferrobot::Result<Vec<Truth>> {
    let mut record: Vec<Truth> = vec![bot.truth()?];
    // The motion ends within its duration and the executor's timeout; this only bounds a
    // motion that would not.
    let limit = duration + 30.0;
    let mut waited = 0.0;
    while !finished() && waited < limit {
        bot.wait(RECORD_DT)?;
        waited += RECORD_DT;
        record.push(bot.truth()?);
    }
    Ok(record)
}

/// The largest error of the arm's `joints` from the goal `to` in the last recorded state, rad.
fn largest_error(joints: &[usize], to: &[f64], record: &[Truth]) -> f64 {
    let last = record.last().map(|t| t.joints.clone()).unwrap_or_default();
    joints
        .iter()
        .zip(to)
        .map(|(&j, &g)| (last[j] - g).abs())
        .fold(0.0, f64::max)
}

/// Print what the planner found and what the executed motion did (`contacts`, one line
/// each), or the JSON object with `--json`.
fn report(a: &Args, robot: &str, j: &ArmPlanJson, contacts: &[String]) {
    if a.json {
        print_json(j);
        return;
    }
    say!(
        "{} in {}: planned in {:.1} ms around {} scene objects, {:.1} mm from them at least: {} waypoints, {:.3} rad, a {:.2} s trajectory",
        robot,
        a.scene,
        j.planning_ms,
        j.scene_objects,
        j.padding_m * 1e3,
        j.path.len(),
        j.path_length_rad,
        j.duration_s
    );
    say!(
        "executed: {} contacts of the arm in the physics engine; ended {:.4} rad from the goal",
        j.contacts,
        j.final_error_rad
    );
    for c in contacts {
        say!("{c}");
    }
    if let Some(p) = a.png.as_deref() {
        say!("wrote {}", p.display());
    }
}

/// The simulator behind `bot` (its guard holds the robot's link: drop it before calling the
/// robot again).
fn simulator(bot: &Robot) -> ferrobot::Result<impl std::ops::DerefMut<Target = LockstepSim> + '_> {
    bot.simulator()
        .ok_or_else(|| ferrobot::Error::Usage("arm-plan needs the simulator".into()))
}

/// The simulated robot's body (links, meshes, link tree).
fn body_of(sim: &LockstepSim) -> ferrobot::Result<&std::sync::Arc<RobotBody>> {
    sim.body()
        .ok_or_else(|| ferrobot::Error::Usage("the simulated robot has no body".into()))
}

/// The optical frame (x right, y down, z forward) of a camera at `eye` looking at `target`,
/// the world's z up.
fn look_at(eye: Point3<f64>, target: Point3<f64>) -> Isometry3<f64> {
    let z = (target - eye).normalize();
    let x = z.cross(&Vector3::z()).normalize();
    let y = z.cross(&x);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Isometry3::from_parts(
        Translation3::from(eye.coords),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// The executed motion (`record`, evenly spaced states) drawn from beside the robot: the arm
/// at [`POSES`] times, the earlier ones faded over the last, and the path of link `ee`.
fn picture(renderer: &Renderer, record: &[Truth], ee: usize) -> ferrobot::Result<RgbImage> {
    let first = record
        .first()
        .ok_or_else(|| ferrobot::Error::Usage("nothing was recorded".into()))?;
    let path: Vec<Point3<f64>> = record
        .iter()
        .map(|t| Point3::from(t.links[ee].translation.vector))
        .collect();
    // Framing: the robot's root and the gripper's path, seen from the front left and above
    // the root's heading, far enough for all of it.
    let root = Point3::from(first.root.translation.vector);
    let mut target = path.iter().fold(root.coords, |s, p| s + p.coords);
    target /= (path.len() + 1) as f64;
    let target = Point3::from(target);
    let radius = path
        .iter()
        .chain(std::iter::once(&root))
        .map(|p| (p - target).norm())
        .fold(0.3, f64::max);
    let heading = first.root.rotation * Vector3::x();
    let left = first.root.rotation * Vector3::y();
    let dir = (heading * 0.75 + left * 0.65 + Vector3::z() * 0.6).normalize();
    let eye = target + dir * (2.0 * radius + 0.35);
    let f = 0.9 * f64::from(WIDTH);
    let camera = PinholeCamera {
        width: WIDTH,
        height: HEIGHT,
        fx: f,
        fy: f,
        cx: f64::from(WIDTH) / 2.0,
        cy: f64::from(HEIGHT) / 2.0,
        pose: look_at(eye, target),
    };
    let is_robot = |img: &RenderedImage, i: usize| {
        renderer
            .label_name(img.labels[i])
            .is_some_and(|n| n.starts_with("robot/"))
    };
    let pick = |k: usize| &record[k * (record.len() - 1) / (POSES - 1)];
    let mut out = RenderedImage::new(WIDTH, HEIGHT);
    let last = pick(POSES - 1);
    renderer.render(&camera, &last.bodies, &last.links, &mut out);
    let mut ghost = RenderedImage::new(WIDTH, HEIGHT);
    for k in 0..POSES - 1 {
        let t = pick(k);
        let f = k as f32 / (POSES - 2).max(1) as f32;
        let tint: [f32; 3] = std::array::from_fn(|c| {
            let (a, b) = (f32::from(TINTS[0][c]), f32::from(TINTS[1][c]));
            a + (b - a) * f
        });
        renderer.render(&camera, &t.bodies, &t.links, &mut ghost);
        for i in 0..out.depth.len() {
            let in_front = out.depth[i] <= 0.0 || ghost.depth[i] < out.depth[i] - 1e-3;
            if is_robot(&ghost, i) && in_front {
                let px = 3 * i..3 * i + 3;
                for ((o, &b), &t) in out.rgb[px.clone()]
                    .iter_mut()
                    .zip(&ghost.rgb[px])
                    .zip(&tint)
                {
                    let g = 0.5 * f32::from(b) + 0.5 * t;
                    *o = ((1.0 - GHOST) * f32::from(*o) + GHOST * g).round() as u8;
                }
            }
        }
    }
    let (w, h) = (WIDTH as usize, HEIGHT as usize);
    let pixels: Vec<(f64, f64)> = path.iter().filter_map(|p| camera.project(p)).collect();
    for s in pixels.windows(2) {
        segment_px(s[0], s[1], (w as f64, h as f64), 2.0, |c, r| {
            // A pen 3 px wide.
            pen_px((c.round() as i64, r.round() as i64), 1, (w, h), |cc, rr| {
                let i = 3 * (rr * w + cc);
                out.rgb[i..i + 3].copy_from_slice(&PATH);
            });
        });
    }
    Ok(RgbImage::new(WIDTH, HEIGHT, out.rgb)?)
}
