//! `[sim]`: the simulator's seed and time step.

use serde::{Deserialize, Serialize};

use super::check::Checker;

/// Simulator settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// Random seed; the same seed gives the same run. TOML integers are i64, so seeds above
    /// 2^63 − 1 cannot be written in a file.
    pub seed: u64,
    /// Physics time step, µs. 1000: assumption (20 steps per 20 ms control period; the
    /// motor time constant is 100 ms). Must divide `mega.control_period_us`.
    pub time_step_us: u32,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            time_step_us: 1000,
        }
    }
}

impl SimConfig {
    pub(crate) fn check(&self, c: &mut Checker<'_>, control_period_us: u32) {
        c.nonzero("time_step_us", self.time_step_us.into());
        if self.time_step_us != 0 && control_period_us != 0 {
            c.require(
                "time_step_us",
                control_period_us.is_multiple_of(self.time_step_us),
                || {
                    format!(
                        "must divide mega.control_period_us = {control_period_us} (got {})",
                        self.time_step_us
                    )
                },
            );
        }
    }
}
