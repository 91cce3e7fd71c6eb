//! The hostile host's messages: every `HostMsg` variant, with hostile and ordinary values.

use ferrobot_protocol::*;
use rand::Rng;

fn hostile_f32<R: Rng + ?Sized>(rng: &mut R) -> f32 {
    const SPECIAL: [f32; 14] = [
        0.0,
        -0.0,
        1e-45,
        -1e-45,
        f32::MIN_POSITIVE,
        1e38,
        -1e38,
        f32::MAX,
        f32::MIN,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1e6,
        -1e6,
    ];
    match rng.random_range(0..10) {
        0..=3 => SPECIAL[rng.random_range(0..SPECIAL.len())],
        4..=7 => rng.random_range(-3.0..3.0),
        _ => rng.random_range(-30.0..30.0),
    }
}

/// `ordinary`, or (half the time) a hostile special value.
fn special_or<R: Rng + ?Sized>(rng: &mut R, ordinary: f32) -> f32 {
    if rng.random_bool(0.5) {
        ordinary
    } else {
        hostile_f32(rng)
    }
}

/// A value that is usually ordinary (in `lo..hi`) and sometimes hostile.
fn value<R: Rng + ?Sized>(rng: &mut R, lo: f32, hi: f32) -> f32 {
    if rng.random_bool(0.8) {
        rng.random_range(lo..=hi)
    } else {
        hostile_f32(rng)
    }
}

fn hostile_u16<R: Rng + ?Sized>(rng: &mut R, ordinary: std::ops::Range<u16>) -> u16 {
    match rng.random_range(0..6) {
        0 => 0,
        1 => u16::MAX,
        2 => rng.random(),
        _ => rng.random_range(ordinary),
    }
}

fn mask<R: Rng + ?Sized>(rng: &mut R, n: usize) -> u16 {
    match rng.random_range(0..8) {
        0 => u16::MAX,
        1 => rng.random(),
        2 => 1 << rng.random_range(0..16),
        _ => rng.random::<u16>() & ((1 << n) - 1),
    }
}

fn index<R: Rng + ?Sized>(rng: &mut R, n: usize) -> u8 {
    if rng.random_bool(0.9) {
        rng.random_range(0..n as u8)
    } else {
        rng.random()
    }
}

fn mode<R: Rng + ?Sized>(rng: &mut R) -> JointMode {
    [
        JointMode::Off,
        JointMode::Position,
        JointMode::Position,
        JointMode::Velocity,
        JointMode::Current,
        JointMode::Pwm,
        JointMode::Teach,
    ][rng.random_range(0..7)]
}

/// How many values a message for the joints of mask `m` (of `n` joints) carries: usually one
/// per selected joint, sometimes any count up to [`MAX_JOINTS`].
fn value_count<R: Rng + ?Sized>(rng: &mut R, m: u16, n: usize) -> usize {
    if rng.random_bool(0.9) {
        (m as u32 & ((1 << n) - 1)).count_ones() as usize
    } else {
        rng.random_range(0..=MAX_JOINTS)
    }
}

/// One message of the stream for firmware `fw`'s current joint table.
pub fn message<R: Rng + ?Sized>(rng: &mut R, fw: &ferrobot_firmware::Firmware) -> HostMsg {
    let joints = &fw.profile().joints;
    let n = joints.len();
    let k = rng.random_range(0..100);
    match k {
        0 => HostMsg::Hello {
            protocol_version: if rng.random_bool(0.5) {
                PROTOCOL_VERSION
            } else {
                rng.random()
            },
            schema_hash: rng.random(),
        },
        1..=2 => HostMsg::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: SCHEMA_HASH,
        },
        3 => HostMsg::GetJoint {
            index: index(rng, n),
        },
        4 => {
            let i = index(rng, n + 1);
            let mut config = joints
                .get(rng.random_range(0..n))
                .cloned()
                .expect("a joint");
            // Commissioning values: hostile ones (refused), or ordinary ones that keep the
            // joint's limits within its mechanical range (a limit the joint cannot physically
            // reach cannot be kept).
            match rng.random_range(0..6) {
                0 => config.limits.min = special_or(rng, config.limits.min + 0.2),
                1 => {
                    let v = rng.random_range(0.05..2.0);
                    config.limits.velocity = special_or(rng, v)
                }
                2 => {
                    let o = rng.random_range(-0.1..0.1);
                    config.offset = special_or(rng, o)
                }
                3 => config.pid.kp = hostile_f32(rng),
                4 => config.sign = rng.random(),
                _ => {}
            }
            HostMsg::ConfigureJoint { index: i, config }
        }
        5..=6 => HostMsg::SetPid {
            joint: index(rng, n),
            gains: PidGains {
                kp: value(rng, 0.0, 60.0),
                ki: value(rng, 0.0, 40.0),
                kd: value(rng, 0.0, 3.0),
                i_limit: value(rng, 0.0, 2.0),
            },
        },
        7..=9 => {
            let j = index(rng, n);
            let base = joints
                .get(j as usize)
                .map(|c| c.limits)
                .unwrap_or(joints[0].limits);
            let a = value(rng, base.min, base.max);
            let b = value(rng, base.min, base.max);
            HostMsg::SetLimits {
                joint: j,
                limits: JointLimits {
                    min: a.min(b),
                    max: a.max(b),
                    velocity: value(rng, 0.05, 2.0),
                    effort: value(rng, 0.0, base.effort),
                },
            }
        }
        10..=17 => HostMsg::SetMode {
            joints: mask(rng, n),
            mode: mode(rng),
        },
        18..=35 => {
            let m = mask(rng, n);
            let count = value_count(rng, m, n);
            let points = (0..count)
                .map(|_| JointPoint {
                    position: value(rng, -1.6, 1.6),
                    velocity: value(rng, -2.0, 2.0),
                    effort: value(rng, -2.0, 2.0),
                })
                .collect();
            HostMsg::Waypoint {
                joints: m,
                duration_us: match rng.random_range(0..6) {
                    0 => 0,
                    1 => u32::MAX,
                    _ => rng.random_range(0..2_000_000),
                },
                points,
            }
        }
        36..=38 => HostMsg::ClearQueue {
            joints: mask(rng, n),
        },
        39..=60 => {
            let m = mask(rng, n);
            let count = value_count(rng, m, n);
            HostMsg::JointCommand {
                joints: m,
                values: (0..count).map(|_| value(rng, -3.0, 3.0)).collect(),
            }
        }
        61..=70 => HostMsg::BaseVelocity {
            v: value(rng, -0.8, 0.8),
            w: value(rng, -3.0, 3.0),
            duration_ms: hostile_u16(rng, 0..3000),
        },
        71 => HostMsg::ResetOdometry,
        72..=74 => HostMsg::Gripper(if rng.random_bool(0.5) {
            GripperCommand::Open
        } else {
            GripperCommand::Close
        }),
        75..=76 => HostMsg::SetWatchdog {
            period_ms: hostile_u16(rng, 1..2500),
        },
        77..=80 => HostMsg::Heartbeat,
        81..=82 => HostMsg::EmergencyStop,
        83..=86 => HostMsg::Resume,
        87 => HostMsg::SetTelemetry {
            period_ms: hostile_u16(rng, 0..100),
        },
        88 => HostMsg::SetLoopPeriod {
            period_us: match rng.random_range(0..4) {
                0 => 0,
                1 => u32::MAX,
                _ => rng.random_range(200..2_000),
            },
        },
        89..=90 => HostMsg::RebootJoint {
            joint: index(rng, n),
        },
        91 => HostMsg::GetDiagnostics,
        92..=93 => HostMsg::SetBaseGeometry {
            left_radius: value(rng, 0.03, 0.04),
            right_radius: value(rng, 0.03, 0.04),
            track: value(rng, 0.2, 0.26),
        },
        _ => HostMsg::Heartbeat,
    }
}

/// Which messages a stream draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mix {
    /// [`message`]: every variant, values hostile or ordinary.
    Broad,
    /// Half [`message`], half [`pointed_message`]: the mixes an outside review found holes
    /// with (issue 48).
    Pointed,
}

/// One message of a stream of mix `mix`.
pub fn mixed_message<R: Rng + ?Sized>(
    rng: &mut R,
    fw: &ferrobot_firmware::Firmware,
    mix: Mix,
) -> HostMsg {
    match mix {
        Mix::Pointed if rng.random_bool(0.5) => pointed_message(rng, fw),
        _ => message(rng, fw),
    }
}

/// A gain at an extreme: zero, a subnormal, the largest the wire allows, the joint's own
/// times a large or small factor, or just past the bound.
fn extreme_gain<R: Rng + ?Sized>(rng: &mut R, own: f32) -> f32 {
    match rng.random_range(0..7) {
        0 => 0.0,
        1 => 1e-7,
        2 => ranges::GAIN_MAX,
        3 => own * 1000.0,
        4 => own * 0.01,
        5 => 1e6,
        _ => own * rng.random_range(0.5..20.0),
    }
}

/// A joint index that is often out of range: the broadcast ID, the joint count, or a joint.
fn edgy_index<R: Rng + ?Sized>(rng: &mut R, n: usize) -> u8 {
    match rng.random_range(0..6) {
        0 => 255,
        1 => n as u8,
        _ => rng.random_range(0..n as u8),
    }
}

/// A message aimed at the holes an outside review found (issue 48): gains at their extremes,
/// broadcast and out-of-range indices, limits narrowed around a joint while it moves, mode
/// changes of a moving (loaded) joint, waypoints with non-finite efforts, and direct
/// commands at the edges of what each mode accepts.
pub fn pointed_message<R: Rng + ?Sized>(rng: &mut R, fw: &ferrobot_firmware::Firmware) -> HostMsg {
    let rows = &fw.profile().joints;
    let n = rows.len();
    let j = rng.random_range(0..n);
    let row = &rows[j];
    // The joint that moves fastest now: mode changes and new limits under load.
    let moving = fw
        .joints()
        .iter()
        .enumerate()
        .max_by(|a, b| {
            a.1.state
                .velocity
                .abs()
                .total_cmp(&b.1.state.velocity.abs())
        })
        .map_or(j, |(k, _)| k);
    match rng.random_range(0..100) {
        0..=19 => HostMsg::SetPid {
            joint: edgy_index(rng, n),
            gains: PidGains {
                kp: extreme_gain(rng, row.pid.kp),
                ki: extreme_gain(rng, row.pid.ki),
                kd: extreme_gain(rng, row.pid.kd),
                i_limit: extreme_gain(rng, row.pid.i_limit.max(0.1)),
            },
        },
        20..=39 => {
            let k = if rng.random_bool(0.7) { moving } else { j };
            let base = rows[k].limits;
            let q = fw.joints()[k].state.position;
            let below = rng.random_range(0.0..0.4);
            let above = rng.random_range(0.0..0.4);
            let min = (q - below).max(base.min);
            HostMsg::SetLimits {
                joint: k as u8,
                limits: JointLimits {
                    min,
                    max: (q + above).min(base.max).max(min + ranges::JOINT_RANGE_MIN),
                    velocity: rng.random_range(ranges::JOINT_SPEED_LIMIT_MIN..=base.velocity),
                    effort: rng.random_range(0.0..=base.effort),
                },
            }
        }
        40..=59 => HostMsg::SetMode {
            joints: 1 << if rng.random_bool(0.7) { moving } else { j },
            mode: [
                JointMode::Position,
                JointMode::Velocity,
                JointMode::Current,
                JointMode::Pwm,
                JointMode::Off,
            ][rng.random_range(0..5)],
        },
        60..=74 => {
            let m = (1u16 << n) - 1;
            let lim = row.limits;
            HostMsg::Waypoint {
                joints: m,
                duration_us: rng.random_range(0..600_000),
                points: (0..n)
                    .map(|_| JointPoint {
                        position: rng.random_range(lim.min..=lim.max),
                        velocity: rng.random_range(-2.0..2.0),
                        effort: [f32::NAN, f32::INFINITY, -f32::INFINITY, 1e30, 0.5]
                            [rng.random_range(0..5)],
                    })
                    .collect(),
            }
        }
        _ => {
            let k = if rng.random_bool(0.7) { moving } else { j };
            let lim = rows[k].limits;
            let edge = match fw.joints()[k].mode {
                JointMode::Velocity => {
                    rng.random_range(lim.velocity..=ranges::JOINT_SPEED_MAX.min(lim.velocity * 4.0))
                }
                JointMode::Current => rng.random_range(lim.effort..=lim.effort * 4.0 + 0.1),
                _ => rng.random_range(0.5..=1.0),
            };
            HostMsg::JointCommand {
                joints: 1 << k,
                values: [if rng.random_bool(0.5) { edge } else { -edge }]
                    .into_iter()
                    .collect(),
            }
        }
    }
}

/// A gravity model sent whole, link after link: the robot's own (`honest`), or one made
/// hostile: masses scaled from nothing to thrice, centres of mass moved or flipped, axes
/// reversed, rows swapped, hostile numbers, links missing or out of order, or a model cleared.
/// Values in range are what the firmware's confirmation must catch; the rest it refuses.
pub fn model_burst<R: Rng + ?Sized>(
    rng: &mut R,
    fw: &ferrobot_firmware::Firmware,
    honest: &[ArmLink],
) -> std::vec::Vec<HostMsg> {
    let n = fw.profile().joints.len();
    if honest.is_empty() || rng.random_bool(0.1) {
        let link = honest.first().copied().unwrap_or(ArmLink {
            joint: 0,
            origin: [0.0; 3],
            rpy: [0.0; 3],
            axis: [0.0, 0.0, 1.0],
            mass: 0.0,
            com: [0.0; 3],
        });
        return vec![HostMsg::ArmLink {
            index: 0,
            count: 0,
            link,
        }];
    }
    let mut links: std::vec::Vec<ArmLink> = honest.to_vec();
    let all = rng.random_bool(0.3);
    for l in links.iter_mut() {
        if !all && rng.random_bool(0.6) {
            continue;
        }
        match rng.random_range(0..8) {
            0 => l.mass *= rng.random_range(0.0..3.0),
            1 => l.com = l.com.map(|c| c * rng.random_range(-3.0..3.0)),
            2 => l.com = [l.com[2], l.com[0], l.com[1]],
            3 => l.axis = l.axis.map(|a| -a),
            4 => l.joint = index(rng, n),
            5 => l.mass = hostile_f32(rng),
            6 => l.origin[rng.random_range(0..3)] = hostile_f32(rng),
            _ => l.mass = rng.random_range(0.0..ranges::LINK_MASS_MAX),
        }
    }
    let count = if rng.random_bool(0.9) {
        links.len() as u8
    } else {
        rng.random()
    };
    let mut order: std::vec::Vec<usize> = (0..links.len()).collect();
    if rng.random_bool(0.1) {
        order.swap(0, rng.random_range(0..links.len()));
    }
    if rng.random_bool(0.1) {
        order.truncate(rng.random_range(0..links.len()));
    }
    order
        .into_iter()
        .map(|i| HostMsg::ArmLink {
            index: i as u8,
            count,
            link: links[i],
        })
        .collect()
}
