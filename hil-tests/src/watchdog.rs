//! Measuring the firmware's watchdog: how long after the last `G`/`K` it stops the motors
//! and releases the solenoid, while telemetry keeps flowing (protocol `mcu`: "if no `G` or
//! `K` arrived for more than 100 ms, the next tick stops every motor at once", and the
//! solenoid follows `SOLENOID_HOLD_AFTER_STOP_US` later).

use crate::host_link::{HostLink, wheel_speeds};
use crate::shield::signed_pwms;
use crate::sim::{CYCLES_PER_MS, Hil, UART_BYTE_CYCLES};
use ratf_protocol::messages::Command;

/// What [`measure_watchdog`] saw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WatchdogRun {
    /// Cycle at which the last feeding batch (`G H I J L Z`) was completely delivered: the
    /// earliest the firmware can have applied it (strict mode applies a batch at its `Z`).
    pub last_feed_cycle: u64,
    /// First sample (every 100 µs) at which a motor was no longer driven (a PWM 0): the trip
    /// began. `None` if never.
    pub trip_cycle: Option<u64>,
    /// First sample with every PWM 0: the motors' stop is complete.
    pub stop_cycle: Option<u64>,
    /// First sample with the solenoid low: the part let go.
    pub release_cycle: Option<u64>,
    /// After the stop every sample until the end showed PWM 0, and after the release the
    /// solenoid low.
    pub stayed_stopped: bool,
    /// Complete telemetry batches received from the last feed to the end of the run.
    pub batches_after_feed: usize,
    /// Cycle at which the run ended.
    pub end_cycle: u64,
}

impl WatchdogRun {
    fn ms_after_feed(&self, cycle: Option<u64>) -> Option<f64> {
        cycle.map(|c| c.saturating_sub(self.last_feed_cycle) as f64 / CYCLES_PER_MS as f64)
    }

    /// Time from the last feed to the first sign of the trip, ms.
    pub fn trip_ms(&self) -> Option<f64> {
        self.ms_after_feed(self.trip_cycle)
    }

    /// Time from the last feed to the motors' complete stop (every PWM 0), ms.
    pub fn stop_ms(&self) -> Option<f64> {
        self.ms_after_feed(self.stop_cycle)
    }

    /// Time from the last feed to the solenoid's release, ms.
    pub fn release_ms(&self) -> Option<f64> {
        self.ms_after_feed(self.release_cycle)
    }
}

/// On a booted `hil` (at least one telemetry batch received): feed the watchdog with
/// `G`=10 rad/s on every wheel and `L`=1 every 20 ms for 100 ms (no plant: the wheels do
/// not turn, so every PI output is positive), then stop feeding and sample the shield and
/// the solenoid pin every 100 µs for `observe_ms` ms.
pub fn measure_watchdog(hil: &mut Hil, observe_ms: u64) -> WatchdogRun {
    let mut host = HostLink::new(true);
    let mut commands = wheel_speeds([10.0; 4]);
    commands.push(Command::Solenoid { on: true });
    let mut last_feed_cycle = 0;
    for _ in 0..5 {
        let bytes = host.batch(&commands);
        hil.send(&bytes);
        last_feed_cycle = hil.cycle() + bytes.len() as u64 * UART_BYTE_CYCLES;
        hil.run_for_ms(20);
    }
    let batches_before = hil.telemetry_batches().len();
    let end_cycle = last_feed_cycle + observe_ms * CYCLES_PER_MS;
    let mut trip_cycle = None;
    let mut stop_cycle = None;
    let mut release_cycle = None;
    let mut stayed_stopped = true;
    while hil.cycle() < end_cycle {
        hil.run_for_us(100);
        let pwms = signed_pwms(&hil.shield());
        let solenoid = hil.solenoid_on();
        if trip_cycle.is_none() && pwms.contains(&0) {
            trip_cycle = Some(hil.cycle());
        }
        match stop_cycle {
            None if pwms == [0; 4] => stop_cycle = Some(hil.cycle()),
            None => {}
            Some(_) => stayed_stopped &= pwms == [0; 4],
        }
        match release_cycle {
            None if !solenoid => release_cycle = Some(hil.cycle()),
            None => {}
            Some(_) => stayed_stopped &= !solenoid,
        }
    }
    WatchdogRun {
        last_feed_cycle,
        trip_cycle,
        stop_cycle,
        release_cycle,
        stayed_stopped,
        batches_after_feed: hil.telemetry_batches().len() - batches_before,
        end_cycle: hil.cycle(),
    }
}
