//! Building a [`Checker`]: its bodies (links with geometry, attached objects), the pairs of
//! moving bodies checked against each other, the shapes of bodies that do not move as
//! obstacles, the world's obstacles and voxels, each body's reach and the broad phase's
//! layout.

use std::cell::RefCell;
use std::sync::Arc;

use nalgebra::Isometry3;

use super::edge::RAKE_SPACING_PER_REACH;
use super::obstacle::{Grid, Obstacle};
use super::{
    check_not_a_link, check_padding, Body, CheckOptions, Checker, Counters, Engine, Scratch,
};
use crate::coarse::{BoxSet, LANES};
use crate::model::{bounding_sphere, CollisionModel};
use crate::scene::PlanningScene;
use crate::shape::Shape;
use crate::spheres::{self, Sphere};
use crate::{Error, Result};

impl Checker {
    /// A checker of `model` in `scene`. Attached objects must name a link of the model;
    /// objects overlapping each other are fine.
    pub fn new(
        model: Arc<CollisionModel>,
        scene: &PlanningScene,
        opts: CheckOptions,
    ) -> Result<Self> {
        check_steps(&opts)?;
        check_padding(opts.padding)?;
        let ids = scene
            .objects()
            .map(|o| &o.id)
            .chain(scene.attached().map(|a| &a.id));
        for id in ids {
            check_not_a_link(&model, id)?;
        }
        let mut bodies = link_bodies(&model);
        let links = bodies.len();
        let touch = add_attached(&model, scene, &mut bodies)?;
        let SelfChecks {
            pairs,
            robot_obstacles,
            fixed_of,
        } = self_checks(&model, scene, &bodies, links, &touch)?;
        let obstacles = scene
            .objects()
            .map(|o| Obstacle::new(&o.id, &o.shape, &o.pose))
            .collect::<Result<Vec<_>>>()?;
        let grid = scene
            .voxels()
            .filter(|v| !v.cells.is_empty())
            .map(|v| Grid::new(v.size, &v.cells));
        let extra: Vec<(usize, Vec<Sphere>)> = bodies[links..]
            .iter()
            .map(|b| (b.link, b.spheres.clone()))
            .collect();
        let reach = model.reach(&extra);
        let span = model.span(&extra);
        let body_reach = body_reach(&model, &bodies);
        let pair_reach = pair_reach(&pairs, &body_reach);
        let all_of = all_of(&bodies, &fixed_of, obstacles.len());
        let all_pairs = (0..pairs.len()).collect();
        let scratch = scratch(&all_of, pairs.len());
        let layout = layout(&bodies);
        let mut checker = Checker {
            pair_reach,
            layout,
            all_of,
            all_boxes: Vec::new(),
            all_pairs,
            body_reach,
            model,
            bodies,
            obstacles,
            robot_obstacles,
            fixed_of,
            grid,
            pairs,
            rake_spacing: (RAKE_SPACING_PER_REACH * span).max(opts.max_step),
            reach,
            opts,
            scratch: RefCell::new(scratch),
            counters: Counters::default(),
            lanes: None,
            engine: Engine::Advancement,
            walk_scratch: RefCell::default(),
        };
        // Through `Checker::obstacle`, which numbers them as `all_of` does.
        checker.all_boxes = checker
            .all_of
            .iter()
            .map(|list| {
                BoxSet::new(list.iter().map(|&k| {
                    let o = checker.obstacle(k);
                    (&o.inv, &o.bbox)
                }))
            })
            .collect();
        checker.set_engine(checker.default_engine())?;
        Ok(checker)
    }
}

/// The steps of [`CheckOptions`]: `1e-4 ≤ min_step ≤ resolution ≤ max_step ≤ 0.5` (m).
fn check_steps(opts: &CheckOptions) -> Result<()> {
    if !(opts.max_step.is_finite()
        && opts.min_step.is_finite()
        && opts.resolution.is_finite()
        && opts.min_step >= 1e-4
        && opts.max_step >= opts.min_step
        && opts.max_step <= 0.5
        && (opts.min_step..=opts.max_step).contains(&opts.resolution))
    {
        return Err(Error::Invalid {
            what: "check options".into(),
            why: format!(
                "min_step {} m, resolution {} m and max_step {} m must satisfy 1e-4 ≤ min_step ≤ resolution ≤ max_step ≤ 0.5",
                opts.min_step, opts.resolution, opts.max_step
            ),
        });
    }
    Ok(())
}

/// A body for each link of `model` with geometry, in link order.
fn link_bodies(model: &CollisionModel) -> Vec<Body> {
    model
        .links()
        .iter()
        .enumerate()
        .filter(|(_, l)| !l.is_empty())
        .map(|(i, l)| Body {
            name: l.name.clone(),
            link: i,
            moving: model.is_moving(i),
            spheres: l.spheres.clone(),
            spheres_exact: l.shapes.iter().all(|(_, s)| matches!(s, Shape::Sphere(_))),
            bound: l.bound,
            exact: l
                .shapes
                .iter()
                .zip(&l.exact)
                .map(|(_, (o, e))| (*o, e.clone()))
                .collect(),
        })
        .collect()
}

/// Adds a body for each of `scene`'s attached objects; returns, for each, the links it may
/// touch (its own and its touch links).
fn add_attached(
    model: &CollisionModel,
    scene: &PlanningScene,
    bodies: &mut Vec<Body>,
) -> Result<Vec<Vec<usize>>> {
    let mut touch: Vec<Vec<usize>> = Vec::new();
    for a in scene.attached() {
        let link = model.link_index(&a.link).ok_or_else(|| Error::Invalid {
            what: format!("attached object {:?}", a.id),
            why: format!("{:?} is no link of {}", a.link, model.name()),
        })?;
        let mut allowed = vec![link];
        for t in &a.touch_links {
            allowed.push(model.link_index(t).ok_or_else(|| Error::Invalid {
                what: format!("attached object {:?}", a.id),
                why: format!("touch link {t:?} is no link of {}", model.name()),
            })?);
        }
        let e = a.shape.to_parry()?;
        let spheres = spheres::cover(&a.shape, &a.pose);
        bodies.push(Body {
            name: a.id.clone(),
            link,
            moving: model.is_moving(link),
            bound: bounding_sphere(&spheres),
            spheres,
            spheres_exact: matches!(a.shape, Shape::Sphere(_)),
            exact: vec![(a.pose * e.correction, e)],
        });
        touch.push(allowed);
    }
    Ok(touch)
}

/// What the robot is checked against of itself.
struct SelfChecks {
    /// Moving body pairs checked against each other.
    pairs: Vec<(usize, usize)>,
    /// The shapes of bodies that do not move, at their fixed poses.
    robot_obstacles: Vec<Obstacle>,
    /// For each body, the robot obstacles it is checked against.
    fixed_of: Vec<Vec<usize>>,
}

/// The pairs of `bodies` (the first `links` of them links, the others attached objects that
/// may touch `touch`) that are checked: moving pairs, and each moving body against the
/// shapes of the bodies that do not move, in their fixed poses.
fn self_checks(
    model: &CollisionModel,
    scene: &PlanningScene,
    bodies: &[Body],
    links: usize,
    touch: &[Vec<usize>],
) -> Result<SelfChecks> {
    // Bodies that do not move are obstacles to the ones that do, in their fixed poses.
    let fixed = model.link_poses(&vec![0.0; model.dof()]);
    let mut robot_obstacles = Vec::new();
    let mut fixed_of: Vec<Vec<usize>> = vec![Vec::new(); bodies.len()];
    let mut pairs = Vec::new();
    for i in 0..bodies.len() {
        for j in 0..bodies.len() {
            if i == j || !bodies[i].moving || (bodies[j].moving && j < i) {
                continue;
            }
            let (a, b) = (&bodies[i], &bodies[j]);
            let allowed = match (i >= links, j >= links) {
                (false, false) => model.acm().is_disabled(&a.name, &b.name),
                (true, false) => touch[i - links].contains(&b.link),
                (false, true) => touch[j - links].contains(&a.link),
                (true, true) => a.link == b.link,
            };
            if allowed {
                continue;
            }
            if b.moving {
                pairs.push((i, j));
            } else {
                for (shape, o) in fixed_shapes(model, scene, b, j, links) {
                    fixed_of[i].push(robot_obstacles.len());
                    robot_obstacles.push(Obstacle::new(&b.name, shape, &(fixed[b.link] * o))?);
                }
            }
        }
    }
    Ok(SelfChecks {
        pairs,
        robot_obstacles,
        fixed_of,
    })
}

/// The shapes of body `b` (number `j`; links first, then `scene`'s attached objects) and
/// their poses in its link's frame.
fn fixed_shapes<'a>(
    model: &'a CollisionModel,
    scene: &'a PlanningScene,
    b: &Body,
    j: usize,
    links: usize,
) -> Vec<(&'a Shape, Isometry3<f64>)> {
    let shapes: Vec<&Shape> = if j < links {
        model.links()[b.link]
            .shapes
            .iter()
            .map(|(_, s)| s)
            .collect()
    } else {
        scene
            .attached()
            .nth(j - links)
            .map(|a| vec![&a.shape])
            .unwrap_or_default()
    };
    let origins: Vec<Isometry3<f64>> = if j < links {
        model.links()[b.link]
            .shapes
            .iter()
            .map(|(o, _)| *o)
            .collect()
    } else {
        scene
            .attached()
            .nth(j - links)
            .map(|a| vec![a.pose])
            .unwrap_or_default()
    };
    shapes.into_iter().zip(origins).collect()
}

/// Each body's reach per planned joint ([`CollisionModel::link_reach`]); 0 when fixed.
fn body_reach(model: &CollisionModel, bodies: &[Body]) -> Vec<Vec<f64>> {
    bodies
        .iter()
        .map(|b| {
            if b.moving {
                model.link_reach(b.link, &b.spheres)
            } else {
                vec![0.0; model.dof()]
            }
        })
        .collect()
}

/// Each moving pair's reach per planned joint: 0 for a joint that moves both, that one's
/// reach for a joint that moves one of them.
fn pair_reach(pairs: &[(usize, usize)], body_reach: &[Vec<f64>]) -> Vec<Vec<f64>> {
    pairs
        .iter()
        .map(|&(i, j)| {
            body_reach[i]
                .iter()
                .zip(&body_reach[j])
                .map(|(&a, &b)| if a > 0.0 && b > 0.0 { 0.0 } else { a + b })
                .collect()
        })
        .collect()
}

/// For each body, every obstacle it is checked against: the `world` obstacles by index, then
/// its robot obstacles (`fixed_of`) after them; none for a body that does not move.
fn all_of(bodies: &[Body], fixed_of: &[Vec<usize>], world: usize) -> Vec<Vec<usize>> {
    bodies
        .iter()
        .zip(fixed_of)
        .map(|(b, fixed)| {
            if b.moving {
                (0..world).chain(fixed.iter().map(|&o| world + o)).collect()
            } else {
                Vec::new()
            }
        })
        .collect()
}

/// Per-state buffers for bodies that check `all_of` (one list per body) and `pairs` moving
/// pairs: outside an edge, each candidate's kept gap is read at edge parameter NaN.
fn scratch(all_of: &[Vec<usize>], pairs: usize) -> Scratch {
    Scratch {
        unlimited: all_of
            .iter()
            .map(|list| vec![(f64::NAN, 0.0); list.len()])
            .collect(),
        unlimited_pairs: vec![(f64::NAN, 0.0); pairs],
        ..Scratch::default()
    }
}

/// Where each body's world spheres go in the broad phase's arrays: `lo..hi`, padded to
/// `lo..end` (a multiple of [`LANES`]); nothing for a body that does not move.
fn layout(bodies: &[Body]) -> Vec<(usize, usize, usize)> {
    let mut layout = Vec::with_capacity(bodies.len());
    let mut at = 0;
    for b in bodies {
        let n = if b.moving { b.spheres.len() } else { 0 };
        let end = at + n.div_ceil(LANES) * LANES;
        layout.push((at, at + n, end));
        at = end;
    }
    layout
}
