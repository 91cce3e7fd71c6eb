//! The firmware core against byte-level fakes of its buses: a scripted Dynamixel bus that
//! answers from a table of present values, a scripted Kobuki, and raw host frames.

use std::collections::{BTreeMap, BTreeSet};

use ferrobot_firmware::time::{Duration, Instant};
use ferrobot_firmware::{config, Firmware, Link};
use ferrobot_protocol::dxl::{self, addr, inst, units, PacketDecoder};
use ferrobot_protocol::*;

/// A fake Dynamixel bus: answers ping, read, write and sync read from fixed present values;
/// logs every instruction it sees.
struct FakeBus {
    present: BTreeMap<u8, (i16, i32, i32)>,
    silent: BTreeSet<u8>,
    corrupt: bool,
    decoder: PacketDecoder<512>,
    log: Vec<(u8, u8, Vec<u8>)>,
}

impl FakeBus {
    fn new(ids: impl IntoIterator<Item = u8>) -> Self {
        Self {
            present: ids.into_iter().map(|id| (id, (0, 0, 2048))).collect(),
            silent: BTreeSet::new(),
            corrupt: false,
            decoder: PacketDecoder::new(),
            log: Vec::new(),
        }
    }

    fn status(&self, id: u8, params: &[u8]) -> Vec<u8> {
        let mut b = vec![0u8; 64];
        let n = dxl::status(&mut b, id, 0, params).expect("fits");
        b.truncate(n);
        if self.corrupt {
            b[n - 3] ^= 0x01;
        }
        b
    }

    fn respond(&mut self, bytes: &[u8]) -> Vec<u8> {
        let mut packets = Vec::new();
        for &b in bytes {
            if let Some(Ok(p)) = self.decoder.push(b) {
                packets.push((p.id, p.instruction, p.params.to_vec()));
            }
        }
        let mut out = Vec::new();
        for (id, ins, params) in packets {
            self.log.push((id, ins, params.clone()));
            let live = |id: u8| self.present.contains_key(&id) && !self.silent.contains(&id);
            match ins {
                inst::PING if live(id) => out.extend(self.status(id, &[0xFC, 0x03, 46])),
                inst::WRITE if live(id) => out.extend(self.status(id, &[])),
                inst::REBOOT if live(id) => out.extend(self.status(id, &[])),
                inst::READ if live(id) => {
                    let (a, n) = (dxl::le_u16(&params, 0), dxl::le_u16(&params, 2));
                    let (_, _, pos) = self.present[&id];
                    let data: Vec<u8> = match a {
                        addr::PRESENT_POSITION => pos.to_le_bytes().to_vec(),
                        _ => vec![0; n as usize],
                    };
                    out.extend(self.status(id, &data[..n as usize]));
                }
                inst::SYNC_READ => {
                    for &sid in &params[4..] {
                        if !live(sid) {
                            break;
                        }
                        let (c, v, p) = self.present[&sid];
                        let mut d = Vec::new();
                        d.extend_from_slice(&c.to_le_bytes());
                        d.extend_from_slice(&v.to_le_bytes());
                        d.extend_from_slice(&p.to_le_bytes());
                        out.extend(self.status(sid, &d));
                    }
                }
                _ => {}
            }
        }
        out
    }
}

/// Run the firmware against the fake bus for `ticks` loop periods from `*now`.
fn run(fw: &mut Firmware, bus: &mut FakeBus, now: &mut Instant, ticks: u64) {
    run_with(fw, bus, now, ticks, |bus, tx| bus.respond(tx));
}

/// [`run`], with `line` standing between the firmware and the bus: it gets the bytes the
/// firmware sent and returns what comes back.
fn run_with(
    fw: &mut Firmware,
    bus: &mut FakeBus,
    now: &mut Instant,
    ticks: u64,
    mut line: impl FnMut(&mut FakeBus, &[u8]) -> Vec<u8>,
) {
    let end = *now + Duration::from_millis(ticks);
    while *now < end {
        *now = (*now + Duration::from_micros(1)).max(fw.next_deadline().min(end));
        fw.poll(*now);
        // Exchange until the bus has nothing more to say within this instant (+100 µs per reply).
        for _ in 0..4 {
            let n = fw.pending(Link::Servo).len();
            if n == 0 {
                break;
            }
            let tx = fw.pending(Link::Servo).to_vec();
            fw.consume(Link::Servo, n);
            let rx = line(bus, &tx);
            if !rx.is_empty() {
                *now += Duration::from_micros(100);
                fw.on_servo_bytes(*now, &rx);
            }
        }
        for link in [Link::Host, Link::Base] {
            let n = fw.pending(link).len();
            fw.consume(link, n);
        }
    }
}

fn hello() -> Vec<u8> {
    frame(
        0,
        &HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: SCHEMA_HASH,
        },
    )
}

fn frame(seq: u16, m: &HostMsg) -> Vec<u8> {
    let mut b = [0u8; MAX_WIRE];
    let n = encode_frame(seq, m, &mut b).expect("fits");
    b[..n].to_vec()
}

fn locobot() -> (Firmware, FakeBus, Instant) {
    let fw = Firmware::new(config::locobot(), "test", Instant::ZERO);
    let bus = FakeBus::new(1..=9);
    (fw, bus, Instant::ZERO)
}

/// The instant `t` µs after boot.
fn us(t: u64) -> Instant {
    Instant::from_micros(t)
}

#[test]
fn configures_every_servo_then_runs_one_sync_read_and_one_sync_write_per_tick() {
    let (mut fw, mut bus, mut now) = locobot();
    run(&mut fw, &mut bus, &mut now, 200);
    // Configuration wrote return delay 0 and the operating mode, and enabled torque, on all nine.
    for id in 1..=9u8 {
        let writes: Vec<&Vec<u8>> = bus
            .log
            .iter()
            .filter(|(i, ins, _)| *i == id && *ins == inst::WRITE)
            .map(|(_, _, p)| p)
            .collect();
        // The last write to each address is what the servo is left with.
        let at = |a: u16| {
            writes
                .iter()
                .rev()
                .find(|p| dxl::le_u16(p, 0) == a)
                .map(|p| p[2..].to_vec())
        };
        assert_eq!(at(addr::RETURN_DELAY_TIME), Some(vec![0]), "servo {id}");
        assert_eq!(
            at(addr::OPERATING_MODE),
            Some(vec![dxl::mode::POSITION]),
            "servo {id}"
        );
        assert_eq!(at(addr::TORQUE_ENABLE), Some(vec![1]), "servo {id}");
    }
    // In steady state: per tick exactly one sync read of 126..136 from all nine, one sync write.
    bus.log.clear();
    run(&mut fw, &mut bus, &mut now, 100);
    let reads: Vec<_> = bus
        .log
        .iter()
        .filter(|(_, i, _)| *i == inst::SYNC_READ)
        .collect();
    let writes: Vec<_> = bus
        .log
        .iter()
        .filter(|(_, i, _)| *i == inst::SYNC_WRITE)
        .collect();
    assert!(
        (99..=101).contains(&reads.len()),
        "{} sync reads in 100 ticks",
        reads.len()
    );
    assert_eq!(reads.len(), writes.len());
    assert_eq!(
        bus.log.len(),
        reads.len() + writes.len(),
        "other traffic in steady state"
    );
    let p = &reads[0].2;
    assert_eq!(
        (dxl::le_u16(p, 0), dxl::le_u16(p, 2)),
        (addr::PRESENT_CURRENT, 10)
    );
    assert_eq!(&p[4..], &[1, 2, 3, 4, 5, 6, 7, 8, 9]);
    assert_eq!(dxl::le_u16(&writes[0].2, 0), addr::GOAL_POSITION);
    assert_eq!(fw.telemetry(now).loop_stats.overruns, 0);
}

/// Goal ticks of the last sync write, by servo ID.
fn last_goals(bus: &FakeBus) -> BTreeMap<u8, i32> {
    let (_, _, p) = bus
        .log
        .iter()
        .rev()
        .find(|(_, i, _)| *i == inst::SYNC_WRITE)
        .expect("a sync write");
    p[4..]
        .chunks(5)
        .map(|c| (c[0], i32::from_le_bytes([c[1], c[2], c[3], c[4]])))
        .collect()
}

#[test]
fn twin_servo_is_mirrored_and_inverted_joints_are_inverted() {
    let (mut fw, mut bus, mut now) = locobot();
    fw.on_host_bytes(now, &hello());
    fw.on_host_bytes(now, &frame(1, &HostMsg::SetWatchdog { period_ms: 2000 }));
    run(&mut fw, &mut bus, &mut now, 200);
    let pts = [0.5f32, 0.5]
        .iter()
        .map(|&p| JointPoint::at_rest(p))
        .collect();
    fw.on_host_bytes(
        now,
        &frame(
            2,
            &HostMsg::Waypoint {
                joints: 0b110,
                duration_us: 0,
                points: pts,
            },
        ),
    );
    // Rate-limited at 1 rad/s: 0.5 rad takes 500 ticks.
    run(&mut fw, &mut bus, &mut now, 700);
    let g = last_goals(&bus);
    let d = (0.5 / units::RAD_PER_TICK).round() as i32;
    // The fake servos never move, so the command stays within its lead of them (it never
    // runs far ahead of a joint that does not follow) and the goal-offset integrator adds to
    // the goal; compare the directions and the mirrored structure, which they keep.
    assert!(g[&2] - 2048 > 0 && g[&2] - 2048 <= d + 320, "{g:?}");
    assert_eq!(g[&2] - 2048, 2048 - g[&3], "twin must be mirrored: {g:?}");
    assert!(g[&4] < 2048, "joint_3 is sign-inverted: {g:?}");
}

#[test]
fn lost_servo_is_reported_left_out_of_the_sync_read_and_the_loop_continues() {
    let (mut fw, mut bus, mut now) = locobot();
    fw.on_host_bytes(now, &hello());
    run(&mut fw, &mut bus, &mut now, 200);
    bus.silent.insert(5);
    run(&mut fw, &mut bus, &mut now, 20);
    bus.log.clear();
    run(&mut fw, &mut bus, &mut now, 250);
    let reads: Vec<_> = bus
        .log
        .iter()
        .filter(|(_, i, _)| *i == inst::SYNC_READ)
        .collect();
    assert!(
        reads.len() >= 249,
        "{} sync reads in 250 ticks",
        reads.len()
    );
    assert!(
        reads.iter().all(|(_, _, p)| !p[4..].contains(&5)),
        "servo 5 still in the sync read"
    );
    let t = fw.telemetry(now);
    assert!(t.faults & fault_flags::SERVO_LOST != 0);
    assert!(fw.diagnostics().servo_timeouts >= 3);
    // Pinged every 100 ms while lost.
    let pings = bus
        .log
        .iter()
        .filter(|(i, ins, _)| *i == 5 && *ins == inst::PING)
        .count();
    assert!(
        (2..=3).contains(&pings),
        "{pings} pings of the lost servo in 250 ms"
    );
}

#[test]
fn corrupted_replies_are_counted_and_never_stop_the_loop() {
    let (mut fw, mut bus, mut now) = locobot();
    run(&mut fw, &mut bus, &mut now, 200);
    let ticks = fw.telemetry(now).loop_stats.ticks;
    bus.corrupt = true;
    run(&mut fw, &mut bus, &mut now, 2);
    bus.corrupt = false;
    run(&mut fw, &mut bus, &mut now, 10);
    assert_eq!(fw.diagnostics().servo_bad_packets, 18);
    assert!(fw.telemetry(now).loop_stats.ticks >= ticks + 11);
}

#[test]
fn host_garbage_is_counted_and_the_link_keeps_working() {
    let (mut fw, mut bus, mut now) = locobot();
    fw.on_host_bytes(now, &hello());
    let mut bad = frame(1, &HostMsg::Heartbeat);
    bad[1] ^= 0x40;
    fw.on_host_bytes(now, &bad);
    fw.on_host_bytes(now, &[1, 2, 3, 0, 0, 0xFF, 0]);
    fw.on_host_bytes(now, &frame(2, &HostMsg::GetDiagnostics));
    run(&mut fw, &mut bus, &mut now, 1);
    let d = fw.diagnostics();
    assert_eq!(d.host_frames, 2);
    assert_eq!(d.host_bad_frames, 3);
}

/// A Kobuki feedback packet with these encoder counts.
fn kobuki_feedback(left: u16, right: u16, bumper: u8) -> Vec<u8> {
    let d = kobuki::BasicSensorData {
        left_encoder: left,
        right_encoder: right,
        bumper,
        ..Default::default()
    };
    let mut payload = vec![kobuki::FB_BASIC_SENSOR_DATA, 15];
    payload.extend_from_slice(&d.to_bytes());
    let mut b = [0u8; 64];
    let n = kobuki::encode_packet(&payload, &mut b).expect("fits");
    b[..n].to_vec()
}

#[test]
fn kobuki_odometry_survives_encoder_wrap_around() {
    let mut fw = Firmware::new(config::locobot(), "test", Instant::ZERO);
    // Both wheels advance 1000 ticks per packet, starting just below the wrap.
    let mut enc: u16 = 65_000;
    for k in 0..=10u64 {
        fw.on_base_bytes(us(k * 20_000), &kobuki_feedback(enc, enc, 0));
        enc = enc.wrapping_add(1000);
    }
    let o = fw.telemetry(us(200_000)).odometry;
    let expected = 10.0 * 1000.0 * 0.002436917 * 0.035;
    assert!((o.x as f64 - expected).abs() < 1e-4, "{o:?} vs {expected}");
    assert!(o.y.abs() < 1e-6 && o.theta.abs() < 1e-6);
}

#[test]
fn watchdog_sends_zero_to_the_base_at_once_and_reports() {
    let mut fw = Firmware::new(config::locobot(), "test", Instant::ZERO);
    fw.on_host_bytes(Instant::ZERO, &hello());
    fw.on_host_bytes(
        Instant::ZERO,
        &frame(
            1,
            &HostMsg::BaseVelocity {
                v: 0.3,
                w: 0.0,
                duration_ms: 10_000,
            },
        ),
    );
    let n = fw.pending(Link::Base).len();
    fw.consume(Link::Base, n);
    fw.poll(us(499_000));
    let n = fw.pending(Link::Base).len();
    fw.consume(Link::Base, n);
    fw.poll(us(500_000));
    // The last base command sent is speed 0, radius 0.
    let tx = fw.pending(Link::Base).to_vec();
    let mut p = kobuki::Parser::new();
    let mut last = None;
    for b in tx {
        if let Some(Ok(payload)) = p.push(b) {
            last = kobuki::sub_payloads(payload)
                .find(|(id, _)| *id == kobuki::CMD_BASE_CONTROL)
                .map(|(_, d)| d.to_vec());
        }
    }
    assert_eq!(last, Some(vec![0, 0, 0, 0]));
    assert!(fw.telemetry(us(500_000)).faults & fault_flags::WATCHDOG != 0);
}

#[test]
fn create2_driver_starts_the_stream_drives_direct_and_integrates_odometry() {
    let mut fw = Firmware::new(config::locobot_lite(), "test", Instant::ZERO);
    fw.on_host_bytes(Instant::ZERO, &hello());
    fw.poll(Instant::ZERO);
    let tx = fw.pending(Link::Base).to_vec();
    // Start, Safe, Stream of bumps/drops, four cliffs and both encoders.
    let mut start = vec![create2::OP_START, create2::OP_SAFE, create2::OP_STREAM, 7];
    start.extend_from_slice(&create2::STREAM_IDS);
    assert_eq!(&tx[..start.len()], &start[..], "{tx:?}");
    let n = fw.pending(Link::Base).len();
    fw.consume(Link::Base, n);
    fw.on_host_bytes(
        us(1000),
        &frame(
            1,
            &HostMsg::BaseVelocity {
                v: 0.1,
                w: 0.0,
                duration_ms: 1000,
            },
        ),
    );
    let tx = fw.pending(Link::Base).to_vec();
    assert_eq!(tx.last_chunk::<5>(), Some(&create2::drive_direct(100, 100)));
    // Stream packets: both encoders +100 counts per 15 ms, across the signed 16-bit wrap.
    let mut enc: i16 = 32_700;
    for k in 0..=20u64 {
        let s = create2::Sensors {
            left_encoder: enc,
            right_encoder: enc,
            ..Default::default()
        };
        let mut b = [0u8; 64];
        let n = create2::encode_stream(&s, &mut b).expect("fits");
        fw.on_base_bytes(us(2000 + k * 15_000), &b[..n]);
        enc = enc.wrapping_add(100);
    }
    let o = fw.telemetry(us(400_000)).odometry;
    let expected = 20.0 * 100.0 * (std::f64::consts::TAU / 508.8) * 0.036;
    assert!((o.x as f64 - expected).abs() < 1e-4, "{o:?} vs {expected}");
    assert_eq!(fw.diagnostics().base_packets, 21);
}

#[test]
fn a_waypoint_sent_before_the_servos_are_configured_is_kept() {
    let (mut fw, mut bus, mut now) = locobot();
    fw.on_host_bytes(now, &hello());
    fw.on_host_bytes(now, &frame(1, &HostMsg::SetWatchdog { period_ms: 2000 }));
    // Before any servo has answered: queue a move of joint_1 to 0.3 rad.
    let pts = [0.3f32].iter().map(|&p| JointPoint::at_rest(p)).collect();
    fw.on_host_bytes(
        now,
        &frame(
            2,
            &HostMsg::Waypoint {
                joints: 1,
                duration_us: 500_000,
                points: pts,
            },
        ),
    );
    run(&mut fw, &mut bus, &mut now, 800);
    let g = last_goals(&bus);
    // The fake servo never moves, so the command waits within its lead of it, towards the
    // target (the goal-offset integrator adds to it): the goal has moved towards 0.3 rad.
    let want = 2048 + 10;
    assert!(
        g[&1] >= want,
        "joint_1 goal {} ticks, want {want}: the waypoint was dropped",
        g[&1]
    );
}

/// The messages the firmware has queued for the host, consumed.
fn host_replies(fw: &mut Firmware) -> Vec<DeviceMsg> {
    let bytes = fw.pending(Link::Host).to_vec();
    fw.consume(Link::Host, bytes.len());
    let mut d = FrameDecoder::new();
    let mut out = Vec::new();
    d.feed::<DeviceMsg>(&bytes, |f| {
        if let Ok(f) = f {
            out.push(f.msg);
        }
    });
    out
}

#[test]
fn calibrated_geometry_is_used_by_the_odometry_and_bad_geometry_is_rejected() {
    let mut fw = Firmware::new(config::locobot_lite(), "test", Instant::ZERO);
    fw.on_host_bytes(Instant::ZERO, &hello());
    fw.poll(Instant::ZERO);
    host_replies(&mut fw);
    let set = |seq, left_radius, right_radius, track| {
        frame(
            seq,
            &HostMsg::SetBaseGeometry {
                left_radius,
                right_radius,
                track,
            },
        )
    };
    let (rl, rr, track) = (0.0363f32, 0.0360f32, 0.2370f32);
    fw.on_host_bytes(us(10), &set(1, rl, rr, track));
    // Rejected, and the good geometry stays: not finite, 39 % off, a track 15 % off.
    fw.on_host_bytes(us(20), &set(2, f32::NAN, rr, track));
    fw.on_host_bytes(us(30), &set(3, 0.05, rr, track));
    fw.on_host_bytes(us(40), &set(4, rl, rr, 0.27));
    let replies = host_replies(&mut fw);
    let acks: Vec<_> = replies
        .iter()
        .filter_map(|m| match m {
            DeviceMsg::Ack { seq } => Some((*seq, None)),
            DeviceMsg::Reject { seq, reason } => Some((*seq, Some(*reason))),
            _ => None,
        })
        .collect();
    assert_eq!(
        acks,
        vec![
            (1, None),
            (2, Some(RejectReason::InvalidConfig)),
            (3, Some(RejectReason::InvalidConfig)),
            (4, Some(RejectReason::InvalidConfig)),
        ]
    );
    // Both encoders +100 counts per packet: the calibrated odometry sees the larger left
    // wheel travel further and turn the base to the right.
    for k in 0..=20u64 {
        let enc = (k * 100) as i16;
        let s = create2::Sensors {
            left_encoder: enc,
            right_encoder: enc,
            ..Default::default()
        };
        let mut b = [0u8; 64];
        let n = create2::encode_stream(&s, &mut b).expect("fits");
        fw.on_base_bytes(us(1000 + k * 15_000), &b[..n]);
    }
    let o = fw.telemetry(us(400_000)).odometry;
    let phi = 2000.0 * std::f64::consts::TAU / 508.8;
    let (dl, dr) = (phi * rl as f64, phi * rr as f64);
    let theta = (dr - dl) / track as f64;
    let dist = 0.5 * (dl + dr);
    assert!((o.theta as f64 - theta).abs() < 1e-5, "{o:?} vs θ {theta}");
    // One arc of radius dist/θ.
    let (x, y) = (
        dist * theta.sin() / theta,
        dist * (1.0 - theta.cos()) / theta,
    );
    assert!(
        (o.x as f64 - x).abs() < 1e-4 && (o.y as f64 - y).abs() < 1e-4,
        "{o:?} vs ({x}, {y}) m"
    );
}

/// A sync-read status of servo `id` (current, velocity, position), as the bus would send it.
fn sync_status(bus: &FakeBus, id: u8, position: i32) -> Vec<u8> {
    let mut d = Vec::new();
    d.extend_from_slice(&0i16.to_le_bytes());
    d.extend_from_slice(&0i32.to_le_bytes());
    d.extend_from_slice(&position.to_le_bytes());
    bus.status(id, &d)
}

#[test]
fn a_late_status_never_completes_a_mode_change_the_servo_has_not_seen() {
    // Protocol 2.0 statuses carry no sequence number. Here a mode change's torque-off write is
    // lost on the line while a late sync-read status of the same servo arrives: taking it as
    // the write's answer would put every later step one answer ahead, and the firmware would
    // count torque on before the servo has seen it (found by the hostile stream, seed 560).
    let (mut fw, mut bus, mut now) = locobot();
    fw.on_host_bytes(now, &hello());
    run(&mut fw, &mut bus, &mut now, 200);
    bus.log.clear();
    fw.on_host_bytes(
        now,
        &frame(
            1,
            &HostMsg::SetMode {
                joints: 0b1,
                mode: JointMode::Velocity,
            },
        ),
    );
    let mut dropped = false;
    run_with(&mut fw, &mut bus, &mut now, 50, |bus, tx| {
        let torque_off = {
            let mut d = PacketDecoder::<512>::new();
            tx.iter().any(|&b| {
                matches!(d.push(b), Some(Ok(p)) if p.id == 1
                    && p.instruction == inst::WRITE
                    && dxl::le_u16(p.params, 0) == addr::TORQUE_ENABLE
                    && p.params.get(2) == Some(&0))
            })
        };
        if torque_off && !dropped {
            dropped = true;
            sync_status(bus, 1, 2048)
        } else {
            bus.respond(tx)
        }
    });
    assert!(dropped, "no torque-off write to servo 1");
    // What servo 1 saw, in order: torque off, then the mode, then torque on.
    let writes: Vec<(u16, Vec<u8>)> = bus
        .log
        .iter()
        .filter(|(id, ins, _)| *id == 1 && *ins == inst::WRITE)
        .map(|(_, _, p)| (dxl::le_u16(p, 0), p[2..].to_vec()))
        .collect();
    let first = |a: u16| writes.iter().position(|(w, _)| *w == a);
    let (off, mode, on) = (
        writes
            .iter()
            .position(|(a, d)| *a == addr::TORQUE_ENABLE && d == &[0]),
        first(addr::OPERATING_MODE),
        writes
            .iter()
            .position(|(a, d)| *a == addr::TORQUE_ENABLE && d == &[1]),
    );
    assert!(
        matches!((off, mode, on), (Some(a), Some(b), Some(c)) if a < b && b < c),
        "servo 1 saw {writes:?}"
    );
    assert_eq!(writes[mode.unwrap()].1, vec![dxl::mode::VELOCITY]);
    assert!(fw.diagnostics().servo_stale >= 1);
    assert_eq!(fw.bus().servos[0].ops, 0, "the mode change did not finish");
}

#[test]
fn a_status_out_of_a_sync_reads_order_is_dropped() {
    // A late status of the last servo arriving first must not count as this read's: the
    // read would end before that servo's own status and the position would be stale.
    let (mut fw, mut bus, mut now) = locobot();
    fw.on_host_bytes(now, &hello());
    run(&mut fw, &mut bus, &mut now, 200);
    bus.present.insert(9, (0, 0, 3000));
    let before = fw.diagnostics().servo_stale;
    run_with(&mut fw, &mut bus, &mut now, 5, |bus, tx| {
        let mut rx = sync_status(bus, 9, 1000);
        rx.extend(bus.respond(tx));
        rx
    });
    assert!(fw.diagnostics().servo_stale > before);
    assert_eq!(fw.bus().servos[8].present.position, 3000);
}

/// The last wheel command queued for the Kobuki, `[speed, radius]` bytes.
fn last_kobuki_command(fw: &mut Firmware) -> Option<Vec<u8>> {
    let tx = fw.pending(Link::Base).to_vec();
    fw.consume(Link::Base, tx.len());
    let mut p = kobuki::Parser::new();
    let mut last = None;
    for b in tx {
        if let Some(Ok(payload)) = p.push(b) {
            if let Some(d) = kobuki::sub_payloads(payload)
                .find(|(id, _)| *id == kobuki::CMD_BASE_CONTROL)
                .map(|(_, d)| d.to_vec())
            {
                last = Some(d);
            }
        }
    }
    last
}

/// A base whose feedback stops (a cable pulled) is stopped at the feedback timeout, not when
/// the command's duration runs out (its bumper and cliff sensors are no longer read), and is
/// refused motion until it speaks again; a stop is always taken.
#[test]
fn a_base_gone_silent_is_stopped_and_refused_motion_until_it_speaks() {
    let mut fw = Firmware::new(config::locobot(), "test", Instant::ZERO);
    fw.on_host_bytes(Instant::ZERO, &hello());
    let drive = |seq, v: f32| {
        frame(
            seq,
            &HostMsg::BaseVelocity {
                v,
                w: 0.0,
                duration_ms: 10_000,
            },
        )
    };
    for k in 0..5u64 {
        fw.on_base_bytes(us(k * 20_000), &kobuki_feedback(0, 0, 0));
    }
    fw.on_host_bytes(us(80_000), &drive(1, 0.3));
    fw.poll(us(80_000));
    let cmd = last_kobuki_command(&mut fw).expect("a command");
    assert_ne!(cmd, vec![0, 0, 0, 0], "driving");
    // Silent since 80 ms; the host keeps talking (the watchdog stays fed).
    fw.on_host_bytes(us(250_000), &frame(2, &HostMsg::GetDiagnostics));
    fw.poll(us(270_000));
    assert_ne!(
        last_kobuki_command(&mut fw),
        Some(vec![0, 0, 0, 0]),
        "before the timeout"
    );
    fw.poll(us(290_000));
    assert_eq!(
        last_kobuki_command(&mut fw),
        Some(vec![0, 0, 0, 0]),
        "stopped at the timeout"
    );
    host_replies(&mut fw);
    fw.on_host_bytes(us(300_000), &drive(3, 0.3));
    fw.on_host_bytes(us(300_000), &drive(4, 0.0));
    let rejects: Vec<_> = host_replies(&mut fw)
        .into_iter()
        .filter_map(|m| match m {
            DeviceMsg::Ack { seq } => Some((seq, None)),
            DeviceMsg::Reject { seq, reason } => Some((seq, Some(reason))),
            _ => None,
        })
        .collect();
    assert_eq!(
        rejects,
        vec![(3, Some(RejectReason::BaseSafety)), (4, None)]
    );
    // It speaks again: motion is taken.
    fw.on_base_bytes(us(320_000), &kobuki_feedback(0, 0, 0));
    fw.on_host_bytes(us(330_000), &drive(5, 0.3));
    fw.poll(us(330_000));
    assert_ne!(last_kobuki_command(&mut fw), Some(vec![0, 0, 0, 0]));
}

#[test]
fn mode_changes_of_many_servos_leave_no_goal_stale_for_long() {
    // Five servos changing mode take five transactions each. Chained all at once between two
    // ticks, they held every other servo's goal for 3 ms: a joint in current mode went on
    // accelerating with a stale effort (pointed seed 716). A servo's own change runs through
    // at once; the next servo's starts only before the next tick is due.
    let (mut fw, mut bus, mut now) = locobot();
    fw.on_host_bytes(now, &hello());
    run(&mut fw, &mut bus, &mut now, 200);
    fw.on_host_bytes(
        now,
        &frame(
            1,
            &HostMsg::SetMode {
                joints: 0b1_1111,
                mode: JointMode::Velocity,
            },
        ),
    );
    // The instants of the goal writes (from the command's), and each servo's writes in
    // order, over 20 ticks.
    let mut goal_writes = vec![now];
    let mut order: Vec<(u8, u16)> = Vec::new();
    let end = now + Duration::from_millis(20);
    while now < end {
        now = (now + Duration::from_micros(1)).max(fw.next_deadline().min(end));
        fw.poll(now);
        while !fw.pending(Link::Servo).is_empty() {
            let tx = fw.pending(Link::Servo).to_vec();
            fw.consume(Link::Servo, tx.len());
            let mut d = PacketDecoder::<512>::new();
            for &b in &tx {
                if let Some(Ok(p)) = d.push(b) {
                    if p.instruction == inst::SYNC_WRITE {
                        goal_writes.push(now);
                    } else if p.instruction == inst::WRITE {
                        order.push((p.id, dxl::le_u16(p.params, 0)));
                    }
                }
            }
            let rx = bus.respond(&tx);
            if !rx.is_empty() {
                now += Duration::from_micros(100);
                fw.on_servo_bytes(now, &rx);
            }
        }
    }
    for s in &fw.bus().servos[..5] {
        assert_eq!((s.ops, s.mode), (0, dxl::mode::VELOCITY), "servo {}", s.id);
    }
    let gaps = goal_writes.windows(2).map(|w| (w[1] - w[0]).as_micros());
    let worst = gaps.max().unwrap_or(u64::MAX);
    // At most a tick (1 ms), the change begun just before it and the one the tick begins with
    // (5 transactions of 100 µs each here): 2 ms. All six chained at once: 3.2 ms.
    assert!(worst <= 2_000, "goals written {worst} µs apart");
    // No servo's change is cut into by another's: between a servo's torque off and its
    // torque on, only its own writes.
    for (k, &(id, a)) in order.iter().enumerate() {
        if a == addr::TORQUE_ENABLE {
            let rest = &order[k + 1..];
            let on = rest
                .iter()
                .position(|&(i, a)| i == id && a == addr::TORQUE_ENABLE);
            let between = &rest[..on.unwrap_or(0)];
            assert!(between.iter().all(|&(i, _)| i == id), "{order:?}");
        }
    }
}

#[test]
fn a_servo_power_cycled_holds_its_joint_where_it_stands_not_where_it_stood() {
    let (mut fw, mut bus, mut now) = locobot();
    fw.on_host_bytes(now, &hello());
    fw.on_host_bytes(now, &frame(1, &HostMsg::SetWatchdog { period_ms: 5000 }));
    run(&mut fw, &mut bus, &mut now, 300);
    assert_eq!(last_goals(&bus)[&1], 2048, "held where configured");
    // Power off: no answer, the joint sags 80 ticks (0.12 rad) while its torque is off; back
    // with its torque off (the fake reads Torque Enable as 0), so it is configured in full.
    bus.silent.insert(1);
    run(&mut fw, &mut bus, &mut now, 300);
    bus.present.get_mut(&1).expect("servo 1").2 = 2048 + 80;
    bus.silent.remove(&1);
    bus.log.clear();
    run(&mut fw, &mut bus, &mut now, 400);
    let goals: Vec<i32> = bus
        .log
        .iter()
        .filter(|(_, i, _)| *i == inst::SYNC_WRITE)
        .filter_map(|(_, _, p)| {
            p[4..]
                .chunks(5)
                .find(|c| c[0] == 1)
                .map(|c| i32::from_le_bytes([c[1], c[2], c[3], c[4]]))
        })
        .collect();
    assert!(
        goals.len() > 100,
        "{} goals for servo 1 after it came back",
        goals.len()
    );
    // Every goal since it came back within 5 ticks (7.7 mrad) of where it stands; before this
    // was mended its joint was held where it stood, 80 ticks away.
    let worst = goals.iter().map(|g| (g - 2128).abs()).max().unwrap_or(0);
    assert!(
        worst <= 5,
        "a goal {worst} ticks from where the joint stands: {goals:?}"
    );
}
