//! Beacon extraction: de-skewed scan points (lidar frame at one reference time) → per
//! beacon, the clusters that look like a 9 cm pole, each with its centre as a range–bearing
//! [`Observation`].
//!
//! Per expected beacon: keep the points within a search radius of its predicted centre;
//! split them into clusters of consecutive points (in scan order) closer than
//! `cluster_gap_m`; reject a cluster whose point count does not fit a pole at that range
//! and angular step, whose extent exceeds the diameter plus a margin, or whose points do
//! not lie on a circle of the pole's radius; estimate the centre of the others. The
//! filter then picks, per beacon, the candidate with the smallest Mahalanobis distance.

use nalgebra::{Matrix2, Vector2};

use super::ekf::Observation;
use crate::config::{CentreMethod, LocalisationConfig};
use crate::field::Field;
use crate::field::geometry::{Pose2, Vec2};

/// Gauss–Newton iterations of the circle fit (it converges in 3–5 from the centroid start).
const FIT_ITERATIONS: usize = 10;

/// Where a beacon is expected, in the lidar frame at the reference time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Expected {
    /// Beacon index.
    pub beacon: usize,
    /// Predicted centre, m, lidar frame.
    pub centre: Vec2,
    /// Search radius around it, m.
    pub search_radius_m: f64,
}

/// Every beacon of `field` as seen from a lidar standing at `lidar` (world frame), each to
/// be searched for within `search_radius_m` of where it should be.
pub fn expected_from(field: &Field, lidar: Pose2, search_radius_m: f64) -> Vec<Expected> {
    field
        .beacons()
        .iter()
        .map(|b| Expected {
            beacon: b.index,
            centre: lidar.inverse_transform_point(b.circle.center),
            search_radius_m,
        })
        .collect()
}

/// Why a cluster was not taken for a pole.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rejection {
    /// Fewer points than a pole gives at that range.
    TooFewPoints,
    /// More points than a pole gives at that range.
    TooManyPoints,
    /// Longer than the pole's diameter.
    TooWide,
    /// The points do not lie on a circle of the pole's radius.
    BadFit,
}

/// The clusters found near one expected beacon.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BeaconClusters {
    /// Pole-like clusters, as observations.
    pub candidates: Vec<Observation>,
    /// The other clusters and why.
    pub rejected: Vec<Rejection>,
}

/// A pole's centre estimated from its points, lidar frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CentreEstimate {
    /// Centre, m.
    pub centre: Vec2,
    /// Covariance of the centre (Cartesian), m².
    pub covariance: Matrix2<f64>,
    /// RMS distance of the points to the circle, m.
    pub fit_rms_m: f64,
}

/// Points a pole of radius `radius_m` whose centre is `centre_range_m` away gives with
/// rays `step_rad` apart (its angular width over the step).
pub fn expected_points(centre_range_m: f64, radius_m: f64, step_rad: f64) -> f64 {
    if centre_range_m <= radius_m || step_rad <= 0.0 {
        return 0.0;
    }
    2.0 * (radius_m / centre_range_m).asin() / step_rad
}

/// The clusters near each expected beacon among `points` (lidar frame, scan order) taken
/// at `times_us` (µs, any common origin; missing times count as 0), `step_rad` the angle
/// between rays, `radius_m` the poles' radius.
pub fn extract(
    points: &[Vec2],
    times_us: &[f64],
    expected: &[Expected],
    step_rad: f64,
    radius_m: f64,
    config: &LocalisationConfig,
) -> Vec<BeaconClusters> {
    expected
        .iter()
        .map(|e| {
            let mut out = BeaconClusters::default();
            for indices in clusters_near(points, e, config.cluster_gap_m) {
                let cluster: Vec<Vec2> = indices.iter().map(|&i| points[i]).collect();
                match judge(&cluster, step_rad, radius_m, config) {
                    Ok(estimate) => {
                        let time_sum: f64 = indices
                            .iter()
                            .map(|&i| times_us.get(i).copied().unwrap_or(0.0))
                            .sum();
                        let mut obs = observation(e.beacon, &estimate, cluster.len(), config);
                        obs.time_us = time_sum / cluster.len() as f64;
                        out.candidates.push(obs);
                    }
                    Err(r) => out.rejected.push(r),
                }
            }
            out
        })
        .collect()
}

/// Runs of consecutive points (as indices) within the search circle, split at gaps; the
/// scan's first and last runs are joined when they meet across the revolution's seam.
fn clusters_near(points: &[Vec2], e: &Expected, gap_m: f64) -> Vec<Vec<usize>> {
    let mut clusters: Vec<Vec<usize>> = Vec::new();
    let mut current: Vec<usize> = Vec::new();
    let mut first_starts_at_zero = false;
    for (i, &p) in points.iter().enumerate() {
        let inside = p.distance(e.centre) <= e.search_radius_m;
        let joins = current
            .last()
            .is_some_and(|&q| points[q].distance(p) <= gap_m);
        if (!inside || !joins) && !current.is_empty() {
            clusters.push(std::mem::take(&mut current));
        }
        if inside {
            if current.is_empty() && i == 0 {
                first_starts_at_zero = true;
            }
            current.push(i);
        }
    }
    let last_open = !current.is_empty();
    if last_open {
        clusters.push(current);
    }
    if last_open && first_starts_at_zero && clusters.len() > 1 {
        let seam_joins = match (clusters.last().and_then(|c| c.last()), clusters[0].first()) {
            (Some(&a), Some(&b)) => points[a].distance(points[b]) <= gap_m,
            _ => false,
        };
        if seam_joins {
            let first = clusters.remove(0);
            if let Some(last) = clusters.last_mut() {
                last.extend(first);
            }
        }
    }
    clusters
}

/// Accept or reject one cluster; the centre when accepted.
fn judge(
    cluster: &[Vec2],
    step_rad: f64,
    radius_m: f64,
    config: &LocalisationConfig,
) -> Result<CentreEstimate, Rejection> {
    let n = cluster.len();
    let estimate = match config.centre_method {
        CentreMethod::CircleFit => circle_fit(cluster, radius_m, config.range_noise_std_m),
        CentreMethod::Centroid => None,
    }
    .unwrap_or_else(|| centroid_pushed(cluster, radius_m, config.range_noise_std_m));
    let expected = expected_points(estimate.centre.norm(), radius_m, step_rad);
    let min = (config.min_point_fraction * expected)
        .floor()
        .max(config.min_points as f64);
    if (n as f64) < min {
        return Err(Rejection::TooFewPoints);
    }
    if n as f64 > config.max_point_factor * expected + 2.0 {
        return Err(Rejection::TooManyPoints);
    }
    let extent = match (cluster.first(), cluster.last()) {
        (Some(&a), Some(&b)) => a.distance(b),
        _ => 0.0,
    };
    if extent > 2.0 * radius_m + config.extent_margin_m {
        return Err(Rejection::TooWide);
    }
    if n >= 3 && estimate.fit_rms_m > config.max_fit_rms_m {
        return Err(Rejection::BadFit);
    }
    Ok(estimate)
}

fn observation(
    beacon: usize,
    estimate: &CentreEstimate,
    points: usize,
    config: &LocalisationConfig,
) -> Observation {
    let c = estimate.centre;
    let d2 = c.dot(c);
    let d = d2.sqrt();
    // d(range, bearing)/d(centre).
    let j = Matrix2::new(c.x / d, c.y / d, -c.y / d2, c.x / d2);
    let floor_b = config.bearing_floor_std_deg.to_radians();
    let floor = Matrix2::from_diagonal(&Vector2::new(
        config.range_floor_std_m * config.range_floor_std_m,
        floor_b * floor_b,
    ));
    Observation {
        beacon,
        range_m: d,
        bearing_rad: c.y.atan2(c.x),
        covariance: j * estimate.covariance * j.transpose() + floor,
        points,
        time_us: 0.0,
    }
}

/// The original's centre: the centroid pushed away from the lidar by the radius, with the
/// covariance of a mean of `n` points of `range_std_m` noise.
pub fn centroid_pushed(points: &[Vec2], radius_m: f64, range_std_m: f64) -> CentreEstimate {
    let n = points.len().max(1) as f64;
    let sum = points.iter().fold(Vec2::ZERO, |a, &p| a + p);
    let mean = sum * (1.0 / n);
    let centre = if mean.norm() > 0.0 {
        mean + mean * (radius_m / mean.norm())
    } else {
        mean
    };
    CentreEstimate {
        centre,
        covariance: Matrix2::identity() * (range_std_m * range_std_m / n),
        fit_rms_m: rms_to_circle(points, centre, radius_m),
    }
}

/// Least-squares circle of known radius through `points` (Gauss–Newton on
/// Σ(|pᵢ − c| − r)², started from [`centroid_pushed`], so the centre lies behind the points
/// as seen from the lidar), with the covariance of range noise `range_std_m` along the
/// rays (see the body). `None` when the problem is singular
/// (fewer than 2 points) or does not converge to a finite centre.
pub fn circle_fit(points: &[Vec2], radius_m: f64, range_std_m: f64) -> Option<CentreEstimate> {
    if points.len() < 2 {
        return None;
    }
    let mut c = centroid_pushed(points, radius_m, range_std_m).centre;
    let mut jtj = Matrix2::zeros();
    for _ in 0..FIT_ITERATIONS {
        jtj = Matrix2::zeros();
        let mut jtr = Vector2::zeros();
        for &p in points {
            let v = p - c;
            let dist = v.norm();
            if dist < 1e-12 {
                continue;
            }
            let row = Vector2::new(-v.x / dist, -v.y / dist);
            jtj += row * row.transpose();
            jtr += row * (dist - radius_m);
        }
        let step = jtj.try_inverse()? * -jtr;
        c += Vec2::new(step.x, step.y);
        if step.norm() < 1e-9 {
            break;
        }
    }
    // The points' noise is along their rays: a range error ε moves point i's residual by
    // ε·(uᵢ·nᵢ) (uᵢ the ray, nᵢ the circle's normal), small at the pole's edges. Covariance
    // of the unweighted fit: A⁻¹ (Σ Jᵢᵀ Jᵢ σ²(uᵢ·nᵢ)²) A⁻¹, A = JᵀJ.
    let a_inv = jtj.try_inverse()?;
    let mut middle = Matrix2::zeros();
    for &p in points {
        let (v, norm) = (p - c, p.norm());
        let dist = v.norm();
        if dist < 1e-12 || norm < 1e-12 {
            continue;
        }
        let row = Vector2::new(-v.x / dist, -v.y / dist);
        let along = p.dot(v) / (norm * dist) * range_std_m;
        middle += row * row.transpose() * (along * along);
    }
    let covariance = a_inv * middle * a_inv;
    c.is_finite().then(|| CentreEstimate {
        centre: c,
        covariance,
        fit_rms_m: rms_to_circle(points, c, radius_m),
    })
}

fn rms_to_circle(points: &[Vec2], centre: Vec2, radius_m: f64) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let sum: f64 = points
        .iter()
        .map(|&p| (p.distance(centre) - radius_m).powi(2))
        .sum();
    (sum / points.len() as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;

    const R: f64 = 0.045;
    const STEP: f64 = 0.5 * std::f64::consts::PI / 180.0;

    /// Points of a circle seen from the origin, rays `STEP` apart, with range noise.
    fn arc(circle_centre: Vec2, radius_m: f64, noise_m: f64, rng: &mut SimRng) -> Vec<Vec2> {
        let mut out = Vec::new();
        let bearing = circle_centre.angle();
        for k in -100..=100 {
            let dir = Vec2::from_angle(bearing + f64::from(k) * STEP + 0.3 * STEP);
            let circle = crate::field::geometry::Circle::new(circle_centre, radius_m);
            if let Some(t) = circle.ray_intersection(Vec2::ZERO, dir) {
                out.push(dir * (t + rng.normal(noise_m)));
            }
        }
        out
    }

    fn expected_at(c: Vec2) -> Expected {
        Expected {
            beacon: 0,
            centre: c,
            search_radius_m: 0.15,
        }
    }

    #[test]
    fn circle_fit_recovers_the_centre_without_noise_and_centroid_is_biased() {
        let mut rng = SimRng::new(3);
        let c = Vec2::new(1.2, 0.4);
        let pts = arc(c, R, 0.0, &mut rng);
        let fit = circle_fit(&pts, R, 0.01).unwrap();
        assert!(fit.centre.distance(c) < 1e-9, "{:?}", fit.centre);
        let cen = centroid_pushed(&pts, R, 0.01);
        // The centroid of the near arc is less than r from the centre: pushed by r it
        // overshoots, away from the lidar (by 8.7 mm here, a fifth of the radius).
        assert!(cen.centre.norm() > c.norm() + 0.005, "{:?}", cen.centre);
    }

    /// Measure both centre methods on simulated noisy poles at 0.3–2 m. Prints a table:
    /// `cargo test -p ratf-host --lib localisation::beacons::tests::centre_methods -- --nocapture`
    #[test]
    fn centre_methods_compared_on_noisy_poles() {
        let mut rng = SimRng::new(11);
        println!(
            "range_m  circle_fit_mean_err_m  centroid_mean_err_m  (σ_r = 0.01 m, 500 poles each)"
        );
        let mut fit_total = 0.0;
        let mut cen_total = 0.0;
        for &range in &[0.3, 0.5, 0.75, 1.0, 1.5, 2.0] {
            let (mut fit_err, mut cen_err) = (0.0, 0.0);
            let trials = 500;
            for t in 0..trials {
                let c = Vec2::from_angle(f64::from(t) * 0.37) * range;
                let pts = arc(c, R, 0.01, &mut rng);
                let fit = circle_fit(&pts, R, 0.01).map_or(c * 100.0, |f| f.centre);
                fit_err += fit.distance(c);
                cen_err += centroid_pushed(&pts, R, 0.01).centre.distance(c);
            }
            let (f, e) = (fit_err / f64::from(trials), cen_err / f64::from(trials));
            println!("{range:7.2}  {f:21.4}  {e:19.4}");
            fit_total += f;
            cen_total += e;
        }
        assert!(
            fit_total < cen_total,
            "circle fit {fit_total} vs centroid {cen_total}"
        );
    }

    #[test]
    fn a_pole_is_accepted_and_a_wall_and_a_lone_point_are_rejected() {
        let config = LocalisationConfig::default();
        let mut rng = SimRng::new(5);
        let c = Vec2::new(1.0, 0.2);
        let pole = arc(c, R, 0.003, &mut rng);
        let found = extract(&pole, &[], &[expected_at(c)], STEP, R, &config);
        assert_eq!(found[0].candidates.len(), 1, "{:?}", found[0]);
        assert!((found[0].candidates[0].range_m - c.norm()).abs() < 0.01);
        // A wall segment through the same place: too many points / too wide.
        let wall: Vec<Vec2> = (-30..=30)
            .map(|k| {
                let dir = Vec2::from_angle(c.angle() + f64::from(k) * STEP);
                dir * (0.98 / dir.x)
            })
            .collect();
        let found = extract(&wall, &[], &[expected_at(c)], STEP, R, &config);
        assert!(found[0].candidates.is_empty() && !found[0].rejected.is_empty());
        // A single stray point (the original would take it for the beacon).
        let found = extract(&[c * 0.97], &[], &[expected_at(c)], STEP, R, &config);
        assert_eq!(found[0].rejected, [Rejection::TooFewPoints]);
        // A wide (0.25 m) box face seen edge on near the beacon is too wide.
        let table: Vec<Vec2> = (0..12)
            .map(|k| c * 0.95 + Vec2::new(0.0, 0.02 * f64::from(k) - 0.1))
            .collect();
        let found = extract(&table, &[], &[expected_at(c)], STEP, R, &config);
        assert!(found[0].candidates.is_empty(), "{:?}", found[0]);
    }

    #[test]
    fn clusters_split_at_gaps_and_join_across_the_seam() {
        let e = expected_at(Vec2::new(1.0, 0.0));
        let a = [Vec2::new(0.96, 0.0), Vec2::new(0.96, 0.01)];
        let far = Vec2::new(3.0, 0.0);
        let b = [Vec2::new(0.96, -0.02), Vec2::new(0.96, -0.01)];
        // Scan order: a, far, b (b at the end, a at the start: one pole across the seam).
        let pts = [a[0], a[1], far, b[0], b[1]];
        let clusters = clusters_near(&pts, &e, 0.04);
        assert_eq!(clusters.len(), 1, "{clusters:?}");
        assert_eq!(clusters[0].len(), 4);
        let pts = [a[0], a[1], far, Vec2::new(0.9, 0.1)];
        assert_eq!(clusters_near(&pts, &e, 0.04).len(), 1 + 1);
    }
}
