//! A velocity script driven closed loop on the localiser's estimate: the script's twist, plus
//! a correction towards where the script would have taken a robot whose wheels do what it
//! believes, once the estimate is further from that than the drive's clearance allows.
//!
//! Why: an open-loop script drifts by what the wheels get wrong, which is what the odometry
//! drive is there to measure. In the harsh world its strafes fall 15 % short and its legs
//! add up, so the drive touched the field in most worlds and the collisions spoilt the legs
//! it fits (`calibrate odometry --world harsh --seed 61 --seeds 30`: 131 collisions, the
//! wheel radius 6.6 % off on average and 43 % at worst; closed loop: none, 0.11 % and
//! 0.25 %). Within [`DEADBAND_M`] and [`DEADBAND_RAD`] of the plan nothing is corrected,
//! so a drive that keeps to its plan drives the script's own legs (forward legs with no
//! strafe in them, and the other way round, which is how the fit tells the rollers' strafe
//! factor from the wheel radius). At rest (the script's stops) nothing is corrected either:
//! the stops' scans must be taken standing.

use ratf_core::field::geometry::{Pose2, Vec2, wrap_angle};
use ratf_core::kinematics::BodyTwist;
use ratf_core::runtime::OperatorCommand;

use super::operator_script::OperatorScript;
use super::scripts::Script;

/// Step of the planned poses' table, s.
const REFERENCE_STEP_S: f64 = 0.005;
/// Error from the plan, per robot-frame axis, left uncorrected, m: the odometry drive is
/// laid out to clear the field by a few centimetres when followed exactly. Chosen on the
/// harsh world's seeds 1–20 and 61–90 with [`DEADBAND_RAD`]: 1 cm (and 1°) touched the
/// field 7 times over 49 drives, 2 cm and 2° 3 times, 2 cm and 1° not at all.
pub const DEADBAND_M: f64 = 0.02;
/// Heading error from the plan left uncorrected, rad (1°): a body turned 2° reaches 5 mm
/// further at its corners.
pub const DEADBAND_RAD: f64 = std::f64::consts::PI / 180.0;
/// Correction per metre (radian) beyond the dead band, 1/s: slow beside the drive's
/// 0.2 m/s legs and 1 rad/s turns, so the correction cannot shake the robot (assumption).
pub const GAIN_PER_S: f64 = 2.0;
/// Largest translation correction, m/s.
pub const MAX_CORRECTION_M_S: f64 = 0.05;
/// Largest rotation correction, rad/s.
pub const MAX_CORRECTION_RAD_S: f64 = 0.2;

/// `script` with its planned poses, driven closed loop on the estimate.
#[derive(Clone, Debug)]
pub struct TrackedScript {
    script: Script,
    /// The planned pose every [`REFERENCE_STEP_S`] from the script's start.
    reference: Vec<Pose2>,
    /// How far the estimate trails the commands, s (see [`TrackedScript::new`]).
    lag_s: f64,
}

impl TrackedScript {
    /// Plan `script`'s poses from its start (its twists integrated). The estimate is held
    /// against the plan of `lag_s` earlier: a robot that does what it is told trails its
    /// commands by the motors' time constant and the telemetry's delay
    /// (`navigation.lag_compensation_s`, 0.12 s: 2.4 cm at the drive's 0.2 m/s), which is
    /// no error to correct.
    pub fn new(script: Script, lag_s: f64) -> Self {
        let steps = (script.duration_s() / REFERENCE_STEP_S).ceil() as usize + 1;
        let mut reference = Vec::with_capacity(steps);
        let mut pose = script.start;
        for k in 0..steps {
            reference.push(pose);
            // The twist at the step's middle, applied over the step.
            let t = script.twist_at((k as f64 + 0.5) * REFERENCE_STEP_S);
            let half = Pose2::new(0.0, 0.0, 0.5 * t.omega_rad_s * REFERENCE_STEP_S);
            let shift = Vec2::new(t.vx_m_s, t.vy_m_s) * REFERENCE_STEP_S;
            pose = pose
                .compose(half)
                .compose(Pose2::new(shift.x, shift.y, 0.0))
                .compose(half);
        }
        Self {
            script,
            reference,
            lag_s: lag_s.max(0.0),
        }
    }

    /// The script.
    pub fn script(&self) -> &Script {
        &self.script
    }

    /// Where the script plans the robot at `seconds` since its start.
    pub fn planned_at(&self, seconds: f64) -> Pose2 {
        let k = (seconds.max(0.0) / REFERENCE_STEP_S).round() as usize;
        self.reference[k.min(self.reference.len() - 1)]
    }

    /// The twist at `seconds` for a robot estimated at `estimate`: the script's, plus the
    /// correction of what lies beyond the dead band (robot frame) of its error from the plan
    /// of the lag earlier.
    pub fn twist_at(&self, seconds: f64, estimate: Option<Pose2>) -> BodyTwist {
        let planned = self.script.twist_at(seconds);
        let at_rest = planned == BodyTwist::default();
        let Some(estimate) = estimate.filter(|_| !at_rest) else {
            return planned;
        };
        let goal = self.planned_at(seconds - self.lag_s);
        let error = estimate.inverse_transform_point(goal.position());
        let heading_error = wrap_angle(goal.yaw_rad - estimate.yaw_rad);
        let beyond = |e: f64, band: f64| e - e.clamp(-band, band);
        let mut v =
            Vec2::new(beyond(error.x, DEADBAND_M), beyond(error.y, DEADBAND_M)) * GAIN_PER_S;
        if v.norm() > MAX_CORRECTION_M_S {
            v = v * (MAX_CORRECTION_M_S / v.norm());
        }
        let omega = (GAIN_PER_S * beyond(heading_error, DEADBAND_RAD))
            .clamp(-MAX_CORRECTION_RAD_S, MAX_CORRECTION_RAD_S);
        BodyTwist::new(
            planned.vx_m_s + v.x,
            planned.vy_m_s + v.y,
            planned.omega_rad_s + omega,
        )
    }
}

impl OperatorScript for TrackedScript {
    fn command_at(&self, seconds: f64) -> OperatorCommand {
        self.command_with(seconds, None)
    }

    fn command_with(&self, seconds: f64, estimate: Option<Pose2>) -> OperatorCommand {
        OperatorCommand::Drive {
            twist: self.twist_at(seconds, estimate),
        }
    }

    fn duration_s(&self) -> f64 {
        self.script.duration_s()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::apps::scripts::odometry_drive;

    #[test]
    fn the_plan_ends_where_the_odometry_drive_is_laid_out_to_end() {
        // The drive goes round its loop, turns a full turn in place and drives up and down
        // one side: it ends at its loop's corner, facing as it started there.
        let (script, _) = odometry_drive();
        let tracked = TrackedScript::new(script, 0.0);
        let end = tracked.planned_at(tracked.duration_s());
        let corner = Pose2::new(-0.64, -0.42, std::f64::consts::FRAC_PI_2);
        assert!(
            (end.position() - corner.position()).norm() < 1e-3,
            "ends at {end:?}"
        );
        assert!(wrap_angle(end.yaw_rad - corner.yaw_rad).abs() < 1e-3);
    }

    #[test]
    fn on_the_plan_it_drives_the_script_and_off_it_it_steers_back() {
        let (script, _) = odometry_drive();
        let tracked = TrackedScript::new(script.clone(), 0.0);
        // Some time into the first leg up the loop's right side (robot frame: forward).
        let t = (1..4000)
            .map(|k| k as f64 * 0.01)
            .find(|&t| script.twist_at(t).vx_m_s > 0.19)
            .unwrap();
        let planned = tracked.planned_at(t);
        assert_eq!(tracked.twist_at(t, Some(planned)), script.twist_at(t));
        // 1 cm to the right: within the dead band, nothing corrected.
        let right = planned.compose(Pose2::new(0.0, -0.01, 0.0));
        assert_eq!(tracked.twist_at(t, Some(right)), script.twist_at(t));
        // 4 cm to the right: strafe left by the gain on the 2 cm beyond the band.
        let far_right = planned.compose(Pose2::new(0.0, -0.04, 0.0));
        let twist = tracked.twist_at(t, Some(far_right));
        assert!((twist.vy_m_s - GAIN_PER_S * 0.02).abs() < 1e-9, "{twist:?}");
        assert_eq!(twist.vx_m_s, script.twist_at(t).vx_m_s);
        // Turned 5° to the left: turned back right, capped.
        let turned = planned.compose(Pose2::new(0.0, 0.0, 5f64.to_radians()));
        let twist = tracked.twist_at(t, Some(turned));
        assert!(twist.omega_rad_s < 0.0 && twist.omega_rad_s >= -MAX_CORRECTION_RAD_S);
    }

    #[test]
    fn a_robot_trailing_its_commands_by_the_lag_is_on_the_plan() {
        let (script, _) = odometry_drive();
        let lag_s = 0.12;
        let tracked = TrackedScript::new(script.clone(), lag_s);
        let t = (1..4000)
            .map(|k| k as f64 * 0.01)
            .find(|&t| script.twist_at(t).vx_m_s > 0.19)
            .unwrap();
        let trailing = tracked.planned_at(t - lag_s);
        assert_eq!(tracked.twist_at(t, Some(trailing)), script.twist_at(t));
    }

    #[test]
    fn at_rest_it_corrects_nothing() {
        let (script, windows) = odometry_drive();
        let tracked = TrackedScript::new(script, 0.0);
        let t = windows[0].start_s + 1.0;
        let off = tracked.planned_at(t).compose(Pose2::new(0.1, 0.1, 0.3));
        assert_eq!(tracked.twist_at(t, Some(off)), BodyTwist::default());
    }
}
