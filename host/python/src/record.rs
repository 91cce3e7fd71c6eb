//! Recording from Python: `ferrobot.Recorder(robot, path)` records the robot into an MCAP file
//! with ROS 2 schemas (`ferrobot-record`) until `finish()` or the end of a `with` block;
//! `ferrobot.export_lerobot(recordings, out, tasks)` makes a LeRobot dataset of recordings.

use std::path::PathBuf;

use parking_lot::Mutex;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::OrRaise;
use crate::robot::Robot;

/// A recording under way: the robot's joint states, odometry, transforms, gripper, commands,
/// faults, camera frames, SLAM's pose and URDF into an MCAP file that Foxglove, rosbag2 and
/// rosbags open. Use it as a context manager, or call `finish()`.
#[pyclass(module = "ferrobot")]
pub struct Recorder {
    inner: Mutex<Option<ferrobot_record::Recorder>>,
    path: PathBuf,
}

fn stats_dict<'py>(
    py: Python<'py>,
    s: &ferrobot_record::RecordStats,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("messages", s.written.messages)?;
    d.set_item("frames", s.written.frames)?;
    d.set_item("telemetry", s.written.telemetry)?;
    d.set_item("events", s.written.events)?;
    d.set_item("frames_dropped", s.frames_dropped)?;
    d.set_item("telemetry_dropped", s.telemetry_dropped)?;
    d.set_item("events_dropped", s.events_dropped)?;
    Ok(d)
}

#[pymethods]
impl Recorder {
    /// Start recording `robot` into the new file `path` (a path that exists is refused:
    /// `ferrobot.errors.PathExists`); `camera=False` leaves the frames out.
    #[new]
    #[pyo3(signature = (robot, path, camera=true))]
    fn new(robot: &Robot, path: PathBuf, camera: bool) -> PyResult<Self> {
        let opts = ferrobot_record::RecordOptions {
            camera,
            ..Default::default()
        };
        let r = ferrobot_record::Recorder::start(&robot.robot, &path, opts)
            .map_err(ferrobot::Error::from)
            .py()?;
        Ok(Recorder {
            inner: Mutex::new(Some(r)),
            path,
        })
    }

    /// The file being written.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// What has been written and dropped so far (a dict of counts).
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self
            .inner
            .lock()
            .as_ref()
            .map(|r| r.stats())
            .unwrap_or_default();
        stats_dict(py, &s)
    }

    /// End the recording (its index and footer) and return its counts; the first error it met
    /// is raised (`ferrobot.errors.Error`; a full disk is an `OSError`-like I/O error). A
    /// second call returns None.
    fn finish<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(r) = self.inner.lock().take() else {
            return Ok(None);
        };
        let s = py
            .detach(|| r.finish())
            .map_err(ferrobot::Error::from)
            .py()?;
        Ok(Some(stats_dict(py, &s)?))
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, py: Python<'_>, _args: &Bound<'_, pyo3::types::PyTuple>) -> PyResult<bool> {
        self.finish(py)?;
        Ok(false)
    }
}

/// The tasks argument: one string for all recordings, or a list of one per recording.
fn tasks_of(tasks: &Bound<'_, PyAny>) -> PyResult<ferrobot_record::lerobot::Tasks> {
    use ferrobot_record::lerobot::Tasks;
    if let Ok(t) = tasks.extract::<String>() {
        return Ok(Tasks::All(t));
    }
    tasks.extract().map(Tasks::Each).map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err("tasks: a string, or a list of one per recording")
    })
}

/// Export `recordings` (MCAP files, one episode each, in order) as a new LeRobot dataset
/// (format v3.0) in `out`, a directory that must not exist; `tasks` is one string for all or
/// one per recording. `fps` frames a second (1 to 1000); `camera=False` leaves the colour
/// frames out. Returns the counts (episodes, frames, tasks, images, truncated).
#[pyfunction]
#[pyo3(signature = (recordings, out, tasks, fps=30, camera=true, robot_type=None))]
pub fn export_lerobot<'py>(
    py: Python<'py>,
    recordings: Vec<PathBuf>,
    out: PathBuf,
    tasks: &Bound<'py, PyAny>,
    fps: u32,
    camera: bool,
    robot_type: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    use ferrobot_record::lerobot::{export, Demonstration, ExportOptions};
    let demos = Demonstration::of(recordings, tasks_of(tasks)?)
        .map_err(ferrobot::Error::from)
        .py()?;
    let opts = ExportOptions {
        fps,
        camera,
        robot_type,
    };
    let s = py
        .detach(|| export(&demos, &out, &opts))
        .map_err(ferrobot::Error::from)
        .py()?;
    let d = PyDict::new(py);
    d.set_item("episodes", s.episodes)?;
    d.set_item("frames", s.frames)?;
    d.set_item("tasks", s.tasks)?;
    d.set_item("images", s.images)?;
    d.set_item("truncated", s.truncated)?;
    Ok(d)
}
