//! Free space for the robot's footprint, and free-space shortcuts: the base is holonomic,
//! so wherever the straight line between two path points is clear for the footprint, the
//! points between are skipped.
//!
//! Two checks, both against walls and dividers (rectangles), beacon poles (circles) and
//! standing parts (rectangles the caller passes in), with a margin:
//! * at a fixed heading: the footprint (robot, plus the carried part in front) sampled
//!   every [`SAMPLE_STEP_M`] along the segment at each heading the robot may hold there
//!   (the follower turns only where the whole swept disc is free, see
//!   `control::route`, so on the rest of a route it holds its start or its goal heading);
//! * at any heading: the disc swept by the footprint turning on the spot (the circle of its
//!   farthest corner), for the stretches where the follower may rotate.

use crate::config::RobotConfig;
use crate::field::geometry::{Circle, Pose2, Rect, Vec2, hypot};
use crate::field::stations::pick_standoff_m;
use crate::field::{Field, OrientedRect, PART_DEPTH_M, PART_WIDTH_M};

/// Sampling step along a segment for the fixed-heading check, m. 0.005: a quarter of the
/// thinnest obstacle (the 20 mm dividers), so no obstacle fits between two samples.
pub const SAMPLE_STEP_M: f64 = 0.005;

/// Resolution of [`FreeSpace::first_free_ahead_m`], m. 0.001: the distances are a few
/// centimetres, and the pose estimate is good to a few millimetres.
pub const AHEAD_STEP_M: f64 = 0.001;

/// The robot's outline for clearance checks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// Body length along the robot's x, m.
    pub length_m: f64,
    /// Body width along the robot's y, m.
    pub width_m: f64,
    /// The body's centre in the robot frame (x ahead, y left of the wheels' centre), m.
    pub center_m: Vec2,
    /// From the robot centre to the magnet's face, m: where a carried part's plate stands
    /// (the pick standoff, `config::RobotConfig::pick_standoff_m`).
    pub magnet_m: f64,
    /// A part is held in front: its centre `magnet_m` + [`PART_DEPTH_M`]/2 ahead of the
    /// robot centre (where the magnet holds it at the pick pose).
    pub carrying: bool,
}

impl Footprint {
    /// The outline `robot` believes it has (its measured body and magnet), carrying a part
    /// or not.
    pub fn of_robot(robot: &RobotConfig, carrying: bool) -> Self {
        Self {
            length_m: robot.footprint_length_m,
            width_m: robot.footprint_width_m,
            center_m: Vec2::new(robot.body_center_x_m, robot.body_center_y_m),
            magnet_m: robot.pick_standoff_m(),
            carrying,
        }
    }

    /// A body `length_m` × `width_m` centred on the wheels, its magnet 15 mm proud of its
    /// front face ([`pick_standoff_m`]; the default robot's outline at 0.30 × 0.30 m).
    pub fn centred(length_m: f64, width_m: f64, carrying: bool) -> Self {
        Self {
            length_m,
            width_m,
            center_m: Vec2::ZERO,
            magnet_m: pick_standoff_m(length_m / 2.0),
            carrying,
        }
    }

    /// The rectangles it covers at `pose`: the body, then the part if carried.
    pub fn rects_at(&self, pose: Pose2, margin_m: f64) -> Vec<OrientedRect> {
        let grow = 2.0 * margin_m;
        let body = pose.compose(Pose2::new(self.center_m.x, self.center_m.y, 0.0));
        let mut rects = vec![OrientedRect::new(
            body,
            self.length_m + grow,
            self.width_m + grow,
        )];
        if self.carrying {
            let part = pose.compose(Pose2::new(self.part_ahead_m(), 0.0, 0.0));
            rects.push(OrientedRect::new(
                part,
                PART_DEPTH_M + grow,
                PART_WIDTH_M + grow,
            ));
        }
        rects
    }

    /// From the robot centre to the centre of a part the magnet holds, m.
    pub fn part_ahead_m(&self) -> f64 {
        self.magnet_m + PART_DEPTH_M / 2.0
    }

    /// From the robot centre to the far face of a part the magnet holds, m.
    pub fn part_reach_m(&self) -> f64 {
        self.magnet_m + PART_DEPTH_M
    }

    /// From the robot centre to the body's back face, m (a distance behind it).
    pub fn back_m(&self) -> f64 {
        self.length_m / 2.0 - self.center_m.x
    }

    /// Radius of the disc it sweeps turning on the spot, m: the body's farthest corner
    /// (√(0.15² + 0.15²) = 0.212 m for a centred 30 × 30 cm), or the carried part's far
    /// corner (√(0.225² + 0.045²) = 0.229 m) if larger.
    pub fn sweep_radius_m(&self) -> f64 {
        let body = hypot(
            self.center_m.x.abs() + self.length_m / 2.0,
            self.center_m.y.abs() + self.width_m / 2.0,
        );
        if self.carrying {
            body.max(hypot(self.part_reach_m(), PART_WIDTH_M / 2.0))
        } else {
            body
        }
    }
}

/// What the footprint must not touch.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeSpace {
    rects: Vec<Rect>,
    circles: Vec<Circle>,
    footprint: Footprint,
    margin_m: f64,
}

/// True when the circle overlaps the oriented rectangle.
fn circle_hits(rect: &OrientedRect, circle: Circle) -> bool {
    let local = rect.pose.inverse_transform_point(circle.center);
    let nearest = Vec2::new(
        local.x.clamp(-rect.half_x_m, rect.half_x_m),
        local.y.clamp(-rect.half_y_m, rect.half_y_m),
    );
    nearest.distance(local) < circle.radius_m
}

impl FreeSpace {
    /// The field's walls, dividers and beacons plus `parts` (footprints of standing parts),
    /// for `footprint` grown by `margin_m` on every side.
    pub fn new(field: &Field, parts: &[Rect], footprint: Footprint, margin_m: f64) -> Self {
        let mut rects: Vec<Rect> = field.obstacles().iter().map(|o| o.rect).collect();
        rects.extend_from_slice(parts);
        Self {
            rects,
            circles: field.beacons().iter().map(|b| b.circle).collect(),
            footprint,
            margin_m,
        }
    }

    /// A floor with nothing on it, for tests of logic that must not meet the field's walls.
    #[cfg(test)]
    pub(crate) fn empty(footprint: Footprint, margin_m: f64) -> Self {
        Self::with_walls(Vec::new(), footprint, margin_m)
    }

    /// A floor with only `walls` on it, for tests of logic near one wall.
    #[cfg(test)]
    pub(crate) fn with_walls(walls: Vec<Rect>, footprint: Footprint, margin_m: f64) -> Self {
        Self {
            rects: walls,
            circles: Vec::new(),
            footprint,
            margin_m,
        }
    }

    /// Distance from `p` to the nearest obstacle, m.
    pub fn clearance_m(&self, p: Vec2) -> f64 {
        let rects = self.rects.iter().map(|r| r.distance_to_point(p));
        let circles = self
            .circles
            .iter()
            .map(|c| c.center.distance(p) - c.radius_m);
        rects.chain(circles).fold(f64::INFINITY, f64::min)
    }

    /// True when the robot can turn on the spot at `p` (its swept disc plus the margin is
    /// clear).
    pub fn can_turn_at(&self, p: Vec2) -> bool {
        self.clearance_m(p) > self.footprint.sweep_radius_m() + self.margin_m
    }

    /// True when the footprint (grown by the margin) at `pose` touches nothing.
    pub fn pose_is_free(&self, pose: Pose2) -> bool {
        self.pose_is_free_with(pose, self.margin_m)
    }

    fn pose_is_free_with(&self, pose: Pose2, margin_m: f64) -> bool {
        self.footprint.rects_at(pose, margin_m).iter().all(|body| {
            self.rects.iter().all(|&r| !body.overlaps_rect(r))
                && self.circles.iter().all(|&c| !circle_hits(body, c))
        })
    }

    /// The gap from the footprint at `pose` (not grown by the margin) to the nearest
    /// obstacle, m, at most `cap_m`: 0 when it touches or overlaps one. Obstacles farther
    /// than the cap from a piece's circumscribed circle are not measured.
    pub fn pose_clearance_m(&self, pose: Pose2, cap_m: f64) -> f64 {
        let mut least = cap_m;
        for piece in self.footprint.rects_at(pose, 0.0) {
            let centre = piece.pose.position();
            let reach_m = piece.circumradius_m();
            for rect in &self.rects {
                if rect.distance_to_point(centre) >= reach_m + least {
                    continue;
                }
                least = least.min(piece.distance_to(&OrientedRect::from_rect(*rect)));
                if least <= 0.0 {
                    return 0.0;
                }
            }
            for circle in &self.circles {
                least =
                    least.min((piece.distance_to_point(circle.center) - circle.radius_m).max(0.0));
            }
        }
        least
    }

    /// The gap from the disc the footprint sweeps turning on the spot at `p` to the nearest
    /// obstacle, m, at most `cap_m`: 0 when the disc touches or overlaps one.
    pub fn turn_clearance_m(&self, p: Vec2, cap_m: f64) -> f64 {
        (self.clearance_m(p) - self.footprint.sweep_radius_m()).clamp(0.0, cap_m)
    }

    /// The least clearance ([`Self::pose_clearance_m`] holding `yaw_rad`, or
    /// [`Self::turn_clearance_m`] with `yaw_rad` `None`) at samples along the straight line
    /// from `a` to `b` at most [`SAMPLE_STEP_M`] apart, m, at most `cap_m`. Every pose
    /// between two samples is within half a step of one, so keeps at least this less
    /// [`SAMPLE_STEP_M`]` / 2` ([`Self::segment_guaranteed_m`]).
    pub fn segment_clearance_m(&self, a: Vec2, b: Vec2, yaw_rad: Option<f64>, cap_m: f64) -> f64 {
        let steps = (a.distance(b) / SAMPLE_STEP_M).ceil().max(1.0) as usize;
        let mut least = cap_m;
        for k in 0..=steps {
            let p = a + (b - a) * (k as f64 / steps as f64);
            let here = match yaw_rad {
                Some(yaw) => self.pose_clearance_m(Pose2::new(p.x, p.y, yaw), least),
                None => self.turn_clearance_m(p, least),
            };
            least = least.min(here);
            if least <= 0.0 {
                break;
            }
        }
        least
    }

    /// The clearance every pose of a straight line keeps whose samples keep
    /// `sampled_m` ([`Self::segment_clearance_m`]), m: half a step less (negative: it may
    /// touch).
    pub fn segment_guaranteed_m(sampled_m: f64) -> f64 {
        sampled_m - SAMPLE_STEP_M / 2.0
    }

    /// The least distance straight ahead of `from`, along its heading and holding it, at
    /// which the footprint (grown by the margin) is free, m: a multiple of [`AHEAD_STEP_M`]
    /// up to `up_to_m` (0 when `from` itself is free), or `None` when no pose up to there is.
    /// For a start backed off from where the robot stood, moved on until it is clear.
    pub fn first_free_ahead_m(&self, from: Pose2, up_to_m: f64) -> Option<f64> {
        let steps = (up_to_m.max(0.0) / AHEAD_STEP_M).ceil() as usize;
        (0..=steps)
            .map(|k| (k as f64 * AHEAD_STEP_M).min(up_to_m.max(0.0)))
            .find(|&d| self.pose_is_free(from.compose(Pose2::new(d, 0.0, 0.0))))
    }

    /// How far the footprint, grown by `margin_m` instead of the space's margin, can
    /// reverse straight from `from`, along its heading and holding it, touching nothing on
    /// the way, m: a multiple of [`AHEAD_STEP_M`] up to `up_to_m`, 0 when `from` itself is
    /// not free. For a reverse off a part found on the floor, kept short of the walls behind.
    pub fn free_reverse_m(&self, from: Pose2, up_to_m: f64, margin_m: f64) -> f64 {
        self.free_along_m(from, -1.0, up_to_m, margin_m)
    }

    /// How far the footprint, grown by `margin_m`, can drive straight on from `from`, along
    /// its heading and holding it, touching nothing on the way, m: a multiple of
    /// [`AHEAD_STEP_M`] up to `up_to_m`, 0 when `from` itself is not free. For a press into
    /// a part found before the face, kept short of the dividers beyond it.
    pub fn free_ahead_m(&self, from: Pose2, up_to_m: f64, margin_m: f64) -> f64 {
        self.free_along_m(from, 1.0, up_to_m, margin_m)
    }

    /// [`Self::free_ahead_m`] (`sign` 1) or [`Self::free_reverse_m`] (`sign` −1).
    fn free_along_m(&self, from: Pose2, sign: f64, up_to_m: f64, margin_m: f64) -> f64 {
        let up_to_m = up_to_m.max(0.0);
        let free_at =
            |d: f64| self.pose_is_free_with(from.compose(Pose2::new(sign * d, 0.0, 0.0)), margin_m);
        if !free_at(0.0) {
            return 0.0;
        }
        let steps = (up_to_m / AHEAD_STEP_M).ceil() as usize;
        (1..=steps)
            .map(|k| (k as f64 * AHEAD_STEP_M).min(up_to_m))
            .take_while(|&d| free_at(d))
            .last()
            .unwrap_or(0.0)
    }

    /// True when the footprint can move from `a` to `b` in a straight line holding each one
    /// of `yaws_rad` throughout. Samples are at most [`SAMPLE_STEP_M`] apart and checked
    /// with the footprint grown by half of that on top of the margin, so every pose between
    /// two samples lies inside a checked one.
    pub fn segment_is_free(&self, a: Vec2, b: Vec2, yaws_rad: &[f64]) -> bool {
        self.segment_is_free_with_margin(a, b, yaws_rad, self.margin_m)
    }

    /// The outline it keeps free.
    pub fn footprint(&self) -> Footprint {
        self.footprint
    }

    /// The margin around the footprint, m.
    pub fn margin_m(&self) -> f64 {
        self.margin_m
    }

    /// [`FreeSpace::segment_is_free`] with `margin_m` instead of the space's margin.
    pub fn segment_is_free_with_margin(
        &self,
        a: Vec2,
        b: Vec2,
        yaws_rad: &[f64],
        margin_m: f64,
    ) -> bool {
        let steps = (a.distance(b) / SAMPLE_STEP_M).ceil().max(1.0) as usize;
        let margin_m = margin_m + SAMPLE_STEP_M / 2.0;
        (0..=steps).all(|k| {
            let p = a + (b - a) * (k as f64 / steps as f64);
            yaws_rad
                .iter()
                .all(|&yaw| self.pose_is_free_with(Pose2::new(p.x, p.y, yaw), margin_m))
        })
    }

    /// Greedy shortcutting: from each kept point, jump to the farthest later point joined by
    /// a straight line free at every heading in `yaws_rad`; points between are dropped. The
    /// first and last points are kept; a segment of the input is kept as it is.
    pub fn shortcut(&self, points: &[Vec2], yaws_rad: &[f64]) -> Vec<Vec2> {
        let Some(&first) = points.first() else {
            return Vec::new();
        };
        let mut kept = vec![first];
        let mut i = 0;
        while i + 1 < points.len() {
            let next = (i + 2..points.len())
                .rev()
                .find(|&j| self.segment_is_free(points[i], points[j], yaws_rad))
                .unwrap_or(i + 1);
            kept.push(points[next]);
            i = next;
        }
        kept
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::PICK_STANDOFF_M;
    use proptest::prelude::*;
    use std::f64::consts::FRAC_PI_2;

    const BARE: Footprint = Footprint {
        length_m: 0.30,
        width_m: 0.30,
        center_m: Vec2::ZERO,
        magnet_m: PICK_STANDOFF_M,
        carrying: false,
    };

    fn space(footprint: Footprint, margin_m: f64) -> FreeSpace {
        FreeSpace::new(&Field::competition(), &[], footprint, margin_m)
    }

    #[test]
    fn sweep_radii() {
        assert!((BARE.sweep_radius_m() - 0.2121).abs() < 1e-4);
        let carrying = Footprint {
            carrying: true,
            ..BARE
        };
        assert!((carrying.sweep_radius_m() - 0.2294).abs() < 1e-4);
        assert_eq!(carrying.rects_at(Pose2::default(), 0.0).len(), 2);
    }

    #[test]
    fn a_body_off_the_wheels_centre_covers_its_own_outline_and_holds_the_part_off_its_front() {
        let robot = RobotConfig {
            body_center_x_m: 0.012,
            body_center_y_m: -0.008,
            ..RobotConfig::default()
        };
        let footprint = Footprint::of_robot(&robot, true);
        // Facing +y at (1, 2): the body's centre 12 mm ahead (+y) and 8 mm right (+x).
        let pose = Pose2::new(1.0, 2.0, FRAC_PI_2);
        let rects = footprint.rects_at(pose, 0.0);
        let body = rects[0].pose.position();
        assert!(body.distance(Vec2::new(1.008, 2.012)) < 1e-12, "{body:?}");
        // The magnet 15 mm proud of the front face, 0.162 m ahead: the part's centre 30 mm on.
        assert!((footprint.magnet_m - 0.177).abs() < 1e-12);
        let part = rects[1].pose.position();
        assert!(part.distance(Vec2::new(1.0, 2.207)) < 1e-12, "{part:?}");
        assert!((footprint.back_m() - 0.138).abs() < 1e-12);
        // The farthest body corner: 0.162 ahead, 0.158 to the side.
        assert!(
            (footprint.sweep_radius_m() - hypot(0.162, 0.158).max(hypot(0.237, 0.045))).abs()
                < 1e-12
        );
        // The default robot is the centred 30 cm square.
        let default = Footprint::of_robot(&RobotConfig::default(), true);
        assert_eq!(default, Footprint::centred(0.30, 0.30, true));
    }

    #[test]
    fn a_detour_through_open_floor_is_cut_and_a_wall_is_not_crossed() {
        let s = space(BARE, 0.02);
        let p = |x: f64, y: f64| Vec2::new(x, y);
        // The column left of machine block A: a dip towards it is cut.
        let cut = s.shortcut(&[p(-0.695, 0.15), p(-0.6, 0.0), p(-0.695, -0.15)], &[0.0]);
        assert_eq!(cut, [p(-0.695, 0.15), p(-0.695, -0.15)]);
        // Across machine block A's wall: the detour must stay.
        let around = [p(-0.55, 0.15), p(-0.35, 0.3), p(-0.15, 0.15)];
        assert!(!s.segment_is_free(around[0], around[2], &[0.0]));
        assert_eq!(s.shortcut(&around, &[0.0]).len(), 3);
        // Turning on the spot: in the open column yes, next to a divider no.
        assert!(s.can_turn_at(p(-0.695, 0.0)));
        assert!(!s.can_turn_at(p(-0.545, 0.255)));
    }

    /// The shortcut path of random points, at random headings, carrying or not: every
    /// segment that is not one of the input's keeps the footprint off every obstacle,
    /// checked every millimetre without the margin.
    fn check_no_crossing(
        points: &[Vec2],
        yaws: &[f64],
        footprint: Footprint,
    ) -> Result<(), TestCaseError> {
        let field = Field::competition();
        let s = space(footprint, 0.0);
        let cut = s.shortcut(points, yaws);
        for w in cut.windows(2) {
            if points.windows(2).any(|o| o[0] == w[0] && o[1] == w[1]) {
                continue;
            }
            let steps = (w[0].distance(w[1]) / 0.001).ceil().max(1.0) as usize;
            for k in 0..=steps {
                let at = w[0] + (w[1] - w[0]) * (k as f64 / steps as f64);
                for &yaw in yaws {
                    for body in footprint.rects_at(Pose2::new(at.x, at.y, yaw), 0.0) {
                        for o in field.obstacles() {
                            prop_assert!(
                                !body.overlaps_rect(o.rect),
                                "shortcut {:?} -> {:?} hits {:?} at {:?}",
                                w[0],
                                w[1],
                                o,
                                at
                            );
                        }
                        for b in field.beacons() {
                            prop_assert!(!circle_hits(&body, b.circle));
                        }
                    }
                }
            }
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(40))]

        #[test]
        fn shortcuts_never_cross_an_obstacle(
            coords in proptest::collection::vec((-0.8f64..0.8, -0.55f64..0.55), 2..6),
            yaw_a in -3.2f64..3.2,
            quarter_turns in 0i32..4,
            carrying in proptest::bool::ANY,
        ) {
            let points: Vec<Vec2> = coords.iter().map(|&(x, y)| Vec2::new(x, y)).collect();
            let yaws = [yaw_a, yaw_a + f64::from(quarter_turns) * FRAC_PI_2];
            let footprint = Footprint { carrying, ..BARE };
            check_no_crossing(&points, &yaws, footprint)?;
        }

        /// The first free pose ahead is free, and the step before it is not (unless it is
        /// the start); with none, no step up to the end is free.
        #[test]
        fn the_first_free_pose_ahead_is_the_first(
            x in -0.8f64..0.8, y in -0.55f64..0.55, yaw in -3.2f64..3.2, up_to_m in 0.0f64..0.1,
        ) {
            let free = space(BARE, 0.003);
            let from = Pose2::new(x, y, yaw);
            let at = |d: f64| from.compose(Pose2::new(d, 0.0, 0.0));
            match free.first_free_ahead_m(from, up_to_m) {
                Some(d) => {
                    prop_assert!((0.0..=up_to_m).contains(&d));
                    prop_assert!(free.pose_is_free(at(d)));
                    if d > 0.0 {
                        prop_assert!(!free.pose_is_free(at(d - AHEAD_STEP_M)));
                    }
                }
                None => {
                    prop_assert!(!free.pose_is_free(from) && !free.pose_is_free(at(up_to_m)));
                }
            }
        }

        /// Every step of a free reverse or drive on is free, and the next step is not (unless
        /// it went the whole way); a start that is not free goes nowhere.
        #[test]
        fn a_free_reverse_or_drive_on_stops_at_the_first_pose_that_is_not(
            x in -0.8f64..0.8, y in -0.55f64..0.55, yaw in -3.2f64..3.2, up_to_m in 0.0f64..0.1,
            ahead in proptest::bool::ANY,
        ) {
            // The margin asked for (1 cm) is not the space's (3 mm).
            let free = space(BARE, 0.003);
            let margin = space(BARE, 0.01);
            let from = Pose2::new(x, y, yaw);
            let sign = if ahead { 1.0 } else { -1.0 };
            let at = |d: f64| from.compose(Pose2::new(sign * d, 0.0, 0.0));
            let went_m = if ahead {
                free.free_ahead_m(from, up_to_m, 0.01)
            } else {
                free.free_reverse_m(from, up_to_m, 0.01)
            };
            prop_assert!((0.0..=up_to_m).contains(&went_m));
            if !margin.pose_is_free(from) {
                prop_assert_eq!(went_m, 0.0);
            } else {
                let steps = (went_m / AHEAD_STEP_M).round() as usize;
                for k in 0..=steps {
                    prop_assert!(margin.pose_is_free(at((k as f64 * AHEAD_STEP_M).min(went_m))));
                }
                if went_m + 1e-12 < up_to_m {
                    prop_assert!(!margin.pose_is_free(at((went_m + AHEAD_STEP_M).min(up_to_m))));
                }
            }
        }
    }
}
