//! # ferrobot-hil
//!
//! Hardware-in-the-loop harness: the real firmware (`boards/mps2-an386`) in QEMU, wired over
//! pseudo-terminals to `ferrobot-sim serve` (servo chain on UART1, base on UART2), with the
//! host on UART0. [`Hil::start`] builds the firmware once per test binary, starts both
//! processes and kills them when dropped, also when a test fails.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use ferrobot_protocol::{encode_frame, DeviceMsg, Frame, FrameDecoder, HostMsg, MAX_WIRE};

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

static FIRMWARE: OnceLock<Result<PathBuf, String>> = OnceLock::new();

/// Build a board's firmware (release) and return its ELF.
///
/// The boards build with Debian's toolchain (their own `rust-toolchain.toml`); a cargo started
/// from `cargo test` inherits `RUSTUP_TOOLCHAIN`, `CARGO*` and `RUSTC*`, which would override
/// it, so the child gets a clean environment. `target_dir` keeps differently-featured builds
/// apart.
pub fn build_board(
    board: &str,
    features: &[&str],
    target_dir: Option<&str>,
) -> Result<PathBuf, String> {
    let dir = repo().join("boards").join(board);
    let mut cmd = Command::new("cargo");
    cmd.current_dir(&dir)
        .args(["build", "--release", "--quiet"])
        .env_clear();
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
        None => dir.join("target"),
    };
    let out = cmd.output().map_err(|e| format!("cannot run cargo: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "build of boards/{board} failed (run scripts/setup-cross.sh first):\n{}",
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    Ok(target.join(format!("thumbv7em-none-eabihf/release/board-{board}")))
}

/// Build the QEMU firmware once per process; its ELF path.
pub fn firmware_elf() -> Result<PathBuf, String> {
    FIRMWARE
        .get_or_init(|| build_board("mps2-an386", &[], None))
        .clone()
}

/// The `ferrobot-sim` binary `cargo test --workspace` built next to this test.
fn sim_binary() -> PathBuf {
    let exe = std::env::current_exe().unwrap_or_default();
    let dir = exe
        .parent()
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .unwrap_or_default();
    dir.join("ferrobot-sim")
}

/// A child process killed on drop.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// QEMU running the firmware, the plants, and the host link's path.
pub struct Hil {
    qemu: Proc,
    _sim: Proc,
    sim_in: ChildStdin,
    sim_out: BufReader<ChildStdout>,
    /// The host link (UART0's PTY).
    pub host: PathBuf,
    /// The defmt log (UART3), a file.
    pub log: PathBuf,
}

impl Hil {
    /// Start the plants of `robot` and the firmware in QEMU.
    pub fn start(robot: &str) -> Result<Hil, String> {
        let elf = firmware_elf()?;
        let sim_bin = sim_binary();
        if !sim_bin.exists() {
            return Err(format!(
                "{} not built: run `cargo test --workspace`",
                sim_bin.display()
            ));
        }
        let mut sim = Command::new(&sim_bin)
            .args(["serve", "--robot", robot, "--seed", "11"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .map_err(|e| format!("cannot start {}: {e}", sim_bin.display()))?;
        let sim_in = sim.stdin.take().ok_or("no stdin")?;
        let mut sim_out = BufReader::new(sim.stdout.take().ok_or("no stdout")?);
        let sim = Proc(sim);
        let mut line = String::new();
        sim_out.read_line(&mut line).map_err(|e| e.to_string())?;
        let v: serde_json::Value =
            serde_json::from_str(&line).map_err(|e| format!("{e}: {line:?}"))?;
        let servo = v["servo_bus"].as_str().ok_or("no servo bus")?.to_string();
        let base = v["base"].as_str().ok_or("no base")?.to_string();
        let log = std::env::temp_dir().join(format!(
            "ferrobot-hil-{}-{}.defmt",
            std::process::id(),
            line.len() ^ servo.len()
        ));
        let (qemu, host) = ferrobot::backend::emulated::start_qemu(&elf, &servo, Some(&base), &log)
            .map_err(|e| e.to_string())?;
        let qemu = Proc(qemu);
        Ok(Hil {
            qemu,
            _sim: sim,
            sim_in,
            sim_out,
            host,
            log,
        })
    }

    /// One control line to the plants; their JSON answer.
    pub fn plants(&mut self, cmd: &str) -> serde_json::Value {
        let _ = writeln!(self.sim_in, "{cmd}");
        let _ = self.sim_in.flush();
        let mut line = String::new();
        let _ = self.sim_out.read_line(&mut line);
        serde_json::from_str(&line).unwrap_or(serde_json::Value::Null)
    }

    /// Whether QEMU still runs.
    pub fn qemu_alive(&mut self) -> bool {
        matches!(self.qemu.0.try_wait(), Ok(None))
    }

    /// A raw frame-level client on the host link.
    pub fn raw(&self) -> Result<RawClient, String> {
        RawClient::open(&self.host)
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
            .map_err(|e| e.to_string())?;
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

    /// Wait for a message `pred` accepts.
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
