//! Firmware measurements, printed as a Markdown table:
//! `cargo bench -p ferrobot-hil --bench firmware`.
//!
//! * flash and static RAM of both boards (`size -A` of the release ELFs);
//! * instructions per servo-loop tick (LoCoBot: 9 servos and the Kobuki), counted in QEMU with
//!   `-icount shift=0` by the `tick-bench` build of the mps2-an386 board;
//! * host-link round trip of a small command (Heartbeat → Ack), 1,000 times: to the firmware
//!   in QEMU, and to the firmware core running as a Linux process behind a PTY.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use ferrobot_hil::{build_board, build_board_with, Hil, RawClient};
use ferrobot_protocol::*;

fn sizes(elf: &Path) -> (u64, u64) {
    let out = Command::new("size")
        .arg("-A")
        .arg(elf)
        .output()
        .expect("size runs");
    let text = String::from_utf8_lossy(&out.stdout);
    let sec = |name: &str| {
        text.lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0)
    };
    let data = sec(".data");
    (
        sec(".vector_table") + sec(".text") + sec(".rodata") + data,
        data + sec(".bss") + sec(".uninit"),
    )
}

fn round_trips(raw: &mut RawClient, n: usize) -> (f64, f64) {
    let mut t = Vec::with_capacity(n);
    for _ in 0..n {
        let start = Instant::now();
        let seq = raw.send(&HostMsg::Heartbeat);
        let got = raw.wait(
            Duration::from_secs(2),
            |m| matches!(m, DeviceMsg::Ack { seq: s } if *s == seq),
        );
        assert!(got.is_some(), "no answer");
        t.push(start.elapsed().as_secs_f64() * 1e3);
    }
    t.sort_by(f64::total_cmp);
    (t[n / 2], t[n * 99 / 100])
}

fn handshake(raw: &mut RawClient) {
    for _ in 0..50 {
        raw.send(&HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: SCHEMA_HASH,
        });
        if raw
            .wait(
                Duration::from_millis(300),
                |m| matches!(m, DeviceMsg::Hello(i) if i.accepted),
            )
            .is_some()
        {
            // Telemetry off, so only the answers travel.
            raw.command(&HostMsg::SetTelemetry { period_ms: 0 });
            return;
        }
    }
    panic!("no handshake");
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    println!("| measurement | result | goal |");
    println!("|---|---|---|");
    for (board, goal) in [
        ("mps2-an386", "≤ 64 KiB flash, ≤ 32 KiB RAM"),
        ("opencr", "builds and links"),
    ] {
        let elf = build_board(board, &[], None).unwrap_or_else(|e| panic!("{e}"));
        let (flash, ram) = sizes(&elf);
        println!("| {board}: flash / static RAM | {flash} B ({:.1} KiB) / {ram} B ({:.1} KiB) | {goal} |", flash as f64 / 1024.0, ram as f64 / 1024.0);
    }
    // The tick runs the LoCoBot's gravity model, as the host derives it from the description.
    let cfg = ferrobot_profile::bundled("locobot").expect("the LoCoBot");
    let model = ferrobot_profile::arm_model(&cfg).expect("its arm model");
    let model: Vec<String> = model
        .iter()
        .map(|l| {
            let mut v = vec![f32::from(l.joint)];
            v.extend(l.origin.iter().chain(&l.rpy).chain(&l.axis));
            v.push(l.mass);
            v.extend(&l.com);
            v.iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect();
    let env = [("FERROBOT_TICK_BENCH_MODEL", model.join(";"))];
    let bench = build_board_with(
        "mps2-an386",
        &["tick-bench"],
        Some("../target/tick-bench"),
        &env,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut qemu = Command::new("qemu-system-arm")
        .args(ferrobot::backend::emulated::QEMU_MACHINE_ARGS)
        .args([
            "-icount",
            "shift=0,sleep=off",
            "-serial",
            "stdio",
            "-kernel",
        ])
        .arg(&bench)
        .stdout(Stdio::piped())
        .spawn()
        .expect("qemu");
    let mut line = String::new();
    BufReader::new(qemu.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("result line");
    let _ = qemu.kill();
    let _ = qemu.wait();
    let field = |k: &str| {
        line.split_whitespace()
            .find_map(|w| w.strip_prefix(k))
            .unwrap_or("?")
            .to_string()
    };
    println!(
        "| instructions per servo-loop tick, LoCoBot (9 servos + Kobuki, its 5-link gravity model), qemu -icount | {} (worst {}) = {:.1} % of a 168 MHz Cortex-M4 at 1 kHz | ≤ 20,000 |",
        field("instructions_per_tick="),
        field("worst_tick_instructions="),
        field("instructions_per_tick=").parse::<f64>().unwrap_or(0.0) / 168_000.0 * 100.0
    );
    {
        let hil = Hil::start("locobot").unwrap_or_else(|e| panic!("{e}"));
        let mut raw = hil.raw().expect("port");
        handshake(&mut raw);
        let (med, p99) = round_trips(&mut raw, 1000);
        println!("| host-link round trip, firmware in QEMU (PTY) | median {med:.3} ms, p99 {p99:.3} ms | - (micro-ROS: 2.55 ms over USB) |");
    }
    let link = std::env::temp_dir().join(format!("ferrobot-rtt-{}", std::process::id()));
    let mut proc = Command::new(env!("CARGO_BIN_EXE_firmware-process"))
        .arg("locobot")
        .arg(&link)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("firmware process");
    let mut first = String::new();
    BufReader::new(proc.stdout.take().expect("stdout"))
        .read_line(&mut first)
        .expect("announce");
    let mut raw = RawClient::open(&link).expect("port");
    handshake(&mut raw);
    let (med, p99) = round_trips(&mut raw, 1000);
    println!("| host-link round trip, firmware core as a Linux process (PTY) | median {med:.3} ms, p99 {p99:.3} ms | ≤ 0.2 ms median (micro-ROS: 2.55 ms over USB) |");
    let _ = proc.kill();
    let _ = proc.wait();
}
