//! The arm's gravity model the host derives for the firmware (`ferrobot_profile::arm_model`)
//! against the bundled URDFs: every link's inertial data, every fixed joint, the fingers and the AR tag,
//! walked as the URDF's tree with its own transforms, at 125 poses of the arm.

use ferrobot_protocol::gravity::{torques, G};

type V3 = [f64; 3];
type M3 = [[f64; 3]; 3];

fn mul(a: &M3, b: &M3) -> M3 {
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    r
}

fn apply(a: &M3, v: V3) -> V3 {
    [0, 1, 2].map(|i| a[i][0] * v[0] + a[i][1] * v[1] + a[i][2] * v[2])
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn rot(axis: V3, q: f64) -> M3 {
    let n = dot(axis, axis).sqrt();
    let [x, y, z] = axis.map(|a| a / n);
    let (s, c) = q.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

/// URDF fixed rotation: roll about x, then pitch about y, then yaw about z (fixed axes).
fn rpy(r: V3) -> M3 {
    mul(
        &rot([0.0, 0.0, 1.0], r[2]),
        &mul(&rot([0.0, 1.0, 0.0], r[1]), &rot([1.0, 0.0, 0.0], r[0])),
    )
}

/// Gravity torque about each of `arm` (joint names) at angles `q`, from the URDF's tree:
/// every link's pose from the root, every revolute joint of the arm at its angle, every other
/// movable joint at zero; τᵢ = aᵢ · Σ (cₖ − oᵢ) × mₖ·g over the links beyond joint i.
fn urdf_torques(urdf: &urdf_rs::Robot, arm: &[String], q: &[f64]) -> Vec<f64> {
    use std::collections::HashMap;
    let root = urdf
        .links
        .iter()
        .find(|l| !urdf.joints.iter().any(|j| j.child.link == l.name))
        .expect("root link")
        .name
        .clone();
    // Pose (rotation, origin) of every link, and which arm joints each lies beyond.
    let mut pose: HashMap<String, (M3, V3, Vec<usize>)> = HashMap::new();
    let id: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    pose.insert(root, (id, [0.0; 3], vec![]));
    // Joint origin and axis of each arm joint in the root frame.
    let mut frames = vec![([0.0; 3], [0.0; 3]); arm.len()];
    while pose.len() < urdf.links.len() {
        let before = pose.len();
        for j in &urdf.joints {
            if pose.contains_key(&j.child.link) {
                continue;
            }
            let Some((r, p, beyond)) = pose.get(&j.parent.link).cloned() else {
                continue;
            };
            let origin = add(p, apply(&r, j.origin.xyz.0));
            let r = mul(&r, &rpy(j.origin.rpy.0));
            let mut beyond = beyond.clone();
            let angle = match arm.iter().position(|a| *a == j.name) {
                Some(i) => {
                    frames[i] = (origin, apply(&r, j.axis.xyz.0));
                    beyond.push(i);
                    q[i]
                }
                None => 0.0,
            };
            let r = match j.joint_type {
                urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                    mul(&r, &rot(j.axis.xyz.0, angle))
                }
                _ => r,
            };
            pose.insert(j.child.link.clone(), (r, origin, beyond));
        }
        assert!(pose.len() > before, "the URDF is not a tree");
    }
    let mut tau = vec![0.0; arm.len()];
    for l in &urdf.links {
        let (r, p, beyond) = &pose[&l.name];
        let m = l.inertial.mass.value;
        let c = add(*p, apply(r, l.inertial.origin.xyz.0));
        for &i in beyond {
            let (o, a) = frames[i];
            tau[i] += dot(a, cross(sub(c, o), [0.0, 0.0, -G as f64 * m]));
        }
    }
    tau
}

/// Poses of an `n`-joint arm that load it: 125 of the second, third and fourth joints on a
/// grid, every other joint varied along.
fn poses(n: usize) -> Vec<Vec<f64>> {
    let grid = [-1.5, -0.8, 0.0, 0.7, 1.5];
    let mut out = Vec::new();
    for k in 0..125usize {
        let (a, b, c) = (k / 25, (k / 5) % 5, k % 5);
        let q = (0..n)
            .map(|i| match i {
                1 => grid[a],
                2 => grid[b],
                3 => grid[c],
                _ => 1.5 * (0.37 * k as f64 + 0.61 * i as f64).sin(),
            })
            .collect();
        out.push(q);
    }
    out
}

/// The gravity model the host derives from each bundled arm's URDF (and sends the firmware,
/// in f32) gives the URDF tree's own gravity torques at 125 poses.
#[test]
fn the_arm_model_matches_the_urdf_of_every_bundled_arm() {
    for robot in ["locobot", "locobot_lite", "sawyer"] {
        let cfg = ferrobot_profile::bundled(robot).expect("bundled");
        let model = ferrobot_profile::arm_links(&cfg);
        let arm: Vec<String> = model.iter().map(|l| l.joint.clone()).collect();
        assert_eq!(arm, cfg.arm.as_ref().expect("an arm").joints, "{robot}");
        let links: Vec<_> = model.iter().map(|l| l.link).collect();
        let wire = ferrobot_profile::arm_model(&cfg).expect("a model");
        let links32: Vec<_> = wire.iter().map(|l| l.link()).collect();
        for (w, name) in wire.iter().zip(&arm) {
            assert_eq!(cfg.joints[w.joint as usize].name.as_str(), name, "{robot}");
            assert_eq!(
                ferrobot_protocol::ranges::arm_link_error(w),
                None,
                "{robot}"
            );
        }
        let n = links.len();
        let (mut worst, mut worst32, mut largest) = (0.0f64, 0.0f64, 0.0f64);
        for q in poses(n) {
            let want = urdf_torques(&cfg.urdf, &arm, &q);
            let mut got = vec![0.0; n];
            assert_eq!(torques(&links, &q, G as f64, &mut got), n);
            // In f32 too, as the firmware runs it.
            let mut got32 = vec![0.0f32; n];
            let q32: Vec<f32> = q.iter().map(|&v| v as f32).collect();
            torques(&links32, &q32, G, &mut got32);
            for ((w, g), g32) in want.iter().zip(&got).zip(&got32) {
                worst = worst.max((w - g).abs());
                worst32 = worst32.max((w - *g32 as f64).abs());
                largest = largest.max(w.abs());
            }
        }
        eprintln!("{robot}: largest load {largest:.3} N·m, worst error {worst:.2e} (f64), {worst32:.2e} (f32)");
        // The poses load the arm (about 1 N·m on the LoCoBot's shoulder at full reach).
        assert!(largest > 0.9, "{robot}: largest load {largest} N·m");
        assert!(worst < 1e-9, "{robot}: worst error {worst} N·m");
        assert!(
            worst32 < 1e-3 * largest.max(1.0),
            "{robot}: worst f32 error {worst32} N·m"
        );
    }
}
