//! The original tuning node's CSV logs (original-system.md §3.1; `shared/data/
//! motor-pwm-steps-11.79V.csv`): `secs,nsecs`, then per motor 0..3 `sample_period` (s),
//! `pwm` (−255..255), `encoder_delta` (ticks in the period), `ticks_per_rev`,
//! `angular_speed` (ignored: the original driver divides by the nominal period).
//!
//! Parsed from text (no file I/O here) into one [`Sample`] sequence per wheel, the speed
//! recomputed from the ticks and the firmware's measured period, the voltage from the PWM and
//! the battery voltage the team measured (PWM `pwm_max` = the battery).

use super::motor_model::Sample;
use std::f64::consts::TAU;

/// Columns per motor.
const PER_MOTOR: usize = 5;

/// Why a CSV cannot be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CsvError {
    /// The header does not have the expected columns.
    #[error(
        "header has {columns} columns, expected secs,nsecs then 5 per motor (sample_period, \
         pwm, encoder_delta, ticks_per_rev, angular_speed): not a tuning-node log"
    )]
    Header {
        /// Columns found.
        columns: usize,
    },
    /// A data row is malformed.
    #[error("line {line}: {what}")]
    Row {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        what: String,
    },
    /// No data rows.
    #[error("no data rows")]
    Empty,
}

/// Parse `text` into one sample sequence per motor (motor index order), with `battery_v`
/// volts at PWM `pwm_max`.
pub fn parse(text: &str, battery_v: f64, pwm_max: f64) -> Result<Vec<Vec<Sample>>, CsvError> {
    let mut lines = text.lines().enumerate();
    let columns = lines
        .next()
        .map_or(0, |(_, header)| header.split(',').count());
    if columns < 2 + PER_MOTOR || !(columns - 2).is_multiple_of(PER_MOTOR) {
        return Err(CsvError::Header { columns });
    }
    let motors = (columns - 2) / PER_MOTOR;
    let mut wheels = vec![Vec::new(); motors];
    for (index, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let row_error = |what: String| CsvError::Row {
            line: index + 1,
            what,
        };
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != columns {
            return Err(row_error(format!(
                "{} fields, the header has {columns}",
                fields.len()
            )));
        }
        let number = |i: usize| {
            fields[i]
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    row_error(format!("field {} is not a number: {:?}", i + 1, fields[i]))
                })
        };
        for (m, wheel) in wheels.iter_mut().enumerate() {
            let base = 2 + m * PER_MOTOR;
            let period_s = number(base)?;
            let pwm = number(base + 1)?;
            let delta = number(base + 2)?;
            let ticks_per_rev = number(base + 3)?;
            if period_s <= 0.0 {
                // The first row of a log has no period yet.
                continue;
            }
            if ticks_per_rev <= 0.0 {
                return Err(row_error(format!(
                    "motor {m}: ticks_per_rev {ticks_per_rev} must be positive"
                )));
            }
            wheel.push(Sample {
                period_s,
                voltage_v: pwm / pwm_max * battery_v,
                speed_rad_s: delta * TAU / ticks_per_rev / period_s,
            });
        }
    }
    if wheels.iter().all(Vec::is_empty) {
        return Err(CsvError::Empty);
    }
    Ok(wheels)
}

/// The battery voltage a log's file name states (`…-11.79V.csv`), V.
pub fn battery_from_name(name: &str) -> Option<f64> {
    let stem = name.strip_suffix(".csv").unwrap_or(name);
    let volts = stem.strip_suffix(['V', 'v'])?;
    let start = volts
        .rfind(|c: char| !(c.is_ascii_digit() || c == '.'))
        .map_or(0, |i| i + 1);
    volts[start..].parse().ok().filter(|v: &f64| *v > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LOG: &str = "secs,nsecs,sample_period,pwm,encoder_delta,ticks_per_rev,angular_speed\n\
        1,0,0,0,0,2803.2,0\n\
        1,20000000,0.02,51,28.032,2803.2,3.14\n";

    #[test]
    fn reads_a_one_motor_log() {
        let wheels = parse(LOG, 12.0, 255.0).unwrap();
        assert_eq!(wheels.len(), 1);
        assert_eq!(wheels[0].len(), 1);
        let s = wheels[0][0];
        assert!((s.voltage_v - 2.4).abs() < 1e-12);
        assert!((s.speed_rad_s - TAU / 100.0 / 0.02).abs() < 1e-9);
    }

    #[test]
    fn names_the_bad_line() {
        let bad = LOG.replace("0.02,51", "0.02,x");
        assert!(matches!(
            parse(&bad, 12.0, 255.0),
            Err(CsvError::Row { line: 3, .. })
        ));
        assert!(matches!(
            parse("a,b,c\n", 12.0, 255.0),
            Err(CsvError::Header { columns: 3 })
        ));
    }

    #[test]
    fn battery_from_the_file_name() {
        assert_eq!(battery_from_name("motor-pwm-steps-11.79V.csv"), Some(11.79));
        assert_eq!(battery_from_name("steps.csv"), None);
    }
}
