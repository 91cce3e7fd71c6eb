//! `ferrobot.SharedWorld`: a simulated world several robots share on one clock
//! ([`ferrobot::SharedWorld`]); robots join it with `Robot(..., world=w, start_pose=...)`.

use pyo3::prelude::*;

use crate::errors::OrRaise;

/// A simulated world several robots share: one scene, one physics world, one clock. Each
/// `Robot(name, world=w, start_pose=[x, y, theta])` joins it; what one does the others meet
/// (bumpers, cameras), and one robot's wait lets every robot's time pass and steps their
/// motions.
#[pyclass(name = "SharedWorld", module = "ferrobot", frozen)]
pub struct SharedWorld {
    pub(crate) world: ferrobot::SharedWorld,
}

#[pymethods]
impl SharedWorld {
    /// A world of a bundled scene (`"empty"`, `"tabletop"`, `"apartment"`, `"shelf"`,
    /// `"clutter"`) or a scene file, no robot in it yet.
    #[new]
    #[pyo3(signature = (scene="empty"))]
    fn new(py: Python<'_>, scene: &str) -> PyResult<Self> {
        let world = py.detach(|| ferrobot::SharedWorld::new(scene)).py()?;
        Ok(SharedWorld { world })
    }

    /// How many robots have joined.
    fn robots(&self) -> usize {
        self.world.robots()
    }

    /// The world's clock, s.
    fn time(&self) -> f64 {
        self.world.time()
    }

    /// Robot `i`'s (in joining order) true base pose `[x, y, theta]` in the world (m, rad):
    /// the simulator's ground truth.
    fn true_pose(&self, i: usize) -> PyResult<[f64; 3]> {
        let t = self
            .world
            .truth(i)
            .ok_or_else(|| {
                ferrobot::Error::Usage(format!(
                    "robot {i}: the world has {} robots",
                    self.world.robots()
                ))
            })
            .py()?;
        let p = t.root.translation.vector;
        Ok([p.x, p.y, t.root.rotation.euler_angles().2])
    }

    fn __repr__(&self) -> String {
        format!("{:?}", self.world)
    }
}
