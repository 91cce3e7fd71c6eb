//! The robot's spheres placed for many configurations at once: forward kinematics compiled
//! from the collision model into a short list of steps with the fixed parts folded into
//! constants (`f32`), then evaluated over [`Lane`]s.
//!
//! A step computes one moving link's frame in the robot's root frame: its parent's frame
//! (computed before it, or a constant when the parent does not move) times the joint's origin
//! times the joint's motion. A revolute joint's rotation is `c·A₀ + s·A₁ + (1 − c)·A₂` with
//! `c, s` the cosine and sine of its angle and `A₀ = O`, `A₁ = O[a]ₓ`, `A₂ = O·a·aᵀ` constants
//! (`O` the origin's rotation, or the whole fixed chain above a joint whose parent does not
//! move; `a` the unit axis): Rodrigues' formula with the origin folded in.

use nalgebra::{Isometry3, Matrix3, Vector3};

use ferrobot_kinematics::JointType;

use super::lane::{sin_cos, splat_all, Lane};
use crate::model::CollisionModel;
use crate::spheres::Sphere;
use crate::{Error, Result};

/// A frame in lanes: rotation (row-major 3 × 3) and translation, m.
#[derive(Debug, Clone, Copy)]
pub struct Frame<L> {
    /// Rotation, row-major.
    pub r: [L; 9],
    /// Translation, m.
    pub t: [L; 3],
}

/// Rotation (row-major) and translation of a constant frame, `f32`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Constant {
    r: [f32; 9],
    t: [f32; 3],
}

impl Constant {
    fn of(pose: &Isometry3<f64>) -> Self {
        let m = pose.rotation.to_rotation_matrix().into_inner();
        Constant {
            r: rows(&m),
            t: [
                pose.translation.x as f32,
                pose.translation.y as f32,
                pose.translation.z as f32,
            ],
        }
    }

    #[inline(always)]
    fn splat<L: Lane>(&self) -> Frame<L> {
        Frame {
            r: splat_all(&self.r),
            t: splat_all(&self.t),
        }
    }
}

fn rows(m: &Matrix3<f64>) -> [f32; 9] {
    std::array::from_fn(|k| m[(k / 3, k % 3)] as f32)
}

/// How a step's joint value follows the configuration: `mul · q[input] + add`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Input {
    input: usize,
    mul: f32,
    add: f32,
}

/// A step's motion.
#[derive(Debug, Clone, PartialEq)]
enum Motion {
    /// The link's frame is its base: a fixed joint, or one the planned joints do not drive.
    None,
    /// Rotation about the axis: the three constant matrices of Rodrigues' formula, row-major.
    Revolute { input: Input, a: [[f32; 9]; 3] },
    /// Translation along the unit axis (joint frame).
    Prismatic { input: Input, axis: [f32; 3] },
}

/// One moving link's frame.
#[derive(Debug, Clone, PartialEq)]
struct Step {
    /// The parent's step, or `None` when the parent does not move (then `base` is the
    /// parent's constant frame times the origin).
    parent: Option<usize>,
    /// The joint's origin, or (without a moving parent) the whole constant chain above it.
    base: Constant,
    motion: Motion,
}

/// A sphere of a moving link: its step and its centre (link frame, m) and radius (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgramSphere {
    /// Index of the step ([`SphereProgram::link_of_step`]) whose frame carries it.
    pub step: usize,
    /// Centre in the link's frame, m.
    pub centre: [f32; 3],
    /// Radius, m.
    pub radius: f32,
}

/// The robot's moving spheres as a function of the planned joints, compiled for lanes.
#[derive(Debug, Clone)]
pub struct SphereProgram {
    dof: usize,
    steps: Vec<Step>,
    /// [`CollisionModel::links`] index of each step's link.
    links: Vec<usize>,
    spheres: Vec<ProgramSphere>,
    /// Each body's spheres: a range of `spheres`.
    bodies: Vec<std::ops::Range<usize>>,
}

impl SphereProgram {
    /// The program of `model`'s moving links, the joints it does not plan at their current
    /// values: one body per moving link with spheres.
    pub fn new(model: &CollisionModel) -> Result<Self> {
        let bodies: Vec<(usize, &[Sphere])> = model
            .links()
            .iter()
            .enumerate()
            .filter(|(l, g)| model.is_moving(*l) && !g.spheres.is_empty())
            .map(|(l, g)| (l, g.spheres.as_slice()))
            .collect();
        Self::with_bodies(model, &bodies)
    }

    /// The program of `bodies`: each a moving link of `model` ([`CollisionModel::links`]
    /// index) and spheres in its frame (its own, or an object it carries).
    pub fn with_bodies(model: &CollisionModel, bodies: &[(usize, &[Sphere])]) -> Result<Self> {
        let tree = model.tree();
        let names = model.joint_names();
        let planned: Vec<usize> = names
            .iter()
            .map(|n| tree.joint_index(n).ok_or_else(|| unknown(n)))
            .collect::<Result<_>>()?;
        let values = model.tree_values(&vec![0.0; names.len()]);
        let fixed_poses = tree.poses(&values);
        let mut step_of = vec![None; model.links().len()];
        let mut steps = Vec::new();
        let mut links = Vec::new();
        for l in 0..model.links().len() {
            if !model.is_moving(l) {
                continue;
            }
            let origin = tree.link_origin(l).unwrap_or_else(Isometry3::identity);
            let parent_step = tree.parent(l).and_then(|p| step_of[p]);
            let mut base = match (parent_step, tree.parent(l)) {
                (None, Some(p)) => fixed_poses[p] * origin,
                _ => origin,
            };
            let joint = tree.link_joint(l);
            let motion = match joint.map(|j| (j, driven(model, &planned, j))) {
                Some((j, Some(input))) => motion(model, j, input, &base),
                // A joint the plan does not drive keeps its value: folded into the base.
                Some((j, None)) => {
                    base *= joint_motion(model, j, values[j]);
                    Motion::None
                }
                None => Motion::None,
            };
            step_of[l] = Some(steps.len());
            steps.push(Step {
                parent: parent_step,
                base: Constant::of(&base),
                motion,
            });
            links.push(l);
        }
        let mut spheres = Vec::new();
        let mut ranges = Vec::with_capacity(bodies.len());
        for &(l, list) in bodies {
            let step = step_of
                .get(l)
                .copied()
                .flatten()
                .ok_or_else(|| Error::Invalid {
                    what: "sphere program".into(),
                    why: format!("link {l} does not move with the planned joints"),
                })?;
            let start = spheres.len();
            spheres.extend(list.iter().map(|sp| ProgramSphere {
                step,
                centre: [sp.centre.x as f32, sp.centre.y as f32, sp.centre.z as f32],
                radius: sp.radius as f32,
            }));
            ranges.push(start..spheres.len());
        }
        Ok(SphereProgram {
            dof: names.len(),
            steps,
            links,
            spheres,
            bodies: ranges,
        })
    }

    /// Planned joints: the length of a configuration.
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// The moving spheres, in the order [`SphereProgram::place`] writes their centres.
    pub fn spheres(&self) -> &[ProgramSphere] {
        &self.spheres
    }

    /// Body `b`'s spheres: a range of [`SphereProgram::spheres`] (bodies in the order given).
    pub fn body(&self, b: usize) -> std::ops::Range<usize> {
        self.bodies[b].clone()
    }

    /// Bodies.
    pub fn bodies(&self) -> usize {
        self.bodies.len()
    }

    /// The [`CollisionModel::links`] index of step `step`'s link.
    pub fn link_of_step(&self, step: usize) -> usize {
        self.links[step]
    }

    /// Steps: the moving links.
    pub fn steps(&self) -> usize {
        self.steps.len()
    }

    /// Every moving link's frame for the configurations `q` (one value per planned joint,
    /// rad or m, each holding [`Lane::LANES`] configurations), into `frames` (one per step).
    #[inline(always)]
    pub fn frames<L: Lane>(&self, q: &[L], frames: &mut Vec<Frame<L>>) {
        frames.clear();
        for step in &self.steps {
            let parent = step.parent.map(|p| frames[p]);
            let f = match (&step.motion, &parent) {
                (Motion::Revolute { input, a }, None) => Frame {
                    r: rodrigues(a, value(q, input)),
                    t: splat_all(&step.base.t),
                },
                (Motion::Revolute { input, a }, Some(p)) => Frame {
                    r: mat_mul(&p.r, &rodrigues(a, value(q, input))),
                    t: transform(p, &step.base.t),
                },
                (Motion::None, None) => step.base.splat(),
                (Motion::None, Some(p)) => compose(p, &step.base),
                (Motion::Prismatic { input, axis }, _) => {
                    let mut f = match &parent {
                        Some(p) => compose(p, &step.base),
                        None => step.base.splat(),
                    };
                    let v = value(q, input);
                    let a: [L; 3] = splat_all(axis);
                    for i in 0..3 {
                        let along =
                            f.r[3 * i] * a[0] + f.r[3 * i + 1] * a[1] + f.r[3 * i + 2] * a[2];
                        f.t[i] = f.t[i] + along * v;
                    }
                    f
                }
            };
            frames.push(f);
        }
    }

    /// The centre of every sphere ([`SphereProgram::spheres`]' order), root frame, m, for the
    /// configurations `q`; `frames` is scratch.
    #[inline(always)]
    pub fn place<L: Lane>(&self, q: &[L], frames: &mut Vec<Frame<L>>, centres: &mut Vec<[L; 3]>) {
        self.frames(q, frames);
        centres.clear();
        centres.resize(self.spheres.len(), [L::splat(0.0); 3]);
        self.place_range(frames, 0..self.spheres.len(), centres);
    }

    /// The centres of the spheres `range` ([`SphereProgram::spheres`]' order), root frame, m,
    /// from `frames` ([`SphereProgram::frames`]), into the same places of `centres`.
    #[inline(always)]
    pub fn place_range<L: Lane>(
        &self,
        frames: &[Frame<L>],
        range: std::ops::Range<usize>,
        centres: &mut [[L; 3]],
    ) {
        for i in range {
            let s = &self.spheres[i];
            centres[i] = transform(&frames[s.step], &s.centre);
        }
    }
}

fn unknown(name: &str) -> Error {
    Error::Invalid {
        what: "sphere program".into(),
        why: format!("planned joint {name:?} is not in the tree"),
    }
}

#[inline(always)]
fn value<L: Lane>(q: &[L], input: &Input) -> L {
    q[input.input] * L::splat(input.mul) + L::splat(input.add)
}

/// The rotation `c·A₀ + s·A₁ + (1 − c)·A₂` of angle `v` (rad).
#[inline(always)]
fn rodrigues<L: Lane>(a: &[[f32; 9]; 3], v: L) -> [L; 9] {
    let (s, c) = sin_cos(v);
    let omc = L::splat(1.0) - c;
    let mut r = [L::splat(0.0); 9];
    for (k, r) in r.iter_mut().enumerate() {
        *r = c * L::splat(a[0][k]) + s * L::splat(a[1][k]) + omc * L::splat(a[2][k]);
    }
    r
}

/// `a · b`, row-major 3 × 3.
#[inline(always)]
fn mat_mul<L: Lane>(a: &[L; 9], b: &[L; 9]) -> [L; 9] {
    let mut r = [L::splat(0.0); 9];
    for (k, r) in r.iter_mut().enumerate() {
        let (i, j) = (k / 3, k % 3);
        *r = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
    }
    r
}

/// `f` applied to the point `p`.
#[inline(always)]
fn transform<L: Lane>(f: &Frame<L>, p: &[f32; 3]) -> [L; 3] {
    let p: [L; 3] = splat_all(p);
    let mut r = [L::splat(0.0); 3];
    for (i, r) in r.iter_mut().enumerate() {
        *r = f.r[3 * i] * p[0] + f.r[3 * i + 1] * p[1] + f.r[3 * i + 2] * p[2] + f.t[i];
    }
    r
}

/// `f · c`.
#[inline(always)]
fn compose<L: Lane>(f: &Frame<L>, c: &Constant) -> Frame<L> {
    Frame {
        r: mat_mul(&f.r, &splat_all(&c.r)),
        t: transform(f, &c.t),
    }
}

/// The rigid motion of joint `j` at value `v` (rad or m), in its joint frame.
fn joint_motion(model: &CollisionModel, j: usize, v: f64) -> Isometry3<f64> {
    let joint = &model.tree().joints()[j];
    match joint.kind {
        JointType::Revolute => Isometry3::rotation(joint.axis * v),
        JointType::Prismatic => {
            Isometry3::translation(joint.axis.x * v, joint.axis.y * v, joint.axis.z * v)
        }
    }
}

/// How the plan drives joint `j`: its own planned value, or its leader's when it mimics a
/// planned joint; `None` when the plan does not move it.
fn driven(model: &CollisionModel, planned: &[usize], j: usize) -> Option<Input> {
    if let Some(k) = planned.iter().position(|&p| p == j) {
        return Some(Input {
            input: k,
            mul: 1.0,
            add: 0.0,
        });
    }
    let m = model.tree().joints()[j].mimic?;
    planned.iter().position(|&p| p == m.leader).map(|k| Input {
        input: k,
        mul: m.multiplier as f32,
        add: m.offset as f32,
    })
}

/// The motion of driven joint `j` for the step whose base is `base` (f64).
fn motion(model: &CollisionModel, j: usize, input: Input, base: &Isometry3<f64>) -> Motion {
    let joint = &model.tree().joints()[j];
    let o = base.rotation.to_rotation_matrix().into_inner();
    let a: Vector3<f64> = joint.axis;
    match joint.kind {
        JointType::Revolute => Motion::Revolute {
            input,
            a: [
                rows(&o),
                rows(&(o * a.cross_matrix())),
                rows(&(o * a * a.transpose())),
            ],
        },
        JointType::Prismatic => Motion::Prismatic {
            input,
            axis: [a.x as f32, a.y as f32, a.z as f32],
        },
    }
}
