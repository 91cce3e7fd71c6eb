//! The firmware core against a structured hostile host: the fuzzer's bytes are the random
//! source of [`ferrobot_sim::hostile`]'s message generator (which `HostMsg` variant, which
//! hostile or ordinary field values, how much time between messages), so every input is a
//! stream of well-formed commands that reaches the firmware's handlers, run through the
//! lockstep simulator with the plants. The first byte picks the profile (LoCoBot or
//! LoCoBot-Lite). Throughout, the invariants of the hostile test are checked on the plants'
//! true state (joint limits and speeds, wheel speeds, servo modes); at the end an emergency
//! stop must stop everything and a valid session must recover the arm. Any violation or panic
//! is a crash.
#![cfg_attr(fuzzing, no_main)]
use ferrobot_sim::hostile::hostile_stream;
use rand::RngCore;

/// The fuzzer's bytes as a random source; zeros once they are used up.
struct Bytes<'a>(&'a [u8]);

impl RngCore for Bytes<'_> {
    fn next_u32(&mut self) -> u32 {
        let mut b = [0u8; 4];
        self.fill_bytes(&mut b);
        u32::from_le_bytes(b)
    }

    fn next_u64(&mut self) -> u64 {
        let mut b = [0u8; 8];
        self.fill_bytes(&mut b);
        u64::from_le_bytes(b)
    }

    fn fill_bytes(&mut self, dst: &mut [u8]) {
        let n = dst.len().min(self.0.len());
        dst[..n].copy_from_slice(&self.0[..n]);
        dst[n..].fill(0);
        self.0 = &self.0[n..];
    }
}

ferrobot_fuzz::target!(run);

/// One input.
fn run(data: &[u8]) {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let robot = if pick & 1 == 0 {
        "locobot"
    } else {
        "locobot_lite"
    };
    // About one message per 24 bytes of input, at most 200.
    let messages = (rest.len() / 24).clamp(1, 200);
    let (c, _) = hostile_stream(&mut Bytes(rest), robot, 7, messages);
    assert!(
        c.violations.is_empty(),
        "{robot}: {} violations, first: {}",
        c.violations.len(),
        c.violations[0]
    );
}
