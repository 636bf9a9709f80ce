//! Simulated time: [`Tick`] (global, picoseconds), [`Cycles`] (one clock domain) and
//! [`ClockDomain`], the only bridge between them.
//!
//! Picoseconds because every clock of the simulated machine has an integral period in them: 40 MHz
//! is 25,000 ps and 20 MHz 50,000 ps. A u64 of picoseconds lasts 213 days of simulated time.
//!
//! **Overflow saturates.** Adding, multiplying and summing times and cycle counts, and converting
//! cycles to ticks, stop at `u64::MAX` instead of wrapping (or panicking): a config's costs and
//! clocks are user input, and a span too long for a u64 is simply later than every time limit a
//! run can have, so the run stops at its limit with a report rather than wrapping to an early,
//! meaningless time (which the event queue would refuse as an event in the past). Subtraction
//! still panics when it would go below zero: that is a simulator bug, not a long run.

use std::fmt;
use std::iter::Sum;
use std::num::NonZeroU64;
use std::ops::{Add, AddAssign, Mul, Sub};

/// A point in (or span of) global simulated time, in picoseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Tick(pub u64);

/// A count of clock cycles of one clock domain (which domain is the holder's business: a count
/// of one unit's cycles is in that unit's clock).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Cycles(pub u64);

/// A clock: its period in ticks. Only [`ClockDomain::from_hz`] makes one, and it rejects a zero
/// clock, so the period is nonzero by its type and every division by it is safe.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClockDomain {
    period_ps: NonZeroU64,
}

/// Why a clock frequency cannot be a [`ClockDomain`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockError {
    /// Zero hertz.
    Zero,
    /// 10^12 / hz is not an integer number of picoseconds.
    NotIntegralPicoseconds(u64),
}

impl fmt::Display for ClockError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ClockError::Zero => write!(f, "a clock of 0 Hz has no period"),
            ClockError::NotIntegralPicoseconds(hz) => write!(
                f,
                "{hz} Hz has a period that is not a whole number of picoseconds"
            ),
        }
    }
}

impl std::error::Error for ClockError {}

impl Tick {
    pub const ZERO: Tick = Tick(0);
    pub const MAX: Tick = Tick(u64::MAX);

    /// Picoseconds since time zero.
    pub fn as_ps(self) -> u64 {
        self.0
    }

    /// Seconds, for reports only (never for ordering).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-12
    }

    pub fn saturating_sub(self, other: Tick) -> Tick {
        Tick(self.0.saturating_sub(other.0))
    }
}

impl Cycles {
    pub const ZERO: Cycles = Cycles(0);

    pub fn get(self) -> u64 {
        self.0
    }
}

impl ClockDomain {
    /// A clock of `hz` hertz; its period must be a whole number of picoseconds.
    pub fn from_hz(hz: u64) -> Result<ClockDomain, ClockError> {
        if hz == 0 {
            return Err(ClockError::Zero);
        }
        if 1_000_000_000_000 % hz != 0 {
            return Err(ClockError::NotIntegralPicoseconds(hz));
        }
        // hz divides 10^12, so hz <= 10^12 and the quotient is at least 1.
        let period_ps = NonZeroU64::new(1_000_000_000_000 / hz).expect("hz <= 10^12");
        Ok(ClockDomain { period_ps })
    }

    /// The period of one cycle (never zero).
    pub fn period(self) -> Tick {
        Tick(self.period_ps.get())
    }

    /// Frequency in hertz.
    pub fn hz(self) -> u64 {
        1_000_000_000_000 / self.period_ps
    }

    /// The span of `cycles` clocks ([`Tick::MAX`] if that is more than a u64 holds: see the
    /// module doc on saturation).
    pub fn to_ticks(self, cycles: Cycles) -> Tick {
        Tick(cycles.0.saturating_mul(self.period_ps.get()))
    }

    /// Whole cycles elapsed by `tick` (rounded down).
    pub fn cycles_floor(self, tick: Tick) -> Cycles {
        Cycles(tick.0 / self.period_ps)
    }

    /// The first clock edge at or after `tick`, as a cycle count (rounded up).
    pub fn cycles_ceil(self, tick: Tick) -> Cycles {
        self.cycles_floor_ceil(tick).1
    }

    /// [`ClockDomain::cycles_floor`] and [`ClockDomain::cycles_ceil`] of `tick` by one
    /// division, not the three of calling both, for a caller that needs both at every instant.
    pub fn cycles_floor_ceil(self, tick: Tick) -> (Cycles, Cycles) {
        let whole = tick.0 / self.period_ps;
        let ceil = whole + u64::from(tick.0 % self.period_ps != 0);
        (Cycles(whole), Cycles(ceil))
    }

    /// The first clock edge at or after `tick`.
    pub fn next_edge(self, tick: Tick) -> Tick {
        self.to_ticks(self.cycles_ceil(tick))
    }
}

/// Addition, multiplication and sums saturate at `u64::MAX` (see the module doc); subtraction
/// panics below zero.
macro_rules! arithmetic {
    ($t:ident) => {
        impl Add for $t {
            type Output = $t;
            fn add(self, rhs: $t) -> $t {
                $t(self.0.saturating_add(rhs.0))
            }
        }
        impl AddAssign for $t {
            fn add_assign(&mut self, rhs: $t) {
                self.0 = self.0.saturating_add(rhs.0);
            }
        }
        impl Sub for $t {
            type Output = $t;
            fn sub(self, rhs: $t) -> $t {
                $t(self.0 - rhs.0)
            }
        }
        impl Mul<u64> for $t {
            type Output = $t;
            fn mul(self, rhs: u64) -> $t {
                $t(self.0.saturating_mul(rhs))
            }
        }
        impl Sum for $t {
            fn sum<I: Iterator<Item = $t>>(iter: I) -> $t {
                iter.fold($t(0), |a, b| a + b)
            }
        }
    };
}
arithmetic!(Tick);
arithmetic!(Cycles);

impl fmt::Display for Tick {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ps", self.0)
    }
}

impl fmt::Display for Cycles {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} cycles", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mhz(n: u64) -> ClockDomain {
        ClockDomain::from_hz(n * 1_000_000).unwrap()
    }

    #[test]
    fn forty_mhz_is_25_000_ps() {
        let clk = mhz(40);
        assert_eq!(clk.period(), Tick(25_000));
        assert_eq!(clk.hz(), 40_000_000);
    }

    #[test]
    fn twenty_mhz_is_50_000_ps() {
        let clk = mhz(20);
        assert_eq!(clk.period(), Tick(50_000));
        assert_eq!(clk.hz(), 20_000_000);
    }

    #[test]
    fn zero_and_non_integral_frequencies_are_errors() {
        assert_eq!(ClockDomain::from_hz(0), Err(ClockError::Zero));
        // 10^12 / 3 = 333,333,333,333.3 ps: not representable.
        assert_eq!(
            ClockDomain::from_hz(3),
            Err(ClockError::NotIntegralPicoseconds(3))
        );
        // The messages are what a user sees for a bad configuration.
        assert_eq!(
            ClockError::Zero.to_string(),
            "a clock of 0 Hz has no period"
        );
        assert_eq!(
            ClockError::NotIntegralPicoseconds(3).to_string(),
            "3 Hz has a period that is not a whole number of picoseconds"
        );
    }

    #[test]
    fn extreme_frequencies() {
        // 1 THz is a 1 ps period, the finest clock a picosecond tick can express.
        assert_eq!(
            ClockDomain::from_hz(1_000_000_000_000).unwrap().period(),
            Tick(1)
        );
        assert_eq!(
            ClockDomain::from_hz(1).unwrap().period(),
            Tick(1_000_000_000_000)
        );
        assert!(ClockDomain::from_hz(2_000_000_000_000).is_err());
    }

    #[test]
    fn cycles_and_ticks_round_trip_on_edges() {
        for clk in [mhz(40), mhz(20)] {
            for n in [0, 1, 2, 7, 1_000, 123_456_789] {
                let t = clk.to_ticks(Cycles(n));
                assert_eq!(t, Tick(n * clk.period().as_ps()));
                assert_eq!(clk.cycles_floor(t), Cycles(n));
                assert_eq!(clk.cycles_ceil(t), Cycles(n));
                // An edge is its own next edge: no waiting a full cycle when already there.
                assert_eq!(clk.next_edge(t), t);
            }
        }
    }

    #[test]
    fn rounding_at_a_non_edge_tick() {
        let clk = mhz(40);
        // Just after the 4th edge (100,000 ps).
        let t = Tick(100_001);
        assert_eq!(clk.cycles_floor(t), Cycles(4));
        assert_eq!(clk.cycles_ceil(t), Cycles(5));
        assert_eq!(clk.next_edge(t), Tick(125_000));
        // Just before the 5th edge.
        let t = Tick(124_999);
        assert_eq!(clk.cycles_floor(t), Cycles(4));
        assert_eq!(clk.cycles_ceil(t), Cycles(5));
        assert_eq!(clk.next_edge(t), Tick(125_000));
        // A 40 MHz edge halfway through a 20 MHz cycle.
        let slow = mhz(20);
        assert_eq!(slow.cycles_floor(Tick(25_000)), Cycles(0));
        assert_eq!(slow.next_edge(Tick(25_000)), Tick(50_000));
    }

    #[test]
    fn cycles_arithmetic_and_sum() {
        assert_eq!(Cycles(3) + Cycles(4), Cycles(7));
        assert_eq!(Cycles(10) - Cycles(4), Cycles(6));
        assert_eq!(Cycles(6) * 5, Cycles(30));
        let mut c = Cycles::ZERO;
        c += Cycles(2);
        c += Cycles(9);
        assert_eq!(c, Cycles(11));
        assert_eq!(c.get(), 11);
        let total: Cycles = [Cycles(1), Cycles(2), Cycles(3)].into_iter().sum();
        assert_eq!(total, Cycles(6));
        // The empty sum is zero, so totals over no work need no special case.
        assert_eq!(std::iter::empty::<Cycles>().sum::<Cycles>(), Cycles::ZERO);
        assert_eq!(Cycles(8).to_string(), "8 cycles");
    }

    /// Spans too long for a u64 saturate: they are later than any time limit, never an early
    /// wrapped time.
    #[test]
    fn overflow_saturates() {
        let slow = ClockDomain::from_hz(1).unwrap();
        assert_eq!(slow.to_ticks(Cycles(u64::MAX)), Tick::MAX);
        assert_eq!(slow.to_ticks(Cycles(18_446_745)), Tick::MAX);
        assert_eq!(slow.to_ticks(Cycles(18_446_744)), Tick(18_446_744 * PS));
        assert_eq!(Tick(u64::MAX - 1) + Tick(5), Tick::MAX);
        let mut t = Tick(u64::MAX - 3);
        t += Tick(4);
        assert_eq!(t, Tick::MAX);
        assert_eq!(Cycles(u64::MAX / 2) * 3, Cycles(u64::MAX));
        let total: Cycles = [Cycles(u64::MAX), Cycles(1)].into_iter().sum();
        assert_eq!(total, Cycles(u64::MAX));
    }

    /// Picoseconds per second.
    const PS: u64 = 1_000_000_000_000;

    #[test]
    fn tick_arithmetic_and_display() {
        assert_eq!(Tick(5) + Tick(7), Tick(12));
        assert_eq!(Tick(12) - Tick(7), Tick(5));
        assert_eq!(Tick(25_000) * 4, Tick(100_000));
        assert_eq!(Tick(3).saturating_sub(Tick(5)), Tick::ZERO);
        assert_eq!(Tick(5).saturating_sub(Tick(3)), Tick(2));
        let total: Tick = [Tick(1), Tick(2)].into_iter().sum();
        assert_eq!(total, Tick(3));
        assert_eq!(Tick(25_000).to_string(), "25000 ps");
        assert!((Tick(1_000_000_000_000).as_secs_f64() - 1.0).abs() < 1e-12);
        assert_eq!(Tick(9).as_ps(), 9);
    }
}
