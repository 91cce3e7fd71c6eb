//! Measuring one state: a lower bound (m) of each moving body's clearance to its obstacles,
//! the voxels and the other moving bodies, coarse bound first, then spheres, then exact
//! shapes only where the cheaper bound limits the step; or the first contact.

use std::sync::atomic::Ordering;

use nalgebra::Isometry3;

use super::broad::{sphere_spheres_gap, spheres_gap, Placed};
use super::exact::exact_gap;
use super::obstacle::Grid;
use super::{still_far, Body, Checker, Contact, Scratch, Speeds};
use crate::shape::Sdf;
use crate::spheres::Sphere;

impl Checker {
    /// The gap (m) between the robot at `q` and the nearest of the world's objects and voxels
    /// (not its own links), without the padding: exact (GJK's certified bound) where below
    /// `cap`, at most `cap`; 0 at a contact and for a `q` outside the limits.
    pub fn world_gap(&self, q: &[f64], cap: f64) -> f64 {
        if !self.within_limits(q) || cap.is_nan() {
            return 0.0;
        }
        let mut s = self.scratch.borrow_mut();
        let s = &mut *s;
        self.model.link_poses_into(q, &mut s.values, &mut s.poses);
        s.spheres.reset(&self.layout);
        let mut gap = cap.max(0.0);
        for (bi, b) in self.bodies.iter().enumerate() {
            if !b.moving {
                continue;
            }
            let pose = s.poses[b.link];
            let centre = pose * b.bound.centre;
            for o in &self.obstacles {
                if o.coarse_gap(&centre, b.bound.radius) >= gap {
                    continue;
                }
                let d = exact_gap(
                    &b.exact,
                    &pose,
                    &o.placed,
                    &Isometry3::identity(),
                    gap,
                    &self.counters,
                );
                gap = gap.min(d);
            }
            if let Some(g) = &self.grid {
                s.spheres.place(bi, &b.spheres, &pose, self.layout[bi]);
                match self.grid_gap(g, b, bi, s, gap, 0.0) {
                    Ok(d) => gap = gap.min(d),
                    Err(_) => return 0.0,
                }
            }
            if gap <= 0.0 {
                return 0.0;
            }
        }
        gap
    }

    /// A lower bound (m, at most `cap`) of how far every robot point at `q` may move while
    /// no contact can occur: the clearance to the scene and to links that do not move, and
    /// half the clearance between moving links. A contact is an error naming the bodies.
    pub(super) fn measure(&self, q: &[f64], cap: f64) -> std::result::Result<f64, Contact> {
        self.measure_with(q, None, cap, (cap * 0.5).max(self.opts.min_step))
    }

    /// How far (in units of `speed`) the robot may go from `q` with no contact possible: each
    /// body's gap divided by its `speed` (m of point motion per unit; a pair's by the sum of
    /// both), at most `cap`. Without `speed`, every body moves at 1 (the result is
    /// [`Checker::measure`]'s clearance). Exact distances are computed only where the spheres'
    /// bound is below `exact_below` (m; 0: only where spheres overlap, to tell contact from
    /// none).
    pub(super) fn measure_with(
        &self,
        q: &[f64],
        speed: Option<&Speeds>,
        cap: f64,
        exact_below: f64,
    ) -> std::result::Result<f64, Contact> {
        self.counters.states.fetch_add(1, Ordering::Relaxed);
        let mut s = self.scratch.borrow_mut();
        let s = &mut *s;
        self.model.link_poses_into(q, &mut s.values, &mut s.poses);
        s.spheres.reset(&self.layout);
        s.bounds.clear();
        s.bounds.extend(self.bodies.iter().map(|b| Sphere {
            centre: s.poses[b.link] * b.bound.centre,
            radius: b.bound.radius,
        }));
        let mut clear = cap;
        // Counted here and added once: an atomic add per obstacle costs more than the test.
        let mut checks = 0u64;
        let speed_of = |b: usize| speed.map_or(1.0, |v| v.body[b]).max(1e-9);
        let mut found = Ok(());
        for (bi, b) in self.bodies.iter().enumerate() {
            if !b.moving {
                continue;
            }
            found = self.measure_body(s, bi, speed_of(bi), exact_below, &mut clear, &mut checks);
            if found.is_err() {
                break;
            }
        }
        if found.is_ok() {
            found = self.measure_pairs(s, speed, exact_below, &mut clear, &mut checks);
        }
        self.counters
            .sphere_checks
            .fetch_add(checks, Ordering::Relaxed);
        found.map(|()| clear.max(0.0))
    }

    /// [`Checker::measure_with`] for moving body `bi` (moving at `m`) against its obstacles
    /// and the voxels: lowers `clear` (in units of the speed) and counts its sphere-level
    /// tests into `checks`; the first contact is an error.
    fn measure_body(
        &self,
        s: &mut Scratch,
        bi: usize,
        m: f64,
        exact_below: f64,
        clear: &mut f64,
        checks: &mut u64,
    ) -> std::result::Result<(), Contact> {
        let b = &self.bodies[bi];
        let bound = s.bounds[bi];
        let (lo, hi, end) = self.layout[bi];
        let (list, far, t) = if s.near.on {
            (
                &s.near.obstacles[bi][..],
                &mut s.near.obstacle_far[bi][..],
                s.near.t,
            )
        } else {
            (&self.all_of[bi][..], &mut s.unlimited[bi][..], f64::NAN)
        };
        for (&k, far) in list.iter().zip(far.iter_mut()) {
            // Its gap at another state of the edge still clears this step ([`Near`]).
            if still_far(*far, t, *clear) {
                continue;
            }
            // Remember the gap, in units of the edge parameter.
            let mut keep = |gap: f64| *far = (t, gap / m);
            let o = self.obstacle(k);
            let pad = self.padding_of(k);
            *checks += 1;
            let coarse = o.coarse_gap(&bound.centre, bound.radius) - pad;
            if coarse >= *clear * m {
                keep(coarse);
                continue;
            }
            *checks += (hi - lo) as u64;
            let w = &mut s.spheres;
            w.place(bi, &b.spheres, &s.poses[b.link], self.layout[bi]);
            let lb = f64::from(spheres_gap(
                &o.sdf,
                &o.inv,
                &w.x[lo..end],
                &w.y[lo..end],
                &w.z[lo..end],
                &w.r[lo..end],
            )) - pad;
            if lb >= *clear * m {
                keep(lb);
                continue;
            }
            // The spheres limit the step: the shapes' own bound, tighter.
            let d = exact_gap(
                &b.exact,
                &s.poses[b.link],
                &o.placed,
                &Isometry3::identity(),
                exact_below + pad,
                &self.counters,
            ) - pad;
            if d <= 0.0 {
                return Err(Contact {
                    a: b.name.clone(),
                    b: o.id.clone(),
                });
            }
            let d = d.max(lb);
            keep(d);
            *clear = clear.min(d / m);
        }
        if let Some(g) = &self.grid {
            s.spheres
                .place(bi, &b.spheres, &s.poses[b.link], self.layout[bi]);
            let gap = self.grid_gap(g, b, bi, s, *clear * m, self.opts.padding)?;
            *clear = clear.min(gap / m);
        }
        Ok(())
    }

    /// [`Checker::measure_with`] for the moving pairs, at their relative speed: lowers
    /// `clear` and counts into `checks`; the first contact is an error.
    fn measure_pairs(
        &self,
        s: &mut Scratch,
        speed: Option<&Speeds>,
        exact_below: f64,
        clear: &mut f64,
        checks: &mut u64,
    ) -> std::result::Result<(), Contact> {
        let (pairs, far, t) = if s.near.on {
            (&s.near.pairs[..], &mut s.near.pair_far[..], s.near.t)
        } else {
            (&self.all_pairs[..], &mut s.unlimited_pairs[..], f64::NAN)
        };
        for (&p, far) in pairs.iter().zip(far.iter_mut()) {
            let (i, j) = self.pairs[p];
            if still_far(*far, t, *clear) {
                continue;
            }
            let (bi, bj) = (&s.bounds[i], &s.bounds[j]);
            let m = speed.map_or(2.0, |v| v.pair[p].max(1e-9));
            let mut keep = |gap: f64| *far = (t, gap / m);
            *checks += 1;
            let gap = (bi.centre - bj.centre).norm() - bi.radius - bj.radius;
            if gap >= m * *clear {
                keep(gap);
                continue;
            }
            let reach = (m * *clear) as f32;
            let w = &mut s.spheres;
            let lb = f64::from(self.pair_spheres_gap(w, &s.poses, (i, j), bj, reach, checks));
            if lb >= m * *clear {
                keep(lb);
                continue;
            }
            // The spheres limit the step: the shapes' own bound, tighter.
            let (a, b) = (&self.bodies[i], &self.bodies[j]);
            let d = exact_gap(
                &a.exact,
                &s.poses[a.link],
                &b.exact,
                &s.poses[b.link],
                2.0 * exact_below,
                &self.counters,
            );
            if d <= 0.0 {
                return Err(Contact {
                    a: a.name.clone(),
                    b: b.name.clone(),
                });
            }
            let d = d.max(lb);
            keep(d);
            *clear = clear.min(d / m);
        }
        Ok(())
    }

    /// A lower bound (m) of the gap between the spheres of moving bodies `i` and `j` (whose
    /// bound is `bj`), each sphere of `i` first tested against `bj` and against `j`'s spheres
    /// only where nearer than `reach`; counts the tests into `checks`.
    fn pair_spheres_gap(
        &self,
        w: &mut Placed,
        poses: &[Isometry3<f64>],
        (i, j): (usize, usize),
        bj: &Sphere,
        reach: f32,
        checks: &mut u64,
    ) -> f32 {
        let (li, hi_, _) = self.layout[i];
        let (lj, hj, ej) = self.layout[j];
        w.place(
            i,
            &self.bodies[i].spheres,
            &poses[self.bodies[i].link],
            self.layout[i],
        );
        w.place(
            j,
            &self.bodies[j].spheres,
            &poses[self.bodies[j].link],
            self.layout[j],
        );
        let (cx, cy, cz) = (bj.centre.x as f32, bj.centre.y as f32, bj.centre.z as f32);
        let rj = bj.radius as f32;
        let mut lb = f32::INFINITY;
        for k in li..hi_ {
            let (x, y, z, r) = (w.x[k], w.y[k], w.z[k], w.r[k]);
            // This sphere against the other body's bound first.
            *checks += 1;
            let far = ((cx - x).powi(2) + (cy - y).powi(2) + (cz - z).powi(2)).sqrt() - rj - r;
            if far >= reach {
                lb = lb.min(far);
                continue;
            }
            *checks += (hj - lj) as u64;
            let g = sphere_spheres_gap(
                (x, y, z, r),
                (&w.x[lj..ej], &w.y[lj..ej], &w.z[lj..ej], &w.r[lj..ej]),
            );
            lb = lb.min(g);
        }
        lb
    }

    /// A lower bound of body `b`'s gap to the voxels less `pad` (at most `cap`), or the
    /// contact (closer than `pad`).
    fn grid_gap(
        &self,
        g: &Grid,
        b: &Body,
        bi: usize,
        s: &Scratch,
        cap: f64,
        pad: f64,
    ) -> std::result::Result<f64, Contact> {
        let (lo, hi, _) = self.layout[bi];
        let w = &s.spheres;
        let size = g.size as f32;
        let half = size / 2.0;
        let mut clear = cap;
        for k in lo..hi {
            let (x, y, z) = (w.x[k], w.y[k], w.z[k]);
            let reach = w.r[k] + (clear + pad) as f32;
            for i in g.span(0, x - reach, x + reach) {
                for j in g.span(1, y - reach, y + reach) {
                    for kk in g.column(i, j, g.span(2, z - reach, z + reach)) {
                        self.counters.sphere_checks.fetch_add(1, Ordering::Relaxed);
                        let c = [
                            (i as f32 + 0.5) * size,
                            (j as f32 + 0.5) * size,
                            (kk as f32 + 0.5) * size,
                        ];
                        let sdf = Sdf::Box {
                            centre: c,
                            half: [half; 3],
                        };
                        let lb = f64::from(sdf.distance(x, y, z) - w.r[k]) - pad;
                        if lb >= clear {
                            continue;
                        }
                        let pose = Isometry3::translation(
                            f64::from(c[0]),
                            f64::from(c[1]),
                            f64::from(c[2]),
                        );
                        let d = exact_gap(
                            &b.exact,
                            &s.poses[b.link],
                            &g.cube,
                            &pose,
                            pad,
                            &self.counters,
                        ) - pad;
                        if d <= 0.0 {
                            return Err(Contact {
                                a: b.name.clone(),
                                b: format!("voxel [{i}, {j}, {kk}]"),
                            });
                        }
                        clear = clear.min(d);
                    }
                }
            }
        }
        Ok(clear)
    }
}
