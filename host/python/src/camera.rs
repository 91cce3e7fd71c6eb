//! `bot.camera`: PyRobot's camera (images, intrinsics, point clouds, frames) and its pan-tilt
//! head. Images reach numpy without a copy: the arrays own the Rust buffers.

use ferrobot::nav::{Cell, MapImage};
use ferrobot::perception::{DepthImage, PointCloud, RgbImage};
use nalgebra::Isometry3;
use pyo3::prelude::*;

use crate::convert::truthy;
use pyo3::types::PyTuple;

use crate::arm::finish;
use crate::convert::{self, integers};
use crate::errors::OrRaise;

/// The RGB-D camera on its pan-tilt head: PyRobot's `LoCoBotCamera`.
#[pyclass(frozen, module = "ferrobot._native")]
pub struct Camera {
    camera: ferrobot::Camera,
    head: Option<ferrobot::head::Head>,
    robot: ferrobot::Robot,
}

impl Camera {
    /// The camera of `robot`, with its head when it has one.
    pub fn new(
        camera: ferrobot::Camera,
        head: Option<ferrobot::head::Head>,
        robot: ferrobot::Robot,
    ) -> Self {
        Camera {
            camera,
            head,
            robot,
        }
    }

    fn head(&self, py: Python<'_>) -> PyResult<&ferrobot::head::Head> {
        self.head.as_ref().ok_or_else(|| {
            crate::errors::to_py(
                py,
                ferrobot::Error::NoComponent {
                    robot: self.robot.name().to_string(),
                    component: "pan-tilt head",
                },
            )
        })
    }

    fn pan_tilt(&self, py: Python<'_>, pan: f64, tilt: f64, wait: bool) -> PyResult<Py<PyAny>> {
        let head = self.head(py)?.clone();
        let m = py.detach(|| head.set_pan_tilt_async(pan, tilt)).py()?;
        finish(py, &self.robot, "pan-tilt motion", m, wait)
    }
}

/// `(trans (3,), rot (3, 3), T (4, 4))`, PyRobot's `get_link_transform`.
pub fn transform_tuple<'py>(py: Python<'py>, t: &Isometry3<f64>) -> PyResult<Bound<'py, PyAny>> {
    let p = ferrobot::Pose::from(*t);
    let mut rows = Vec::with_capacity(16);
    for (row, x) in p.rotation.iter().zip(p.position) {
        rows.extend(row);
        rows.push(x);
    }
    rows.extend([0.0, 0.0, 0.0, 1.0]);
    Ok(PyTuple::new(
        py,
        [
            convert::vec1(py, p.position.to_vec()),
            convert::mat3(py, p.rotation)?,
            convert::shaped(py, rows, &[4, 4])?,
        ],
    )?
    .into_any())
}

/// `(points (N, 3) float64 m, colours (N, 3) uint8)` from `n` points' coordinates and
/// colours, row by row.
fn points_tuple<'py>(
    py: Python<'py>,
    n: usize,
    pts: Vec<f64>,
    colours: &[[u8; 3]],
) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyTuple::new(
        py,
        [
            convert::shaped(py, pts, &[n, 3])?,
            convert::shaped(py, colours.concat(), &[n, 3])?,
        ],
    )?
    .into_any())
}

/// A cloud as `(points (N, 3) float64 m, colours (N, 3) uint8)`.
pub fn cloud_tuple(py: Python<'_>, cloud: PointCloud) -> PyResult<Bound<'_, PyAny>> {
    let pts: Vec<f64> = cloud.points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    points_tuple(py, cloud.points.len(), pts, &cloud.colours)
}

/// A colour image as `(H, W, 3)` uint8 (its buffer moved into numpy).
fn rgb_array(py: Python<'_>, img: RgbImage) -> PyResult<Bound<'_, PyAny>> {
    let shape = [img.height as usize, img.width as usize, 3];
    convert::shaped(py, img.data, &shape)
}

/// A depth image as `(H, W)` float32 m (its buffer moved into numpy).
fn depth_array(py: Python<'_>, img: DepthImage) -> PyResult<Bound<'_, PyAny>> {
    let shape = [img.height as usize, img.width as usize];
    convert::shaped(py, img.data, &shape)
}

/// `(grid (H, W) uint8: 0 free, 100 occupied, 255 unknown; row 0 at the map's bottom,
/// resolution m/cell, origin [x, y] m)`: an occupancy map as ROS's `OccupancyGrid` holds it.
pub fn occupancy_tuple(py: Python<'_>, m: MapImage) -> PyResult<Bound<'_, PyAny>> {
    let cells: Vec<u8> = m
        .cells
        .iter()
        .map(|c| match c {
            Cell::Free => 0,
            Cell::Occupied => 100,
            Cell::Unknown => 255,
        })
        .collect();
    let grid = convert::shaped(py, cells, &[m.height, m.width])?;
    Ok((grid, m.resolution, convert::vec1(py, m.origin.to_vec()))
        .into_pyobject(py)?
        .into_any())
}

#[pymethods]
impl Camera {
    /// The colour image: `(H, W, 3)` uint8, RGB.
    fn get_rgb<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        rgb_array(py, py.detach(|| self.camera.get_rgb()).py()?)
    }

    /// The depth image, aligned with the colour image: `(H, W)` float32, m (0 where unknown).
    fn get_depth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        depth_array(py, py.detach(|| self.camera.get_depth()).py()?)
    }

    /// Colour and depth of one frame: `(rgb (H, W, 3) uint8, depth (H, W) float32 m)`.
    fn get_rgb_depth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let (rgb, depth) = py.detach(|| self.camera.get_rgb_depth()).py()?;
        PyTuple::new(py, [rgb_array(py, rgb)?, depth_array(py, depth)?])
    }

    /// The intrinsic matrix `K` (3x3, px).
    fn get_intrinsics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let k = py.detach(|| self.camera.get_intrinsics()).py()?;
        convert::mat3(py, k)
    }

    /// The point cloud of the next frame, depths within the description's range:
    /// `(points (N, 3) m, colours (N, 3) uint8)`, in the camera's optical frame (`in_cam`) or
    /// in `base_link`.
    #[pyo3(signature = (in_cam=true))]
    fn get_current_pcd<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = truthy)] in_cam: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let cloud = py.detach(|| self.camera.get_current_pcd(in_cam)).py()?;
        cloud_tuple(py, cloud)
    }

    /// The 3-D points of pixels (rows `rs`, columns `cs`): `(points (N, 3) m, colours (N, 3)
    /// uint8)`, in `base_link` or the optical frame (`in_cam`). A pixel without depth gives
    /// NaNs (PyRobot gave the camera's origin).
    #[pyo3(signature = (rs, cs, in_cam=false))]
    fn pix_to_3dpt<'py>(
        &self,
        py: Python<'py>,
        rs: &Bound<'_, PyAny>,
        cs: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = truthy)] in_cam: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let rows = integers(rs, "rs")?;
        let cols = integers(cs, "cs")?;
        let px = py
            .detach(|| self.camera.pix_to_3dpt(&rows, &cols, in_cam))
            .py()?;
        let pts: Vec<f64> = px
            .points
            .iter()
            .flat_map(|p| p.map_or([f64::NAN; 3], |p| [p.x, p.y, p.z]))
            .collect();
        points_tuple(py, px.points.len(), pts, &px.colours)
    }

    /// Pose of URDF frame `src` in frame `tgt`: `(trans (3,), rot (3, 3), T (4, 4))`.
    fn get_link_transform<'py>(
        &self,
        py: Python<'py>,
        src: &str,
        tgt: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let t = py
            .detach(|| self.camera.get_link_transform(src, tgt))
            .py()?;
        transform_tuple(py, &t)
    }

    /// Pan to `pan` (rad), the tilt kept.
    #[pyo3(signature = (pan, wait=true))]
    fn set_pan(
        &self,
        py: Python<'_>,
        pan: f64,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let tilt = self.get_tilt(py)?;
        self.pan_tilt(py, pan, tilt, wait)
    }

    /// Tilt to `tilt` (rad; positive looks down), the pan kept.
    #[pyo3(signature = (tilt, wait=true))]
    fn set_tilt(
        &self,
        py: Python<'_>,
        tilt: f64,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        let pan = self.get_pan(py)?;
        self.pan_tilt(py, pan, tilt, wait)
    }

    /// Pan and tilt together (rad).
    #[pyo3(signature = (pan, tilt, wait=true))]
    fn set_pan_tilt(
        &self,
        py: Python<'_>,
        pan: f64,
        tilt: f64,
        #[pyo3(from_py_with = truthy)] wait: bool,
    ) -> PyResult<Py<PyAny>> {
        self.pan_tilt(py, pan, tilt, wait)
    }

    /// `[pan, tilt]` now, rad.
    fn get_state(&self, py: Python<'_>) -> PyResult<Vec<f64>> {
        let head = self.head(py)?;
        Ok(py.detach(|| head.get_state()).py()?.to_vec())
    }

    /// `[pan, tilt]` now, rad.
    #[getter(state)]
    fn state_now(&self, py: Python<'_>) -> PyResult<Vec<f64>> {
        self.get_state(py)
    }

    /// The pan now, rad.
    fn get_pan(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(self.get_state(py)?[0])
    }

    /// The tilt now, rad.
    fn get_tilt(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(self.get_state(py)?[1])
    }

    /// Back to pan 0, tilt 0.
    fn reset(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.pan_tilt(py, 0.0, 0.0, true)
    }

    fn __repr__(&self) -> String {
        format!("<ferrobot.Camera of {:?}>", self.robot.name())
    }
}
