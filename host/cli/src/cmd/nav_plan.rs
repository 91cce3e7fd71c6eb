//! `ferrobot nav-plan`: the global planner alone on a map in ROS map_server's format.

use std::path::Path;

use ferrobot::nav::{Cell, GlobalPlanner, GridAStar, MapImage};
use ferrobot_cli::plot::Canvas;
use serde::Serialize;

use super::common::print_json;

/// `ferrobot nav-plan`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// The map's YAML file.
    #[arg(long)]
    pub map: std::path::PathBuf,
    /// Start x y, m (map frame).
    #[arg(long, num_args = 2, allow_negative_numbers = true, value_names = ["X", "Y"], required = true)]
    pub from: Vec<f64>,
    /// Goal x y, m (map frame).
    #[arg(long, num_args = 2, allow_negative_numbers = true, value_names = ["X", "Y"], required = true)]
    pub to: Vec<f64>,
    /// Robot radius, m.
    #[arg(long, allow_negative_numbers = true)]
    pub radius: f64,
    /// Treat unknown cells as free (default: occupied).
    #[arg(long)]
    pub unknown_free: bool,
    /// Also draw the map and the path into this PNG file.
    #[arg(long)]
    pub plot: Option<std::path::PathBuf>,
    /// Print one JSON object: `{"length_m", "path": [[x, y], ...]}`.
    #[arg(long)]
    pub json: bool,
}

/// `nav-plan --json`, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct PathJson {
    /// Path length, m.
    length_m: f64,
    /// Waypoints `[x, y]` from the start to the goal, m.
    path: Vec<[f64; 2]>,
}

/// Plan and print the path (or draw it).
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let (from, to) = ([a.from[0], a.from[1]], [a.to[0], a.to[1]]);
    let map = MapImage::load(&a.map)?;
    let grid = map.to_grid(!a.unknown_free)?;
    let path = GridAStar.plan(&grid, from, to, a.radius)?;
    if let Some(out) = a.plot.as_deref() {
        draw(&map, &path.points, a.radius, out)?;
    }
    if a.json {
        print_json(&PathJson {
            length_m: path.length,
            path: path.points,
        });
    } else {
        say!(
            "path of {:.3} m through {} waypoints (robot radius {} m):",
            path.length,
            path.points.len(),
            a.radius
        );
        for p in &path.points {
            say!("  {:.3} {:.3}", p[0], p[1]);
        }
        if let Some(out) = a.plot.as_deref() {
            say!("drawn into {}", out.display());
        }
    }
    Ok(())
}

/// The map (occupied black, unknown grey, free white) and the path (red) as a PNG.
fn draw(map: &MapImage, path: &[[f64; 2]], radius: f64, out: &Path) -> ferrobot::Result<()> {
    let r = map.resolution;
    let (w, h) = (map.width as f64 * r, map.height as f64 * r);
    let span = w.max(h);
    let centre = [map.origin[0] + w / 2.0, map.origin[1] + h / 2.0];
    let size = 800;
    let grid = (span / 10.0).max(span / size as f64);
    let mut c = Canvas::new(size, centre, span, grid)?;
    for j in 0..map.height {
        for i in 0..map.width {
            let colour = match map.cells[j * map.width + i] {
                Cell::Free => continue,
                Cell::Occupied => [0; 3],
                Cell::Unknown => [190; 3],
            };
            let lo = [map.origin[0] + i as f64 * r, map.origin[1] + j as f64 * r];
            c.fill_rect(lo, [lo[0] + r, lo[1] + r], colour);
        }
    }
    c.polyline(path, [214, 39, 40], 3);
    c.legend(&[
        ([214, 39, 40], format!("path, robot radius {radius} m")),
        ([0; 3], "occupied".into()),
        ([190; 3], "unknown".into()),
    ]);
    c.caption(&format!("grid lines every {grid:.2} m"));
    c.save(out)
}
