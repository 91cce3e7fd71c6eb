//! `ferrobot teleop ROBOT`: drive a robot from the keyboard in a terminal, with PyRobot's key
//! map and steps (`ferrobot_teleop::KeyMap::pyrobot`): the shell around the sans-IO core
//! ([`ferrobot_teleop::Teleop`]), the terminal ([`terminal`]) giving keys, the robot
//! ([`operator`]) executing the core's commands, each turn of the loop letting [`Pace::tick`]
//! of robot time pass ([`TICK_S`] in real time, or `--step-ms` of simulated time). How time
//! passes: `docs/design/cli.md`.

mod operator;
mod screen;
mod terminal;
mod trace;

#[cfg(feature = "gamepad")]
mod gamepad;

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use ferrobot::{validate, Backend};
use ferrobot_teleop::{Command, HoldTiming, KeyMap, Teleop};

use crate::cmd::common::{self, BackendArgs};
use operator::Operator;

/// The gamepads, when built with them (feature `gamepad`) and the system offers them.
#[cfg(feature = "gamepad")]
type Pad = Option<gamepad::Gamepad>;
/// No gamepad without the feature.
#[cfg(not(feature = "gamepad"))]
type Pad = ();

/// Open the gamepads, and say what reads keys.
fn open_pad() -> (Pad, String) {
    #[cfg(feature = "gamepad")]
    {
        match gamepad::Gamepad::open() {
            Ok(p) => {
                let n = p.connected();
                (Some(p), format!("keyboard and gamepads ({n} connected)"))
            }
            Err(e) => (None, format!("keyboard (no gamepads: {e})")),
        }
    }
    #[cfg(not(feature = "gamepad"))]
    {
        ((), "keyboard".into())
    }
}

/// The loop's period on the robot's clock without `--step-ms`, s.
pub const TICK_S: f64 = 0.01;
/// How long the robot is watched after a quit (base stopping, arm holding), s.
pub const SETTLE_S: f64 = 0.3;

/// The arguments of `ferrobot teleop`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Robot name or configuration path.
    pub robot: String,
    /// Scene name or path (the simulated world).
    #[arg(long, default_value = "empty")]
    pub scene: String,
    /// Where the robot runs.
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Simulator only: advance simulated time by this many ms per turn of the loop, each turn
    /// reading keys for as long of wall time, never catching up (default: real time).
    #[arg(long, allow_negative_numbers = true)]
    pub step_ms: Option<f64>,
    /// The terminal's auto-repeat delay, s (0.05-2): how long a first press of an arrow
    /// drives the base when the terminal does not report key releases.
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub repeat_delay: f64,
    /// Write one JSON line per turn (time, keys, commands, state) to this new file.
    #[arg(long)]
    pub trace: Option<std::path::PathBuf>,
    /// Record the session into this new MCAP file (ROS 2 schemas: joint states, commands,
    /// odometry, transforms, the camera; see `ferrobot record`): a demonstration.
    #[arg(long)]
    pub record: Option<std::path::PathBuf>,
    /// With --record, leave the camera's frames out.
    #[arg(long, requires = "record")]
    pub record_without_camera: bool,
}

/// How the loop lets time pass.
#[derive(Debug, Clone, Copy)]
pub struct Pace {
    /// Robot time per turn, s.
    pub tick: f64,
    /// Collect keys for `tick` of wall time before letting `tick` of robot time pass (the
    /// lockstep simulator, which has no clock of its own); otherwise the robot's clock paces.
    pub lockstep: bool,
}

/// Why the loop ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum QuitReason {
    /// A quit key.
    Key,
    /// The terminal closed (SIGHUP, or its input ended).
    Hangup,
    /// SIGTERM or SIGINT from outside.
    Signal,
}

/// The session's recorder, with --record.
fn start_recording(
    a: &Args,
    bot: &ferrobot::Robot,
) -> ferrobot::Result<Option<ferrobot_record::Recorder>> {
    let Some(path) = &a.record else {
        return Ok(None);
    };
    let opts = ferrobot_record::RecordOptions {
        camera: !a.record_without_camera,
        ..Default::default()
    };
    Ok(Some(ferrobot_record::Recorder::start(bot, path, opts)?))
}

/// Check the arguments, connect, drive, and leave the robot safe.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    let backend = check(a)?;
    let mut trace = a.trace.as_deref().map(trace::Trace::create).transpose()?;
    let pace = Pace {
        tick: a.step_ms.map_or(TICK_S, |ms| ms / 1000.0),
        lockstep: a.step_ms.is_some(),
    };
    let bot = common::robot_builder(&a.robot)
        .scene(&a.scene)
        .backend(backend.clone())
        .build()?;
    let recorder = start_recording(a, &bot)?;
    let mut op = Operator::new(bot)?;
    op.start_pose();
    let wrist = op.wrist_joints();
    let map = KeyMap::pyrobot([&wrist[0], &wrist[1]]).retain(|action| op.can(action));
    let timing = HoldTiming {
        first: a.repeat_delay,
        ..HoldTiming::default()
    };
    let mut core = Teleop::new(map, timing);
    let (stop, hangup) = watch_signals()?;
    let term = terminal::Terminal::open()?;
    let (pad, input) = open_pad();
    let header = screen::Header {
        robot: op.name().to_string(),
        backend: describe(&backend, pace),
        input,
        releases: term.releases(),
        timing,
    };
    let mut screen = screen::Screen::new(header, core.key_map());
    let mut inputs = Inputs {
        term,
        pad,
        stop,
        hangup,
    };
    let reason = drive(
        &mut core,
        &mut op,
        &mut inputs,
        &mut screen,
        &mut trace,
        pace,
    );
    // Leave the robot safe first, then the terminal.
    let report = op.quit(SETTLE_S);
    if let Some(t) = trace.as_mut() {
        t.end(reason, &report);
    }
    let recorded = recorder.map(ferrobot_record::Recorder::finish).transpose();
    drop(inputs);
    if reason != QuitReason::Hangup {
        // On the restored terminal; a closed one is no error here.
        use std::io::Write;
        let _ = writeln!(std::io::stdout(), "{}", report.summary(reason));
    }
    if let (Some(s), Some(path)) = (recorded?, &a.record) {
        if reason != QuitReason::Hangup {
            use std::io::Write;
            let _ = writeln!(
                std::io::stdout(),
                "recorded {} messages ({} frames) into {}",
                s.written.messages,
                s.written.frames,
                path.display()
            );
        }
    }
    Ok(())
}

/// The arguments, the robot and the world checked before the terminal is taken; the backend
/// to drive (the simulator in real time unless `--step-ms`).
fn check(a: &Args) -> ferrobot::Result<Backend> {
    if let Some(ms) = a.step_ms {
        validate::in_range("--step-ms", ms, 1.0, 1000.0)?;
    }
    validate::in_range("--repeat-delay", a.repeat_delay, 0.05, 2.0)?;
    let cfg = common::load(&a.robot)?;
    let backend = match (a.backend.backend()?, a.step_ms) {
        (Backend::Sim { seed, .. }, step) => Backend::Sim {
            seed,
            realtime: step.is_none(),
        },
        (_, Some(_)) => {
            return Err(ferrobot::Error::Usage(
                "--step-ms is for the simulator (--backend sim) only".into(),
            ))
        }
        (b, None) => b,
    };
    if cfg.arm.is_none() && cfg.base.is_none() && cfg.camera.is_none() {
        return Err(ferrobot::Error::Usage(format!(
            "{} has nothing to teleoperate",
            cfg.name
        )));
    }
    // The world, checked before the terminal is taken (the robot loads it again).
    ferrobot::scene::Scene::load(&ferrobot::scene::SceneSource::from_arg(&a.scene))?;
    if !(std::io::stdin().is_terminal() && std::io::stdout().is_terminal()) {
        return Err(ferrobot::Error::Usage(
            "teleop needs a terminal on standard input and output".into(),
        ));
    }
    Ok(backend)
}

/// Flags raised by SIGTERM or SIGINT (the first) and SIGHUP (the second).
fn watch_signals() -> ferrobot::Result<(Arc<AtomicBool>, Arc<AtomicBool>)> {
    let stop = Arc::new(AtomicBool::new(false));
    let hangup = Arc::new(AtomicBool::new(false));
    for (sig, flag) in [
        (signal_hook::consts::SIGHUP, &hangup),
        (signal_hook::consts::SIGTERM, &stop),
        (signal_hook::consts::SIGINT, &stop),
    ] {
        signal_hook::flag::register(sig, flag.clone())
            .map_err(|e| ferrobot::Error::Link(format!("cannot watch signal {sig}: {e}")))?;
    }
    Ok((stop, hangup))
}

/// Where keys and requests to leave come from.
struct Inputs {
    /// The terminal (restored when dropped).
    term: terminal::Terminal,
    /// Gamepads.
    pad: Pad,
    /// SIGTERM or SIGINT came.
    stop: Arc<AtomicBool>,
    /// SIGHUP came.
    hangup: Arc<AtomicBool>,
}

/// The loop: keys in, commands out, time passes, the screen follows. Returns why it ended.
fn drive(
    core: &mut Teleop,
    op: &mut Operator,
    inputs: &mut Inputs,
    screen: &mut screen::Screen,
    trace: &mut Option<trace::Trace>,
    pace: Pace,
) -> QuitReason {
    let Inputs {
        term,
        pad,
        stop,
        hangup,
    } = inputs;
    let mut events = Vec::new();
    loop {
        let wall = Instant::now()
            + if pace.lockstep {
                Duration::from_secs_f64(pace.tick)
            } else {
                Duration::ZERO
            };
        let now = op.time();
        let mut commands = Vec::new();
        let mut closed = false;
        events.clear();
        // Every key that comes before the turn's wall-clock end, stamped with the robot's time.
        loop {
            match term.next_key(wall.saturating_duration_since(Instant::now())) {
                terminal::Input::Key(k) => {
                    events.push(k);
                    commands.extend(core.on_key(now, k, term.releases()));
                }
                terminal::Input::Resize => screen.invalidate(),
                terminal::Input::Idle => break,
                terminal::Input::Closed => {
                    closed = true;
                    break;
                }
            }
        }
        #[cfg(not(feature = "gamepad"))]
        let () = *pad;
        #[cfg(feature = "gamepad")]
        if let Some(pad) = pad.as_mut() {
            for k in pad.events() {
                events.push(k);
                commands.extend(core.on_key(now, k, true));
            }
        }
        commands.extend(core.poll(now));
        for c in &commands {
            op.execute(c, core.key_map());
        }
        if let Some(t) = trace.as_mut() {
            t.turn(now, &events, &commands, &op.state());
        }
        if hangup.load(Ordering::Relaxed) || closed {
            return QuitReason::Hangup;
        }
        if stop.load(Ordering::Relaxed) {
            return QuitReason::Signal;
        }
        if commands.contains(&Command::Quit) {
            return QuitReason::Key;
        }
        op.wait(pace.tick);
        op.observe();
        screen.draw(&op.state(), core);
    }
}

/// The backend and the pace, for the screen's header.
fn describe(backend: &Backend, pace: Pace) -> String {
    match backend {
        Backend::Sim { .. } if pace.lockstep => {
            format!("sim, {:.0} ms per turn", pace.tick * 1000.0)
        }
        Backend::Sim { .. } => "sim, real time".into(),
        Backend::Serial { path } => format!("serial {}", path.display()),
        Backend::Emulated { .. } => "emulated (QEMU)".into(),
        _ => "other".into(),
    }
}
