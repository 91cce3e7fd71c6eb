//! `ferrobot bench host-loop`: the host-run firmware's servo loop on the wall clock, against
//! the simulated plants served in real time on pseudo-terminals (`ferrobot_sim::serve`), with
//! the arm moving: the period between ticks and its jitter as this machine keeps it, the
//! firmware's own loop counters, and the wire's budget per tick at the description's bit
//! rate with the U2D2's USB latency, which pseudo-terminals do not have.

use std::time::{Duration, Instant};

use ferrobot::backend::direct::{check::Devices, temp_link, HostLink, HostRunFirmware, Ports};
use ferrobot::{Backend, Robot};
use serde::Serialize;

use super::common::{load, print_json};

/// `ferrobot bench host-loop`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Robot (it needs a `[direct]` section).
    #[arg(long, default_value = "locobot")]
    pub robot: String,
    /// Wall-clock seconds to measure.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// One JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// The figures, fields in alphabetical order (see [`print_json`]).
#[derive(Serialize)]
struct Report {
    /// Bytes on the bus per tick: the sync read, every servo's status, the goals' sync write.
    bus_bytes_per_tick: usize,
    /// Their time at the bit rate, ms.
    bus_ms_per_tick: f64,
    /// Servos on the bus.
    servos: usize,
    /// The bus's bit rate, bit/s.
    baud: u32,
    /// The configured loop period, ms.
    period_ms: f64,
    /// Measured interval between ticks: mean, median, 99th percentile, largest, ms.
    interval_ms: [f64; 4],
    /// Standard deviation of the interval, ms.
    jitter_ms: f64,
    /// Ticks measured.
    ticks: usize,
    /// The firmware's own count of ticks that overran their period.
    overruns: u32,
    /// Servo replies that missed their deadline.
    servo_timeouts: u32,
    /// Worst-case time per tick on a U2D2 with the FTDI latency timer at 1 ms and at the
    /// driver's default 16 ms: the bus time plus one timer period and one USB frame, ms.
    usb_worst_ms: [f64; 2],
}

/// Bytes of one tick at `n` servos: the sync read (14 + n), each status (11 + 10), the goals'
/// sync write of a 4-byte register (14 + 5 n).
fn bus_bytes(n: usize) -> usize {
    (14 + n) + 21 * n + (14 + 5 * n)
}

/// Mean, median, 99th percentile and largest of `v` (sorted here), and the standard deviation.
fn stats(mut v: Vec<f64>) -> ([f64; 4], f64) {
    v.sort_by(f64::total_cmp);
    let n = v.len().max(1) as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    let at = |q: f64| {
        v.get(((v.len() as f64 - 1.0) * q).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    ([mean, at(0.5), at(0.99), at(1.0)], var.sqrt())
}

/// Run the host-run firmware on the plants served in real time for `seconds`, the arm swinging.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    if !(a.seconds >= 0.1 && a.seconds <= 3600.0) {
        return Err(ferrobot::Error::OutOfRange {
            what: "--seconds".into(),
            value: a.seconds,
            min: 0.1,
            max: 3600.0,
        });
    }
    let cfg = load(&a.robot)?;
    let direct = cfg
        .direct_config()
        .ok_or_else(|| ferrobot::Error::Usage(format!("{} has no [direct] section", cfg.name)))?;
    let (served, _plants) = ferrobot_sim::serve::serve(&cfg.name, 1)
        .map_err(|e| ferrobot::Error::Link(format!("plants: {e}")))?;
    let ticks = ferrobot::backend::direct::runtime::TickLog::default();
    let ports = Ports {
        host: HostLink::Serve(temp_link("bench-host-loop")),
        devices: Devices {
            servo: Some(served.servo_bus.clone().into()),
            base: served.base.clone().map(Into::into),
        },
        clock: None,
        ticks: Some(ticks.clone()),
    };
    let firmware = HostRunFirmware::start(&cfg, &ports)?;
    let bot = Robot::builder(&cfg.name)
        .backend(Backend::Serial {
            path: firmware.link.clone(),
        })
        .use_camera(false)
        .build()?;
    let arm = bot.arm()?;
    let start = Instant::now();
    if let Ok(mut t) = ticks.lock() {
        t.clear();
    }
    let mut k = 0;
    while start.elapsed() < Duration::from_secs_f64(a.seconds) {
        let q = if k % 2 == 0 { 0.4 } else { -0.4 };
        arm.set_joint_positions(&[q, 0.2, -0.2, 0.3, q])?;
        k += 1;
    }
    let log: Vec<Instant> = ticks.lock().map(|t| t.clone()).unwrap_or_default();
    let telemetry = bot.telemetry()?;
    let diagnostics = bot.diagnostics()?;
    drop(bot);
    drop(firmware);
    let intervals: Vec<f64> = log
        .windows(2)
        .map(|w| (w[1] - w[0]).as_secs_f64() * 1e3)
        .collect();
    let (interval_ms, jitter_ms) = stats(intervals);
    let servos = cfg.joints.len() + cfg.joints.iter().filter(|j| j.twin_id.is_some()).count();
    let bytes = bus_bytes(servos);
    let baud = direct.bus.baud;
    let bus_ms = bytes as f64 * 10.0 / baud as f64 * 1e3;
    let r = Report {
        bus_bytes_per_tick: bytes,
        bus_ms_per_tick: bus_ms,
        servos,
        baud,
        period_ms: f64::from(direct.bus.loop_period_us) / 1e3,
        interval_ms,
        jitter_ms,
        ticks: log.len(),
        overruns: telemetry.loop_stats.overruns,
        servo_timeouts: diagnostics.servo_timeouts,
        usb_worst_ms: [bus_ms + 1.0 + 1.0, bus_ms + 16.0 + 1.0],
    };
    if a.json {
        print_json(&r);
    } else {
        table(&r);
    }
    Ok(())
}

fn table(r: &Report) {
    say!(
        "host-run servo loop, {} servos at {} bit/s, period {:.1} ms",
        r.servos,
        r.baud,
        r.period_ms
    );
    say!(
        "| ticks | interval mean | median | p99 | max | jitter (sd) | overruns | servo timeouts |"
    );
    say!("|---|---|---|---|---|---|---|---|");
    let [mean, p50, p99, max] = r.interval_ms;
    say!(
        "| {} | {mean:.3} ms | {p50:.3} ms | {p99:.3} ms | {max:.3} ms | {:.3} ms | {} | {} |",
        r.ticks,
        r.jitter_ms,
        r.overruns,
        r.servo_timeouts
    );
    say!(
        "wire per tick: {} bytes = {:.2} ms at {} bit/s; worst tick on a U2D2: {:.2} ms with \
         the latency timer at 1 ms, {:.2} ms at 16 ms",
        r.bus_bytes_per_tick,
        r.bus_ms_per_tick,
        r.baud,
        r.usb_worst_ms[0],
        r.usb_worst_ms[1]
    );
}
