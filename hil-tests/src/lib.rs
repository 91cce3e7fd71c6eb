//! # ferrobot-hil
//!
//! Hardware-in-the-loop harness: the real firmware (`boards/mps2-an386`) in QEMU, its serial
//! ports on pseudo-terminals served by the simulated plants, which grant it simulated time
//! over a virtual-time link ([`ferrobot_sim::board`]); the host on the firmware's host link.
//! Because the firmware and the plants agree on time, the suite gives the same results on a
//! slow or busy machine, only later; tests wait on simulated time ([`Hil::eventually`]).
//!
//! [`Hil::start`] builds the firmware once per test binary and starts QEMU and the plants;
//! dropping the [`Hil`] stops both. When a test fails (panics) while a [`Hil`] is alive, the
//! [`Hil`] prints its [`Hil::diagnosis`]: the firmware's decoded defmt log, the plants'
//! counters, the last frames on each link and what QEMU said (`FERROBOT_HIL_REPORT=1` prints
//! it after passing tests too).

pub mod defmt_log;

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use ferrobot::backend::emulated::EmulatedBoard;
use ferrobot_protocol::{encode_frame, DeviceMsg, Frame, FrameDecoder, HostMsg, MAX_WIRE};
use ferrobot_sim::board::BoardOptions;

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

static FIRMWARE: OnceLock<Result<PathBuf, String>> = OnceLock::new();

/// Build a board's firmware (release) and return its ELF.
///
/// The boards build with Debian's toolchain (their own `rust-toolchain.toml`); a cargo started
/// from `cargo test` inherits `RUSTUP_TOOLCHAIN`, `CARGO*` and `RUSTC*`, which would override
/// it, so the child gets a clean environment. `target_dir`, relative to the board's directory,
/// keeps differently-featured builds apart; without it the build goes to `boards/target`, the
/// directory both boards' `.cargo/config.toml` name.
pub fn build_board(
    board: &str,
    features: &[&str],
    target_dir: Option<&str>,
) -> Result<PathBuf, String> {
    build_board_with(board, features, target_dir, &[])
}

/// [`build_board`] with environment variables `env` set for the build (read by the board's
/// code with `option_env!`).
pub fn build_board_with(
    board: &str,
    features: &[&str],
    target_dir: Option<&str>,
    env: &[(&str, String)],
) -> Result<PathBuf, String> {
    let dir = repo().join("boards").join(board);
    let mut cmd = Command::new("cargo");
    cmd.current_dir(&dir)
        .args(["build", "--release", "--quiet"])
        .env_clear();
    for (k, v) in env {
        cmd.env(k, v);
    }
    if !features.is_empty() {
        cmd.arg("--features").arg(features.join(","));
    }
    for k in ["PATH", "HOME", "TMPDIR", "CARGO_HOME", "RUSTUP_HOME"] {
        if let Ok(v) = std::env::var(k) {
            cmd.env(k, v);
        }
    }
    let target = match target_dir {
        Some(t) => {
            cmd.env("CARGO_TARGET_DIR", dir.join(t));
            dir.join(t)
        }
        // Both boards' `.cargo/config.toml` name one target directory, `boards/target`.
        None => dir.join("../target"),
    };
    let out = cmd.output().map_err(|e| format!("cannot run cargo: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "build of boards/{board} failed (run scripts/setup-cross.sh first):\n{}",
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    Ok(ferrobot::backend::emulated::board_elf(&target, board))
}

/// Build the QEMU firmware once per process; its ELF path.
pub fn firmware_elf() -> Result<PathBuf, String> {
    FIRMWARE
        .get_or_init(|| build_board("mps2-an386", &[], None))
        .clone()
}

/// Seed of the plants in every HIL test.
pub const SEED: u64 = 11;

/// Wall time after which a wait on simulated time gives up if simulated time has not moved
/// at all (the emulation has stopped).
pub const STALL: Duration = Duration::from_secs(15);

/// The firmware in QEMU with its plants; the host link's path.
pub struct Hil {
    /// QEMU and the plants.
    pub board: EmulatedBoard,
    /// The host's end of the host link.
    pub host: PathBuf,
    elf: PathBuf,
}

impl Hil {
    /// Start the plants of `robot` and the firmware in QEMU, paced at real time.
    pub fn start(robot: &str) -> Result<Hil, String> {
        let elf = firmware_elf()?;
        let log = std::env::temp_dir().join(format!(
            "ferrobot-hil-{}-{robot}-{}.defmt",
            std::process::id(),
            Instant::now().elapsed().as_nanos() ^ (&elf as *const _ as u128)
        ));
        let opts = BoardOptions {
            seed: SEED,
            ..BoardOptions::default()
        };
        let board = EmulatedBoard::start_with(robot, &elf, opts, log).map_err(|e| e.to_string())?;
        Ok(Hil {
            host: board.server.host.clone(),
            board,
            elf,
        })
    }

    /// One control line to the plants ([`ferrobot_sim::console`]); their JSON answer.
    pub fn plants(&mut self, cmd: &str) -> serde_json::Value {
        self.board.server.command(cmd)
    }

    /// Simulated time.
    pub fn now(&self) -> Duration {
        Duration::from_micros(self.board.server.now_us())
    }

    /// Whether QEMU still runs.
    pub fn qemu_alive(&mut self) -> bool {
        self.board.qemu_exited().is_none()
    }

    /// A raw frame-level client on the host link.
    pub fn raw(&self) -> Result<RawClient, String> {
        RawClient::open(&self.host)
    }

    /// Poll `f` until it returns `Some`, or panic once `within` of simulated time has passed
    /// (or simulated time has stood still for [`STALL`] of wall time).
    pub fn eventually<T>(
        &mut self,
        within: Duration,
        what: &str,
        mut f: impl FnMut(&mut Self) -> Option<T>,
    ) -> T {
        let deadline = self.now() + within;
        let mut last = (self.now(), Instant::now());
        loop {
            if let Some(v) = f(self) {
                return v;
            }
            let now = self.now();
            assert!(
                now < deadline,
                "timed out waiting for {what} ({within:?} of simulated time)"
            );
            if now != last.0 {
                last = (now, Instant::now());
            }
            assert!(
                last.1.elapsed() < STALL,
                "simulated time stood still at {now:?} for {STALL:?} while waiting for {what}"
            );
            self.sleep(Duration::from_millis(20));
        }
    }

    /// Let `dt` of simulated time pass.
    pub fn sleep(&self, dt: Duration) {
        let until = self.now() + dt;
        let started = Instant::now();
        while self.now() < until && started.elapsed() < STALL + dt {
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Everything that tells why a test failed: the firmware's decoded defmt log, the plants'
    /// clock and counters, the last frames on each link, and what QEMU said.
    pub fn diagnosis(&mut self) -> String {
        let mut s = String::from("---- HIL diagnosis ----\n");
        s.push_str(&self.board.server.report());
        s.push_str(&format!(
            "QEMU: {}\n",
            self.board
                .qemu_exited()
                .unwrap_or_else(|| "running".to_string())
        ));
        for line in self.board.qemu_stderr() {
            s.push_str(&format!("  qemu: {line}\n"));
        }
        s.push_str(&format!(
            "firmware log ({}), decoded:\n",
            self.board.log.display()
        ));
        match (
            defmt_log::Table::from_elf(&self.elf),
            std::fs::read(&self.board.log),
        ) {
            (Ok(table), Ok(bytes)) => {
                let lines = table.decode(&bytes);
                if lines.is_empty() {
                    s.push_str("  (empty)\n");
                }
                for l in lines.iter().rev().take(40).rev() {
                    s.push_str(&format!("  {l}\n"));
                }
            }
            (Err(e), _) => s.push_str(&format!("  cannot read the format table: {e}\n")),
            (_, Err(e)) => s.push_str(&format!("  cannot read the log: {e}\n")),
        }
        s.push_str("---- end of HIL diagnosis ----");
        s
    }
}

impl Drop for Hil {
    fn drop(&mut self) {
        if std::thread::panicking() || std::env::var_os("FERROBOT_HIL_REPORT").is_some() {
            eprintln!("{}", self.diagnosis());
        }
    }
}

/// Frames and bytes straight on the host link, for handshakes and corruption tests.
pub struct RawClient {
    port: Box<dyn serialport::SerialPort>,
    decoder: FrameDecoder,
    seq: u16,
}

impl RawClient {
    /// Open a port.
    pub fn open(path: &Path) -> Result<RawClient, String> {
        let port = serialport::new(path.to_string_lossy(), 1_000_000)
            .timeout(Duration::from_millis(5))
            .open()
            .map_err(|e| format!("cannot open {}: {e}", path.display()))?;
        Ok(RawClient {
            port,
            decoder: FrameDecoder::new(),
            seq: 100,
        })
    }

    /// Send a message; its sequence number.
    pub fn send(&mut self, msg: &HostMsg) -> u16 {
        self.seq = self.seq.wrapping_add(1);
        let mut b = [0u8; MAX_WIRE];
        if let Ok(n) = encode_frame(self.seq, msg, &mut b) {
            let _ = self.port.write_all(&b[..n]);
        }
        self.seq
    }

    /// Send raw bytes.
    pub fn send_raw(&mut self, bytes: &[u8]) {
        let _ = self.port.write_all(bytes);
    }

    /// Wait up to `timeout` (wall time) for a message `pred` accepts.
    pub fn wait(
        &mut self,
        timeout: Duration,
        pred: impl Fn(&DeviceMsg) -> bool,
    ) -> Option<DeviceMsg> {
        let deadline = Instant::now() + timeout;
        let mut buf = [0u8; 512];
        while Instant::now() < deadline {
            let n = self.port.read(&mut buf).unwrap_or(0);
            for &b in &buf[..n] {
                if let Some(Ok(Frame { msg, .. })) = self.decoder.push::<DeviceMsg>(b) {
                    if pred(&msg) {
                        return Some(msg);
                    }
                }
            }
        }
        None
    }

    /// Say Hello in this build's protocol version and schema, and wait up to `timeout` (wall
    /// time) for the firmware's accepting answer.
    pub fn hello(&mut self, timeout: Duration) -> Option<DeviceMsg> {
        self.send(&HostMsg::Hello {
            protocol_version: ferrobot_protocol::PROTOCOL_VERSION,
            schema_hash: ferrobot_protocol::SCHEMA_HASH,
        });
        self.wait(timeout, |m| matches!(m, DeviceMsg::Hello(i) if i.accepted))
    }

    /// Send a command and wait for its acknowledgement (true) or rejection (false).
    pub fn command(&mut self, msg: &HostMsg) -> Option<bool> {
        let seq = self.send(msg);
        match self.wait(Duration::from_secs(3), |m| {
            matches!(m, DeviceMsg::Ack { seq: s } | DeviceMsg::Reject { seq: s, .. } if *s == seq)
        }) {
            Some(DeviceMsg::Ack { .. }) => Some(true),
            Some(_) => Some(false),
            None => None,
        }
    }
}
