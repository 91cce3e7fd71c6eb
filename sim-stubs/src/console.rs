//! The plants' control lines: what a test or a person types to a plant server to read ground
//! truth and to inject faults, one line in, one JSON object out. Shared by the real-time
//! server ([`crate::serve`]) and the conductor's server ([`crate::board`]).
//!
//! * `time`: `{"time_us"}`, the plants' simulated time;
//! * `truth`: `{"truth": [x, y, θ], "wheel_speed": [l, r], "target": [l, r]}` of the base;
//! * `bodies`: `{"bodies": [{"id", "position": [x, y, z], "quaternion": [x, y, z, w]}]}`, the
//!   scene's bodies now (world frame, m; empty without a physics world; [`bodies`]);
//! * `servo ID`: `{"id", "angle", "torque_enabled", "hardware_error"}`;
//! * `object ID TICK` / `object ID none`: an object the servo closes on (below TICK);
//! * `block ID RAD` / `block ID none`: the servo's joint is blocked above RAD;
//! * `silent ID on|off`: the servo stops (or resumes) answering;
//! * `noise N`: about N bytes of noise on the servo bus towards the firmware: random bytes
//!   and status packets with a broken CRC (`damaged_packets` in the answer).
//!
//! Unknown or malformed lines get `{"error": ...}`.

use serde_json::{json, Value};

use crate::bases::BasePlant;
use crate::chain::ServoChain;
use crate::servo::ServoSim;

/// Carry out `line` on the plants at simulated time `now_us`; `noise` puts bytes on the servo
/// bus towards the firmware.
pub fn command(
    chain: &mut ServoChain,
    base: Option<&mut BasePlant>,
    now_us: u64,
    line: &str,
    noise: &mut dyn FnMut(Vec<u8>),
) -> Value {
    let w: Vec<&str> = line.split_whitespace().collect();
    let id = w.get(1).and_then(|s| s.parse::<u8>().ok());
    let mut with_servo = |f: &dyn Fn(&mut ServoSim) -> Value| {
        let Some(id) = id else {
            return json!({"error": "need a servo ID"});
        };
        match chain.servo_mut(id) {
            Some(s) => f(s),
            None => json!({"error": format!("no servo {id}")}),
        }
    };
    match w.first().copied() {
        Some("time") => json!({ "time_us": now_us }),
        Some("truth") => match base {
            Some(b) => {
                json!({"truth": b.drive.truth, "wheel_speed": [b.drive.speed.0, b.drive.speed.1],
                       "target": [b.drive.target.0, b.drive.target.1]})
            }
            None => json!({"error": "no base"}),
        },
        Some("servo") => with_servo(&|s| {
            json!({"id": s.id, "angle": s.theta, "torque_enabled": s.torque_enabled(),
                   "hardware_error": s.hardware_error()})
        }),
        Some(kind @ ("object" | "block")) => {
            let below = kind == "object";
            let at = w.get(2).and_then(|v| v.parse::<f64>().ok());
            with_servo(&|s| {
                s.obstacle = at.map(|a| {
                    let rad = if below {
                        ferrobot_protocol::dxl::units::tick_to_rad(a as i32) as f64
                    } else {
                        a
                    };
                    (rad, below)
                });
                json!({"ok": true})
            })
        }
        Some("silent") => {
            let on = w.get(2) == Some(&"on");
            with_servo(&|s| {
                s.silent = on;
                json!({"ok": true})
            })
        }
        Some("noise") => {
            let n = w.get(1).and_then(|v| v.parse::<usize>().ok()).unwrap_or(0);
            let (bytes, damaged) = servo_noise(n);
            noise(bytes);
            json!({"ok": true, "bytes": n, "damaged_packets": damaged})
        }
        _ => json!({"error": format!("unknown command {line:?}")}),
    }
}

/// The answer to `bodies`: every scene body's id and live pose (world frame, m, quaternion
/// `[x, y, z, w]`), none without a physics world.
pub fn bodies(world: Option<&crate::world::World>) -> Value {
    let list: Vec<Value> = world
        .map(|w| {
            w.body_ids()
                .iter()
                .zip(w.body_poses())
                .map(|(id, p)| {
                    let q = p.rotation.coords;
                    json!({"id": id, "position": [p.translation.x, p.translation.y, p.translation.z],
                           "quaternion": [q.x, q.y, q.z, q.w]})
                })
                .collect()
        })
        .unwrap_or_default();
    json!({ "bodies": list })
}

/// About `n` bytes of servo-bus noise (random bytes, then a status packet whose CRC the noise
/// broke, repeated), seeded by `n`; and how many damaged packets it holds.
pub fn servo_noise(n: usize) -> (Vec<u8>, u32) {
    let mut rng = crate::rng::SimRng::new(n as u64, 99);
    let mut q = Vec::new();
    let mut damaged = 0;
    while q.len() < n {
        for _ in 0..16 {
            q.push((rng.uniform() * 256.0) as u8);
        }
        let mut b = [0u8; 32];
        let id = 1 + (rng.uniform() * 9.0) as u8;
        if let Ok(len) = ferrobot_protocol::dxl::status(&mut b, id, 0, &[0x12, 0x34, 0x56, 0x78]) {
            b[len - 1] ^= 0xA5;
            q.extend_from_slice(&b[..len]);
            damaged += 1;
        }
    }
    (q, damaged)
}
