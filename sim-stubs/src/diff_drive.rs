//! A differential-drive base: wheel actuators with lag, acceleration limit and deadband;
//! wheels whose true radius and track differ from the nominal ones; seeded wheel slip;
//! quantised encoders; round obstacles and the physics world's colliders ([`Surroundings`])
//! that the bumper meets and the body cannot enter (the wheels stall against them). The
//! ground-truth pose (the simulator's motion capture) is kept in `f64` beside everything the
//! robot measures.

use crate::rng::SimRng;
use ferrobot_protocol::geometry::wrap;

/// Physical parameters of a base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiffDriveParams {
    /// True left wheel radius, m.
    pub left_radius: f64,
    /// True right wheel radius, m.
    pub right_radius: f64,
    /// True track (wheel separation), m.
    pub track: f64,
    /// Encoder ticks per wheel revolution.
    pub ticks_per_rev: f64,
    /// First-order lag of the wheel speed controller, s.
    pub lag: f64,
    /// Largest wheel acceleration, m/s².
    pub accel_limit: f64,
    /// Largest wheel speed, m/s.
    pub max_speed: f64,
    /// Commanded wheel speeds below this magnitude do not move the wheel, m/s.
    pub deadband: f64,
    /// Standard deviation of the slip ratio per step (fraction of wheel travel lost).
    pub slip_std: f64,
    /// Mean slip ratio while accelerating, per m/s² of wheel acceleration.
    pub slip_per_accel: f64,
    /// Robot radius for contacts, m.
    pub body_radius: f64,
}

/// A round obstacle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obstacle {
    /// Centre x, m (world frame).
    pub x: f64,
    /// Centre y, m.
    pub y: f64,
    /// Radius, m.
    pub r: f64,
}

/// Which part of the bumper touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Contact {
    /// Left bumper.
    pub left: bool,
    /// Centre bumper.
    pub center: bool,
    /// Right bumper.
    pub right: bool,
}

/// Ground-truth pose, world frame: x, y (m), θ (rad).
pub type Pose = [f64; 3];

/// The base's body touching something of the world around it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Touch {
    /// Which thing is touched (stable for the life of the world).
    pub id: u64,
    /// Direction from the base's centre to the touching point, world frame (rad, from +x).
    pub bearing: f64,
    /// How far the body reaches into it, m (negative: a gap of that size).
    pub depth: f64,
    /// Fixed in the world (walls, furniture): the base cannot push it.
    pub fixed: bool,
}

/// What the base's body can touch besides its round obstacles: the physics world.
pub trait Surroundings {
    /// Everything within `gap` (m) of the base's bumper body, an upright cylinder of
    /// `radius` (m) centred at `(x, y)` (world frame, m) at bumper height.
    fn touches(&self, x: f64, y: f64, radius: f64, gap: f64) -> Vec<Touch>;
}

/// Largest gap at which the bumper reports a touch (its travel), m.
pub const BUMPER_GAP: f64 = 0.001;

/// The bumper segment a contact at `bearing` (rad, world) presses on a base heading `theta`,
/// if any (only the front half has a bumper).
fn press(contact: &mut Contact, bearing: f64, theta: f64) {
    let b = wrap(bearing - theta);
    if b.abs() <= std::f64::consts::FRAC_PI_2 {
        if b > 0.35 {
            contact.left = true;
        } else if b < -0.35 {
            contact.right = true;
        } else {
            contact.center = true;
        }
    }
}

/// The base plant.
#[derive(Debug, Clone)]
pub struct DiffDrive {
    /// Parameters.
    pub p: DiffDriveParams,
    /// Ground truth.
    pub truth: Pose,
    /// Commanded wheel surface speeds (left, right), m/s.
    pub target: (f64, f64),
    /// Actual wheel surface speeds at the nominal... true radius (left, right), m/s.
    pub speed: (f64, f64),
    /// Accumulated encoder ticks (left, right), fractional.
    pub ticks: (f64, f64),
    /// Obstacles.
    pub obstacles: Vec<Obstacle>,
    /// Current contact.
    pub contact: Contact,
    /// When `Some`, ground truth after every step is appended (for path plots).
    pub trace: Option<Vec<Pose>>,
    rng: SimRng,
}

impl DiffDrive {
    /// A base at the origin.
    pub fn new(p: DiffDriveParams, rng: SimRng) -> Self {
        Self {
            p,
            truth: [0.0; 3],
            target: (0.0, 0.0),
            speed: (0.0, 0.0),
            ticks: (0.0, 0.0),
            obstacles: Vec::new(),
            contact: Contact::default(),
            trace: None,
            rng,
        }
    }

    /// Command wheel surface speeds (left, right), m/s.
    pub fn command(&mut self, left: f64, right: f64) {
        let db = |v: f64| {
            if v.abs() < self.p.deadband {
                0.0
            } else {
                v.clamp(-self.p.max_speed, self.p.max_speed)
            }
        };
        self.target = (db(left), db(right));
    }

    /// Encoder counts as the 16-bit counters report them.
    pub fn encoder_counts(&self) -> (u16, u16) {
        (
            self.ticks.0.floor() as i64 as u16,
            self.ticks.1.floor() as i64 as u16,
        )
    }

    /// Advance by `dt` seconds (round obstacles only).
    pub fn step(&mut self, dt: f64) {
        self.step_among(dt, None);
    }

    /// The wheels' speeds after `dt` seconds towards their targets (actuator lag, acceleration
    /// limit, static friction); their accelerations, m/s².
    fn wheel_speeds(&mut self, dt: f64) -> [f64; 2] {
        let p = self.p;
        let mut next = [0.0; 2];
        let mut accel = [0.0; 2];
        for (k, (v, t)) in [(self.speed.0, self.target.0), (self.speed.1, self.target.1)]
            .into_iter()
            .enumerate()
        {
            let want = v + (t - v) * (dt / p.lag).min(1.0);
            let dv = (want - v).clamp(-p.accel_limit * dt, p.accel_limit * dt);
            next[k] = v + dv;
            // Static friction holds a wheel whose drive has stopped once it is slow.
            if t == 0.0 && next[k].abs() < p.deadband {
                next[k] = 0.0;
            }
            accel[k] = (next[k] - v) / dt;
        }
        self.speed = (next[0], next[1]);
        accel
    }

    /// Advance by `dt` seconds among round obstacles and `world`'s colliders: the bumper
    /// reports what the body touches; the body does not move deeper into a fixed collider
    /// (the wheels stall: neither the pose nor the encoders move that step) and pushes movable
    /// ones (the world moves them).
    pub fn step_among(&mut self, dt: f64, world: Option<&dyn Surroundings>) {
        let p = self.p;
        let before = (self.speed, self.ticks);
        let accel = self.wheel_speeds(dt);
        // Wheel rotation (what the encoders count) and ground travel (less slip).
        let rot_l = self.speed.0 * dt / p.left_radius;
        let rot_r = self.speed.1 * dt / p.right_radius;
        let k = p.ticks_per_rev / std::f64::consts::TAU;
        self.ticks.0 += rot_l * k;
        self.ticks.1 += rot_r * k;
        let slip = |rng: &mut SimRng, a: f64| {
            (p.slip_per_accel * a.abs() + rng.normal(p.slip_std).abs()).min(0.5)
        };
        let sl = slip(&mut self.rng, accel[0]);
        let sr = slip(&mut self.rng, accel[1]);
        let dl = rot_l * p.left_radius * (1.0 - sl);
        let dr = rot_r * p.right_radius * (1.0 - sr);
        let ds = 0.5 * (dl + dr);
        let dth = (dr - dl) / p.track;
        let [x, y, _] = self.truth;
        let [nx, ny, nth] = ferrobot_protocol::geometry::arc_step(self.truth, ds, dth);
        // Obstacles: the body cannot enter them; the bumper reports where it touches.
        let mut contact = Contact::default();
        let mut blocked = false;
        for o in &self.obstacles {
            let (ddx, ddy) = (o.x - nx, o.y - ny);
            let dist = (ddx * ddx + ddy * ddy).sqrt();
            if dist < o.r + p.body_radius {
                press(&mut contact, ddy.atan2(ddx), nth);
                let (odx, ody) = (o.x - x, o.y - y);
                let old = (odx * odx + ody * ody).sqrt();
                if dist < old {
                    blocked = true;
                }
            }
        }
        let mut stalled = false;
        if let Some(w) = world {
            let now = w.touches(nx, ny, p.body_radius, BUMPER_GAP);
            let mut was: Option<Vec<Touch>> = None;
            for t in &now {
                press(&mut contact, t.bearing, nth);
                // Deeper into something fixed than before the step: the wheels stall.
                if t.fixed && t.depth > 0.0 && (nx, ny) != (x, y) {
                    let was = was.get_or_insert_with(|| w.touches(x, y, p.body_radius, 0.0));
                    let old = was
                        .iter()
                        .find(|o| o.id == t.id)
                        .map_or(f64::NEG_INFINITY, |o| o.depth);
                    if t.depth > old + 1e-7 {
                        stalled = true;
                    }
                }
            }
        }
        self.contact = contact;
        if stalled {
            (self.speed, self.ticks) = before;
            self.speed = (0.0, 0.0);
        } else if blocked {
            self.truth = [x, y, nth];
        } else {
            self.truth = [nx, ny, nth];
        }
        if let Some(t) = &mut self.trace {
            t.push(self.truth);
        }
    }
}
