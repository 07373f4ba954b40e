//! `[field]`: the shop floor as the team measured it on the day. Everything else about the
//! floor is the rules' (`field::Field::competition`); the beacons are placed by the teams
//! themselves (competition.md §1.5), so their positions belong in the configuration.

use serde::{Deserialize, Serialize};

use super::check::{Checker, num};
use crate::field::Field;
use crate::field::geometry::hypot;

/// The floor as measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FieldConfig {
    /// Centres of the beacons B0..B3, world frame, m. Default: the original's positions
    /// (±0.888, ±0.538) m (`sdpo_ratf_ros_localization.yaml`); measure them with a tape
    /// from the printed floor's edges after setting the poles up (`ratf calibrate` will).
    pub beacons_m: [[f64; 2]; 4],
}

impl Default for FieldConfig {
    fn default() -> Self {
        let field = Field::competition();
        Self {
            beacons_m: field
                .beacons()
                .map(|b| [b.circle.center.x, b.circle.center.y]),
        }
    }
}

impl FieldConfig {
    /// Farthest a beacon may stand from the floor's centre, m: the rules put the poles in
    /// the team areas just beyond the printed floor's corners (≈ 1.05 m away); 2 m leaves
    /// room for any hall.
    pub const MAX_BEACON_DISTANCE_M: f64 = 2.0;

    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        for (index, [x, y]) in self.beacons_m.iter().enumerate() {
            c.require(
                &format!("beacons_m[{index}]"),
                format!("[{}, {}]", num(*x), num(*y)),
                x.is_finite() && y.is_finite() && hypot(*x, *y) <= Self::MAX_BEACON_DISTANCE_M,
                || {
                    format!(
                        "must be finite and within {} m of the floor's centre (the poles stand \
                         just beyond the floor's corners, about 1.05 m out)",
                        Self::MAX_BEACON_DISTANCE_M
                    )
                },
            );
        }
        for a in 0..4 {
            for b in a + 1..4 {
                let [ax, ay] = self.beacons_m[a];
                let [bx, by] = self.beacons_m[b];
                let apart_m = hypot(ax - bx, ay - by);
                c.require_all("beacons_m", apart_m >= 0.2, || {
                    format!(
                        "beacons {a} and {b} are {} m apart: at least 0.2 m, or the localiser \
                         cannot tell them apart",
                        num(apart_m)
                    )
                });
            }
        }
    }

    /// The competition floor with these beacon positions.
    pub fn field(&self) -> Field {
        Field::competition().with_beacon_centres(self.beacons_m)
    }
}
