//! The robot's spheres placed for many configurations at once: forward kinematics compiled
//! from the collision model into a short list of steps with the fixed parts folded into
//! constants (`f32`), then evaluated over [`Lane`]s.
//!
//! A step computes one moving link's frame in the robot's root frame, turned by a constant
//! rotation `Q` that takes the z axis to its joint's axis (the identity for a joint about z and
//! for a link that does not turn): its parent's frame (computed before it, or a constant when
//! the parent does not move) times a constant frame (`Qₚᵀ` times the joint's origin times `Q`)
//! times the joint's motion, which for a revolute joint is then a turn about z: four products
//! and two sums per row. The constants' zero entries are skipped and their ±1 entries not
//! multiplied (the URDF's axes and right angles make most of them so), and each sphere's centre
//! is held in its turned frame (`Qᵀ c`): the same places, in far fewer operations than a
//! general rotation product per joint.

use std::f64::consts::PI;

use nalgebra::{Isometry3, Matrix3, Rotation3, Vector3};

use ferrobot_kinematics::JointType;

use super::lane::{sin_cos, splat_all, Lane};
use crate::model::CollisionModel;
use crate::spheres::Sphere;
use crate::{Error, Result};

/// A frame in lanes: rotation (row-major 3 × 3) and translation, m. A step's frame is its
/// link's, turned by the step's constant rotation (see the module).
#[derive(Debug, Clone, Copy)]
pub struct Frame<L> {
    /// Rotation, row-major.
    pub r: [L; 9],
    /// Translation, m.
    pub t: [L; 3],
}

/// Rotation and translation of a constant frame, `f32`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Constant {
    /// Rotation, row-major.
    r: [f32; 9],
    /// Where the rotation is a signed permutation of the axes (the URDF's right angles): for
    /// each column `j`, the column of the identity it is, and whether it is negated.
    axes: Option<([usize; 3], [bool; 3])>,
    t: [f32; 3],
}

impl Constant {
    fn of(r: &Matrix3<f64>, t: &Vector3<f64>) -> Self {
        let r: [f32; 9] = std::array::from_fn(|k| snap(r[(k / 3, k % 3)]));
        // Each column one ±1 (a rotation's other entries are then 0).
        let axis = |j: usize| (0..3).find(|&k| r[3 * k + j].abs() == 1.0);
        let axes = match (axis(0), axis(1), axis(2)) {
            (Some(a), Some(b), Some(c)) => {
                let from = [a, b, c];
                Some((from, [0, 1, 2].map(|j| r[3 * from[j] + j] < 0.0)))
            }
            _ => None,
        };
        Constant {
            r,
            axes,
            t: [t.x as f32, t.y as f32, t.z as f32],
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

/// `v` in `f32`, exactly 0 or ±1 within 10⁻¹² of them (the sines and cosines of right angles
/// in `f64`: dropping a 6·10⁻¹⁷ moves nothing by more than `f32` rounding does).
fn snap(v: f64) -> f32 {
    for exact in [0.0, 1.0, -1.0] {
        if (v - exact).abs() < 1e-12 {
            return exact as f32;
        }
    }
    v as f32
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
    /// Rotation about the step frame's z axis.
    Revolute { input: Input },
    /// Translation along the unit axis (step frame).
    Prismatic { input: Input, axis: [f32; 3] },
}

/// One moving link's frame (turned).
#[derive(Debug, Clone, PartialEq)]
struct Step {
    /// The parent's step, or `None` when the parent does not move.
    parent: Option<usize>,
    /// The step's frame before its motion: in the parent step's frame, or (without a moving
    /// parent) in the root frame, the whole constant chain above it.
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
    /// Centre in the step's turned frame, m ([`Constant`]'s rounding).
    turned: [f32; 3],
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
        // Each step's turn (`Q`, f64).
        let mut turns: Vec<Matrix3<f64>> = Vec::new();
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
            let (motion, turn) = match joint.map(|j| (j, driven(model, &planned, j))) {
                Some((j, Some(input))) => motion(model, j, input),
                // A joint the plan does not drive keeps its value: folded into the base.
                Some((j, None)) => {
                    base *= joint_motion(model, j, values[j]);
                    (Motion::None, Matrix3::identity())
                }
                None => (Motion::None, Matrix3::identity()),
            };
            // In the parent step's turned frame (`Qₚᵀ`), turned by this step's `Q`.
            let above = parent_step.map_or_else(Matrix3::identity, |p: usize| turns[p].transpose());
            let r = above * base.rotation.to_rotation_matrix().into_inner() * turn;
            let t = above * base.translation.vector;
            step_of[l] = Some(steps.len());
            steps.push(Step {
                parent: parent_step,
                base: Constant::of(&r, &t),
                motion,
            });
            turns.push(turn);
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
            spheres.extend(list.iter().map(|sp| {
                let turned = turns[step].transpose() * sp.centre.coords;
                ProgramSphere {
                    step,
                    centre: [sp.centre.x as f32, sp.centre.y as f32, sp.centre.z as f32],
                    radius: sp.radius as f32,
                    turned: [turned.x as f32, turned.y as f32, turned.z as f32],
                }
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

    /// Every moving link's frame (turned: see the module) for the configurations `q` (one
    /// value per planned joint, rad or m, each holding [`Lane::LANES`] configurations), into
    /// `frames` (one per step).
    #[inline(always)]
    pub fn frames<L: Lane>(&self, q: &[L], frames: &mut Vec<Frame<L>>) {
        frames.clear();
        for step in &self.steps {
            let mut f = match step.parent {
                Some(p) => after(&frames[p], &step.base),
                None => step.base.splat(),
            };
            match &step.motion {
                Motion::None => {}
                Motion::Revolute { input } => turn_z(&mut f, value(q, input)),
                Motion::Prismatic { input, axis } => {
                    let v = value(q, input);
                    let a: [L; 3] = splat_all(axis);
                    for i in 0..3 {
                        let along =
                            f.r[3 * i] * a[0] + f.r[3 * i + 1] * a[1] + f.r[3 * i + 2] * a[2];
                        f.t[i] = f.t[i] + along * v;
                    }
                }
            }
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
            centres[i] = transform(&frames[s.step], &s.turned);
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

/// `f` turned by the angle `v` (rad) about its z axis: `f · Rz(v)`.
#[inline(always)]
fn turn_z<L: Lane>(f: &mut Frame<L>, v: L) {
    let (s, c) = sin_cos(v);
    for i in 0..3 {
        let (x, y) = (f.r[3 * i], f.r[3 * i + 1]);
        f.r[3 * i] = x * c + y * s;
        f.r[3 * i + 1] = y * c - x * s;
    }
}

/// `f` applied to the constant point `p`.
#[inline(always)]
fn transform<L: Lane>(f: &Frame<L>, p: &[f32; 3]) -> [L; 3] {
    let p: [L; 3] = splat_all(p);
    let mut r = [L::splat(0.0); 3];
    for (i, r) in r.iter_mut().enumerate() {
        *r = f.r[3 * i] * p[0] + f.r[3 * i + 1] * p[1] + f.r[3 * i + 2] * p[2] + f.t[i];
    }
    r
}

/// `f · c` for the constant frame `c`: where `c` turns axis to axis, each column of `f`'s
/// rotation is one of its own, or its negation.
#[inline(always)]
fn after<L: Lane>(f: &Frame<L>, c: &Constant) -> Frame<L> {
    let mut r = [L::splat(0.0); 9];
    match &c.axes {
        Some((from, negate)) => {
            for j in 0..3 {
                for i in 0..3 {
                    let x = f.r[3 * i + from[j]];
                    r[3 * i + j] = if negate[j] { L::splat(0.0) - x } else { x };
                }
            }
        }
        None => {
            let m: [L; 9] = splat_all(&c.r);
            for i in 0..3 {
                for j in 0..3 {
                    r[3 * i + j] =
                        f.r[3 * i] * m[j] + f.r[3 * i + 1] * m[3 + j] + f.r[3 * i + 2] * m[6 + j];
                }
            }
        }
    }
    Frame {
        r,
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

/// The motion of driven joint `j`, and the step's turn `Q` (a revolute joint's axis to z; the
/// identity for a prismatic one).
fn motion(model: &CollisionModel, j: usize, input: Input) -> (Motion, Matrix3<f64>) {
    let joint = &model.tree().joints()[j];
    let a: Vector3<f64> = joint.axis;
    match joint.kind {
        JointType::Revolute => {
            let z = Vector3::z();
            let turn = Rotation3::rotation_between(&z, &a)
                .unwrap_or_else(|| Rotation3::from_axis_angle(&Vector3::x_axis(), PI));
            (Motion::Revolute { input }, turn.into_inner())
        }
        JointType::Prismatic => (
            Motion::Prismatic {
                input,
                axis: [a.x as f32, a.y as f32, a.z as f32],
            },
            Matrix3::identity(),
        ),
    }
}
