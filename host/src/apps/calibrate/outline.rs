//! The body's outline as a team measures it with a rule, in the simulator: how far each face
//! stands from the wheels' centre (the robot frame's origin, midway between the four axles),
//! drawn from the world's true outline with the rule's error.
//!
//! On a real robot the team writes the same four figures into `[robot]` (README: Fit your
//! robot). The robot docks with its magnet's face [`ratf_core::config::RobotConfig::pick_standoff_m`]
//! from a plate and keeps its faces off the walls by them; the world's outline is drawn
//! around the configuration's (`ratf_sim::truth`), so an unmeasured robot believes the
//! nominal centred square and misses its own by up to the drawn spread.

use ratf_core::config::{Config, WorldProfile};
use ratf_core::rng::SimRng;
use ratf_sim::truth::WorldTruth;

/// σ of one face's distance from the wheels' centre read off a steel rule, m. 0.001: read to
/// the millimetre from the axles' centre line, the rule held square by hand (an assumption;
/// calipers do better, a tape worse).
pub const RULE_SIGMA_M: f64 = 0.001;

/// The four faces' distances from the wheels' centre, m (each positive).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outline {
    /// To the front face (+x).
    pub front_m: f64,
    /// To the back face (−x).
    pub back_m: f64,
    /// To the left face (+y).
    pub left_m: f64,
    /// To the right face (−y).
    pub right_m: f64,
}

impl Outline {
    /// The world's true outline in `config`'s world (its `[sim] seed` and `world`), each
    /// face measured with [`RULE_SIGMA_M`]; exactly in the ideal world, which is the robot's
    /// own model (there the rule reads what the configuration says, as every other measure
    /// of that world would).
    pub fn measured_in_sim(config: &Config) -> Self {
        let truth = WorldTruth::draw(config, 0.0);
        let [x, y] = truth.body_offset_m;
        let (half_length, half_width) = (
            truth.footprint_length_m / 2.0,
            truth.footprint_width_m / 2.0,
        );
        let mut rule = SimRng::new(config.sim.seed).fork("outline rule");
        let sigma_m = match config.sim.world {
            WorldProfile::Ideal => 0.0,
            WorldProfile::Realistic | WorldProfile::Harsh => RULE_SIGMA_M,
        };
        let mut read = |true_m: f64| true_m + rule.normal(sigma_m);
        Self {
            front_m: read(half_length + x),
            back_m: read(half_length - x),
            left_m: read(half_width + y),
            right_m: read(half_width - y),
        }
    }

    /// The robot believes this outline: its length, width and centre.
    pub fn apply(&self, config: &mut Config) {
        let robot = &mut config.robot;
        robot.footprint_length_m = self.front_m + self.back_m;
        robot.footprint_width_m = self.left_m + self.right_m;
        robot.body_center_x_m = (self.front_m - self.back_m) / 2.0;
        robot.body_center_y_m = (self.left_m - self.right_m) / 2.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world(profile: WorldProfile, seed: u64) -> Config {
        let mut config = Config::default();
        config.sim.world = profile;
        config.sim.seed = seed;
        config
    }

    #[test]
    fn the_measured_outline_is_the_true_one_within_a_few_rule_errors() {
        for seed in 1..=20 {
            let config = world(WorldProfile::Harsh, seed);
            let truth = WorldTruth::draw(&config, 0.0);
            let mut measured = config.clone();
            Outline::measured_in_sim(&config).apply(&mut measured);
            let robot = &measured.robot;
            let errors = [
                robot.footprint_length_m - truth.footprint_length_m,
                robot.footprint_width_m - truth.footprint_width_m,
                robot.body_center_x_m - truth.body_offset_m[0],
                robot.body_center_y_m - truth.body_offset_m[1],
            ];
            for error in errors {
                assert!(
                    error.abs() < 4.0 * RULE_SIGMA_M * 2f64.sqrt(),
                    "{seed}: {errors:?}"
                );
            }
        }
    }

    #[test]
    fn in_the_ideal_world_the_rule_reads_the_configuration() {
        let mut config = world(WorldProfile::Ideal, 3);
        config.robot.body_center_x_m = 0.01;
        let mut measured = config.clone();
        Outline::measured_in_sim(&config).apply(&mut measured);
        let (robot, written) = (&measured.robot, &config.robot);
        assert!((robot.footprint_length_m - written.footprint_length_m).abs() < 1e-12);
        assert!((robot.footprint_width_m - written.footprint_width_m).abs() < 1e-12);
        assert!((robot.body_center_x_m - 0.01).abs() < 1e-12);
        assert!(robot.body_center_y_m.abs() < 1e-12);
    }
}
