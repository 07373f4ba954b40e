//! What the IMU gave during a window (pure): the chip that answered and the gyro bias of a
//! still robot ([`ratf_core::drivers::imu::bias::estimate_gyro_bias`], as at start-up).

use ratf_core::drivers::imu::bias::{BiasConfig, estimate_gyro_bias};
use ratf_core::drivers::imu::{Chip, ImuSample};
use serde::Serialize;

/// Gyro samples kept per window (a minute at 200 Hz): bounded memory.
const MAX_SAMPLES: usize = 200 * 60;

/// Samples collected over a window.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImuWindow {
    gyro_rad_s: Vec<[f64; 3]>,
    first_us: Option<u64>,
    saturated: u32,
    lost: bool,
}

impl ImuWindow {
    /// One sample, arrived at `at_us`.
    pub fn on_sample(&mut self, sample: &ImuSample, at_us: u64) {
        self.first_us.get_or_insert(at_us);
        self.saturated += u32::from(sample.saturated);
        if self.gyro_rad_s.len() < MAX_SAMPLES {
            self.gyro_rad_s.push(sample.gyro_rad_s);
        }
    }

    /// The IMU's thread gave up (too many failed reads in a row).
    pub fn on_lost(&mut self) {
        self.lost = true;
    }

    /// When the first sample arrived, µs.
    pub fn first_us(&self) -> Option<u64> {
        self.first_us
    }

    /// The summary for `chip`.
    pub fn summary(&self, chip: Chip, window_s: f64) -> ImuSummary {
        let bias = estimate_gyro_bias(&self.gyro_rad_s, &BiasConfig::default());
        ImuSummary {
            who_am_i: match chip {
                Chip::Mpu9250 => 0x71,
                Chip::Mpu9255 => 0x73,
            },
            chip: format!("{chip:?}"),
            samples: self.gyro_rad_s.len() as u32,
            samples_per_s: self.gyro_rad_s.len() as f64 / window_s.max(1e-9),
            gyro_bias_deg_s: bias.ok().map(|b| b.map(f64::to_degrees)),
            bias_error: bias.err().map(|e| e.to_string()),
            saturated: self.saturated,
            lost: self.lost,
        }
    }
}

/// What the IMU gave during a window.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImuSummary {
    /// The `WHO_AM_I` register (0x71 MPU9250, 0x73 MPU9255).
    pub who_am_i: u8,
    /// The chip.
    pub chip: String,
    /// Samples read.
    pub samples: u32,
    /// Samples per second.
    pub samples_per_s: f64,
    /// Gyro bias per axis (robot x, y, z), °/s; `None` when it could not be estimated.
    pub gyro_bias_deg_s: Option<[f64; 3]>,
    /// Why it could not be.
    pub bias_error: Option<String>,
    /// Samples at the end of a range.
    pub saturated: u32,
    /// The thread gave up reading.
    pub lost: bool,
}

impl ImuSummary {
    /// What is wrong, each with what to check.
    pub fn problems(&self, bus: &str) -> Vec<String> {
        let mut problems = Vec::new();
        if self.lost {
            problems.push(format!(
                "{bus}: reads failed repeatedly: check the IMU's wires (SDA pin 3, SCL pin 5) \
                 and its 3.3 V"
            ));
        }
        if let Some(e) = &self.bias_error {
            problems.push(format!(
                "no gyro bias: {e} (keep the robot still during the check)"
            ));
        }
        if self.saturated > 0 {
            problems.push(format!(
                "{} saturated samples while standing still: a loose mount or a faulty chip",
                self.saturated
            ));
        }
        problems
    }

    /// One line of what was seen.
    pub fn describe(&self) -> String {
        let bias = self.gyro_bias_deg_s.map_or("unknown".to_owned(), |b| {
            format!("({:+.3}, {:+.3}, {:+.3}) °/s", b[0], b[1], b[2])
        });
        format!(
            "WHO_AM_I 0x{:02X} ({}), {} samples ({:.0}/s), gyro bias {bias}",
            self.who_am_i, self.chip, self.samples, self.samples_per_s
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(z: f64) -> ImuSample {
        ImuSample {
            time_us: 0,
            gyro_rad_s: [0.001, -0.002, z],
            accel_m_s2: [0.0, 0.0, 9.81],
            temperature_c: 25.0,
            saturated: false,
        }
    }

    #[test]
    fn a_still_gyro_gives_its_bias() {
        let mut w = ImuWindow::default();
        for i in 0..400u64 {
            let noise = if i % 2 == 0 { 1e-4 } else { -1e-4 };
            w.on_sample(&sample(0.02 + noise), i * 5_000);
        }
        let s = w.summary(Chip::Mpu9255, 2.0);
        assert_eq!(s.who_am_i, 0x73);
        let bias = s.gyro_bias_deg_s.expect("a bias");
        assert!((bias[2] - 0.02_f64.to_degrees()).abs() < 1e-6, "{bias:?}");
        assert!(s.problems("/dev/i2c-1").is_empty());
        assert!(s.describe().contains("WHO_AM_I 0x73 (Mpu9255)"));
    }

    #[test]
    fn too_few_samples_or_a_moving_robot_is_a_problem() {
        let mut w = ImuWindow::default();
        for i in 0..50u64 {
            w.on_sample(&sample(0.0), i * 5_000);
        }
        w.on_lost();
        let problems = w
            .summary(Chip::Mpu9250, 2.0)
            .problems("/dev/i2c-1")
            .join("\n");
        assert!(
            problems.contains("at least 200 samples, got 50"),
            "{problems}"
        );
        assert!(problems.contains("/dev/i2c-1: reads failed"), "{problems}");
        let mut moving = ImuWindow::default();
        for i in 0..400u64 {
            moving.on_sample(&sample(if i % 2 == 0 { 0.5 } else { -0.5 }), i * 5_000);
        }
        let problems = moving.summary(Chip::Mpu9255, 2.0).problems("/dev/i2c-1");
        assert!(problems[0].contains("moved"), "{problems:?}");
    }
}
