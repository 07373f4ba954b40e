//! `[sim]`: the simulator's seed, time step, and what stands around the field.

use serde::{Deserialize, Serialize};

use super::check::{Checker, num};
use super::limits;

/// How far the simulated world's truth departs from the robot's beliefs (its
/// configuration). Per seed, the simulator draws the truth from the profile's distributions
/// (`ratf_sim::truth`, sources in `../shared/reference/real-world-errors.md`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum WorldProfile {
    /// The world is exactly what the robot believes (the first wave's simulator): for
    /// regression only, since no real floor is like it.
    Ideal,
    /// The real-world error budget's "realistic" column: a lidar with its datasheet's
    /// calibration errors, beacons placed with a tape, worn wheels, mecanum roller slip, a
    /// MEMS gyro's scale and bias, motors that differ. The default: every figure a team
    /// reads should come from a world that is not its robot's own model.
    #[default]
    Realistic,
    /// About twice realistic: a stress test.
    Harsh,
}

impl WorldProfile {
    /// The name used in the CLI, the config and the logs.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Ideal => "ideal",
            Self::Realistic => "realistic",
            Self::Harsh => "harsh",
        }
    }
}

impl std::fmt::Display for WorldProfile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Simulator settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// How the world's truth departs from the robot's beliefs: `realistic` by default (issue
    /// 11); `ratf sim` and the benches take `--world`.
    pub world: WorldProfile,
    /// Random seed; the same seed gives the same run. TOML integers are i64, so seeds above
    /// 2^63 − 1 cannot be written in a file.
    pub seed: u64,
    /// Physics time step, µs. 1000: assumption (20 steps per 20 ms control period; the
    /// motor time constant is 100 ms). Must divide `mega.control_period_us`; 10 to 5000
    /// (the simulator reads the IMU at most once a step, every 5 ms).
    pub time_step_us: u32,
    /// Things around the field the lidar may see (`[[sim.clutter]]`, world frame). Default:
    /// a person standing 0.2 m beyond the floor's right edge (legs at x = 1.1 and 1.3 m) and
    /// the edge of a 0.75 m table 0.3 m beyond its top edge: assumptions, a competition field
    /// is never alone in its hall. Neither is within 0.45 m of a beacon.
    pub clutter: Vec<ClutterConfig>,
}

/// One thing standing near the field, `kind = "cylinder"` or `kind = "block"`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ClutterConfig {
    /// A vertical cylinder (a leg, a pole), m.
    Cylinder {
        /// Centre x, m.
        x_m: f64,
        /// Centre y, m.
        y_m: f64,
        /// Radius, m.
        radius_m: f64,
        /// Height, m.
        height_m: f64,
    },
    /// A vertical box, axis-aligned (a table, a wall), m.
    Block {
        /// Lowest x, m.
        x_min_m: f64,
        /// Highest x, m.
        x_max_m: f64,
        /// Lowest y, m.
        y_min_m: f64,
        /// Highest y, m.
        y_max_m: f64,
        /// Height, m.
        height_m: f64,
    },
}

impl ClutterConfig {
    /// A person's two legs (Ø 0.12 m, 0.2 m apart along x, 0.8 m tall) centred at (x, y):
    /// an assumption of typical adult proportions.
    pub fn person(x_m: f64, y_m: f64) -> [Self; 2] {
        [-0.1, 0.1].map(|dx| Self::Cylinder {
            x_m: x_m + dx,
            y_m,
            radius_m: 0.06,
            height_m: 0.8,
        })
    }

    fn check(&self, c: &mut Checker<'_>, key: &str) {
        const WHERE: &str = "standing in the hall: the X4 sees at most 16.4 m, so farther \
                             clutter is invisible";
        const SIZE: &str = "a person's leg, a pole, a table or a wall of the hall";
        let position = |c: &mut Checker<'_>, name: &str, value: f64| {
            c.within(&format!("{key}.{name}"), value, -20.0, 20.0, "m", WHERE);
        };
        match *self {
            Self::Cylinder {
                x_m,
                y_m,
                radius_m,
                height_m,
            } => {
                position(c, "x_m", x_m);
                position(c, "y_m", y_m);
                c.within(&format!("{key}.radius_m"), radius_m, 0.001, 5.0, "m", SIZE);
                c.within(&format!("{key}.height_m"), height_m, 0.001, 10.0, "m", SIZE);
            }
            Self::Block {
                x_min_m,
                x_max_m,
                y_min_m,
                y_max_m,
                height_m,
            } => {
                position(c, "x_min_m", x_min_m);
                position(c, "y_min_m", y_min_m);
                position(c, "x_max_m", x_max_m);
                position(c, "y_max_m", y_max_m);
                c.require(
                    &format!("{key}.x_max_m"),
                    num(x_max_m),
                    x_max_m > x_min_m,
                    || format!("must exceed x_min_m = {}", num(x_min_m)),
                );
                c.require(
                    &format!("{key}.y_max_m"),
                    num(y_max_m),
                    y_max_m > y_min_m,
                    || format!("must exceed y_min_m = {}", num(y_min_m)),
                );
                c.within(&format!("{key}.height_m"), height_m, 0.001, 10.0, "m", SIZE);
            }
        }
    }
}

impl Default for SimConfig {
    fn default() -> Self {
        let mut clutter = ClutterConfig::person(1.2, 0.0).to_vec();
        clutter.push(ClutterConfig::Block {
            x_min_m: -0.6,
            x_max_m: 0.6,
            y_min_m: 0.9,
            y_max_m: 1.0,
            height_m: 0.75,
        });
        Self {
            world: WorldProfile::Realistic,
            seed: 1,
            time_step_us: 1000,
            clutter,
        }
    }
}

impl SimConfig {
    /// Most clutter items: each is ray-cast for every one of the lidar's ~5 000 samples a
    /// second, and a hundred already fills a crowded hall.
    pub const MAX_CLUTTER: usize = 100;

    pub(crate) fn check(&self, c: &mut Checker<'_>, control_period_us: u32) {
        c.within_int(
            "time_step_us",
            self.time_step_us,
            10,
            i128::from(limits::IMU_READ_PERIOD_US),
            "µs",
            "at most the IMU's 5 ms read period, which the simulator reads once per step; \
             at least 10 µs, a byte's time at 1 Mbaud",
        );
        c.within_int(
            "clutter",
            self.clutter.len() as u64,
            0,
            Self::MAX_CLUTTER as i128,
            "items",
            "each is ray-cast for every lidar sample; a hundred fills a crowded hall",
        );
        for (i, clutter) in self.clutter.iter().enumerate() {
            clutter.check(c, &format!("clutter[{i}]"));
        }
        // Against a control period and a step that are themselves valid (else reported there).
        let period_ok = (1_000..=100_000).contains(&control_period_us)
            && control_period_us.is_multiple_of(1_000);
        let step_ok = (10..=limits::IMU_READ_PERIOD_US).contains(&self.time_step_us);
        if period_ok && step_ok {
            c.require(
                "time_step_us",
                self.time_step_us,
                control_period_us.is_multiple_of(self.time_step_us),
                || {
                    format!(
                        "must divide mega.control_period_us = {control_period_us}, so the \
                         Mega's ticks fall on steps"
                    )
                },
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clutter_parses_from_toml_by_kind() {
        let text = r#"
            [[clutter]]
            kind = "cylinder"
            x_m = 1.0
            y_m = 0.2
            radius_m = 0.05
            height_m = 1.0

            [[clutter]]
            kind = "block"
            x_min_m = 0.0
            x_max_m = 1.0
            y_min_m = 0.9
            y_max_m = 1.0
            height_m = 0.7
        "#;
        let sim: SimConfig = toml::from_str(text).unwrap();
        assert_eq!(sim.clutter.len(), 2);
        assert!(matches!(sim.clutter[1], ClutterConfig::Block { height_m, .. } if height_m == 0.7));
        let bad = toml::from_str::<SimConfig>("[[clutter]]\nkind = \"sphere\"\n");
        assert!(bad.is_err());
    }

    #[test]
    fn a_backwards_block_is_rejected_by_key() {
        let sim = SimConfig {
            clutter: vec![ClutterConfig::Block {
                x_min_m: 1.0,
                x_max_m: 0.0,
                y_min_m: 0.0,
                y_max_m: 1.0,
                height_m: 1.0,
            }],
            ..SimConfig::default()
        };
        let mut issues = Vec::new();
        sim.check(&mut Checker::new("sim", &mut issues), 20_000);
        assert_eq!(issues.len(), 1);
        assert_eq!(issues[0].key, "sim.clutter[0].x_max_m");
    }
}
