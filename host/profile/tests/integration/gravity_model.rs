//! The firmware's gravity model of the LoCoBot arm (`LOCOBOT_GRAVITY`, a compact table) against
//! the bundled URDF: every link's inertial data, every fixed joint, the fingers and the AR tag,
//! walked as the URDF's tree with its own transforms, at 125 poses of the arm.

use ferrobot_firmware::config::LOCOBOT_GRAVITY;
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

#[test]
fn the_firmware_gravity_model_matches_the_urdf_of_both_locobots() {
    let links: Vec<_> = LOCOBOT_GRAVITY.links.iter().map(|l| l.to_f64()).collect();
    for robot in ["locobot", "locobot_lite"] {
        let cfg = ferrobot_profile::bundled(robot).expect("bundled");
        let arm: Vec<String> = LOCOBOT_GRAVITY
            .joints
            .iter()
            .map(|&j| cfg.joints[j as usize].name.to_string())
            .collect();
        assert_eq!(arm, ["joint_1", "joint_2", "joint_3", "joint_4", "joint_5"]);
        // The built-in firmware profile of this robot carries the model.
        let profile = ferrobot_firmware::config::by_name(robot).expect("profile");
        assert_eq!(profile.gravity, Some(LOCOBOT_GRAVITY));
        assert_eq!(
            ferrobot_profile::firmware_profile(&cfg).gravity,
            Some(LOCOBOT_GRAVITY)
        );
        let mut worst: f64 = 0.0;
        let mut largest: f64 = 0.0;
        let mut poses = 0;
        // 5 × 5 × 5 poses of the three pitch joints, with the yaw and the roll varied along.
        let grid = [-1.5, -0.8, 0.0, 0.7, 1.5];
        for (a, &q2) in grid.iter().enumerate() {
            for (b, &q3) in grid.iter().enumerate() {
                for (c, &q4) in grid.iter().enumerate() {
                    let k = (a * 25 + b * 5 + c) as f64;
                    let q = [
                        1.5 * (0.37 * k).sin(),
                        q2,
                        q3,
                        q4,
                        1.5 * (0.61 * k + 0.3).cos(),
                    ];
                    let want = urdf_torques(&cfg.urdf, &arm, &q);
                    let mut got = [0.0; 5];
                    assert_eq!(torques(&links, &q, G as f64, &mut got), 5);
                    for (w, g) in want.iter().zip(&got) {
                        worst = worst.max((w - g).abs());
                        largest = largest.max(w.abs());
                    }
                    // In f32 too, as the firmware runs it, within the same tolerance.
                    let mut got32 = [0.0f32; 5];
                    let q32 = q.map(|v| v as f32);
                    torques(&LOCOBOT_GRAVITY.links, &q32, G, &mut got32);
                    for (w, g) in want.iter().zip(&got32) {
                        worst = worst.max((w - *g as f64).abs());
                    }
                    poses += 1;
                }
            }
        }
        assert_eq!(poses, 125);
        // The poses load the arm (about 1 N·m on the shoulder at full reach).
        assert!(largest > 0.9, "{robot}: largest load {largest} N·m");
        assert!(worst < 1e-4, "{robot}: worst error {worst} N·m");
    }
}
