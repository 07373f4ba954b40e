//! Closing the firmware's speed loop through simulated motors: [`PlantLoop`] advances four
//! [`WheelPlant`]s in lockstep with the simulator, reading each motor's voltage from the
//! simulated PCA9685 and driving the resulting quadrature edges onto `PINA`.
//!
//! The plants are stepped every [`PLANT_STEP_CYCLES`] (5 µs), a quarter of the encoder
//! ISR's 20 µs sampling period, so edges land within 5 µs of their exact time; at the
//! motor's top speed (2.19 · 11.1 ≈ 24 rad/s, ≈ 10 900 edges/s) that is at most one edge per
//! step per wheel, which [`PlantLoop::max_edges_per_step`] lets a test check.

use crate::plant::WheelPlant;
use crate::shield::voltages_v;
use crate::sim::{CLOCK_HZ, Hil};
use ratf_protocol::messages::WHEEL_COUNT;

/// Plant step, cycles (5 µs at 16 MHz).
pub const PLANT_STEP_CYCLES: u64 = 80;

/// Four wheels driven by the firmware's motor outputs.
#[derive(Clone, Debug, Default)]
pub struct PlantLoop {
    /// The wheels, in motor-index order.
    pub plants: [WheelPlant; WHEEL_COUNT],
    max_edges_per_step: u64,
}

impl PlantLoop {
    /// Four wheels at rest.
    pub fn new() -> Self {
        Self::default()
    }

    /// Most edges any wheel produced in one plant step so far (should stay ≤ 1).
    pub fn max_edges_per_step(&self) -> u64 {
        self.max_edges_per_step
    }

    /// Wheel speeds, rad/s.
    pub fn speeds_rad_s(&self) -> [f64; WHEEL_COUNT] {
        std::array::from_fn(|k| self.plants[k].speed_rad_s())
    }

    /// Advance the simulator and the plants together by one plant step.
    pub fn step(&mut self, hil: &mut Hil) {
        let voltages = voltages_v(&hil.shield());
        let dt_s = PLANT_STEP_CYCLES as f64 / CLOCK_HZ as f64;
        let mut edges = [0i64; WHEEL_COUNT];
        for (k, plant) in self.plants.iter_mut().enumerate() {
            edges[k] = plant.step(dt_s, voltages[k]);
            self.max_edges_per_step = self.max_edges_per_step.max(edges[k].unsigned_abs());
        }
        if edges.iter().any(|&e| e != 0) {
            hil.update_lines(|lines| {
                for (wheel, &n) in edges.iter().enumerate() {
                    for _ in 0..n.unsigned_abs() {
                        lines.step(wheel, n > 0);
                    }
                }
            });
        }
        hil.run_until(hil.cycle() + PLANT_STEP_CYCLES);
    }

    /// Advance until cycle `until`, calling `each_step` after every plant step.
    pub fn run_until(&mut self, hil: &mut Hil, until: u64, mut each_step: impl FnMut(&Hil, &Self)) {
        while hil.cycle() < until {
            self.step(hil);
            each_step(hil, self);
        }
    }
}

/// Settling of one wheel-speed step: when the speed entered ±`band` of the reference for
/// good (until the end of the run), measured from the moment the reference was first sent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settling {
    /// Time from the first command to the start of the final stay within the band, s;
    /// `None` if the speed was outside the band at the end of the run.
    pub settle_s: Option<f64>,
    /// Largest |speed| seen, rad/s.
    pub peak_rad_s: f64,
}

/// Tracks [`Settling`] from speed samples.
#[derive(Clone, Copy, Debug)]
pub struct SettlingMeter {
    reference_rad_s: f64,
    band_rad_s: f64,
    start_s: f64,
    entered_s: Option<f64>,
    peak_rad_s: f64,
}

impl SettlingMeter {
    /// A meter for a step to `reference_rad_s` sent at `start_s`, with a relative band
    /// (0.05 = ±5 %).
    pub fn new(reference_rad_s: f64, band: f64, start_s: f64) -> Self {
        Self {
            reference_rad_s,
            band_rad_s: band * reference_rad_s.abs(),
            start_s,
            entered_s: None,
            peak_rad_s: 0.0,
        }
    }

    /// Account for the speed `speed_rad_s` at time `t_s`.
    pub fn sample(&mut self, t_s: f64, speed_rad_s: f64) {
        self.peak_rad_s = self.peak_rad_s.max(speed_rad_s.abs());
        if (speed_rad_s - self.reference_rad_s).abs() <= self.band_rad_s {
            self.entered_s.get_or_insert(t_s);
        } else {
            self.entered_s = None;
        }
    }

    /// The result so far.
    pub fn settling(&self) -> Settling {
        Settling {
            settle_s: self.entered_s.map(|t| t - self.start_s),
            peak_rad_s: self.peak_rad_s,
        }
    }
}

/// The reference behaviour on the same plant, on the host: `protocol::mcu::Mcu` with
/// `config`, ticking every 20 ms from t = 0, receiving the four-wheel reference batch 5 ms
/// after every tick (as the HIL tests send it), driving four [`WheelPlant`]s (PWM/255 ×
/// 11.1 V) for `duration_s`. Returns wheel 0's settling into ±5 %.
pub fn reference_settling(
    config: ratf_protocol::mcu::McuConfig,
    reference_rad_s: f32,
    duration_s: f64,
) -> Settling {
    use crate::host_link::{HostLink, wheel_speeds};
    use ratf_protocol::mcu::{Mcu, TickInputs};

    const STEP_US: u32 = 5;
    let mut mcu = Mcu::new(config);
    let mut host = HostLink::new(true);
    let mut plants = [WheelPlant::new(); WHEEL_COUNT];
    let mut pwm = [0i16; WHEEL_COUNT];
    let mut edges_in_period = [0i64; WHEEL_COUNT];
    let first_command_s = 0.005;
    let mut meter = SettlingMeter::new(f64::from(reference_rad_s), 0.05, first_command_s);
    let steps = (duration_s * 1e6) as u32 / STEP_US;
    for step in 0..steps {
        let t_us = step * STEP_US;
        if t_us.is_multiple_of(20_000) {
            let inputs = TickInputs {
                encoder_deltas: edges_in_period.map(|e| e as i16),
                ..TickInputs::default()
            };
            pwm = mcu.control_tick(t_us, &inputs).actuation.pwm;
            edges_in_period = [0; WHEEL_COUNT];
        }
        if t_us % 20_000 == 5_000 {
            mcu.receive(
                &host.batch(&wheel_speeds([reference_rad_s; WHEEL_COUNT])),
                t_us,
            );
        }
        for k in 0..WHEEL_COUNT {
            let voltage_v = f64::from(pwm[k]) / 255.0 * crate::shield::BATTERY_VOLTAGE_V;
            edges_in_period[k] += plants[k].step(f64::from(STEP_US) * 1e-6, voltage_v);
        }
        meter.sample(f64::from(t_us + STEP_US) * 1e-6, plants[0].speed_rad_s());
    }
    meter.settling()
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_protocol::mcu::McuConfig;

    #[test]
    fn settling_meter_finds_the_last_entry() {
        let mut m = SettlingMeter::new(10.0, 0.05, 1.0);
        for (t, w) in [
            (1.0, 0.0),
            (1.1, 10.2),
            (1.2, 11.0),
            (1.3, 10.4),
            (1.4, 9.8),
        ] {
            m.sample(t, w);
        }
        let s = m.settling();
        assert!((s.settle_s.unwrap() - 0.3).abs() < 1e-12);
        assert_eq!(s.peak_rad_s, 11.0);
        m.sample(1.5, 12.0);
        assert_eq!(m.settling().settle_s, None);
    }

    /// The reference behaviour (`protocol::mcu` defaults) with this plant settles, both
    /// ways. It prints its settling time: the HIL test compares the firmware with it.
    #[test]
    fn reference_mcu_with_this_plant_settles() {
        for reference in [10.0f32, -10.0] {
            let s = reference_settling(McuConfig::default(), reference, 1.5);
            println!("reference {reference} rad/s: {s:?}");
            let settle_s = s.settle_s.expect("the reference does not settle");
            assert!(settle_s < 1.0, "{s:?}");
        }
    }
}
