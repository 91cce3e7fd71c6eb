//! Time on the firmware's clock, in the manner of smoltcp's `time` module and embassy-time:
//! an [`Instant`] is a point on the clock (µs since boot, or since any epoch the shell
//! chooses, never going backwards), a [`Duration`] a span of time (µs).
//!
//! No operation overflows, wraps or panics: an instant plus or minus a duration saturates at
//! the ends of the clock, the span from a later instant to an earlier one is zero, and sums
//! and multiples of durations saturate.

use core::ops::{Add, AddAssign, Sub};

/// A point on the firmware's clock, µs since boot.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Instant {
    micros: u64,
}

/// A span of time, µs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Duration {
    micros: u64,
}

impl Instant {
    /// Boot (the clock's epoch).
    pub const ZERO: Instant = Instant { micros: 0 };
    /// The end of the clock: a deadline that never comes.
    pub const MAX: Instant = Instant { micros: u64::MAX };

    /// The instant `micros` µs after boot.
    pub const fn from_micros(micros: u64) -> Self {
        Instant { micros }
    }

    /// The instant `millis` ms after boot (saturating).
    pub const fn from_millis(millis: u64) -> Self {
        Instant {
            micros: millis.saturating_mul(1000),
        }
    }

    /// The instant `secs` s after boot (saturating).
    pub const fn from_secs(secs: u64) -> Self {
        Instant {
            micros: secs.saturating_mul(1_000_000),
        }
    }

    /// Time since boot, µs.
    pub const fn as_micros(self) -> u64 {
        self.micros
    }

    /// The span from `earlier` to `self`; zero if `earlier` is later.
    pub const fn saturating_duration_since(self, earlier: Instant) -> Duration {
        Duration {
            micros: self.micros.saturating_sub(earlier.micros),
        }
    }
}

impl Duration {
    /// No time.
    pub const ZERO: Duration = Duration { micros: 0 };

    /// A span of `micros` µs.
    pub const fn from_micros(micros: u64) -> Self {
        Duration { micros }
    }

    /// A span of `millis` ms (saturating).
    pub const fn from_millis(millis: u64) -> Self {
        Duration {
            micros: millis.saturating_mul(1000),
        }
    }

    /// A span of `secs` s (saturating).
    pub const fn from_secs(secs: u64) -> Self {
        Duration {
            micros: secs.saturating_mul(1_000_000),
        }
    }

    /// The span, µs.
    pub const fn as_micros(self) -> u64 {
        self.micros
    }

    /// The span, s (rounded to the nearest `f32`).
    pub fn as_secs_f32(self) -> f32 {
        self.micros as f32 * 1e-6
    }

    /// Whether the span is zero.
    pub const fn is_zero(self) -> bool {
        self.micros == 0
    }

    /// `n` times the span (saturating).
    pub const fn saturating_mul(self, n: u64) -> Duration {
        Duration {
            micros: self.micros.saturating_mul(n),
        }
    }

    /// How many whole `period`s fit in the span; `None` for a zero `period`.
    pub const fn checked_div_duration(self, period: Duration) -> Option<u64> {
        self.micros.checked_div(period.micros)
    }
}

/// Later by a span, saturating at [`Instant::MAX`].
impl Add<Duration> for Instant {
    type Output = Instant;

    fn add(self, d: Duration) -> Instant {
        Instant {
            micros: self.micros.saturating_add(d.micros),
        }
    }
}

/// Later by a span, saturating at [`Instant::MAX`].
impl AddAssign<Duration> for Instant {
    fn add_assign(&mut self, d: Duration) {
        *self = *self + d;
    }
}

/// Earlier by a span, saturating at [`Instant::ZERO`].
impl Sub<Duration> for Instant {
    type Output = Instant;

    fn sub(self, d: Duration) -> Instant {
        Instant {
            micros: self.micros.saturating_sub(d.micros),
        }
    }
}

/// The span between two instants, zero if the right one is later (see
/// [`Instant::saturating_duration_since`]).
impl Sub<Instant> for Instant {
    type Output = Duration;

    fn sub(self, earlier: Instant) -> Duration {
        self.saturating_duration_since(earlier)
    }
}

/// The sum of two spans, saturating.
impl Add for Duration {
    type Output = Duration;

    fn add(self, d: Duration) -> Duration {
        Duration {
            micros: self.micros.saturating_add(d.micros),
        }
    }
}

/// The difference of two spans, zero if the right one is longer.
impl Sub for Duration {
    type Output = Duration;

    fn sub(self, d: Duration) -> Duration {
        Duration {
            micros: self.micros.saturating_sub(d.micros),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constructors_agree() {
        assert_eq!(Duration::from_secs(2), Duration::from_millis(2000));
        assert_eq!(Duration::from_millis(3), Duration::from_micros(3000));
        assert_eq!(Instant::from_secs(1), Instant::from_millis(1000));
        assert_eq!(Instant::from_millis(7).as_micros(), 7000);
        assert_eq!(Duration::from_millis(u64::MAX).as_micros(), u64::MAX);
        assert_eq!(Instant::from_secs(u64::MAX), Instant::MAX);
        assert_eq!(Instant::default(), Instant::ZERO);
        assert_eq!(Duration::default(), Duration::ZERO);
    }

    #[test]
    fn instant_arithmetic_saturates() {
        let t = Instant::from_micros(100);
        assert_eq!(t + Duration::from_micros(5), Instant::from_micros(105));
        assert_eq!(t - Duration::from_micros(5), Instant::from_micros(95));
        assert_eq!(t - Duration::from_micros(500), Instant::ZERO);
        assert_eq!(Instant::MAX + Duration::from_micros(1), Instant::MAX);
        let mut u = Instant::from_micros(u64::MAX - 1);
        u += Duration::from_secs(1);
        assert_eq!(u, Instant::MAX);
        assert_eq!(t - Instant::from_micros(40), Duration::from_micros(60));
        assert_eq!(Instant::from_micros(40) - t, Duration::ZERO);
        assert_eq!(t.saturating_duration_since(Instant::MAX), Duration::ZERO);
    }

    #[test]
    fn duration_arithmetic_saturates() {
        let d = Duration::from_micros(1000);
        assert_eq!(d + d, Duration::from_millis(2));
        assert_eq!(d - Duration::from_secs(1), Duration::ZERO);
        assert_eq!(d.saturating_mul(3), Duration::from_millis(3));
        assert_eq!(d.saturating_mul(u64::MAX).as_micros(), u64::MAX);
        assert_eq!(
            Duration::from_micros(u64::MAX) + d,
            Duration::from_micros(u64::MAX)
        );
        assert_eq!(Duration::from_micros(3500).checked_div_duration(d), Some(3));
        assert_eq!(d.checked_div_duration(Duration::ZERO), None);
        assert!(Duration::ZERO.is_zero() && !d.is_zero());
    }

    #[test]
    fn seconds_as_f32_are_micros_times_1e_6() {
        for us in [0u64, 1, 250, 1000, 15_000, 16_777_217, u64::MAX] {
            assert_eq!(Duration::from_micros(us).as_secs_f32(), us as f32 * 1e-6);
        }
        assert_eq!(Duration::from_millis(1).as_secs_f32(), 1e-3);
    }
}
