//! Trajectories (TUM format, ATE) and RGB-D sequences (the TUM RGB-D layout) on disk: round
//! trips, the ATE of known errors, and malformed files refused with the file and line named.

use std::path::PathBuf;

use ferrobot_perception::{DepthImage, Intrinsics, RgbImage};
use ferrobot_slam::optimise::planar;
use ferrobot_slam::{ate, parse_tum, to_tum, Dataset, DatasetWriter, Error, Stamped};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

/// A path `name` that does not exist yet, in a temporary directory removed with the guard.
fn dir(name: &str) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().expect("temporary directory");
    let d = tmp.path().join(name);
    (tmp, d)
}

fn circle(n: usize) -> Vec<Stamped> {
    (0..n)
        .map(|i| {
            let a = i as f64 * 0.1;
            Stamped {
                time: i as f64 / 30.0,
                pose: planar([a.cos(), a.sin(), a + 1.5]),
            }
        })
        .collect()
}

#[test]
fn tum_text_round_trips_and_the_ate_ignores_a_rigid_offset() {
    let a = circle(50);
    let back = parse_tum(&to_tum(&a), std::path::Path::new("t")).expect("parse");
    assert_eq!(back.len(), a.len());
    for (x, y) in a.iter().zip(&back) {
        assert!((x.time - y.time).abs() < 1e-6);
        assert!((x.pose.translation.vector - y.pose.translation.vector).norm() < 1e-6);
        assert!(x.pose.rotation.angle_to(&y.pose.rotation) < 1e-6);
    }
    // The same trajectory in another frame: no error after alignment.
    let t = Isometry3::from_parts(
        Translation3::new(3.0, -1.0, 0.2),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7),
    );
    let moved: Vec<Stamped> = a
        .iter()
        .map(|s| Stamped {
            time: s.time,
            pose: t * s.pose,
        })
        .collect();
    let e = ate(&moved, &a, 0.001).expect("ate");
    assert!(e.rmse < 1e-9 && e.pairs == 50, "{e:?}");
    // Every other position 1 cm up: the RMSE of ±0.5 cm about the best alignment.
    let bumped: Vec<Stamped> = a
        .iter()
        .enumerate()
        .map(|(i, s)| Stamped {
            time: s.time,
            pose: Isometry3::translation(0.0, 0.0, if i % 2 == 0 { 0.01 } else { 0.0 }) * s.pose,
        })
        .collect();
    let e = ate(&bumped, &a, 0.001).expect("ate");
    assert!((e.rmse - 0.005).abs() < 1e-4, "{e:?}");
    // Poses far apart in time do not pair.
    let late: Vec<Stamped> = a
        .iter()
        .map(|s| Stamped {
            time: s.time + 100.0,
            pose: s.pose,
        })
        .collect();
    assert!(matches!(
        ate(&late, &a, 0.02),
        Err(Error::Trajectory { .. })
    ));
}

#[test]
fn malformed_trajectories_name_the_line() {
    let p = std::path::Path::new("traj.txt");
    for (text, line) in [
        ("# c\n0 0 0 0 0 0 0 1\n1 2 3\n", 3),
        ("0 0 0 0 0 0 0 x\n", 1),
        ("\n0 0 0 0 0 0 0 0\n", 2),
        ("0 NaN 0 0 0 0 0 1\n", 1),
        ("0 inf 0 0 0 0 0 1\n", 1),
    ] {
        match parse_tum(text, p) {
            Err(Error::File { why, .. }) => {
                assert!(why.starts_with(&format!("line {line}:")), "{text:?}: {why}")
            }
            other => panic!("{text:?}: {other:?}"),
        }
    }
}

#[test]
fn a_written_sequence_reads_back_pairs_its_images_and_keeps_its_depth() {
    let (_tmp, d) = dir("seq");
    let k = Intrinsics::new(8, 6, 10.0, 10.0, 4.0, 3.0).expect("k");
    let mut w = DatasetWriter::create(&d, 5000.0).expect("create");
    for i in 0..5 {
        let rgb = RgbImage::new(8, 6, vec![i as u8 * 40; 8 * 6 * 3]).expect("rgb");
        let depth = DepthImage::new(8, 6, (0..48).map(|j| 0.5 + 0.0371 * j as f32).collect())
            .expect("depth");
        w.add(
            i as f64 / 30.0,
            &rgb,
            &depth,
            Some(planar([i as f64, 0.0, 0.0])),
        )
        .expect("add");
    }
    w.finish(&k).expect("finish");
    let ds = Dataset::open(&d).expect("open");
    assert_eq!(ds.intrinsics, k);
    assert_eq!(ds.frames.len(), 5);
    assert_eq!(ds.ground_truth.as_ref().map(Vec::len), Some(5));
    let (t, rgb, depth) = ds.load(3).expect("load");
    assert!((t - 0.1).abs() < 1e-6);
    assert_eq!(rgb.data[0], 120);
    // 1/5000 m steps: within half a step, 0.1 mm (and f32 rounding).
    for (j, &z) in depth.data.iter().enumerate() {
        assert!((z - (0.5 + 0.0371 * j as f32)).abs() <= 1.01e-4, "{j}: {z}");
    }
    // Colour and depth stamps 10 ms apart still pair; 30 ms apart do not.
    std::fs::write(
        d.join("depth.txt"),
        "0.010 depth/0.000000.png\n0.163333 depth/0.033333.png\n",
    )
    .expect("write");
    let ds = Dataset::open(&d).expect("open");
    assert_eq!(ds.frames.len(), 1);
    // A missing image is an error naming it.
    std::fs::write(d.join("depth.txt"), "0.0 depth/none.png\n").expect("write");
    let ds = Dataset::open(&d).expect("open");
    assert!(matches!(ds.load(0), Err(Error::File { path, .. }) if path.ends_with("none.png")));
    assert!(matches!(ds.load(9), Err(Error::File { .. })));
}

#[test]
fn images_of_another_size_than_the_camera_are_refused() {
    let (_tmp, d) = dir("size");
    let mut w = DatasetWriter::create(&d, 1000.0).expect("create");
    let rgb = RgbImage::new(8, 6, vec![0; 144]).expect("rgb");
    let depth = DepthImage::new(8, 6, vec![1.0; 48]).expect("depth");
    w.add(0.0, &rgb, &depth, None).expect("add");
    w.finish(&Intrinsics::new(16, 12, 10.0, 10.0, 8.0, 6.0).expect("k"))
        .expect("finish");
    let ds = Dataset::open(&d).expect("open");
    assert!(ds.ground_truth.is_none());
    match ds.load(0) {
        Err(Error::File { why, .. }) => assert!(why.contains("8x6"), "{why}"),
        other => panic!("{other:?}"),
    }
}

/// A map file of one keyframe at `t` (camera at the body), no features, the given depth
/// points, no landmarks or edges, as `Map::save` lays it out.
/// The map file lives in a temporary directory removed with the guard.
fn map_file(name: &str, t: [f64; 3], cloud: &[[f32; 3]]) -> (tempfile::TempDir, PathBuf) {
    let pose = |b: &mut Vec<u8>, t: [f64; 3]| {
        for v in [t[0], t[1], t[2], 0.0, 0.0, 0.0, 1.0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
    };
    let mut b = b"FERROBOT-SLAM-MAP 1\n".to_vec();
    b.extend_from_slice(&1u32.to_le_bytes());
    b.extend_from_slice(&0f64.to_le_bytes());
    pose(&mut b, t);
    pose(&mut b, [0.0; 3]);
    b.extend_from_slice(&0u32.to_le_bytes());
    b.extend_from_slice(&(cloud.len() as u32).to_le_bytes());
    for p in cloud {
        for v in p {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&[1, 2, 3]);
    }
    b.extend_from_slice(&0u32.to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes());
    let (tmp, d) = dir(name);
    std::fs::create_dir_all(&d).expect("dir");
    let f = d.join("map.slam");
    std::fs::write(&f, b).expect("write");
    (tmp, f)
}

#[test]
fn maps_with_points_far_away_are_refused_or_too_large_to_grid_not_a_panic() {
    // (From review: a finite but huge point loaded, then overflowed the grid's size.)
    let (_tmp, f) = map_file("far", [0.0; 3], &[[3.0e38, 0.0, 0.5]]);
    assert!(matches!(
        ferrobot_slam::Map::load(&f),
        Err(Error::File { .. })
    ));
    // Within the file's bounds (10 km) but a grid of 2 cm cells would be too large.
    let (_tmp, f) = map_file(
        "wide",
        [0.0; 3],
        &[[9.0e3, 0.0, 0.5], [0.0, 9.0e3, 0.5], [0.0, 0.0, 0.5]],
    );
    let map = ferrobot_slam::Map::load(&f).expect("loads");
    let e = map.occupancy(&ferrobot_slam::GridSettings::default());
    assert!(matches!(e, Err(Error::InvalidSettings { .. })), "{e:?}");
    // The kept grid refuses it alike, and again on the next update (it starts afresh).
    let mut kept =
        ferrobot_slam::OccupancyGrid::new(ferrobot_slam::GridSettings::default()).expect("new");
    for _ in 0..2 {
        let e = kept.update(&map);
        assert!(matches!(e, Err(Error::InvalidSettings { .. })), "{e:?}");
    }
    // Hostile settings are refused when the kept grid is made.
    for s in [
        ferrobot_slam::GridSettings {
            resolution: f64::NAN,
            ..Default::default()
        },
        ferrobot_slam::GridSettings {
            resolution: 0.0,
            ..Default::default()
        },
        ferrobot_slam::GridSettings {
            band: [0.8, 0.1],
            ..Default::default()
        },
        ferrobot_slam::GridSettings {
            slab: f64::INFINITY,
            ..Default::default()
        },
        ferrobot_slam::GridSettings {
            surface: -1.0,
            ..Default::default()
        },
        // Cells no ray reached were occupied.
        ferrobot_slam::GridSettings {
            min_hits: 0,
            ..Default::default()
        },
        // Nothing was ever occupied.
        ferrobot_slam::GridSettings {
            min_ratio: f64::NAN,
            ..Default::default()
        },
        // Every floor ray was dropped.
        ferrobot_slam::GridSettings {
            floor: f64::NAN,
            ..Default::default()
        },
    ] {
        let e = ferrobot_slam::OccupancyGrid::new(s);
        assert!(matches!(e, Err(Error::InvalidSettings { .. })), "{s:?}");
    }
    // A small one grids, and holds its obstacle.
    let (_tmp, f) = map_file("small", [0.0; 3], &[[0.3, 0.0, 0.5]]);
    let map = ferrobot_slam::Map::load(&f).expect("loads");
    let grid = map.occupancy(&ferrobot_slam::GridSettings {
        min_hits: 1,
        ..Default::default()
    });
    assert!(grid
        .expect("grid")
        .expect("some")
        .cells
        .contains(&ferrobot_nav::Cell::Occupied));
}

/// A ball on the floor 1 m ahead (its top's points 0.12-0.18 m up) and a wall 2 m ahead seen
/// over it: the rays to the wall pass over the ball's cell 0.5 m up and clear only that height,
/// so the ball stays on the grid; counted over the whole band at once they would outvote it.
#[test]
fn a_low_obstacle_is_not_cleared_by_the_rays_that_pass_over_it() {
    let mut cloud: Vec<[f32; 3]> = (0..4).map(|k| [1.0, 0.0, 0.12 + 0.02 * k as f32]).collect();
    // Camera 0.6 m up at the origin: points are given relative to it.
    for p in &mut cloud {
        p[2] -= 0.6;
    }
    for k in 0..30 {
        cloud.push([2.0, 0.0005 * k as f32, 0.5 - 0.6]);
    }
    let (_tmp, f) = map_file("ball", [0.0, 0.0, 0.6], &cloud);
    let map = ferrobot_slam::Map::load(&f).expect("loads");
    let at = |g: &ferrobot_nav::MapImage, x: f64, y: f64| {
        let i = ((x - g.origin[0]) / g.resolution).floor() as usize;
        let j = ((y - g.origin[1]) / g.resolution).floor() as usize;
        g.cells[j * g.width + i]
    };
    let grid = map
        .occupancy(&ferrobot_slam::GridSettings::default())
        .expect("grid")
        .expect("some");
    assert_eq!(at(&grid, 1.0, 0.0), ferrobot_nav::Cell::Occupied);
    assert_eq!(at(&grid, 2.0, 0.0), ferrobot_nav::Cell::Occupied);
    assert_eq!(at(&grid, 1.5, 0.0), ferrobot_nav::Cell::Free);
    // One slab for the whole band: 30 rays over the ball against its 4 points.
    let flat = map
        .occupancy(&ferrobot_slam::GridSettings {
            slab: 0.7,
            ..Default::default()
        })
        .expect("grid")
        .expect("some");
    assert_eq!(at(&flat, 1.0, 0.0), ferrobot_nav::Cell::Free);
    // A surface height beyond the slab is refused.
    let e = map.occupancy(&ferrobot_slam::GridSettings {
        surface: 0.5,
        ..Default::default()
    });
    assert!(matches!(e, Err(Error::InvalidSettings { .. })), "{e:?}");
    // Slabs too thin to count are refused.
    let e = map.occupancy(&ferrobot_slam::GridSettings {
        slab: 1e-4,
        ..Default::default()
    });
    assert!(matches!(e, Err(Error::InvalidSettings { .. })), "{e:?}");
}

/// A bed's top 1-2 m ahead, its points a millimetre above the 0.5 m edge between two slabs,
/// seen from a camera 0.6 m up: every ray to the far part of the top grazes over the near
/// part within the slab above the edge. The top stays on the grid because its points also
/// count in the slab below (which no ray passes); counted in their own slab only, the grazing
/// rays outvote them and the bed's top is free.
#[test]
fn a_flat_top_at_a_slab_s_edge_is_not_cleared_by_the_rays_grazing_over_it() {
    let mut cloud: Vec<[f32; 3]> = Vec::new();
    for i in 0..50 {
        for y in [0.005f32, 0.015] {
            cloud.push([1.0 + 0.02 * i as f32 + 0.01, y, 0.501 - 0.6]);
        }
    }
    let (_tmp, f) = map_file("bed", [0.0, 0.0, 0.6], &cloud);
    let map = ferrobot_slam::Map::load(&f).expect("loads");
    let occupied = |settings: &ferrobot_slam::GridSettings| {
        let g = map.occupancy(settings).expect("grid").expect("some");
        (0..50)
            .filter(|i| {
                let x = 1.01 + 0.02 * *i as f64;
                let col = ((x - g.origin[0]) / g.resolution).floor() as usize;
                let row = ((0.01 - g.origin[1]) / g.resolution).floor() as usize;
                g.cells[row * g.width + col] == ferrobot_nav::Cell::Occupied
            })
            .count()
    };
    let held = occupied(&ferrobot_slam::GridSettings::default());
    assert!(held >= 48, "{held} of the top's 50 cells occupied");
    let own_slab = occupied(&ferrobot_slam::GridSettings {
        surface: 0.0,
        ..Default::default()
    });
    assert!(
        own_slab <= 10,
        "{own_slab} of 50 occupied without the spread"
    );
}
