//! `ferrobot teleop` through a real pseudo-terminal: the built binary runs on a PTY (its
//! controlling terminal), keys go in as a terminal sends them, and the screen it draws is read
//! back through a VT100 parser. Each key must move what it should by PyRobot's step, as the
//! screen shows it; a base key held by auto-repeats (or by a terminal that reports releases)
//! drives the base, and its release stops it within 0.2 s of robot time (from the trace the
//! program writes: the robot's own odometry); quitting leaves the base stopped and the arm
//! holding, exits 0 and restores the terminal (cooked mode, as `stty` reports it, the cursor
//! and the main screen back).
//!
//! The simulator runs with `--step-ms 10`: 10 ms of simulated time per turn (the default
//! turn), each turn reading keys for 10 ms of wall time. Waits are on the screen's content; the wall-clock
//! limit only guards against a hang.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use portable_pty::{native_pty_system, Child, CommandBuilder, MasterPty, PtySize, SlavePty};

/// The longest any wait for the screen may take before the test fails.
const GUARD: Duration = Duration::from_secs(90);
/// End-effector steps must show within this, m (arrival tolerance of the joints, through the
/// arm's lever).
const EE_TOL: f64 = 0.002;
/// Joint, pan and tilt steps must show within this, rad (the arm's arrival tolerance).
const JOINT_TOL: f64 = 0.01;
/// A base key's release must stop the base within this much robot time, s.
const RELEASE_STOP: f64 = 0.2;
/// "Stopped": the measured forward speed below 10 % of PyRobot's teleoperation speed (and
/// the Kobuki's 5 mm/s deadband), m/s ...
const STOPPED_V: f64 = 0.005;
/// ... and the turn rate below 10 % of its turn rate, rad/s.
const STOPPED_W: f64 = 0.05;

/// The terminal's size.
const ROWS: std::num::NonZeroU16 = std::num::NonZeroU16::new(40).expect("rows");
const COLS: std::num::NonZeroU16 = std::num::NonZeroU16::new(120).expect("cols");

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_ferrobot"))
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ferrobot-teleop-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// The robot's state as the screen shows it.
#[derive(Debug, Clone, Default)]
struct Shown {
    t: f64,
    arm: Vec<f64>,
    ee: Vec<f64>,
    gripper: String,
    head: Vec<f64>,
    base: Vec<f64>,
    held: String,
    moving: String,
    commands: u64,
    last: String,
}

/// The numbers in `s`, in order.
fn numbers(s: &str) -> Vec<f64> {
    s.split(|c: char| c.is_whitespace() || c == '[' || c == ']')
        .filter_map(|w| w.parse::<f64>().ok())
        .collect()
}

fn parse(text: &str) -> Option<Shown> {
    let line = |prefix: &str| {
        text.lines()
            .find(|l| l.starts_with(prefix))
            .map(|l| l[prefix.len()..].trim().to_string())
    };
    let header = line("ferrobot teleop")?;
    let t = header
        .split(" t ")
        .nth(1)
        .and_then(|r| numbers(r).first().copied())?;
    let last = line("last     #")?;
    let (count, last) = last.split_once(' ').unwrap_or((&last, ""));
    Some(Shown {
        t,
        arm: numbers(&line("arm      q")?),
        ee: numbers(&line("ee       p")?).into_iter().take(3).collect(),
        gripper: line("gripper ")?,
        head: numbers(&line("head     ")?),
        base: numbers(&line("base     ")?),
        held: line("held     ")?,
        moving: line("moving   ")?,
        commands: count.parse().ok()?,
        last: last.to_string(),
    })
}

/// One `ferrobot teleop` on a pseudo-terminal.
struct Session {
    child: Box<dyn Child + Send + Sync>,
    master: Option<Box<dyn MasterPty + Send>>,
    slave: Box<dyn SlavePty + Send>,
    /// The keyboard's end of the terminal (shared with the auto-repeat thread).
    writer: Arc<Mutex<Option<Box<dyn Write + Send>>>>,
    output: mpsc::Receiver<Vec<u8>>,
    close_reader: Arc<AtomicBool>,
    parser: vt100::Parser,
    raw: Vec<u8>,
    /// Answer the keyboard-enhancement query as a kitty-protocol terminal.
    kitty: bool,
    answered: bool,
    trace: PathBuf,
}

impl Session {
    fn start(dir: &Path, kitty: bool) -> Session {
        let pair = native_pty_system()
            .openpty(PtySize {
                rows: ROWS.get(),
                cols: COLS.get(),
                pixel_width: 0,
                pixel_height: 0,
            })
            .expect("openpty");
        let trace = dir.join("trace.jsonl");
        let mut cmd = CommandBuilder::new(bin());
        cmd.args(["teleop", "locobot", "--step-ms", "10", "--trace"]);
        cmd.arg(&trace);
        // The session recorded, as a demonstration is (frames left out: the test's pace is
        // the terminal's, and rendering them would only slow it).
        cmd.args(["--record-without-camera", "--record"]);
        cmd.arg(dir.join("session.mcap"));
        cmd.cwd(dir);
        cmd.env("TERM", "xterm-256color");
        let child = pair
            .slave
            .spawn_command(cmd)
            .expect("spawn ferrobot teleop");
        let mut reader = pair.master.try_clone_reader().expect("reader");
        let writer = pair.master.take_writer().expect("writer");
        let (tx, rx) = mpsc::channel();
        let close_reader = Arc::new(AtomicBool::new(false));
        let close = close_reader.clone();
        // The screen redraws its clock every turn, so reads come often and the flag is seen.
        std::thread::spawn(move || {
            let mut buf = [0u8; 8192];
            while let Ok(n) = reader.read(&mut buf) {
                if n == 0 || tx.send(buf[..n].to_vec()).is_err() || close.load(Ordering::SeqCst) {
                    break;
                }
            }
        });
        Session {
            child,
            master: Some(pair.master),
            slave: pair.slave,
            writer: Arc::new(Mutex::new(Some(writer))),
            output: rx,
            close_reader,
            parser: vt100::Parser::new(ROWS, COLS, 0),
            raw: Vec::new(),
            kitty,
            answered: false,
            trace,
        }
    }

    /// [`Session::start`], then wait until the start pose is reached and the screen says how
    /// key releases are known.
    fn ready(dir: &Path, kitty: bool) -> Session {
        let mut s = Session::start(dir, kitty);
        let releases = if kitty {
            "releases reported"
        } else {
            "releases inferred"
        };
        s.until("the start pose", |sh, text| {
            (sh.last == "ready" && sh.moving == "none" && text.contains(releases)).then_some(())
        });
        s
    }

    fn send(&mut self, bytes: &[u8]) {
        type_keys(&self.writer, bytes);
    }

    /// Take what the program wrote within `timeout`; answer its terminal queries.
    fn pump(&mut self, timeout: Duration) -> bool {
        let Ok(chunk) = self.output.recv_timeout(timeout) else {
            return false;
        };
        self.parser.process(&chunk);
        self.raw.extend_from_slice(&chunk);
        // crossterm asks for the keyboard-enhancement flags, then the primary device
        // attributes; a terminal without the kitty protocol answers only the latter.
        if !self.answered && find(&self.raw, b"\x1b[?u").is_some() {
            self.answered = true;
            let answer: &[u8] = if self.kitty {
                b"\x1b[?0u\x1b[?62;22c"
            } else {
                b"\x1b[?62;22c"
            };
            self.send(answer);
        }
        true
    }

    /// Wait until the screen satisfies `f`; fail after [`GUARD`].
    fn until<T>(&mut self, what: &str, f: impl Fn(&Shown, &str) -> Option<T>) -> T {
        let start = Instant::now();
        loop {
            let text = self.parser.screen().contents();
            if let Some(s) = parse(&text) {
                if let Some(v) = f(&s, &text) {
                    return v;
                }
            }
            if start.elapsed() > GUARD {
                panic!("waited {GUARD:?} for {what}; the screen:\n{text}");
            }
            self.pump(Duration::from_millis(50));
        }
    }

    fn shown(&mut self) -> Shown {
        self.until("the screen", |s, _| Some(s.clone()))
    }

    /// Wait until nothing moves, and return the state.
    fn settled(&mut self) -> Shown {
        self.until("no motion", |s, _| (s.moving == "none").then(|| s.clone()))
    }

    /// Send `key`, wait until its command has been executed and its motion has ended.
    fn step(&mut self, key: &[u8], label: &str) -> Shown {
        let before = self.settled();
        self.send(key);
        self.until(&format!("{label} done"), |s, _| {
            (s.commands > before.commands && s.moving == "none" && s.t > before.t).then(|| {
                assert!(
                    s.last.starts_with(label),
                    "{label}: the last command shows {:?}",
                    s.last
                );
                s.clone()
            })
        })
    }

    /// Hold a base key for `seconds` of robot time, as a terminal without release events
    /// sends it: once, then after its auto-repeat delay (0.4 s) again every 20 ms, from a
    /// thread of its own as a keyboard's repeat timer would (the sleeps are the keyboard's
    /// cadence, not waits for state); released once the screen's clock shows `seconds` gone.
    fn hold_by_repeats(&mut self, key: &'static [u8], seconds: f64) {
        let start = self.shown().t;
        let writer = self.writer.clone();
        let held = Arc::new(AtomicBool::new(true));
        let still = held.clone();
        let keyboard = std::thread::spawn(move || {
            type_keys(&writer, key);
            std::thread::sleep(Duration::from_millis(400));
            while still.load(Ordering::SeqCst) {
                type_keys(&writer, key);
                std::thread::sleep(Duration::from_millis(20));
            }
        });
        self.until("the hold's end", |s, _| {
            (s.t >= start + seconds).then_some(())
        });
        held.store(false, Ordering::SeqCst);
        keyboard.join().expect("keyboard thread");
    }

    /// Wait until the base rests and no key is held.
    fn base_rests(&mut self) -> Shown {
        self.until("the base at rest", |s, _| {
            (s.held == "-" && s.base[3].abs() < 1e-4 && s.base[4].abs() < 1e-4).then(|| s.clone())
        })
    }

    /// Wait for the program's end (the guard as above); its exit code.
    fn exit_code(&mut self) -> u32 {
        let start = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().expect("wait") {
                // Whatever it printed last.
                while self.pump(Duration::from_millis(100)) {}
                return status.exit_code();
            }
            assert!(start.elapsed() < GUARD, "teleop did not exit");
            if !self.pump(Duration::from_millis(50)) {
                // The terminal is closed: nothing to read, poll the process (a budget, not a
                // wait for state: it ends by itself or the guard fails the test).
                std::thread::sleep(Duration::from_millis(5));
            }
        }
    }

    /// The trace's lines.
    fn trace(&self) -> Vec<serde_json::Value> {
        std::fs::read_to_string(&self.trace)
            .expect("trace")
            .lines()
            .map(|l| serde_json::from_str(l).expect("trace line"))
            .collect()
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        let _ = self.child.kill();
    }
}

/// Write `bytes` to the terminal as typed keys.
fn type_keys(writer: &Mutex<Option<Box<dyn Write + Send>>>, bytes: &[u8]) {
    let mut w = writer.lock().expect("keyboard");
    let w = w.as_mut().expect("terminal open");
    w.write_all(bytes).expect("write keys");
    w.flush().expect("flush keys");
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

/// Each hold of `key` in the trace, ended by the core's base stop: the robot time of the key's
/// last event before the stop, how long after it the odometry first showed the base stopped,
/// and the largest speed (m/s or rad/s) during the hold. A hold broken by a stop while the key
/// was still coming counts as two.
fn release_stops(trace: &[serde_json::Value], key: &str) -> Vec<(f64, f64, f64)> {
    let turns: Vec<&serde_json::Value> = trace.iter().filter(|l| l.get("t").is_some()).collect();
    let has = |l: &serde_json::Value, field: &str, what: &str| {
        l[field].as_array().is_some_and(|k| {
            k.iter()
                .any(|e| e.as_str().is_some_and(|e| e.starts_with(what)))
        })
    };
    let t = |l: &serde_json::Value| l["state"]["t"].as_f64().expect("t");
    let base = |l: &serde_json::Value| -> Vec<f64> {
        serde_json::from_value(l["state"]["base"].clone()).expect("base")
    };
    let mut out = Vec::new();
    let mut last_key: Option<usize> = None;
    let mut peak = 0.0f64;
    for (k, l) in turns.iter().enumerate() {
        if has(l, "keys", key) {
            last_key = Some(k);
        }
        if let Some(lk) = last_key {
            let b = base(l);
            peak = peak.max(b[3].abs()).max(b[4].abs());
            if has(l, "commands", "BaseStop") {
                let released = t(turns[lk]);
                let stopped = turns[k..]
                    .iter()
                    .find(|m| {
                        let b = base(m);
                        t(m) > released && b[3].abs() < STOPPED_V && b[4].abs() < STOPPED_W
                    })
                    .map_or(f64::INFINITY, |m| t(m) - released);
                out.push((released, stopped, peak));
                last_key = None;
                peak = 0.0;
            }
        }
    }
    out
}

/// The stty settings of the terminal after the program: run `stty -a` on the same PTY.
fn stty(s: &mut Session) -> String {
    let mut cmd = CommandBuilder::new("stty");
    cmd.arg("-a");
    let mut child = s.slave.spawn_command(cmd).expect("spawn stty");
    let start = s.raw.len();
    let begun = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().expect("wait stty") {
            break st;
        }
        assert!(begun.elapsed() < GUARD, "stty did not end");
        s.pump(Duration::from_millis(50));
    };
    while s.pump(Duration::from_millis(100)) {}
    assert!(status.success(), "stty failed");
    String::from_utf8_lossy(&s.raw[start..]).into_owned()
}

#[test]
fn every_key_moves_what_it_should_a_released_base_key_stops_and_quitting_is_safe() {
    let dir = scratch("keys");
    let mut s = Session::ready(&dir, false);
    // The end effector: PyRobot's steps along each axis of base_link.
    let ee = [
        (b"w", "w (", [0.01, 0.0, 0.0]),
        (b"s", "s (", [-0.01, 0.0, 0.0]),
        (b"a", "a (", [0.0, 0.01, 0.0]),
        (b"d", "d (", [0.0, -0.01, 0.0]),
        (b"z", "z (", [0.0, 0.0, 0.015]),
        (b"x", "x (", [0.0, 0.0, -0.01]),
    ];
    for (key, label, d) in ee {
        let before = s.settled();
        let after = s.step(key, label);
        let moved: Vec<f64> = after
            .ee
            .iter()
            .zip(&before.ee)
            .map(|(a, b)| a - b)
            .collect();
        assert!(
            close(&moved, &d, EE_TOL),
            "{label}: the end effector moved {moved:?}, the step is {d:?}"
        );
    }
    // The wrist joints.
    for (key, label, joint, delta) in [
        (b"h", "h (", 3, 0.1),
        (b"j", "j (", 3, -0.1),
        (b"k", "k (", 4, 0.25),
        (b"l", "l (", 4, -0.25),
    ] {
        let before = s.settled();
        let after = s.step(key, label);
        let mut want = before.arm.clone();
        want[joint] += delta;
        assert!(
            close(&after.arm, &want, JOINT_TOL),
            "{label}: joints {:?} -> {:?}, want {want:?}",
            before.arm,
            after.arm
        );
    }
    // Pan and tilt.
    for (key, label, d) in [
        (b"u", "u (", [0.08, 0.0]),
        (b"i", "i (", [-0.08, 0.0]),
        (b"o", "o (", [0.0, 0.08]),
        (b"p", "p (", [0.0, -0.08]),
    ] {
        let before = s.settled();
        let after = s.step(key, label);
        let want = [before.head[0] + d[0], before.head[1] + d[1]];
        assert!(
            close(&after.head, &want, JOINT_TOL),
            "{label}: head {:?} -> {:?}, want {want:?}",
            before.head,
            after.head
        );
    }
    // The gripper.
    let closed = s.step(b"m", "m (");
    assert!(closed.gripper == "Closed", "m: gripper {}", closed.gripper);
    let open = s.step(b"n", "n (");
    assert!(open.gripper == "Open", "n: gripper {}", open.gripper);
    // The base, held by auto-repeats: forward, backward, left, right.
    let arrows: [(&[u8], &str, usize, f64); 4] = [
        (b"\x1b[A", "Up", 0, 1.0),
        (b"\x1b[B", "Down", 0, -1.0),
        (b"\x1b[D", "Left", 2, 1.0),
        (b"\x1b[C", "Right", 2, -1.0),
    ];
    for (key, name, axis, sign) in arrows {
        let before = s.base_rests();
        s.hold_by_repeats(key, 1.0);
        let after = s.base_rests();
        let moved = after.base[axis] - before.base[axis];
        // 0.05 m/s or 0.5 rad/s for about a second, less the start and stop.
        let want = if axis == 0 { 0.05 } else { 0.5 };
        assert!(
            moved * sign > 0.8 * want && moved * sign < 1.3 * want,
            "{name}: the base moved {moved} along axis {axis} in about 1 s (PyRobot's speed {want})"
        );
    }
    // Quit during a large arm move (home): the arm holds where it is.
    let before = s.settled();
    s.send(b"r");
    s.until("the arm moving home", |sh, _| {
        (sh.commands > before.commands && sh.moving.contains("arm")).then_some(())
    });
    s.send(b"q");
    assert_eq!(s.exit_code(), 0, "teleop's exit code");
    let tail = String::from_utf8_lossy(&s.raw).into_owned();
    assert!(
        tail.contains("\x1b[?1049l") && tail.rfind("\x1b[?25h") > tail.rfind("\x1b[?25l"),
        "the main screen and the cursor are not restored"
    );
    let trace = s.trace();
    let end = trace.last().expect("trace end");
    assert_eq!(end["quit"], "key");
    let report = &end["report"];
    assert_eq!(report["base_stopped"], true, "{report}");
    let moved = report["arm_moved"].as_f64().expect("arm_moved");
    assert!(moved < 0.01, "the arm moved {moved} rad after quitting");
    let arm: Vec<f64> = serde_json::from_value(report["state"]["arm"].clone()).expect("arm");
    assert!(
        arm.iter().any(|q| q.abs() > 0.05),
        "the arm went on home after quitting: {arm:?}"
    );
    let summary = s.parser.screen().contents();
    assert!(summary.contains("teleop: quit (Key)"), "{summary}");
    let settings = stty(&mut s);
    let words: Vec<&str> = settings.split_whitespace().collect();
    for mode in ["icanon", "echo", "isig"] {
        assert!(words.contains(&mode), "stty after teleop: {settings}");
    }
    // The session's recording: the operator's commands, as the robot acknowledged them.
    let mut topics = std::collections::BTreeMap::<String, usize>::new();
    for m in ferrobot_record::reader::Reading::open(dir.join("session.mcap")).expect("recording") {
        *topics
            .entry(m.expect("message").topic.to_string())
            .or_default() += 1;
    }
    for topic in [
        "/cmd_vel",
        "/joint_commands",
        "/ferrobot/commands",
        "/joint_states",
    ] {
        assert!(
            topics.get(topic).copied().unwrap_or(0) > 0,
            "{topic}: {topics:?}"
        );
    }
    // Releases, from the robot's own record.
    // The release is the last hold's end. A repeat delayed past the repeat hold by a loaded
    // machine shows as an earlier, extra hold (the base pauses, as it would on a terminal that
    // repeats too slowly): counted and printed, not failed; the distances above bound them.
    for key in ["Up", "Down", "Left", "Right"] {
        let stops = release_stops(&trace, key);
        let (at, after, peak) = *stops.last().expect("a hold");
        let pauses = stops.len() - 1;
        println!("teleop: {key} released (last repeat) at t = {at:.3} s, base stopped {after:.3} s later (peak {peak:.3}; {pauses} pause(s) while held)");
        assert!(
            after <= RELEASE_STOP,
            "{key}: the base stopped {after} s after the last repeat"
        );
        assert!(
            pauses <= 2,
            "{key}: the hold broke {pauses} times: {stops:?}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn with_reported_releases_a_release_stops_the_base_and_a_closing_terminal_quits_safely() {
    let dir = scratch("kitty");
    let mut s = Session::ready(&dir, true);
    // Kitty's encoding: `w` pressed (its release is ignored), then Up pressed, held 0.8 s
    // with no repeat, released.
    let before = s.settled();
    let after = s.step(b"\x1b[119u", "w (");
    let moved = after.ee[0] - before.ee[0];
    assert!((moved - 0.01).abs() <= EE_TOL, "w moved x by {moved}");
    s.send(b"\x1b[119;1:3u");
    let start = s.base_rests();
    s.send(b"\x1b[1;1:1A");
    s.until("the base driving", |sh, _| (sh.held == "Up").then_some(()));
    // Held past the first-press hold (0.5 s): a kitty terminal sends repeat events while a
    // key is held, each renewing the hold's backstop.
    let mut next = start.t + 0.03;
    loop {
        let sh = s.shown();
        if sh.t > start.t + 0.8 {
            break;
        }
        if sh.t >= next {
            s.send(b"\x1b[1;1:2A");
            next = sh.t + 0.03;
        }
        s.pump(Duration::from_millis(50));
    }
    s.send(b"\x1b[1;1:3A");
    let rest = s.base_rests();
    let moved = rest.base[0] - start.base[0];
    assert!(
        moved > 0.03 && moved < 0.06,
        "Up held 0.8 s moved {moved} m"
    );
    // The terminal closes: the kernel hangs the program up.
    s.close_reader.store(true, Ordering::SeqCst);
    *s.writer.lock().expect("keyboard") = None;
    s.master = None;
    assert_eq!(s.exit_code(), 0, "teleop's exit code after a hangup");
    let trace = s.trace();
    let stops = release_stops(&trace, "Up");
    assert_eq!(stops.len(), 1, "{stops:?}");
    let (at, after, _) = stops[0];
    println!(
        "teleop (reported releases): Up released at t = {at:.3} s, base stopped {after:.3} s later"
    );
    assert!(
        after <= RELEASE_STOP,
        "the base stopped {after} s after the release"
    );
    let end = trace.last().expect("trace end");
    assert_eq!(end["quit"], "hangup", "{end}");
    assert_eq!(end["report"]["base_stopped"], true, "{end}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ctrl_c_and_escape_quit_safely_too() {
    for (name, key) in [("ctrl-c", &b"\x03"[..]), ("esc", &b"\x1b"[..])] {
        let dir = scratch(name);
        let mut s = Session::ready(&dir, false);
        s.send(key);
        assert_eq!(s.exit_code(), 0, "{name}: teleop's exit code");
        let trace = s.trace();
        let end = trace.last().expect("trace end");
        assert_eq!(end["quit"], "key", "{name}: {end}");
        assert_eq!(end["report"]["base_stopped"], true, "{name}: {end}");
        let screen = s.parser.screen().contents();
        assert!(screen.contains("teleop: quit (Key)"), "{name}: {screen}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
