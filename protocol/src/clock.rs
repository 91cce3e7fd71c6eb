//! The virtual-time link between an emulated board and the plants it drives.
//!
//! An emulated board (the firmware in QEMU) has no clock of its own: a *conductor* beside the
//! simulated plants owns simulated time and grants it to the board one step at a time, so that
//! the firmware and the plants agree on time whatever the host machine is doing. A slow or busy
//! machine gives the same results, only later.
//!
//! Both messages travel framed like host ⇄ firmware messages ([`crate::encode_frame`],
//! [`crate::FrameDecoder`]) on a serial line of their own (UART4 on `mps2-an386`):
//!
//! * [`Advance`] (conductor → board): simulated time is now `now_us`, and the bytes the
//!   conductor has written on each plant line so far ([`PLANT_LINES`]: servo bus, base) total
//!   `release`. The conductor writes the bytes that reach the board at `now_us` together with
//!   this message; the board consumes no byte beyond `release` before the next `Advance`, so
//!   whichever of its serial lines delivers first, every byte is taken at its own time.
//! * [`Idle`] (board → conductor): the board has done everything it had to do at `now_us`,
//!   has consumed `rx` bytes (all released ones) and sent `tx` bytes on each plant line since
//!   it started, and next wants to run at `next_us`.
//!
//! The conductor advances time only when the board is idle at the current time with every
//! released byte consumed, and every byte the board sent has reached the plants. The host
//! link is not part of this: the host is a real-time peer, and its bytes are taken at the
//! simulated time at which they arrive.

use serde::{Deserialize, Serialize};

/// Plant lines whose bytes the clock accounts for: index 0 the servo bus, 1 the base.
pub const PLANT_LINES: usize = 2;

/// Conductor → board: simulated time is now `now_us`; bytes written so far total `release`.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub struct Advance {
    /// Simulated time, µs since the board started.
    pub now_us: u64,
    /// Bytes written to the board on each plant line since start (servo bus, base), wrapping.
    pub release: [u32; PLANT_LINES],
}

/// Board → conductor: idle at `now_us`.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub struct Idle {
    /// The board's simulated time, µs.
    pub now_us: u64,
    /// The earliest time the board next wants to run, µs (`u64::MAX`: none).
    pub next_us: u64,
    /// Bytes consumed on each plant line since start (servo bus, base), wrapping.
    pub rx: [u32; PLANT_LINES],
    /// Bytes sent on each plant line since start (servo bus, base), wrapping.
    pub tx: [u32; PLANT_LINES],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{encode_frame, Frame, FrameDecoder, MAX_WIRE};

    #[test]
    fn idle_round_trips_through_a_frame() {
        let idle = Idle {
            now_us: 25_000,
            next_us: u64::MAX,
            rx: [u32::MAX, 3],
            tx: [7, 0],
        };
        let mut buf = [0u8; MAX_WIRE];
        let n = encode_frame(9, &idle, &mut buf).unwrap_or(0);
        assert!(n > 0 && n < 48, "{n} bytes");
        let mut d = FrameDecoder::new();
        let mut got = None;
        d.feed(&buf[..n], |r: Result<Frame<Idle>, _>| got = r.ok());
        assert_eq!(got.map(|f| f.msg), Some(idle));
    }
}
