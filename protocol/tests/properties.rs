//! Property tests of the framing and the Dynamixel codec: round trips of every message,
//! detection of every single-byte corruption, and resynchronisation after garbage.

use ferrobot_protocol::dxl::{self, PacketDecoder};
use ferrobot_protocol::*;
use heapless::{String, Vec};
use proptest::collection::vec;
use proptest::prelude::*;

fn f() -> impl Strategy<Value = f32> {
    -1.0e4f32..1.0e4f32
}

fn name() -> impl Strategy<Value = Name> {
    "[a-z_0-9]{0,16}".prop_map(|s| String::try_from(s.as_str()).unwrap_or_default())
}

fn limits() -> impl Strategy<Value = JointLimits> {
    (f(), f(), f(), f()).prop_map(|(min, max, velocity, effort)| JointLimits {
        min,
        max,
        velocity,
        effort,
    })
}

fn pid() -> impl Strategy<Value = PidGains> {
    (f(), f(), f(), f()).prop_map(|(kp, ki, kd, i_limit)| PidGains {
        kp,
        ki,
        kd,
        i_limit,
    })
}

fn joint_config() -> impl Strategy<Value = JointConfig> {
    (
        name(),
        prop_oneof![
            Just(JointKind::Arm),
            Just(JointKind::Head),
            Just(JointKind::Gripper)
        ],
        prop_oneof![Just(ServoModel::Xm430W350), Just(ServoModel::Xl430W250)],
        any::<u8>(),
        proptest::option::of(any::<u8>()),
        prop_oneof![Just(1i8), Just(-1i8)],
        f(),
        limits(),
        pid(),
        (any::<[u16; 5]>(), any::<u32>(), any::<u32>()),
    )
        .prop_map(
            |(name, kind, model, servo_id, twin_id, sign, offset, limits, pid, (g, pv, pa))| {
                JointConfig {
                    name,
                    kind,
                    model,
                    servo_id,
                    twin_id,
                    sign,
                    offset,
                    limits,
                    pid,
                    position_ki: offset,
                    servo: ServoGains {
                        pos_p: g[0],
                        pos_i: g[1],
                        pos_d: g[2],
                        vel_p: g[3],
                        vel_i: g[4],
                        profile_velocity: pv,
                        profile_acceleration: pa,
                    },
                }
            },
        )
}

fn mode() -> impl Strategy<Value = JointMode> {
    prop_oneof![
        Just(JointMode::Off),
        Just(JointMode::Position),
        Just(JointMode::Velocity),
        Just(JointMode::Current),
        Just(JointMode::Pwm)
    ]
}

fn point() -> impl Strategy<Value = JointPoint> {
    (f(), f(), f()).prop_map(|(position, velocity, effort)| JointPoint {
        position,
        velocity,
        effort,
    })
}

fn host_msg() -> impl Strategy<Value = HostMsg> {
    prop_oneof![
        (any::<u16>(), any::<u32>()).prop_map(|(protocol_version, schema_hash)| HostMsg::Hello {
            protocol_version,
            schema_hash
        }),
        any::<u8>().prop_map(|index| HostMsg::GetJoint { index }),
        (any::<u8>(), joint_config())
            .prop_map(|(index, config)| HostMsg::ConfigureJoint { index, config }),
        (any::<u8>(), pid()).prop_map(|(joint, gains)| HostMsg::SetPid { joint, gains }),
        (any::<u8>(), limits()).prop_map(|(joint, limits)| HostMsg::SetLimits { joint, limits }),
        (any::<u16>(), mode()).prop_map(|(joints, mode)| HostMsg::SetMode { joints, mode }),
        (any::<u16>(), any::<u32>(), vec(point(), 0..=MAX_JOINTS)).prop_map(
            |(joints, duration_us, p)| {
                HostMsg::Waypoint {
                    joints,
                    duration_us,
                    points: Vec::from_slice(&p).unwrap_or_default(),
                }
            }
        ),
        any::<u16>().prop_map(|joints| HostMsg::ClearQueue { joints }),
        (any::<u16>(), vec(f(), 0..=MAX_JOINTS)).prop_map(|(joints, v)| HostMsg::JointCommand {
            joints,
            values: Vec::from_slice(&v).unwrap_or_default()
        }),
        (f(), f(), any::<u16>()).prop_map(|(v, w, duration_ms)| HostMsg::BaseVelocity {
            v,
            w,
            duration_ms
        }),
        Just(HostMsg::ResetOdometry),
        prop_oneof![Just(GripperCommand::Open), Just(GripperCommand::Close)]
            .prop_map(HostMsg::Gripper),
        any::<u16>().prop_map(|period_ms| HostMsg::SetWatchdog { period_ms }),
        Just(HostMsg::Heartbeat),
        Just(HostMsg::EmergencyStop),
        Just(HostMsg::Resume),
        any::<u16>().prop_map(|period_ms| HostMsg::SetTelemetry { period_ms }),
        any::<u32>().prop_map(|period_us| HostMsg::SetLoopPeriod { period_us }),
        any::<u8>().prop_map(|joint| HostMsg::RebootJoint { joint }),
        Just(HostMsg::GetDiagnostics),
        (f(), f(), f()).prop_map(|(left_radius, right_radius, track)| {
            HostMsg::SetBaseGeometry {
                left_radius,
                right_radius,
                track,
            }
        }),
    ]
}

fn telemetry() -> impl Strategy<Value = Telemetry> {
    (
        any::<u64>(),
        vec((f(), f(), f()), 0..=MAX_JOINTS),
        any::<u8>(),
        (f(), f(), f(), f(), f()),
        (f(), f(), f(), f()),
        any::<u16>(),
        any::<u16>(),
        any::<[u32; 3]>(),
    )
        .prop_map(
            |(time_us, j, queued, o, w, base_flags, faults, l)| Telemetry {
                time_us,
                joints: j
                    .into_iter()
                    .map(|(position, velocity, effort)| JointState {
                        position,
                        velocity,
                        effort,
                    })
                    .collect(),
                queued,
                gripper: GripperState::Holding,
                odometry: Odometry {
                    x: o.0,
                    y: o.1,
                    theta: o.2,
                    v: o.3,
                    w: o.4,
                },
                wheels: WheelData {
                    left: w.0,
                    right: w.1,
                    left_rate: w.2,
                    right_rate: w.3,
                },
                base_flags,
                faults,
                loop_stats: LoopStats {
                    ticks: l[0],
                    worst_tick_us: l[1],
                    overruns: l[2],
                },
            },
        )
}

fn device_msg() -> impl Strategy<Value = DeviceMsg> {
    prop_oneof![
        (
            any::<u16>(),
            any::<u32>(),
            name(),
            name(),
            vec(Just(JointKind::Arm), 0..=MAX_JOINTS),
            any::<bool>(),
            any::<bool>()
        )
            .prop_map(
                |(
                    protocol_version,
                    schema_hash,
                    board,
                    robot,
                    joints,
                    accepted,
                    watchdog_tripped,
                )| {
                    DeviceMsg::Hello(DeviceInfo {
                        protocol_version,
                        schema_hash,
                        firmware_version: [0, 1, 2],
                        board,
                        robot,
                        joints: Vec::from_slice(&joints).unwrap_or_default(),
                        base: BaseKind::Kobuki,
                        loop_period_us: 1000,
                        accepted,
                        watchdog_tripped,
                    })
                }
            ),
        (any::<u8>(), joint_config())
            .prop_map(|(index, config)| DeviceMsg::Joint { index, config }),
        any::<u16>().prop_map(|seq| DeviceMsg::Ack { seq }),
        any::<u16>().prop_map(|seq| DeviceMsg::Reject {
            seq,
            reason: RejectReason::OutOfLimits
        }),
        telemetry().prop_map(DeviceMsg::Telemetry),
        (
            any::<u16>(),
            any::<u64>(),
            proptest::option::of(any::<u8>())
        )
            .prop_map(|(code, time_us, joint)| {
                DeviceMsg::Fault(Fault {
                    kind: FaultKind::ServoHardware,
                    joint,
                    servo_id: joint,
                    code,
                    time_us,
                })
            }),
        any::<[u32; 10]>().prop_map(|c| DeviceMsg::Diagnostics(Diagnostics {
            host_frames: c[0],
            host_bad_frames: c[1],
            host_tx_dropped: c[2],
            servo_packets: c[3],
            servo_bad_packets: c[4],
            servo_timeouts: c[5],
            servo_alerts: c[6],
            base_packets: c[7],
            base_bad_packets: c[8],
            servo_stale: c[9],
        })),
        "[ -~]{0,64}"
            .prop_map(|s| DeviceMsg::Log(String::try_from(s.as_str()).unwrap_or_default())),
    ]
}

fn encode<M: serde::Serialize>(seq: u16, m: &M) -> std::vec::Vec<u8> {
    let mut out = [0u8; MAX_WIRE];
    let n = encode_frame(seq, m, &mut out).expect("every message fits a frame");
    out[..n].to_vec()
}

fn decode_all<M: serde::de::DeserializeOwned>(
    bytes: &[u8],
) -> (std::vec::Vec<Frame<M>>, FrameStats) {
    let mut d = FrameDecoder::new();
    let mut frames = std::vec::Vec::new();
    d.feed(bytes, |r: Result<Frame<M>, FrameError>| {
        if let Ok(fr) = r {
            frames.push(fr)
        }
    });
    (frames, d.stats())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn host_messages_round_trip(seq in any::<u16>(), m in host_msg()) {
        let wire = encode(seq, &m);
        prop_assert!(wire.len() <= MAX_WIRE);
        prop_assert_eq!(wire.iter().filter(|&&b| b == 0).count(), 1);
        let (frames, _) = decode_all::<HostMsg>(&wire);
        prop_assert_eq!(frames, vec![Frame { seq, msg: m }]);
    }

    #[test]
    fn device_messages_round_trip(seq in any::<u16>(), m in device_msg()) {
        let wire = encode(seq, &m);
        prop_assert!(wire.len() <= MAX_WIRE);
        let (frames, _) = decode_all::<DeviceMsg>(&wire);
        prop_assert_eq!(frames, vec![Frame { seq, msg: m }]);
    }

}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Every position, every one of the 255 wrong values: the corrupted frame never decodes, and
    /// the good frame after it does.
    #[test]
    fn every_single_byte_corruption_is_detected(m in host_msg(), seq in any::<u16>()) {
        let wire = encode(seq, &m);
        let good = encode(seq.wrapping_add(1), &HostMsg::Heartbeat);
        for pos in 0..wire.len() {
            for delta in 1..=255u8 {
                let mut bad = wire.clone();
                bad[pos] ^= delta;
                let mut stream = bad.clone();
                stream.push(0); // a lost delimiter must not take the next frame with it
                stream.extend_from_slice(&good);
                let (frames, stats) = decode_all::<HostMsg>(&stream);
                prop_assert!(!frames.iter().any(|fr| fr.seq == seq), "corruption at {} by {:#x} accepted", pos, delta);
                prop_assert_eq!(frames.last().map(|fr| fr.seq), Some(seq.wrapping_add(1)));
                prop_assert!(stats.dropped() >= 1);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn garbage_between_frames_is_skipped(
        a in host_msg(), b in host_msg(), garbage in vec(any::<u8>(), 0..600), delimit in any::<bool>()
    ) {
        let mut stream = encode(1, &a);
        stream.extend_from_slice(&garbage);
        if delimit { stream.push(0); }
        stream.extend_from_slice(&encode(2, &b));
        let (frames, _) = decode_all::<HostMsg>(&stream);
        prop_assert_eq!(frames.first().map(|f| f.seq), Some(1));
        prop_assert_eq!(frames.last(), Some(&Frame { seq: 2, msg: b }));
    }

    #[test]
    fn frame_decoder_never_panics(bytes in vec(any::<u8>(), 0..2000)) {
        let _ = decode_all::<HostMsg>(&bytes);
        let _ = decode_all::<DeviceMsg>(&bytes);
    }

    #[test]
    fn dxl_round_trip(id in 0u8..0xFD, ins in prop_oneof![Just(dxl::inst::WRITE), Just(dxl::inst::SYNC_WRITE), Just(dxl::inst::STATUS)], params in vec(any::<u8>(), 0..200)) {
        let mut buf = [0u8; 512];
        let mut p = dxl::PacketWriter::new(&mut buf, id, ins);
        p.extend(&params);
        let n = p.finish().expect("fits");
        let mut d = PacketDecoder::<512>::new();
        let mut got = None;
        for &b in &buf[..n] {
            if let Some(Ok(pkt)) = d.push(b) {
                got = Some((pkt.id, pkt.instruction, pkt.params.to_vec()));
            }
        }
        prop_assert_eq!(got, Some((id, ins, params)));
    }

    #[test]
    fn dxl_single_byte_corruption_is_detected(id in 0u8..0xFD, params in vec(any::<u8>(), 0..40), pos in any::<prop::sample::Index>(), delta in 1..=255u8) {
        let mut buf = [0u8; 128];
        let n = dxl::write(&mut buf, id, 116, &params).expect("fits");
        let pos = pos.index(n);
        buf[pos] ^= delta;
        let mut d = PacketDecoder::<128>::new();
        let mut accepted = false;
        for &b in &buf[..n] {
            if let Some(Ok(_)) = d.push(b) {
                accepted = true;
            }
        }
        // Followed by a good packet, which must decode (a corrupted LEN may swallow it; then the one after).
        let mut good = [0u8; 16];
        let g = dxl::ping(&mut good, 5).expect("fits");
        let mut recovered = false;
        for _ in 0..40 {
            for &b in &good[..g] {
                if let Some(Ok(p)) = d.push(b) {
                    recovered |= p.id == 5;
                }
            }
            if recovered { break; }
        }
        prop_assert!(!accepted);
        prop_assert!(recovered);
    }

    #[test]
    fn dxl_decoder_never_panics(bytes in vec(any::<u8>(), 0..2000)) {
        let mut d = PacketDecoder::<256>::new();
        for b in bytes {
            let _ = d.push(b);
        }
    }
}

#[test]
fn locobot_telemetry_fits_and_overhead_is_six() {
    let t = Telemetry {
        time_us: u64::MAX,
        joints: (0..MAX_JOINTS)
            .map(|_| JointState {
                position: 1.0,
                velocity: 2.0,
                effort: 3.0,
            })
            .collect(),
        queued: 255,
        gripper: GripperState::Closing,
        odometry: Odometry::default(),
        wheels: WheelData::default(),
        base_flags: u16::MAX,
        faults: u16::MAX,
        loop_stats: LoopStats {
            ticks: u32::MAX,
            worst_tick_us: u32::MAX,
            overruns: u32::MAX,
        },
    };
    let msg = DeviceMsg::Telemetry(t);
    let mut body = [0u8; 1024];
    let body = postcard::to_slice(
        &Frame {
            seq: u16::MAX,
            msg: msg.clone(),
        },
        &mut body,
    )
    .expect("encodes");
    let wire = encode(u16::MAX, &msg);
    assert_eq!(wire.len(), body.len() + FRAME_OVERHEAD);
    assert!(wire.len() <= MAX_WIRE, "{} bytes", wire.len());
}

/// The name of every host message, by an exhaustive match with no wildcard arm: this compiles
/// only while [`HostMsg`] is not `#[non_exhaustive]`, so other crates (the firmware) can match
/// it exhaustively and a new message without a handler fails to compile there. (It repeats
/// `HostMsg::kind` on purpose: only a match outside the crate proves that.)
fn host_msg_name(m: &HostMsg) -> &'static str {
    match m {
        HostMsg::Hello { .. } => "Hello",
        HostMsg::GetJoint { .. } => "GetJoint",
        HostMsg::ConfigureJoint { .. } => "ConfigureJoint",
        HostMsg::SetPid { .. } => "SetPid",
        HostMsg::SetLimits { .. } => "SetLimits",
        HostMsg::SetMode { .. } => "SetMode",
        HostMsg::Waypoint { .. } => "Waypoint",
        HostMsg::ClearQueue { .. } => "ClearQueue",
        HostMsg::JointCommand { .. } => "JointCommand",
        HostMsg::BaseVelocity { .. } => "BaseVelocity",
        HostMsg::ResetOdometry => "ResetOdometry",
        HostMsg::Gripper(_) => "Gripper",
        HostMsg::SetWatchdog { .. } => "SetWatchdog",
        HostMsg::Heartbeat => "Heartbeat",
        HostMsg::EmergencyStop => "EmergencyStop",
        HostMsg::Resume => "Resume",
        HostMsg::SetTelemetry { .. } => "SetTelemetry",
        HostMsg::SetLoopPeriod { .. } => "SetLoopPeriod",
        HostMsg::RebootJoint { .. } => "RebootJoint",
        HostMsg::GetDiagnostics => "GetDiagnostics",
        HostMsg::SetBaseGeometry { .. } => "SetBaseGeometry",
        HostMsg::ArmLink { .. } => "ArmLink",
    }
}

/// A link of the arm's gravity model fits one frame, whatever its numbers.
#[test]
fn an_arm_link_fits_a_frame() {
    let link = ArmLink {
        joint: u8::MAX,
        origin: [f32::MAX; 3],
        rpy: [f32::MIN; 3],
        axis: [f32::NAN; 3],
        mass: f32::MAX,
        com: [f32::MIN_POSITIVE; 3],
    };
    let msg = HostMsg::ArmLink {
        index: u8::MAX,
        count: u8::MAX,
        link,
    };
    let wire = encode(u16::MAX, &msg);
    assert!(wire.len() <= MAX_WIRE, "{} bytes", wire.len());
}

#[test]
fn host_messages_can_be_matched_exhaustively() {
    for m in [
        HostMsg::Heartbeat,
        HostMsg::EmergencyStop,
        HostMsg::GetDiagnostics,
    ] {
        assert_eq!(host_msg_name(&m), m.kind());
    }
}

/// The schema hash comes from the message types' structure: it is the hash of
/// `(HostMsg, DeviceMsg)`'s schema, and a type that differs anywhere (here: one message set
/// without the device side) hashes differently.
#[test]
fn the_schema_hash_follows_the_message_types() {
    use postcard_schema::key::Key;
    let fold =
        |k: [u8; 8]| u32::from_le_bytes([k[0] ^ k[4], k[1] ^ k[5], k[2] ^ k[6], k[3] ^ k[7]]);
    let both = fold(Key::for_path::<(HostMsg, DeviceMsg)>("ferrobot").to_bytes());
    assert_eq!(both, SCHEMA_HASH);
    let host_only = fold(Key::for_path::<(HostMsg,)>("ferrobot").to_bytes());
    let swapped = fold(Key::for_path::<(DeviceMsg, HostMsg)>("ferrobot").to_bytes());
    assert_ne!(host_only, SCHEMA_HASH);
    assert_ne!(swapped, SCHEMA_HASH);
}
