//! PyRobot's constructor dictionaries (`arm_config`, `base_config`, ...) and Ferrobot's own
//! keywords, read into a [`ferrobot::RobotBuilder`]. A key PyRobot's LoCoBot classes do not
//! take is refused, as PyRobot refuses it (there a `TypeError` from the class's constructor).

use std::path::PathBuf;

use ferrobot::config::BaseController;
use ferrobot::{Backend, RobotBuilder};
use pyo3::prelude::*;

use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyString};

use crate::errors::{invalid, OrRaise};

/// The keys each PyRobot dictionary takes: PyRobot's LoCoBot classes' keyword arguments.
pub const ARM_KEYS: [&str; 5] = [
    "use_moveit",
    "moveit_planner",
    "planning_time",
    "control_mode",
    "analytical_ik",
];
/// `base_config`'s keys (`LoCoBotBase`'s keyword arguments).
pub const BASE_KEYS: [&str; 4] = ["base_controller", "base_planner", "map_img_dir", "base"];
/// `gripper_config`'s keys (`LoCoBotGripper`'s).
pub const GRIPPER_KEYS: [&str; 1] = ["wait_time"];
/// `common_config`'s keys: the simulated world's scene (Habitat's `scene_path` in PyRobot).
pub const COMMON_KEYS: [&str; 2] = ["scene", "scene_path"];

/// The controller a PyRobot `base_controller` names: the description's names (PyRobot's
/// `ilqr` and `proportional` among them, and Ferrobot's `lqr` and `dwa`), and PyRobot's
/// `movebase` (ROS's planner and local controller), which is the dynamic window approach,
/// Ferrobot's obstacle-aware local controller. Anything else is `InvalidArgument`.
pub fn controller(py: Python<'_>, name: &str) -> PyResult<BaseController> {
    if name == "movebase" {
        return Ok(BaseController::Dwa);
    }
    name.parse().map_err(|_| {
        let names: Vec<String> = BaseController::ALL
            .iter()
            .map(|c| format!("{:?}", c.name()))
            .chain(["\"movebase\"".to_string()])
            .collect();
        invalid(
            py,
            "base_controller",
            &format!("one of {}", names.join(", ")),
            format!("{name:?}"),
        )
    })
}

/// Checks that `dict` (one of PyRobot's configuration dictionaries, or `None`) has only
/// `keys`; returns it.
pub fn checked<'py>(
    dict: Option<&Bound<'py, PyDict>>,
    what: &str,
    keys: &[&str],
) -> PyResult<Option<Bound<'py, PyDict>>> {
    let Some(d) = dict else { return Ok(None) };
    for k in d.keys() {
        let name: String = k.extract().unwrap_or_else(|_| format!("{k}"));
        if !keys.contains(&name.as_str()) {
            return Err(invalid(
                d.py(),
                what,
                &format!("keys among {}", keys.join(", ")),
                format!("the key {name:?}"),
            ));
        }
    }
    Ok(Some(d.clone()))
}

/// A string value of `dict[key]`, when present.
pub fn string(dict: &Option<Bound<'_, PyDict>>, key: &str) -> PyResult<Option<String>> {
    let Some(d) = dict else { return Ok(None) };
    let Some(v) = d.get_item(key)? else {
        return Ok(None);
    };
    if v.is_none() {
        return Ok(None);
    }
    v.extract::<String>()
        .map(Some)
        .map_err(|_| invalid(d.py(), key, "a string", format!("{v}")))
}

/// The environment variable that names the backend of a `Robot` whose `backend` is not given.
pub const BACKEND_ENV: &str = "FERROBOT_BACKEND";

/// The backend asked for: `backend` if given, else [`BACKEND_ENV`], else `"sim"`.
pub fn backend_spec(py: Python<'_>, backend: Option<String>) -> PyResult<String> {
    match backend {
        Some(b) => Ok(b),
        None => match std::env::var(BACKEND_ENV) {
            Ok(b) => Ok(b),
            Err(std::env::VarError::NotPresent) => Ok("sim".into()),
            Err(std::env::VarError::NotUnicode(v)) => {
                Err(invalid(py, BACKEND_ENV, "text", format!("{v:?}")))
            }
        },
    }
}

/// `Backend::Direct` from `"direct"` or `"direct:servo=PATH,base=PATH,camera=SOCKET"` (each key
/// at most once, any of them); `None` for anything else.
fn direct(spec: &str) -> Option<Backend> {
    let rest = match spec.strip_prefix("direct") {
        Some("") => "",
        Some(r) => r.strip_prefix(':').filter(|r| !r.is_empty())?,
        None => return None,
    };
    let (mut servo, mut base, mut camera) = (None, None, None);
    for pair in rest.split(',').filter(|_| !rest.is_empty()) {
        let (key, value) = pair.split_once('=')?;
        let slot = match key {
            "servo" => &mut servo,
            "base" => &mut base,
            "camera" => &mut camera,
            _ => return None,
        };
        if value.is_empty() || slot.is_some() {
            return None;
        }
        *slot = Some(PathBuf::from(value));
    }
    Some(Backend::Direct {
        servo,
        base,
        camera,
    })
}

/// The remote backend a string names: `"remote:ENDPOINT"` with, after commas,
/// `namespace=NS` and `credentials=FILE` (a `user:password` file), e.g.
/// `"remote:tcp/127.0.0.1:7447,namespace=/locobot"`; `None` for another backend, an error for
/// a malformed remote one.
pub fn remote(py: Python<'_>, spec: &str) -> PyResult<Option<Remote>> {
    let Some(rest) = spec.strip_prefix("remote:") else {
        return Ok(None);
    };
    let bad = |why: &str| {
        invalid(
            py,
            "backend",
            "\"remote:ENDPOINT[,namespace=NS][,credentials=FILE]\"",
            format!("{spec:?} ({why})"),
        )
    };
    let mut parts = rest.split(',');
    let endpoint = parts
        .next()
        .filter(|e| !e.is_empty())
        .ok_or_else(|| bad("no endpoint"))?;
    let mut r = Remote {
        access: ferrobot_bridge::Access::connect(endpoint),
        namespace: "/".into(),
    };
    for pair in parts {
        match pair.split_once('=') {
            Some(("namespace", ns)) if !ns.is_empty() => r.namespace = ns.into(),
            Some(("credentials", file)) if !file.is_empty() => {
                let c = ferrobot_bridge::Credentials::from_file(file)
                    .map_err(|e| bad(&e.to_string()))?;
                r.access.credentials = Some(c);
            }
            _ => return Err(bad(&format!("unknown option {pair:?}"))),
        }
    }
    Ok(Some(r))
}

/// `builder` on the backend `spec` names ([`backend`], [`remote`]); a remote robot is the
/// description `name` served elsewhere, and is connected to here (waiting up to 10 s for it).
pub fn with_backend(
    py: Python<'_>,
    builder: RobotBuilder,
    spec: &str,
    name: &str,
    seed: u64,
    realtime: bool,
) -> PyResult<RobotBuilder> {
    match remote(py, spec)? {
        Some(r) => {
            let timeout = std::time::Duration::from_secs(10);
            py.detach(|| {
                ferrobot_bridge::remote::attach(builder, name, &r.access, &r.namespace, timeout)
            })
            .map_err(ferrobot::Error::from)
            .py()
        }
        None => Ok(builder.backend(backend(py, spec, seed, realtime)?)),
    }
}

/// A served robot to drive through the remote backend ([`remote`]).
pub struct Remote {
    /// Where it is served, and the credentials.
    pub access: ferrobot_bridge::Access,
    /// Its namespace.
    pub namespace: String,
}

/// The backend a string names: `"sim"`, `"serial:PATH"`, `"emulated"`, `"emulated:ELF"`,
/// `"direct"`, `"direct:servo=PATH,base=PATH,camera=SOCKET"` or `"direct-emulated"`.
pub fn backend(py: Python<'_>, spec: &str, seed: u64, realtime: bool) -> PyResult<Backend> {
    let bad = || {
        invalid(
            py,
            "backend",
            "\"sim\", \"serial:PATH\", \"emulated\", \"emulated:ELF\", \"direct\", \
             \"direct:servo=PATH,base=PATH,camera=SOCKET\" or \"direct-emulated\"",
            format!("{spec:?}"),
        )
    };
    if spec == "sim" {
        return Ok(Backend::Sim { seed, realtime });
    }
    if let Some(path) = spec.strip_prefix("serial:") {
        if path.is_empty() {
            return Err(bad());
        }
        return Ok(Backend::Serial {
            path: PathBuf::from(path),
        });
    }
    if spec == "direct-emulated" {
        return Ok(Backend::DirectEmulated);
    }
    if let Some(b) = direct(spec) {
        return Ok(b);
    }
    if spec == "emulated" {
        return Ok(Backend::Emulated {
            firmware: PathBuf::from(ferrobot::backend::emulated::DEFAULT_FIRMWARE),
        });
    }
    if let Some(elf) = spec.strip_prefix("emulated:") {
        return Ok(Backend::Emulated {
            firmware: PathBuf::from(elf),
        });
    }
    Err(bad())
}

/// A Python scalar as a TOML value (for [`RobotBuilder::set`]).
pub fn toml_value(v: &Bound<'_, PyAny>, key: &str) -> PyResult<toml::Value> {
    let py = v.py();
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return v
            .extract::<i64>()
            .map(toml::Value::Integer)
            .map_err(|_| invalid(py, key, "an integer within 64 bits", format!("{v}")));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(items) = v.extract::<Vec<Bound<'_, PyAny>>>() {
        let values: PyResult<Vec<toml::Value>> = items.iter().map(|i| toml_value(i, key)).collect();
        return Ok(toml::Value::Array(values?));
    }
    Err(invalid(
        py,
        key,
        "a bool, number, string or list of them",
        format!("{v}"),
    ))
}

/// `base_config`'s `base_controller` as the description's `base.controller`.
pub fn base_controller(
    py: Python<'_>,
    builder: RobotBuilder,
    base_cfg: &Option<Bound<'_, PyDict>>,
) -> PyResult<RobotBuilder> {
    let Some(name) = string(base_cfg, "base_controller")? else {
        return Ok(builder);
    };
    Ok(builder.set("base.controller", controller(py, &name)?.name()))
}

/// PyRobot's IK tolerances (its `ARM.IK_POSITION_TOLERANCE` and `ARM.IK_ORIENTATION_TOLERANCE`,
/// the goal bounds it gave trac_ik), m and rad: the Python API's, so that a pose PyRobot's
/// programs ask of a 5-DOF arm, reachable only within them, is reached as PyRobot reached it.
/// The Rust API keeps the description's (1e-5 by default).
pub const PYROBOT_IK_TOLERANCES: (f64, f64) = (0.01, 0.1);

/// [`PYROBOT_IK_TOLERANCES`] on the builder of a robot with an arm (before the caller's
/// `overrides`, which win).
pub fn pyrobot_ik_tolerances(
    builder: RobotBuilder,
    source: &ferrobot::config::ConfigSource,
) -> RobotBuilder {
    let has_arm = ferrobot::profile::load(source, &[]).is_ok_and(|c| c.arm.is_some());
    if !has_arm {
        return builder;
    }
    let (position, orientation) = PYROBOT_IK_TOLERANCES;
    builder
        .set("arm.ik_position_tolerance", position)
        .set("arm.ik_orientation_tolerance", orientation)
}

/// `overrides` (dotted configuration keys to values) on the builder.
pub fn apply_overrides(
    mut builder: RobotBuilder,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<RobotBuilder> {
    if let Some(d) = overrides {
        for (k, v) in d.iter() {
            let key: String = k
                .extract()
                .map_err(|_| invalid(d.py(), "overrides", "string keys", format!("{k}")))?;
            builder = builder.set(&key, toml_value(&v, &key)?);
        }
    }
    Ok(builder)
}
