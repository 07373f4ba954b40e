//! What the Mega sent during a window (pure): telemetry rate, integrity errors both ways,
//! resets, encoder ticks per wheel, the switch; and what to say about it.

use ratf_core::drivers::mega_link::{MegaLinkStats, WheelTelemetry};
use ratf_protocol::messages::{Faults, QuadratureErrors};
use serde::Serialize;

/// Telemetry collected over a window.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MegaWindow {
    batches: u32,
    verified: u32,
    first_us: Option<u64>,
    last_us: Option<u64>,
    period_sum_us: u64,
    resets: u32,
    ticks: [i64; 4],
    faults: Option<(Faults, Faults)>,
    quadrature: Option<(QuadratureErrors, QuadratureErrors)>,
    switch: Option<(bool, bool)>,
    switch_changes: u32,
    device_faults: Vec<String>,
}

impl MegaWindow {
    /// One telemetry batch, arrived at `at_us`.
    pub fn on_telemetry(&mut self, telemetry: &WheelTelemetry, at_us: u64) {
        self.batches += 1;
        self.verified += u32::from(telemetry.verified);
        self.first_us.get_or_insert(at_us);
        self.last_us = Some(at_us);
        self.period_sum_us += u64::from(telemetry.period_us);
        if let Some(deltas) = telemetry.deltas_ticks {
            for (total, delta) in self.ticks.iter_mut().zip(deltas) {
                *total += i64::from(delta);
            }
        }
        if let Some(f) = telemetry.faults {
            self.faults = Some((self.faults.map_or(f, |(first, _)| first), f));
        }
        if let Some(q) = telemetry.quadrature_errors {
            self.quadrature = Some((self.quadrature.map_or(q, |(first, _)| first), q));
        }
        let pressed = telemetry.switch_pressed;
        if let Some((_, last)) = self.switch
            && last != pressed
        {
            self.switch_changes += 1;
        }
        self.switch = Some((self.switch.map_or(pressed, |(first, _)| first), pressed));
    }

    /// The Mega rebooted (`r`).
    pub fn on_reset(&mut self) {
        self.resets += 1;
    }

    /// The Mega's thread reported a fault (port lost, …).
    pub fn on_fault(&mut self, message: &str) {
        self.device_faults.push(message.to_owned());
    }

    /// Ticks per wheel over the window (motor index order).
    pub fn ticks(&self) -> [i64; 4] {
        self.ticks
    }

    /// Telemetry batches received.
    pub fn batches(&self) -> u32 {
        self.batches
    }

    /// When the first batch arrived, µs.
    pub fn first_us(&self) -> Option<u64> {
        self.first_us
    }

    /// The switch's state changes seen.
    pub fn switch_changes(&self) -> u32 {
        self.switch_changes
    }

    /// The summary, with the host's link counters at the window's start and end.
    pub fn summary(
        &self,
        stats: (Option<MegaLinkStats>, Option<MegaLinkStats>),
        window_s: f64,
    ) -> MegaSummary {
        let span_s = match (self.first_us, self.last_us) {
            (Some(a), Some(b)) if b > a => (b - a) as f64 * 1e-6,
            _ => 0.0,
        };
        let rate_hz = if span_s > 0.0 {
            f64::from(self.batches - 1) / span_s
        } else {
            0.0
        };
        let host = |s: &MegaLinkStats| {
            s.link.batches_discarded()
                + s.incomplete_batches
                + s.bad_messages
                + s.link.frames_aborted
        };
        let host_errors = match stats {
            (Some(a), Some(b)) => host(&b).wrapping_sub(host(&a)),
            (None, Some(b)) => host(&b),
            _ => 0,
        };
        let delta = |(a, b): (Faults, Faults)| MegaFaults {
            i2c: b.i2c.wrapping_sub(a.i2c),
            rx_batches_discarded: b.rx_batches_discarded.wrapping_sub(a.rx_batches_discarded),
            rx_bad_messages: b.rx_bad_messages.wrapping_sub(a.rx_bad_messages),
            serial_bytes_dropped: b.serial_bytes_dropped.wrapping_sub(a.serial_bytes_dropped),
        };
        let quadrature = self.quadrature.map_or([0; 4], |(a, b)| {
            std::array::from_fn(|k| b.0[k].wrapping_sub(a.0[k]))
        });
        MegaSummary {
            window_s,
            batches: self.batches,
            batches_per_s: rate_hz,
            mean_period_ms: if self.batches > 0 {
                self.period_sum_us as f64 / f64::from(self.batches) * 1e-3
            } else {
                0.0
            },
            checksums: self.batches > 0 && self.verified == self.batches,
            host_integrity_errors: host_errors,
            mega_faults: self.faults.map(delta).unwrap_or_default(),
            quadrature_errors: quadrature,
            resets: self.resets,
            ticks: self.ticks,
            switch_pressed: self.switch.map(|(_, last)| last),
            switch_changes: self.switch_changes,
            device_faults: self.device_faults.clone(),
        }
    }
}

/// The Mega's own fault counters' increase over the window (its `x` channel).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct MegaFaults {
    /// I2C transfers to the motor shield that failed.
    pub i2c: u8,
    /// Batches from the host the Mega discarded (CRC, count, sequence).
    pub rx_batches_discarded: u8,
    /// Frames from the host rejected as malformed.
    pub rx_bad_messages: u8,
    /// Serial bytes the Mega lost (buffers full).
    pub serial_bytes_dropped: u8,
}

/// What the Mega sent during a window.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MegaSummary {
    /// The window's length, s.
    pub window_s: f64,
    /// Telemetry batches (one per control tick, 9 frames each).
    pub batches: u32,
    /// Telemetry batches per second, from their arrival times.
    pub batches_per_s: f64,
    /// Mean control period the Mega measured (`k`), ms.
    pub mean_period_ms: f64,
    /// Every batch carried a verified checksum (the ratf firmware; an original Mega sends
    /// none).
    pub checksums: bool,
    /// Batches or frames the host discarded (corrupt, out of sequence, incomplete,
    /// unknown).
    pub host_integrity_errors: u32,
    /// The Mega's own fault counters' increase.
    pub mega_faults: MegaFaults,
    /// Invalid quadrature transitions per wheel.
    pub quadrature_errors: [u8; 4],
    /// Reboots seen (`r`).
    pub resets: u32,
    /// Encoder ticks per wheel, motor index order.
    pub ticks: [i64; 4],
    /// The switch at the end (`None`: no telemetry).
    pub switch_pressed: Option<bool>,
    /// Times the switch changed.
    pub switch_changes: u32,
    /// Faults the Mega's thread reported (port lost, …).
    pub device_faults: Vec<String>,
}

impl MegaSummary {
    /// What is wrong, each with what to check; empty when the Mega is healthy.
    /// `expected_hz`: one batch per `[mega] control_period_us`.
    pub fn problems(&self, expected_hz: f64, port: &str) -> Vec<String> {
        let mut problems = Vec::new();
        if self.batches == 0 {
            problems.push(format!(
                "{port}: opened, but no telemetry in {:.1} s: is the ratf firmware flashed \
                 (README \"On the robot\")? check [link] mega_baud (115200) and the USB cable",
                self.window_s
            ));
            return problems;
        }
        if (self.batches_per_s - expected_hz).abs() > 0.1 * expected_hz {
            problems.push(format!(
                "{:.1} telemetry batches per second, expected {expected_hz:.0} ([mega] \
                 control_period_us): a firmware built for another period, or a loaded link",
                self.batches_per_s
            ));
        }
        if self.host_integrity_errors > 0 {
            problems.push(format!(
                "{} corrupt or incomplete batches from the Mega: check the USB cable (short, \
                 shielded, away from the motor wires)",
                self.host_integrity_errors
            ));
        }
        let f = self.mega_faults;
        if f.rx_batches_discarded > 0 || f.rx_bad_messages > 0 || f.serial_bytes_dropped > 0 {
            problems.push(format!(
                "the Mega discarded {} batches and {} frames from the host and lost {} bytes: \
                 check the USB cable and [mega] send_checksums",
                f.rx_batches_discarded, f.rx_bad_messages, f.serial_bytes_dropped
            ));
        }
        if f.i2c > 0 {
            problems.push(format!(
                "{} failed I2C transfers to the motor shield: check its SDA (pin 20) and SCL \
                 (pin 21) wires and its logic power",
                f.i2c
            ));
        }
        for (k, &q) in self.quadrature_errors.iter().enumerate() {
            if q > 0 {
                problems.push(format!(
                    "encoder {k}: {q} invalid quadrature transitions: a loose or noisy wire on \
                     pins {} and {}, or a missing ground",
                    22 + 2 * k,
                    23 + 2 * k
                ));
            }
        }
        if self.resets > 0 {
            problems.push(format!(
                "the Mega rebooted {} time(s) during the check: its power (brown-out when the \
                 motors start?) or the USB cable",
                self.resets
            ));
        }
        for fault in &self.device_faults {
            problems.push(format!("link: {fault}"));
        }
        problems
    }

    /// One line of what was seen.
    pub fn describe(&self) -> String {
        format!(
            "{:.1} batches/s (period {:.2} ms), {}, {} integrity errors, {} resets, ticks \
             {:?}, switch {}",
            self.batches_per_s,
            self.mean_period_ms,
            if self.checksums {
                "checksummed"
            } else {
                "no checksums"
            },
            self.host_integrity_errors
                + u32::from(self.mega_faults.rx_batches_discarded)
                + u32::from(self.mega_faults.rx_bad_messages),
            self.resets,
            self.ticks,
            match self.switch_pressed {
                Some(true) => "pressed",
                Some(false) => "open",
                None => "unknown",
            }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn batch(totals: [i32; 4], deltas: Option<[i32; 4]>, switch: bool) -> WheelTelemetry {
        WheelTelemetry {
            totals,
            deltas_ticks: deltas,
            period_us: 20_000,
            switch_pressed: switch,
            quadrature_errors: Some(QuadratureErrors([0; 4])),
            faults: Some(Faults::default()),
            settings_ack: None,
            verified: true,
            received_at_us: 0,
            sampled_at_us: 0,
        }
    }

    #[test]
    fn fifty_batches_a_second_with_ticks_and_a_switch_press() {
        let mut w = MegaWindow::default();
        for i in 0..101u64 {
            let deltas = (i > 0).then_some([10, -10, 0, 1]);
            w.on_telemetry(&batch([0; 4], deltas, (40..60).contains(&i)), i * 20_000);
        }
        let s = w.summary((None, None), 2.0);
        assert!((s.batches_per_s - 50.0).abs() < 1e-9);
        assert!((s.mean_period_ms - 20.0).abs() < 1e-9);
        assert_eq!(s.ticks, [1000, -1000, 0, 100]);
        assert_eq!(s.switch_changes, 2);
        assert_eq!(s.switch_pressed, Some(false));
        assert!(s.checksums);
        assert!(s.problems(50.0, "/dev/ratf-mega").is_empty(), "{s:?}");
    }

    #[test]
    fn errors_resets_and_a_silent_port_are_problems() {
        let mut w = MegaWindow::default();
        let mut b = batch([0; 4], None, false);
        w.on_telemetry(&b, 0);
        b.faults = Some(Faults {
            i2c: 3,
            ..Faults::default()
        });
        b.quadrature_errors = Some(QuadratureErrors([0, 0, 2, 0]));
        w.on_telemetry(&b, 20_000);
        w.on_reset();
        let s = w.summary((None, None), 2.0);
        let problems = s.problems(50.0, "/dev/ratf-mega").join("\n");
        assert!(problems.contains("3 failed I2C transfers"), "{problems}");
        assert!(problems.contains("encoder 2: 2 invalid"), "{problems}");
        assert!(problems.contains("rebooted 1 time"), "{problems}");
        let silent = MegaWindow::default().summary((None, None), 2.0);
        let problems = silent.problems(50.0, "/dev/ratf-mega");
        assert_eq!(problems.len(), 1);
        assert!(problems[0].starts_with("/dev/ratf-mega: opened, but no telemetry"));
    }
}
