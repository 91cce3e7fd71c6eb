//! The cables of an emulated board's plant lines, as a test sets them: a stable symlink to
//! each line's pseudo-terminal (as udev's `/dev/serial/by-id` links are), whether the cable is
//! plugged, and the rate the devices at the far end listen at. Pulling a cable closes the
//! line's PTY (the firmware's reads fail with `EIO`, as a vanished USB device's do) and
//! removes its link; plugging it makes a new PTY, under a new name, behind the same link.
//! Bytes sent at another rate than the devices' reach them garbled, both ways.

use std::path::{Path, PathBuf};

use super::ports::relink;

/// The plant lines' cables (index 0 the servo bus, 1 the base).
#[derive(Debug, Clone, PartialEq)]
pub struct Wiring {
    /// Stable symlinks to each line's PTY; `None` for a line the robot does not have.
    pub links: [Option<PathBuf>; 2],
    /// Whether each line's cable is plugged.
    pub plugged: [bool; 2],
    /// The rate the devices on each line listen at, bit/s, if the line's rate is checked (a
    /// host-run firmware sets its devices' rate; QEMU sets its PTYs to a rate of its own,
    /// so a board's lines are not checked).
    pub baud: [Option<u32>; 2],
    /// Fraction of each line's bytes damaged (one bit flipped), both ways, in `[0, 1]`.
    pub corruption: [f64; 2],
}

impl Wiring {
    /// Links in the temporary directory to the servo bus's PTY `servo` and the base's `base`.
    pub(super) fn new(servo: &str, base: Option<&str>) -> std::io::Result<Self> {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let link = |name: &str| {
            std::env::temp_dir().join(format!("ferrobot-line-{}-{n}-{name}", std::process::id()))
        };
        let servo_link = link("servo");
        relink(&servo_link, servo)?;
        let base_link = match base {
            Some(target) => {
                let l = link("base");
                relink(&l, target)?;
                Some(l)
            }
            None => None,
        };
        Ok(Wiring {
            links: [Some(servo_link), base_link],
            plugged: [true, base.is_some()],
            baud: [None; 2],
            corruption: [0.0; 2],
        })
    }

    /// Point line `i`'s link at its new PTY `target`.
    pub(super) fn plugged_in(&self, i: usize, target: &str) {
        if let Some(l) = &self.links[i] {
            let _ = relink(l, target);
        }
    }

    /// Remove line `i`'s link (its cable is out).
    pub(super) fn pulled(&self, i: usize) {
        if let Some(l) = &self.links[i] {
            let _ = std::fs::remove_file(l);
        }
    }

    /// Remove every link.
    pub(super) fn remove_links(&self) {
        for l in self.links.iter().flatten() {
            let _ = std::fs::remove_file(l);
        }
    }

    /// Line `i`'s link, if the robot has that line.
    pub fn link(&self, i: usize) -> Option<&Path> {
        self.links[i].as_deref()
    }
}

/// `bytes` as a line at the wrong rate delivers them: every bit inverted (a receiver sampling
/// at another rate reads other bits; no packet survives it).
pub(super) fn garble(bytes: &mut [u8]) {
    for b in bytes {
        *b = !*b;
    }
}

/// Flip one bit in about `fraction` of `bytes`, drawing from the generator `state`
/// (xorshift64: a seeded, reproducible line).
pub(super) fn damage(bytes: &mut [u8], fraction: f64, state: &mut u64) {
    if fraction <= 0.0 {
        return;
    }
    for b in bytes {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        if ((*state >> 11) as f64) / ((1u64 << 53) as f64) < fraction {
            *b ^= 1 << (*state & 7);
        }
    }
}
