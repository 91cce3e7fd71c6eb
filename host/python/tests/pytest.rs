//! The Python package's tests, run by pytest against the extension this test build made.
//!
//! Cargo builds `ferrobot._native` (the crate's cdylib) beside this test's executable, in the
//! test build's own profile and features: CI builds the extension once, with the rest of the
//! workspace, instead of a second, release build through maturin. Each test here stages the
//! package (the pure-Python half from `python/ferrobot`, the shared library as
//! `_native.abi3.so`) in a directory of its own and runs one file of `tests/python` with the
//! peers' interpreter ([`ferrobot_peers::for_test`]: numpy and pytest, from
//! `scripts/python-env.sh python`), so that nextest runs the files side by side.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The crate's root.
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The extension's shared library, built beside this executable.
fn extension() -> PathBuf {
    let exe = std::env::current_exe().expect("the test's own path");
    let deps = exe.parent().expect("the test's directory");
    let name = format!(
        "{}_native{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    );
    [deps.join(&name), deps.join("..").join(&name)]
        .into_iter()
        .find(|p| p.exists())
        .unwrap_or_else(|| panic!("{name} is not beside {}", exe.display()))
}

/// Links `src`'s entries into `dst` (a fresh directory), recursively for directories.
fn link_tree(src: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).expect("staging directory");
    for entry in std::fs::read_dir(src).expect("package sources") {
        let entry = entry.expect("a directory entry");
        let name = entry.file_name();
        if name == "__pycache__" {
            continue;
        }
        let path = entry.path();
        if path.is_dir() {
            link_tree(&path, &dst.join(&name));
        } else {
            std::os::unix::fs::symlink(&path, dst.join(&name)).expect("a symlink");
        }
    }
}

/// The package staged for one test process: `DIR/ferrobot/...`; returns DIR.
fn stage(test: &str) -> PathBuf {
    let dir = root()
        .join("../../target/python-stage")
        .join(format!("{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let pkg = dir.join("ferrobot");
    link_tree(&root().join("python/ferrobot"), &pkg);
    std::os::unix::fs::symlink(extension(), pkg.join("_native.abi3.so")).expect("a symlink");
    dir
}

/// Runs pytest on `tests/python/FILE` with `args` (its tests failing this test).
fn pytest(file: &str) {
    pytest_with(file, &[]);
}

/// [`pytest`] with pytest's own arguments `args`.
fn pytest_with(file: &str, args: &[&str]) {
    pytest_env(file, args, &[]);
}

/// [`pytest_with`] with the environment variables `env` set.
fn pytest_env(file: &str, args: &[&str], env: &[(&str, &str)]) {
    let modules = "numpy, pytest, yourdfpy, absl, ipykernel, nbclient";
    let Some(python) = ferrobot_peers::for_test(modules, "scripts/python-env.sh python") else {
        return;
    };
    let test = format!("{}{}", file.trim_end_matches(".py"), args.concat());
    let dir = stage(&test);
    // pytest's own `tmp_path`s under a directory removed when this test ends (by default they
    // stay in the system's temporary directory, three runs' worth).
    let basetemp = tempfile::tempdir().expect("temporary directory");
    let status = Command::new(python)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "-rs", file])
        .arg("--basetemp")
        .arg(basetemp.path().join("pytest"))
        .args(args)
        .current_dir(root().join("tests/python"))
        .env("PYTHONPATH", &dir)
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .env("FERROBOT_REPO", root().join("../.."))
        .envs(env.iter().copied())
        .status()
        .expect("pytest runs");
    let _ = std::fs::remove_dir_all(&dir);
    assert!(status.success(), "pytest {file} failed: {status}");
}

/// One test per file of `tests/python`, named after it.
macro_rules! files {
    ($($name:ident),* $(,)?) => {
        $(
            #[test]
            fn $name() {
                pytest(concat!(stringify!($name), ".py"));
            }
        )*
        /// Every `test_*.py` has its test above.
        #[test]
        fn every_file_runs() {
            let listed = [$(concat!(stringify!($name), ".py")),*];
            for entry in std::fs::read_dir(root().join("tests/python")).unwrap() {
                let name = entry.unwrap().file_name().into_string().unwrap();
                if name.starts_with("test_") && name.ends_with(".py") {
                    assert!(listed.contains(&name.as_str()), "{name} is not in tests/pytest.rs");
                }
            }
        }
    };
}

files!(
    test_api,
    test_examples,
    test_hostile,
    test_interrupt,
    test_jupyter,
    test_pyrobot_arm_controls,
    test_pyrobot_arm_utils,
    test_pyrobot_base_controllers,
    test_pyrobot_base_position_control_inits,
    test_pyrobot_base_velocity_control,
    test_pyrobot_camera,
    test_pyrobot_make_robots,
    test_record,
    test_stubs,
    test_threads,
);

/// PyRobot ran its arm and base tests on both LoCoBots (its run_test.py): the LoCoBot-Lite too.
#[test]
fn test_pyrobot_on_the_locobot_lite() {
    for file in [
        "test_pyrobot_arm_controls.py",
        "test_pyrobot_arm_utils.py",
        "test_pyrobot_base_controllers.py",
        "test_pyrobot_base_velocity_control.py",
        "test_pyrobot_make_robots.py",
    ] {
        pytest_with(file, &["--botname", "locobot_lite"]);
    }
}

/// PyRobot's listings, unchanged, on the host-run firmware of a stock robot with its devices
/// emulated (`FERROBOT_BACKEND=direct-emulated`: the plants at the stock robot's rates behind
/// pseudo-terminals): all seven on the LoCoBot, the arm's and the base's on the LoCoBot-Lite.
/// Paced at real time, two files at a time (about three minutes, little CPU): CI runs it
/// beside the build, in a background job of its own (`scripts/test.sh`), not in nextest's
/// queue.
#[test]
fn pyrobot_listings_on_the_host_run_firmware() {
    let env = [("FERROBOT_BACKEND", "direct-emulated")];
    let mut runs: Vec<(&str, &[&str])> = [
        "test_pyrobot_make_robots.py",
        "test_pyrobot_camera.py",
        "test_pyrobot_arm_utils.py",
        "test_pyrobot_arm_controls.py",
        "test_pyrobot_base_velocity_control.py",
        "test_pyrobot_base_controllers.py",
        "test_pyrobot_base_position_control_inits.py",
    ]
    .into_iter()
    .map(|f| (f, &[][..]))
    .collect();
    let lite: &[&str] = &["--botname", "locobot_lite"];
    runs.push(("test_pyrobot_arm_controls.py", lite));
    runs.push(("test_pyrobot_base_velocity_control.py", lite));
    // Two files at a time: each waits on its robot's real-time clock, with little CPU.
    let queue = std::sync::Mutex::new(runs);
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| loop {
                let next = queue.lock().map(|mut q| q.pop()).unwrap_or(None);
                let Some((file, args)) = next else { return };
                pytest_env(file, args, &env);
            });
        }
    });
}

/// PyRobot's listings through the remote backend: two LoCoBots served by this process (each in
/// a simulated world of its own, in lockstep with its clients, under `/robot1` and `/robot2`),
/// each file run by pytest, a second process, against one of them
/// (`FERROBOT_BACKEND=remote:…`), two files at a time. Every robot each listing makes is a
/// client of a served robot; the served robots' time passes as the listings wait, as it does
/// in-process, however busy the machine.
#[test]
fn pyrobot_listings_through_the_remote_backend() {
    use ferrobot_bridge::{access, Access, ServeOptions, Server};
    let served: Vec<_> = ["/robot1", "/robot2"]
        .iter()
        .map(|ns| {
            let robot = ferrobot::Robot::builder("locobot")
                .backend(ferrobot::Backend::Sim {
                    seed: 1,
                    realtime: false,
                })
                .build()
                .expect("robot");
            let port = ferrobot_peers::free_port();
            let endpoint = format!("tcp/127.0.0.1:{port}");
            let session = access::open(&Access::listen(&endpoint)).expect("session");
            let opts = ServeOptions {
                namespace: ns.to_string(),
                lockstep: true,
                ..ServeOptions::default()
            };
            let server = Server::start(&robot, &session, opts).expect("served");
            let spec = format!("remote:{endpoint},namespace={ns}");
            (spec, (server, session, robot))
        })
        .collect();
    let queue = std::sync::Mutex::new(vec![
        "test_pyrobot_make_robots.py",
        "test_pyrobot_camera.py",
        "test_pyrobot_arm_utils.py",
        "test_pyrobot_arm_controls.py",
        "test_pyrobot_base_velocity_control.py",
        "test_pyrobot_base_controllers.py",
    ]);
    std::thread::scope(|s| {
        for (spec, _) in &served {
            let queue = &queue;
            s.spawn(move || loop {
                let next = queue.lock().map(|mut q| q.pop()).unwrap_or(None);
                let Some(file) = next else { return };
                pytest_env(file, &[], &[("FERROBOT_BACKEND", spec.as_str())]);
            });
        }
    });
}
