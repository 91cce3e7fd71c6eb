//! What the board server keeps for a person reading a failed test: the last frames on each
//! link, and the report of the clock, the counters and the plants' state.

use std::collections::VecDeque;
use std::fmt::Write as _;

use ferrobot_firmware::Link;
use ferrobot_protocol::{DeviceMsg, Frame, HostMsg};

use super::{BoardServer, Inner, TRACE_LEN};
use crate::hardware::Hardware;

/// What went over one link, newest last.
#[derive(Default)]
pub(super) struct LinkTrace {
    to_board: VecDeque<(u64, String)>,
    from_board: VecDeque<(u64, String)>,
}

impl LinkTrace {
    fn push(&mut self, to_board: bool, t: u64, what: String) {
        let q = if to_board {
            &mut self.to_board
        } else {
            &mut self.from_board
        };
        if q.len() == TRACE_LEN {
            q.pop_front();
        }
        q.push_back((t, what));
    }
}

fn hex(bytes: &[u8]) -> String {
    let mut s = String::new();
    for b in bytes.iter().take(40) {
        let _ = write!(s, "{b:02X} ");
    }
    if bytes.len() > 40 {
        let _ = write!(s, "... ({} bytes)", bytes.len());
    }
    s.trim_end().to_string()
}

fn short(s: String) -> String {
    if s.len() > 200 {
        let cut = (0..=200)
            .rev()
            .find(|&i| s.is_char_boundary(i))
            .unwrap_or(0);
        format!("{}...", &s[..cut])
    } else {
        s
    }
}

impl Inner {
    pub(super) fn record_plant(&mut self, link: Link, to_board: bool, bytes: &[u8]) {
        let t = self.conductor.now_us();
        let trace = if link == Link::Servo {
            &mut self.servo
        } else {
            &mut self.base
        };
        trace.push(to_board, t, hex(bytes));
    }

    pub(super) fn record_host(&mut self, to_board: bool, bytes: &[u8]) {
        let t = self.conductor.now_us();
        let mut seen = Vec::new();
        if to_board {
            self.host_to_board
                .feed(bytes, |r: Result<Frame<HostMsg>, _>| {
                    seen.push(short(match r {
                        Ok(f) => format!("#{} {:?}", f.seq, f.msg),
                        Err(e) => format!("bad frame: {e:?}"),
                    }))
                });
        } else {
            self.board_to_host
                .feed(bytes, |r: Result<Frame<DeviceMsg>, _>| {
                    seen.push(short(match r {
                        Ok(f) => format!("#{} {:?}", f.seq, f.msg),
                        Err(e) => format!("bad frame: {e:?}"),
                    }))
                });
        }
        for s in seen {
            self.host.push(to_board, t, s);
        }
    }
}

impl BoardServer {
    /// What the server knows, for a person reading a failed test: clock, counters of the
    /// conductor, the plants and the lines, and the last frames on each link.
    pub fn report(&self) -> String {
        let mut i = self.lock();
        let mut s = String::new();
        report_clock(&mut s, &i);
        report_plants(&mut s, i.conductor.hardware());
        report_links(&mut s, &i);
        s
    }
}

/// The clock and the conductor's counters, and the board's last report.
fn report_clock(s: &mut String, i: &Inner) {
    let now = i.conductor.now_us();
    let st = i.conductor.stats();
    let wall = i.first_report.map(|t| t.elapsed().as_secs_f64());
    let _ = writeln!(
        s,
        "plants of {:?}: simulated time {:.3} s{}; {} steps, {} reports from the board, {} bad clock frames, {} re-anchorings of the pace{}",
        i.robot,
        now as f64 * 1e-6,
        wall.map(|w| format!(" after {w:.1} s of wall time since the board's first report ({:.2}x real time)", now as f64 * 1e-6 / w.max(1e-9))).unwrap_or_else(|| " (the board never reported on its clock link)".into()),
        st.advances,
        st.reports,
        st.bad_clock_frames,
        i.paced_behind,
        i.stopped.as_ref().map(|w| format!("; server stopped: {w}")).unwrap_or_default()
    );
    match i.conductor.report() {
        Some(r) => {
            let _ = writeln!(
                s,
                "board's last report: at {} us, next {} us, consumed {:?} and sent {:?} bytes (servo, base); the plants wrote {:?} and read {:?}",
                r.now_us,
                if r.next_us == u64::MAX { "none".to_string() } else { r.next_us.to_string() },
                r.rx,
                r.tx,
                st.written,
                st.read
            );
        }
        None => {
            let _ = writeln!(s, "board's last report: none");
        }
    }
}

/// The servo bus's counters, each servo's state and the base's.
fn report_plants(s: &mut String, hw: &Hardware) {
    let c = hw.chain.stats;
    let _ = writeln!(
        s,
        "servo bus (plants' side): {} instructions, {} status packets, {} bad packets; line bytes [to servos, from servos, to base, from base] = {:?}",
        c.instructions,
        c.statuses,
        c.bad_packets,
        hw.line_bytes()
    );
    for id in 1..=32u8 {
        if let Some(sv) = hw.chain.servo(id) {
            let _ = writeln!(
                s,
                "  servo {id}: angle {:.4} rad, torque {}, hardware error {:#04x}{}",
                sv.theta,
                if sv.torque_enabled() { "on" } else { "off" },
                sv.hardware_error(),
                if sv.silent { ", silent" } else { "" }
            );
        }
    }
    if let Some(b) = hw.base.as_ref() {
        let _ = writeln!(
            s,
            "base: truth {:?}, wheel speed {:?}, target {:?}, {} bad packets",
            b.drive.truth,
            b.drive.speed,
            b.drive.target,
            b.bad_packets()
        );
    }
}

/// The host link's counters and the last frames on each link.
fn report_links(s: &mut String, i: &Inner) {
    let _ = writeln!(
        s,
        "host link: {} bytes to the board, {} from it, {} dropped while no host had the port open (host connected: {})",
        i.host_bytes[0], i.host_bytes[1], i.host_dropped, i.host_connected
    );
    for (name, trace) in [
        ("host", &i.host),
        ("servo bus", &i.servo),
        ("base", &i.base),
    ] {
        for (dir, q) in [
            ("to the board", &trace.to_board),
            ("from the board", &trace.from_board),
        ] {
            if q.is_empty() {
                continue;
            }
            let _ = writeln!(s, "last on {name}, {dir}:");
            for (t, what) in q {
                let _ = writeln!(s, "  {:>10.6} s  {what}", *t as f64 * 1e-6);
            }
        }
    }
}
