//! Finding the beacons again once the filter is lost: which of a scan's candidates to take.
//!
//! After [`Localiser`](super::Localiser) has gone `relock_after_scans` scans without a
//! beacon, its pose covariance is raised to the reset values around a mean that may be
//! 20° or 10 cm off (a Mega unplugged in a turn with the IMU dead freezes the estimate while
//! the robot turns on). The search regions are then wide enough to hold clutter beside the
//! poles, and the sequential update, taking each beacon's candidate nearest the prediction
//! in turn, can lock onto a wrong one: traced on the fault bench, a scan whose two
//! beacons were taken (the other two gated) moved the estimate 27 cm and 16° further from
//! the truth with σθ 0.2°, and the filter then tracked the wrong clusters for seconds.
//!
//! So a lost filter takes a scan's beacons only when they fix the pose on their own
//! ([`unique_fix`]): three or more beacons whose observations agree on one pose (the
//! residual of their least-squares fit within the χ² 99 % quantile), with no other choice
//! of candidates, as many beacons, that agrees on a different pose.

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3, Vector4};

use super::chi2_99;
use super::ekf::{Observation, predicted_measurement};
use crate::field::Beacon;
use crate::field::geometry::{Pose2, wrap_angle};

/// Fewest beacons that fix the pose with a residual to check: three (six measurements for
/// three unknowns); two fit any pose near them exactly.
pub const MIN_FIX_BEACONS: usize = 3;

/// Candidates per beacon considered, the nearest to the prediction first: a bound on the
/// choices tried (5⁴ = 625 at most), far above the one or two a pole and its clutter give.
const MAX_CANDIDATES_PER_BEACON: usize = 4;

/// Gauss–Newton iterations of a fix from the prediction (20° off converges in 4–5).
const FIT_ITERATIONS: usize = 10;

/// Two fixes closer than this in position, m, and [`SAME_FIX_HEADING_RAD`] in heading, are
/// the same fix (a pole seen twice, a centre estimated two ways): 2 cm, twice the range
/// noise of one observation.
const SAME_FIX_POSITION_M: f64 = 0.02;

/// See [`SAME_FIX_POSITION_M`]: 1°, about what 2 cm is at the beacons' typical 1.2 m.
const SAME_FIX_HEADING_RAD: f64 = 1.0_f64.to_radians();

/// A pose the chosen candidates agree on.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Fix {
    /// The fitted pose (x, y, θ), m and rad, world frame.
    pose: Vector3<f64>,
    /// Weighted squared residual about it.
    residual_chi2: f64,
}

/// Per beacon, the candidate to take (an index into that beacon's candidates), when a scan's
/// candidates fix the pose on their own and unambiguously; `None` otherwise. `candidates`
/// are per beacon, in the order of `beacons`; `prediction` is the lost filter's pose (the
/// fit's start); `mount` the lidar on the robot.
pub fn unique_fix(
    prediction: Pose2,
    candidates: &[Vec<Observation>],
    beacons: &[Beacon; 4],
    mount: Pose2,
) -> Option<[Option<usize>; 4]> {
    let start = Vector3::new(prediction.x, prediction.y, prediction.yaw_rad);
    // Every choice whose beacons agree, with how many beacons it takes.
    let agreeing: Vec<(usize, [Option<usize>; 4], Fix)> = choices(candidates)
        .into_iter()
        .filter_map(|choice| {
            let chosen: Vec<(&Observation, &Beacon)> = choice
                .iter()
                .zip(candidates)
                .zip(beacons)
                .filter_map(|((pick, obs), beacon)| pick.map(|i| (&obs[i], beacon)))
                .collect();
            if chosen.len() < MIN_FIX_BEACONS {
                return None;
            }
            let fix = fit(start, &chosen, mount)?;
            (fix.residual_chi2 <= chi2_99(2 * chosen.len() - 3)).then_some((
                chosen.len(),
                choice,
                fix,
            ))
        })
        .collect();
    let most = agreeing.iter().map(|(count, _, _)| *count).max()?;
    let widest: Vec<&(usize, [Option<usize>; 4], Fix)> = agreeing
        .iter()
        .filter(|(count, _, _)| *count == most)
        .collect();
    let (_, choice, fix) = widest
        .iter()
        .min_by(|a, b| a.2.residual_chi2.total_cmp(&b.2.residual_chi2))?;
    widest
        .iter()
        .all(|(_, _, other)| same_fix(fix, other))
        .then_some(*choice)
}

/// Every choice of at most one candidate per beacon (by index, the first
/// [`MAX_CANDIDATES_PER_BEACON`] of each).
fn choices(candidates: &[Vec<Observation>]) -> Vec<[Option<usize>; 4]> {
    let mut out = vec![[None; 4]];
    for (b, obs) in candidates.iter().enumerate().take(4) {
        let n = obs.len().min(MAX_CANDIDATES_PER_BEACON);
        out = out
            .into_iter()
            .flat_map(|choice| {
                (0..=n).map(move |k| {
                    let mut next = choice;
                    next[b] = k.checked_sub(1);
                    next
                })
            })
            .collect();
    }
    out
}

fn same_fix(a: &Fix, b: &Fix) -> bool {
    let d = a.pose - b.pose;
    Vector2::new(d.x, d.y).norm() <= SAME_FIX_POSITION_M
        && wrap_angle(d.z).abs() <= SAME_FIX_HEADING_RAD
}

/// The pose the observations agree on, by Gauss–Newton on (x, y, θ) from `start` weighted
/// by each observation's covariance; `None` for a singular geometry.
fn fit(start: Vector3<f64>, chosen: &[(&Observation, &Beacon)], mount: Pose2) -> Option<Fix> {
    let weights: Vec<Matrix2<f64>> = chosen
        .iter()
        .map(|(obs, _)| obs.covariance.try_inverse())
        .collect::<Option<_>>()?;
    let mut pose = start;
    let mut residual_chi2 = f64::INFINITY;
    for _ in 0..FIT_ITERATIONS {
        let mean = Vector4::new(pose.x, pose.y, pose.z, 0.0);
        let mut information = Matrix3::zeros();
        let mut projected = Vector3::zeros();
        residual_chi2 = 0.0;
        for ((obs, beacon), w) in chosen.iter().zip(&weights) {
            let (h, jac) = predicted_measurement(&mean, beacon.circle.center, mount)?;
            let nu = Vector2::new(obs.range_m - h.x, wrap_angle(obs.bearing_rad - h.y));
            let j = jac.fixed_view::<2, 3>(0, 0).into_owned();
            information += j.transpose() * w * j;
            projected += j.transpose() * w * nu;
            residual_chi2 += (nu.transpose() * w * nu)[(0, 0)];
        }
        let step = information.try_inverse()? * projected;
        pose += step;
        pose.z = wrap_angle(pose.z);
        if step.norm() < 1e-9 {
            break;
        }
    }
    residual_chi2.is_finite().then_some(Fix {
        pose,
        residual_chi2,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Field;

    /// The lidar's mount on the robot, as in the default config (0.07 m ahead, turned 172°).
    fn mount() -> Pose2 {
        Pose2::new(0.07, 0.0, 172.0_f64.to_radians())
    }

    /// What a lidar on a robot at `truth` measures of `beacon`'s centre (no noise), shifted
    /// sideways by `offset_m` in the lidar frame.
    fn seen(truth: Pose2, beacon: &Beacon, offset_m: f64) -> Observation {
        let mean = Vector4::new(truth.x, truth.y, truth.yaw_rad, 0.0);
        let (h, _) = predicted_measurement(&mean, beacon.circle.center, mount()).unwrap();
        Observation {
            beacon: beacon.index,
            range_m: h.x,
            bearing_rad: h.y + offset_m / h.x,
            covariance: Matrix2::new(0.008_f64.powi(2), 0.0, 0.0, 0.3_f64.to_radians().powi(2)),
            points: 8,
            time_us: 0.0,
        }
    }

    fn truth() -> Pose2 {
        Pose2::new(-0.01, -0.03, -26.4_f64.to_radians())
    }

    /// Per beacon, one candidate: where the lidar at [`truth`] sees it.
    fn every_beacon_seen_from_the_truth(beacons: &[Beacon; 4]) -> Vec<Vec<Observation>> {
        beacons
            .iter()
            .map(|b| vec![seen(truth(), b, 0.0)])
            .collect()
    }

    /// The lost estimate of the trace in this module's doc: 6 cm and 20° off.
    fn lost() -> Pose2 {
        Pose2::new(-0.017, 0.027, -6.0_f64.to_radians())
    }

    #[test]
    fn three_beacons_that_agree_fix_the_pose_from_20_degrees_off() {
        let field = Field::competition();
        let beacons = field.beacons();
        let mut candidates = every_beacon_seen_from_the_truth(beacons);
        candidates[1].clear();
        let choice = unique_fix(lost(), &candidates, beacons, mount()).expect("a fix");
        assert_eq!(choice, [Some(0), None, Some(0), Some(0)]);
        let chosen: Vec<_> = [0, 2, 3]
            .iter()
            .map(|&b| (&candidates[b][0], &beacons[b]))
            .collect();
        let fix = fit(
            Vector3::new(lost().x, lost().y, lost().yaw_rad),
            &chosen,
            mount(),
        )
        .unwrap();
        assert!((fix.pose - Vector3::new(truth().x, truth().y, truth().yaw_rad)).norm() < 1e-6);
    }

    #[test]
    fn two_beacons_do_not_fix_a_lost_pose() {
        let field = Field::competition();
        let beacons = field.beacons();
        let mut candidates = every_beacon_seen_from_the_truth(beacons);
        candidates[1].clear();
        candidates[2].clear();
        assert_eq!(unique_fix(lost(), &candidates, beacons, mount()), None);
    }

    #[test]
    fn a_ghost_beside_a_pole_is_left_out_of_the_fix() {
        let field = Field::competition();
        let beacons = field.beacons();
        let mut candidates = every_beacon_seen_from_the_truth(beacons);
        // A leg 25 cm beside beacon 0, listed first.
        candidates[0].insert(0, seen(truth(), &beacons[0], 0.25));
        let choice = unique_fix(lost(), &candidates, beacons, mount()).expect("a fix");
        assert_eq!(choice, [Some(1), Some(0), Some(0), Some(0)]);
    }

    #[test]
    fn observations_that_disagree_fix_nothing() {
        let field = Field::competition();
        let beacons = field.beacons();
        let candidates: Vec<Vec<Observation>> = beacons
            .iter()
            .zip([0.0, 0.3, -0.3, 0.3])
            .map(|(b, offset)| vec![seen(truth(), b, offset)])
            .collect();
        assert_eq!(unique_fix(lost(), &candidates, beacons, mount()), None);
    }

    #[test]
    fn two_choices_that_agree_on_different_poses_are_ambiguous() {
        let field = Field::competition();
        let beacons = field.beacons();
        let elsewhere = Pose2::new(0.1, 0.05, -10.0_f64.to_radians());
        // Three beacons seen from the truth, and another three (sharing none of their
        // candidates) from elsewhere.
        let mut candidates: Vec<Vec<Observation>> = beacons
            .iter()
            .map(|b| vec![seen(truth(), b, 0.0), seen(elsewhere, b, 0.0)])
            .collect();
        candidates[0].truncate(1);
        candidates[3].remove(0);
        assert_eq!(unique_fix(lost(), &candidates, beacons, mount()), None);
    }
}
