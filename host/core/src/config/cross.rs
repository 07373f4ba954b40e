//! Cross-key checks between sections, other than the links' load (`links`): values each
//! fine alone that together leave the robot unable to do its job, with the arithmetic.

use std::f64::consts::TAU;

use super::Config;
use super::check::{Checker, Issue, any_rejected, num};
use super::limits::MAX_ENCODER_EDGES_PER_S;

/// Every cross-section issue of `config`.
pub(crate) fn check(config: &Config, issues: &mut Vec<Issue>) {
    if !any_rejected(
        issues,
        &["robot.max_wheel_speed_rad_s", "robot.ticks_per_wheel_rev"],
    ) {
        encoder_rate(config, &mut Checker::new("robot", issues));
    }
    if !any_rejected(
        issues,
        &[
            "robot.max_wheel_speed_rad_s",
            "robot.wheel_diameter_m",
            "navigation.max_speed_m_s",
        ],
    ) {
        top_speed(config, &mut Checker::new("navigation", issues));
    }
    if !any_rejected(
        issues,
        &[
            "localisation.history_steps",
            "mega.control_period_us",
            "lidar.scan_rate_hz",
        ],
    ) {
        history_covers_a_scan(config, &mut Checker::new("localisation", issues));
    }
}

/// The Mega must count every encoder edge at the top wheel speed.
fn encoder_rate(config: &Config, c: &mut Checker<'_>) {
    let robot = &config.robot;
    let (speed, ticks) = (robot.max_wheel_speed_rad_s, robot.ticks_per_wheel_rev);
    if !(speed.is_finite() && ticks.is_finite() && speed > 0.0 && ticks > 0.0) {
        return;
    }
    let edges_per_s = speed * ticks / TAU;
    c.require(
        "max_wheel_speed_rad_s",
        num(speed),
        edges_per_s <= MAX_ENCODER_EDGES_PER_S,
        || {
            format!(
                "the Mega cannot count that fast: {} rad/s × robot.ticks_per_wheel_rev {} / 2π \
                 = {edges_per_s:.0} edges/s per encoder, above the {MAX_ENCODER_EDGES_PER_S:.0} \
                 it counts without loss (firmware-mega/README.md); at most {:.1} rad/s",
                num(speed),
                num(ticks),
                MAX_ENCODER_EDGES_PER_S * TAU / ticks,
            )
        },
    );
}

/// The follower's top speed must be one the wheels can reach.
fn top_speed(config: &Config, c: &mut Checker<'_>) {
    let robot = &config.robot;
    let rim_m_s = robot.max_wheel_speed_rad_s * robot.wheel_radius_m();
    let speed = config.navigation.max_speed_m_s;
    if !(rim_m_s.is_finite() && speed.is_finite()) {
        return;
    }
    c.require("max_speed_m_s", num(speed), speed <= rim_m_s, || {
        format!(
            "faster than the wheels turn: robot.max_wheel_speed_rad_s {} × wheel radius {} m = \
             {rim_m_s:.3} m/s at the rim",
            num(robot.max_wheel_speed_rad_s),
            num(robot.wheel_radius_m()),
        )
    });
}

/// The localiser's history must reach back to the middle of a scan when it arrives, or
/// every scan is counted too late and none is used.
fn history_covers_a_scan(config: &Config, c: &mut Checker<'_>) {
    let steps = config.localisation.history_steps;
    let period_us = config.mega.control_period_us;
    let rate = config.lidar.scan_rate_hz;
    if steps < 2 || period_us == 0 || !(rate.is_finite() && rate > 0.0) {
        return;
    }
    let span_us = (steps as f64 - 1.0) * f64::from(period_us);
    let revolution_us = 1e6 / rate;
    let fewest = (revolution_us / f64::from(period_us)).ceil() as u64 + 1;
    c.require("history_steps", steps, span_us >= revolution_us, || {
        format!(
            "too short to apply a scan: ({steps} − 1) × mega.control_period_us {period_us} µs \
             = {:.0} ms, less than one lidar revolution (1 / lidar.scan_rate_hz {} = {:.0} \
             ms); a scan's middle is half a revolution plus the link's delay old when it \
             arrives. At least {fewest} steps",
            span_us / 1000.0,
            num(rate),
            revolution_us / 1000.0,
        )
    });
}
