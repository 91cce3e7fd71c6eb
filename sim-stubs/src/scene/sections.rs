//! The scene file's sections checked into the scene's parts, in the order `parse` takes
//! them: the file itself, the robot's start, the floor, each object, the routes.

use nalgebra::{Isometry3, Translation3};

use super::file::{FloorFile, ObjectFile, RobotFile, RouteFile, SceneFile};
use super::{Body, Ctx, Result, Route, Shape, Waypoint, FLOOR_THICKNESS, MAX_EXTENT};

impl Ctx<'_> {
    /// The file's TOML as its tables, an error naming the key where it does not fit.
    pub(super) fn deserialize(&self, text: &str) -> Result<SceneFile> {
        let de = toml::Deserializer::parse(text).map_err(|e| self.err("-", e.message()))?;
        serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            self.err(
                if key.is_empty() || key == "." {
                    "-".to_string()
                } else {
                    key
                },
                e.inner().message().to_string(),
            )
        })
    }

    /// The robot's start pose (x, y in m, heading in rad) and height, m.
    pub(super) fn robot(&self, robot: Option<&RobotFile>) -> Result<([f64; 3], f64)> {
        Ok(match robot {
            Some(r) => {
                self.finite("robot.pose", r.pose[0], -MAX_EXTENT, MAX_EXTENT)?;
                self.finite("robot.pose", r.pose[1], -MAX_EXTENT, MAX_EXTENT)?;
                self.finite("robot.pose", r.pose[2], -100.0, 100.0)?;
                self.finite("robot.height", r.height, 0.0, 10.0)?;
                (r.pose, r.height)
            }
            None => ([0.0; 3], 0.0),
        })
    }

    /// The floor: a slab whose top is at z = 0.
    pub(super) fn floor(&self, f: &FloorFile) -> Result<Body> {
        let sx = self.positive("floor.size", f.size[0])?;
        let sy = self.positive("floor.size", f.size[1])?;
        let colour = self.colour("floor.colour", f.colour)?;
        let texture = f
            .texture
            .as_ref()
            .map(|t| self.texture("floor.texture", t, colour))
            .transpose()?;
        Ok(Body {
            id: "floor".into(),
            shape: Shape::Box([sx, sy, FLOOR_THICKNESS]),
            pose: Isometry3::translation(0.0, 0.0, -FLOOR_THICKNESS / 2.0),
            mass: 0.0,
            friction: self.finite("floor.friction", f.friction, 0.0, 10.0)?,
            colour,
            texture,
            fixed: true,
        })
    }

    /// Object `i`, static or movable.
    pub(super) fn object(&self, i: usize, o: &ObjectFile) -> Result<Body> {
        let key = format!("object[{i}]");
        if o.id.is_empty() || o.id.len() > 64 {
            return Err(self.err(format!("{key}.id"), "an id of 1-64 characters"));
        }
        let shape = self.shape(&key, o)?;
        let rotation = self.rotation(&key, o)?;
        let mut p = [0.0; 3];
        for (k, v) in p.iter_mut().zip(o.position) {
            *k = self.finite(&format!("{key}.position"), v, -MAX_EXTENT, MAX_EXTENT)?;
        }
        let mass = self.mass(&key, o)?;
        if !o.fixed && shape.volume() <= 0.0 {
            return Err(self.err(
                format!("{key}.mesh"),
                "a movable mesh must be a closed surface (its volume is 0)",
            ));
        }
        let colour = self.colour(&format!("{key}.colour"), o.colour)?;
        let texture = o
            .texture
            .as_ref()
            .map(|t| self.texture(&format!("{key}.texture"), t, colour))
            .transpose()?;
        Ok(Body {
            id: o.id.clone(),
            shape,
            pose: Isometry3::from_parts(Translation3::new(p[0], p[1], p[2]), rotation),
            mass,
            friction: self.finite(&format!("{key}.friction"), o.friction, 0.0, 10.0)?,
            colour,
            texture,
            fixed: o.fixed,
        })
    }

    /// An object's mass, kg: none for a static one, (0, 1000] for a movable one.
    fn mass(&self, key: &str, o: &ObjectFile) -> Result<f64> {
        Ok(match (o.fixed, o.mass) {
            (true, Some(_)) => {
                return Err(self.err(format!("{key}.mass"), "a static object has no mass"))
            }
            (true, None) => 0.0,
            (false, Some(m)) => {
                if !(m.is_finite() && m > 0.0 && m <= 1000.0) {
                    return Err(self.err(
                        format!("{key}.mass"),
                        format!("{m} is not a mass in (0, 1000] kg"),
                    ));
                }
                m
            }
            (false, None) => {
                return Err(self.err(format!("{key}.mass"), "a movable object needs a mass"))
            }
        })
    }

    /// The scripted routes, each with a unique name.
    pub(super) fn routes(&self, raw: &[RouteFile]) -> Result<Vec<Route>> {
        let mut routes: Vec<Route> = Vec::new();
        for (i, r) in raw.iter().enumerate() {
            let key = format!("route[{i}]");
            if r.name.is_empty() || r.name.len() > 64 || routes.iter().any(|o| o.name == r.name) {
                return Err(self.err(format!("{key}.name"), "a unique name of 1-64 characters"));
            }
            if r.waypoints.is_empty() || r.waypoints.len() > 1000 {
                return Err(self.err(format!("{key}.waypoints"), "1-1000 waypoints"));
            }
            let mut waypoints = Vec::new();
            for (k, w) in r.waypoints.iter().enumerate() {
                waypoints.push(self.waypoint(&format!("{key}.waypoints[{k}]"), w)?);
            }
            routes.push(Route {
                name: r.name.clone(),
                waypoints,
                head_tilt: self.finite(&format!("{key}.head_tilt"), r.head_tilt, -1.6, 1.6)?,
            });
        }
        Ok(routes)
    }

    /// One waypoint, `[x, y]`, `[x, y, heading]` or `[x, y, heading, wait]`.
    fn waypoint(&self, wk: &str, w: &[f64]) -> Result<Waypoint> {
        if !(2..=4).contains(&w.len()) {
            return Err(self.err(wk, "[x, y], [x, y, heading] or [x, y, heading, wait]"));
        }
        let x = self.finite(wk, w[0], -MAX_EXTENT, MAX_EXTENT)?;
        let y = self.finite(wk, w[1], -MAX_EXTENT, MAX_EXTENT)?;
        let th = w
            .get(2)
            .map(|&t| self.finite(wk, t, -100.0, 100.0))
            .transpose()?;
        let wait = w
            .get(3)
            .map(|&t| self.finite(wk, t, 0.0, 600.0))
            .transpose()?
            .unwrap_or(0.0);
        Ok(Waypoint {
            xy: [x, y],
            heading: th,
            wait,
        })
    }
}
