//! `ferrobot slam`: visual SLAM on a scripted drive or a recorded sequence.
//!
//! * `ferrobot slam ROBOT --scene SCENE --route NAME --seed K --out DIR`: the simulated robot
//!   drives the route ([`super::route`]) while SLAM runs on every camera frame with the wheel
//!   odometry; writes `estimate.tum`, `ground_truth.tum` and `odometry.tum` (pose of
//!   `base_link` in the world per camera frame, TUM format; the estimate as the final map has
//!   it), `map.yaml` + `map.png` (map_server), `cloud.ply` (the dense coloured map) and
//!   `trajectory.png` (the map with the three trajectories), and `map.slam` (the SLAM map, which
//!   `--map FILE` localises in on a later drive, from a start it is not told).
//! * `ferrobot slam --dataset DIR [--out OUT]`: the same SLAM, all six motions, no odometry,
//!   on a sequence in the TUM RGB-D layout ([`ferrobot::slam::Dataset`]); writes
//!   `OUT/estimate.tum` (camera poses) and `OUT/cloud.ply`.

use std::path::Path;
use std::time::Instant;

use ferrobot::nav::{Cell, MapImage};
use ferrobot::slam::optimise::planar;
use ferrobot::slam::{
    ate, map_iou, write_tum, Dataset, GridSettings, RgbdInput, Slam, SlamSettings, Stamped,
    TrackState,
};
use ferrobot_cli::plot::Canvas;
use ferrobot_sim::floor_plan::OBSTACLE_BAND;
use nalgebra::Isometry3;
use serde::Serialize;

use super::common::print_json;
use super::route::Drive;

/// `ferrobot slam`'s arguments: a drive (ROBOT) or a sequence (`--dataset`).
#[derive(clap::Args)]
pub struct Args {
    /// Robot name or configuration path (not with --dataset).
    #[arg(required_unless_present = "dataset", conflicts_with = "dataset")]
    pub robot: Option<String>,
    /// A recorded RGB-D sequence in the TUM RGB-D layout (rgb.txt, depth.txt, PNGs,
    /// camera.yaml, groundtruth.txt when present).
    #[arg(long)]
    pub dataset: Option<std::path::PathBuf>,
    /// Scene name or path.
    #[arg(long, default_value = "apartment", conflicts_with = "dataset")]
    pub scene: String,
    /// Route of the scene to drive.
    #[arg(long, default_value = "loop", conflicts_with = "dataset")]
    pub route: String,
    /// Seed of the plants' and the camera's noise.
    #[arg(long, default_value_t = 1, conflicts_with = "dataset")]
    pub seed: u64,
    /// Localise in this saved SLAM map (an earlier drive's map.slam) from a start SLAM is
    /// not told.
    #[arg(long, conflicts_with = "dataset")]
    pub map: Option<std::path::PathBuf>,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: Option<std::path::PathBuf>,
    /// Print one JSON object: `{"ate_rmse_m", "frames", "ms_per_frame": {"mean", "p95"},
    /// "occupancy_iou", ...}`.
    #[arg(long)]
    pub json: bool,
}

/// A simulated drive to run SLAM on.
struct DriveArgs<'a> {
    /// Robot name or configuration path.
    robot: &'a str,
    /// Scene name or path.
    scene: &'a str,
    /// Route name in the scene.
    route: &'a str,
    /// Seed of the plants' and the camera's noise.
    seed: u64,
    /// A map saved by an earlier drive to localise in (the start is then unknown).
    saved: Option<&'a Path>,
}

/// Time statistics, ms.
#[derive(Serialize)]
struct Ms {
    mean: f64,
    p95: f64,
}

/// `slam --json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct SlamJson {
    /// The ATE of the poses as tracked, before later loop closures corrected them, m.
    #[serde(skip_serializing_if = "Option::is_none")]
    ate_online_rmse_m: Option<f64>,
    /// Root mean square of the position error after rigid alignment (TUM's ATE), m; only with
    /// a ground truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    ate_rmse_m: Option<f64>,
    /// Frames processed.
    frames: usize,
    /// Keyframes in the map.
    keyframes: usize,
    /// Loops closed.
    loops_closed: usize,
    /// With a saved map: seconds of driving before the robot found itself in it.
    #[serde(skip_serializing_if = "Option::is_none")]
    localised_after_s: Option<f64>,
    /// The longest stretch of frames SLAM had no pose for (lost, no odometry to carry it):
    /// frames ...
    longest_loss_frames: usize,
    /// ... and seconds, from its first lost frame to its last.
    longest_loss_s: f64,
    /// Stretches of frames without a pose (each written to no output file).
    losses: usize,
    /// Frames matched to nothing (carried by the odometry, or unconfirmed).
    lost_frames: usize,
    /// Landmarks kept per frame matched to the map: the median ...
    median_inliers: usize,
    /// ... and the least (`tracking.tsv` has every frame's, with its residual).
    min_inliers: usize,
    /// SLAM's processing time per frame on one core, ms.
    ms_per_frame: Ms,
    /// Intersection over union of the map's occupied cells with the ground-truth floor
    /// plan's (a wall one cell off still counts); drives only.
    #[serde(skip_serializing_if = "Option::is_none")]
    occupancy_iou: Option<f64>,
    /// Intersection over union of the map's free cells with the floor plan's; drives only.
    #[serde(skip_serializing_if = "Option::is_none")]
    occupancy_iou_free: Option<f64>,
    /// The wheel odometry's own ATE over the same frames, m (what SLAM improves on); drives
    /// only.
    #[serde(skip_serializing_if = "Option::is_none")]
    odometry_ate_rmse_m: Option<f64>,
    /// Frames found again by relocalisation.
    relocalised_frames: usize,
}

impl Tally {
    /// The inliers of the frames matched to the map: median and least (0 and 0 if none).
    fn inliers(&self) -> (usize, usize) {
        let mut n: Vec<usize> = self
            .quality
            .iter()
            .filter(|q| matches!(q.1, TrackState::Tracking | TrackState::Relocalised))
            .map(|q| q.3)
            .collect();
        n.sort_unstable();
        (
            n.get(n.len() / 2).copied().unwrap_or(0),
            n.first().copied().unwrap_or(0),
        )
    }

    /// `tracking.tsv`: a line per frame (time s, state, features, inliers, residual in
    /// standard deviations).
    fn write_quality(&self, path: &Path) -> ferrobot::Result<()> {
        let mut text = String::from("# time_s\tstate\tfeatures\tinliers\tresidual_sigma\n");
        for (t, s, f, i, r) in &self.quality {
            text.push_str(&format!("{t:.6}\t{s:?}\t{f}\t{i}\t{r:.3}\n"));
        }
        std::fs::write(path, text)?;
        Ok(())
    }
}

/// The longest stretch of frames `slam` had no pose for: frames and seconds.
fn longest_loss(slam: &Slam) -> (usize, f64) {
    slam.tracking_gaps()
        .iter()
        .max_by_key(|g| g.2)
        .map_or((0, 0.0), |g| (g.2, g.1 - g.0))
}

/// Per-frame bookkeeping of a run.
#[derive(Default)]
struct Tally {
    /// The first frame found in the map by relocalisation.
    first_found: Option<usize>,
    ms: Vec<f64>,
    lost: usize,
    relocalised: usize,
    online: Vec<Stamped>,
    /// Per frame: time, state, features, inliers, residual (`tracking.tsv`).
    quality: Vec<(f64, TrackState, usize, usize, f64)>,
}

impl Tally {
    fn track(&mut self, slam: &mut Slam, input: &RgbdInput<'_>) -> ferrobot::Result<()> {
        let clock = Instant::now();
        let r = slam.track(input)?;
        self.ms.push(clock.elapsed().as_secs_f64() * 1e3);
        self.quality
            .push((input.time, r.state, r.features, r.inliers, r.residual));
        match r.state {
            TrackState::Odometry | TrackState::Lost => self.lost += 1,
            TrackState::Relocalised => {
                self.relocalised += 1;
                self.first_found.get_or_insert(self.ms.len() - 1);
            }
            _ => {}
        }
        // A lost frame has no pose to score.
        if r.state != TrackState::Lost {
            self.online.push(Stamped {
                time: input.time,
                pose: r.pose,
            });
        }
        Ok(())
    }

    fn ms(&self) -> Ms {
        let mut sorted = self.ms.clone();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len().max(1);
        Ms {
            mean: sorted.iter().sum::<f64>() / n as f64,
            p95: sorted
                .get((n as f64 * 0.95) as usize)
                .copied()
                .unwrap_or(0.0),
        }
    }
}

/// Run SLAM and write the files.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let out = match (&a.robot, &a.dataset) {
        (_, Some(dir)) => dataset(dir, a.out.as_deref())?,
        (Some(robot), None) => {
            let out = a
                .out
                .as_deref()
                .ok_or_else(|| ferrobot::Error::Usage("a drive needs --out DIR".into()))?;
            let d = DriveArgs {
                robot,
                scene: &a.scene,
                route: &a.route,
                seed: a.seed,
                saved: a.map.as_deref(),
            };
            drive(&d, out)?
        }
        (None, None) => return Err(ferrobot::Error::Usage("name a ROBOT or a --dataset".into())),
    };
    if a.json {
        print_json(&out);
    } else {
        let cm = |x: Option<f64>| x.map_or("-".into(), |v| format!("{:.2} cm", 100.0 * v));
        say!(
            "{} frames, {} keyframes, {} loops closed, {} frames lost; ATE RMSE {} (odometry alone {}); {:.1} ms per frame (p95 {:.1}); occupancy IoU {}",
            out.frames,
            out.keyframes,
            out.loops_closed,
            out.lost_frames,
            cm(out.ate_rmse_m),
            cm(out.odometry_ate_rmse_m),
            out.ms_per_frame.mean,
            out.ms_per_frame.p95,
            out.occupancy_iou.map_or("-".into(), |v| format!("{v:.3}")),
        );
    }
    Ok(())
}

/// What a drive recorded: SLAM after the last frame, the per-frame tally, and the true and
/// odometry poses of `base_link` in the world per frame.
struct Recorded {
    slam: Slam,
    tally: Tally,
    gt: Vec<Stamped>,
    odo: Vec<Stamped>,
    /// The first frame's time, s.
    first_time: Option<f64>,
}

/// Drive the route with SLAM on every frame; write the files to `out`.
fn drive(a: &DriveArgs, out: &Path) -> ferrobot::Result<SlamJson> {
    let d = Drive::new(a.robot, a.scene, a.route, a.seed)?;
    std::fs::create_dir_all(out)?;
    let rec = record_drive(&d, a.saved)?;
    let Recorded {
        slam,
        mut tally,
        mut gt,
        mut odo,
        first_time,
    } = rec;
    let from = first_frame(a.saved, &tally)?;
    // Lost frames have no pose in the estimates: they are cut by time, the rest by frame.
    let t_from = tally.quality.get(from).map_or(f64::NEG_INFINITY, |q| q.0);
    let since = |poses: Vec<Stamped>| -> Vec<Stamped> {
        poses.into_iter().filter(|s| s.time >= t_from).collect()
    };
    let est = since(slam.trajectory());
    let gt = gt.split_off(from);
    let odo = odo.split_off(from);
    let online = since(std::mem::take(&mut tally.online));
    write_tum(&out.join("estimate.tum"), &est)?;
    tally.write_quality(&out.join("tracking.tsv"))?;
    write_tum(&out.join("ground_truth.tum"), &gt)?;
    write_tum(&out.join("odometry.tum"), &odo)?;
    let map = slam.map();
    map.save(&out.join("map.slam"))?;
    let grid = map
        .occupancy(&GridSettings::default())?
        .ok_or_else(|| ferrobot::Error::Usage("no keyframe: nothing was mapped".into()))?;
    grid.save(&out.join("map.yaml"))?;
    let iou = map_iou(&grid, &floor_plan(&d)?, 1)?;
    ferrobot::perception::io::write_ply(out.join("cloud.ply"), &map.cloud(0.02)?)?;
    let est_ate = ate(&est, &gt, 0.001)?.rmse;
    let odo_ate = ate(&odo, &gt, 0.001)?.rmse;
    let caption = format!(
        "{} in {}, route {}, seed {}: ATE {:.2} cm (wheel odometry {:.2} cm)",
        a.robot,
        a.scene,
        a.route,
        a.seed,
        100.0 * est_ate,
        100.0 * odo_ate
    );
    draw(
        &grid,
        &est,
        &gt,
        &odo,
        &caption,
        &out.join("trajectory.png"),
    )?;
    Ok(SlamJson {
        ate_online_rmse_m: Some(ate(&online, &gt, 0.001)?.rmse),
        ate_rmse_m: Some(est_ate),
        frames: tally.ms.len(),
        keyframes: map.keyframes().len(),
        loops_closed: slam.loops_closed(),
        localised_after_s: a
            .saved
            .and(gt.first().zip(first_time).map(|(g, t0)| g.time - t0)),
        longest_loss_frames: longest_loss(&slam).0,
        longest_loss_s: longest_loss(&slam).1,
        losses: slam.tracking_gaps().len(),
        lost_frames: tally.lost,
        median_inliers: tally.inliers().0,
        min_inliers: tally.inliers().1,
        ms_per_frame: tally.ms(),
        occupancy_iou: Some(iou.occupied),
        occupancy_iou_free: Some(iou.free),
        odometry_ate_rmse_m: Some(odo_ate),
        relocalised_frames: tally.relocalised,
    })
}

/// The first frame scored: each frame's pose is taken as the final map has it (loop closures
/// correct what came before); in a saved map, from the frame that found it.
fn first_frame(saved: Option<&Path>, tally: &Tally) -> ferrobot::Result<usize> {
    Ok(if saved.is_some() {
        tally.first_found.ok_or_else(|| {
            ferrobot::Error::Usage("the robot never found itself in the saved map".into())
        })?
    } else {
        0
    })
}

/// SLAM started (at the true start pose, or lost in the map `saved`) and run on every frame
/// of the drive `d`, with the true and odometry poses of each frame.
fn record_drive(d: &Drive, saved: Option<&Path>) -> ferrobot::Result<Recorded> {
    let radius = d
        .bot
        .config()
        .base
        .as_ref()
        .map_or(0.0, |b| b.footprint_radius);
    // The map's frame is the world's: SLAM starts at the robot's true start pose (the ground
    // truth is used for nothing else).
    let settings = SlamSettings::ground_robot(radius.max(ferrobot::slam::SELF_RADIUS));
    let k = d.bot.camera()?.intrinsics()?;
    let mut slam = match saved {
        // In a saved map the start is not told: SLAM must find it.
        Some(file) => Slam::with_map(settings, k, ferrobot::slam::Map::load(file)?)?,
        None => Slam::new(settings, k, planar(d.start))?,
    };
    let mut tally = Tally::default();
    let (mut gt, mut odo) = (Vec::new(), Vec::new());
    let mut first_time = None;
    d.run(|s| {
        first_time.get_or_insert(s.frame.time.as_secs_f64());
        let time = s.frame.time.as_secs_f64();
        tally.track(
            &mut slam,
            &RgbdInput {
                time,
                rgb: &s.frame.rgb,
                depth: &s.frame.depth,
                camera: s.frame.camera_pose,
                odometry: Some(s.odometry),
            },
        )?;
        gt.push(Stamped {
            time,
            pose: planar(s.truth),
        });
        odo.push(Stamped {
            time,
            pose: d.odometry_in_world(s.odometry),
        });
        Ok(())
    })?;
    Ok(Recorded {
        slam,
        tally,
        gt,
        odo,
        first_time,
    })
}

/// The scene's ground-truth floor plan (2 cm cells, [`OBSTACLE_BAND`]) as a map.
fn floor_plan(d: &Drive) -> ferrobot::Result<MapImage> {
    let plan = d.bot.scene().floor_plan(0.02, OBSTACLE_BAND, false)?;
    Ok(MapImage::from_occupied(
        plan.origin,
        plan.resolution,
        plan.width,
        plan.height,
        &plan.occupied,
    ))
}

fn dataset(dir: &Path, out: Option<&Path>) -> ferrobot::Result<SlamJson> {
    let ds = Dataset::open(dir)?;
    if ds.frames.is_empty() {
        return Err(ferrobot::Error::Usage(format!(
            "{}: no colour and depth images pair up in time",
            dir.display()
        )));
    }
    let mut slam = Slam::new(
        SlamSettings::handheld(),
        ds.intrinsics,
        Isometry3::identity(),
    )?;
    let mut tally = Tally::default();
    for i in 0..ds.frames.len() {
        let (time, rgb, depth) = ds.load(i)?;
        tally.track(
            &mut slam,
            &RgbdInput {
                time,
                rgb: &rgb,
                depth: &depth,
                camera: Isometry3::identity(),
                odometry: None,
            },
        )?;
    }
    let est = slam.trajectory();
    if let Some(out) = out {
        std::fs::create_dir_all(out)?;
        write_tum(&out.join("estimate.tum"), &est)?;
        tally.write_quality(&out.join("tracking.tsv"))?;
        ferrobot::perception::io::write_ply(out.join("cloud.ply"), &slam.map().cloud(0.02)?)?;
    }
    // TUM's ground truth runs at its own rate: pair within 20 ms, as its tools do.
    let ate_of = |poses: &[Stamped]| -> ferrobot::Result<Option<f64>> {
        ds.ground_truth
            .as_ref()
            .map(|gt| ate(poses, gt, 0.02).map(|a| a.rmse))
            .transpose()
            .map_err(Into::into)
    };
    Ok(SlamJson {
        ate_online_rmse_m: ate_of(&tally.online)?,
        ate_rmse_m: ate_of(&est)?,
        frames: tally.ms.len(),
        keyframes: slam.map().keyframes().len(),
        loops_closed: slam.loops_closed(),
        localised_after_s: None,
        longest_loss_frames: longest_loss(&slam).0,
        longest_loss_s: longest_loss(&slam).1,
        losses: slam.tracking_gaps().len(),
        lost_frames: tally.lost,
        median_inliers: tally.inliers().0,
        min_inliers: tally.inliers().1,
        ms_per_frame: tally.ms(),
        occupancy_iou: None,
        occupancy_iou_free: None,
        odometry_ate_rmse_m: None,
        relocalised_frames: tally.relocalised,
    })
}

/// The map (occupied black, unknown grey, free white) and the trajectories: true (green),
/// estimated (red), odometry (blue).
pub(crate) fn draw(
    map: &MapImage,
    est: &[Stamped],
    gt: &[Stamped],
    odo: &[Stamped],
    caption: &str,
    out: &Path,
) -> ferrobot::Result<()> {
    let r = map.resolution;
    let (w, h) = (map.width as f64 * r, map.height as f64 * r);
    let span = w.max(h);
    let centre = [map.origin[0] + w / 2.0, map.origin[1] + h / 2.0];
    let mut c = Canvas::new(900, centre, span, 0.5)?;
    for j in 0..map.height {
        for i in 0..map.width {
            let colour = match map.cells[j * map.width + i] {
                Cell::Free => continue,
                Cell::Occupied => [0, 0, 0],
                Cell::Unknown => [200, 200, 200],
            };
            let x = map.origin[0] + i as f64 * r;
            let y = map.origin[1] + j as f64 * r;
            c.fill_rect([x, y], [x + r, y + r], colour);
        }
    }
    let xy = |s: &[Stamped]| -> Vec<[f64; 2]> {
        s.iter()
            .map(|p| [p.pose.translation.x, p.pose.translation.y])
            .collect()
    };
    let (blue, green, red) = ([40, 90, 220], [30, 160, 60], [220, 40, 40]);
    c.polyline(&xy(odo), blue, 2);
    c.polyline(&xy(gt), green, 2);
    c.polyline(&xy(est), red, 2);
    c.legend(&[
        (red, "SLAM estimate".into()),
        (green, "ground truth".into()),
        (blue, "wheel odometry".into()),
        ([0, 0, 0], "occupied (SLAM map)".into()),
        ([200, 200, 200], "unknown".into()),
    ]);
    c.caption(caption);
    c.save(out)?;
    Ok(())
}
