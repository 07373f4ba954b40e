//! An open-loop hold for the Mega: signed PWM per motor (`K` frames) and the magnet (`L`),
//! resent by the Mega's thread on every host tick until a deadline, for the wiring check
//! (`ratf check`) to turn one wheel at a time.
//!
//! The Mega's own watchdog stops every motor 100 ms after the last `G`/`K`
//! (protocol/README.md §4), so a `K` typed once only twitches a motor; a hold resent every
//! [`super::HOST_TICK_PERIOD_US`] keeps it turning. A hold ends at its deadline (if the
//! check dies half-way the wheel stops by itself), when replaced, or at
//! [`super::mega::MegaHandle::stop`]. While a hold is in force the host watchdog's zero
//! references give way to it; PWM 0 lets a motor coast, so a hold of zeros leaves the
//! wheels free to be turned by hand (zero *references* would have the PI hold them).

use ratf_protocol::messages::WHEEL_COUNT;

/// What to resend and until when.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OpenLoopHold {
    /// Signed PWM per motor, motor index order (the Mega clamps the magnitude to 255).
    pub pwm: [i16; WHEEL_COUNT],
    /// The magnet.
    pub solenoid_on: bool,
    /// The hold ends at this time on the robot's clock, µs ([`u64::MAX`]: until replaced or stopped).
    pub until_us: u64,
}

impl OpenLoopHold {
    /// Every motor coasting (PWM 0) and the magnet off, until replaced or stopped.
    pub const COAST: Self = Self {
        pwm: [0; WHEEL_COUNT],
        solenoid_on: false,
        until_us: u64::MAX,
    };

    /// True while the hold is in force at `now_us`.
    pub const fn active_at(&self, now_us: u64) -> bool {
        now_us < self.until_us
    }
}

/// Whether a batch is due at `now_us` when the last write was at `last_write_us`: at most
/// one per `period_us`.
pub const fn batch_due(last_write_us: Option<u64>, now_us: u64, period_us: u64) -> bool {
    match last_write_us {
        None => true,
        Some(last) => now_us.saturating_sub(last) >= period_us,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hold_is_in_force_until_its_deadline() {
        let hold = OpenLoopHold {
            pwm: [51, 0, 0, 0],
            solenoid_on: false,
            until_us: 1_000_000,
        };
        assert!(hold.active_at(0));
        assert!(hold.active_at(999_999));
        assert!(!hold.active_at(1_000_000));
        assert!(OpenLoopHold::COAST.active_at(u64::MAX - 1));
    }

    #[test]
    fn one_batch_per_period_at_most() {
        assert!(batch_due(None, 0, 20_000));
        assert!(!batch_due(Some(100_000), 119_999, 20_000));
        assert!(batch_due(Some(100_000), 120_000, 20_000));
        // A clock read before the last write is not due (no burst).
        assert!(!batch_due(Some(100_000), 90_000, 20_000));
    }
}
