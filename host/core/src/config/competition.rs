//! `[competition]` and `[mission]`: which round the robot plays and with which software, how
//! it reads the organisers' server, what its task planner assumes, and the mission's
//! timing. These are the robot's settings (what it does on the floor), read by the core.

use serde::{Deserialize, Serialize};

use super::check::Checker;
use super::limits;
use crate::mission::MissionConfig;

/// Which software drives the robot: the one enum behind `--policy` and `[competition]
/// policy`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Policy {
    /// Our task planner (branch and bound), our localiser and our navigation (route
    /// planner, holonomic follower, docking on the switch).
    #[default]
    Ours,
    /// The original 5dpo team's priority planner, line follower and creep to the switch
    /// (original-system.md §6) and its beacon filter (§5), for comparison.
    Original,
}

impl Policy {
    /// Both policies, ours first.
    pub const ALL: [Self; 2] = [Self::Ours, Self::Original];

    /// The name used in the CLI, the config and the logs.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Ours => "ours",
            Self::Original => "original",
        }
    }
}

impl std::fmt::Display for Policy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The round and how the robot plays it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CompetitionConfig {
    /// Round number, 1–3: the rules the planner follows (competition.md §2). The team sets
    /// it before each round; the server does not say which round it is.
    pub round: u8,
    /// Who plans and drives.
    pub policy: Policy,
    /// Machine processing time the planner assumes, s. 0: the rules let the organisers set
    /// it (competition.md §2); the 2022–2023 finals used none.
    pub machine_delay_s: f64,
    /// How often the robot asks the server for the part list while waiting for the start,
    /// and at most how often it reads the four areas (`IWP OWP MAP MBP`) while driving to a
    /// pick, s. 0.2: assumption, ten times the 50 Hz tick and well above the server's
    /// reply time on a venue's Wi-Fi (tens of ms); the original polled only at start.
    pub poll_period_s: f64,
    /// Time the planner charges for a pick (dock, grip, back out), s. 1.0: the mission's
    /// docking approach and grip settle as measured in simulated rounds (≈ 1 s).
    pub planner_pick_s: f64,
    /// Time the planner charges for a drop (release, back out), s. 0.8: as above.
    pub planner_drop_s: f64,
    /// Travel speed the planner assumes between slots, m/s. 0.4: the original's cruise
    /// speed (original-system.md §6.3); only the order of actions depends on it.
    pub planner_speed_m_s: f64,
    /// Turn rate the planner assumes, rad/s. 0.8: the original's (original-system.md §6.3).
    pub planner_turn_rate_rad_s: f64,
}

impl Default for CompetitionConfig {
    fn default() -> Self {
        Self {
            round: 3,
            policy: Policy::Ours,
            machine_delay_s: 0.0,
            poll_period_s: 0.2,
            planner_pick_s: 1.0,
            planner_drop_s: 0.8,
            planner_speed_m_s: 0.4,
            planner_turn_rate_rad_s: 0.8,
        }
    }
}

impl CompetitionConfig {
    /// Longest machine delay accepted, s: the round itself lasts at most a few minutes.
    pub const MAX_MACHINE_DELAY_S: f64 = 300.0;

    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        c.within_int(
            "round",
            self.round,
            1,
            3,
            "",
            "the competition's three rounds (competition.md §2)",
        );
        c.within(
            "machine_delay_s",
            self.machine_delay_s,
            0.0,
            Self::MAX_MACHINE_DELAY_S,
            "s",
            "half the 10-minute slot (competition.md §2)",
        );
        c.within(
            "poll_period_s",
            self.poll_period_s,
            0.02,
            10.0,
            "s",
            "from one 50 Hz tick to 10 s, 5dpo's wait between part-list requests",
        );
        const ACTION: &str = "a pick or a drop takes seconds; a minute is a tenth of the slot";
        c.within(
            "planner_pick_s",
            self.planner_pick_s,
            0.0,
            60.0,
            "s",
            ACTION,
        );
        c.within(
            "planner_drop_s",
            self.planner_drop_s,
            0.0,
            60.0,
            "s",
            ACTION,
        );
        c.within(
            "planner_speed_m_s",
            self.planner_speed_m_s,
            0.01,
            5.0,
            "m/s",
            "the default wheels reach 0.73 m/s; only the order of actions depends on it",
        );
        c.within(
            "planner_turn_rate_rad_s",
            self.planner_turn_rate_rad_s,
            0.01,
            20.0,
            "rad/s",
            "the default wheels turn the robot at 4.2 rad/s at most",
        );
    }

    /// The poll period in µs.
    pub fn poll_period_us(&self) -> u64 {
        (self.poll_period_s * 1e6).round() as u64
    }
}

impl MissionConfig {
    pub(crate) fn check(&self, c: &mut Checker<'_>) {
        c.within(
            "drive_timeout_s",
            self.drive_timeout_s,
            0.1,
            limits::ROUND_SLOT_S,
            "s",
            "at most the 10-minute slot (competition.md §2)",
        );
        const SETTLE: &str = "the magnet reaches its force in tens of ms";
        c.within("grip_settle_s", self.grip_settle_s, 0.0, 10.0, "s", SETTLE);
        c.within(
            "release_settle_s",
            self.release_settle_s,
            0.0,
            10.0,
            "s",
            SETTLE,
        );
        c.within(
            "drop_fix_wait_s",
            self.drop_fix_wait_s,
            0.0,
            10.0,
            "s",
            "the X4 scans at 7 Hz: a few tenths of a second hold several scans",
        );
        c.within(
            "back_out_m",
            self.back_out_m,
            0.0,
            limits::STRAIGHT_RUN_M,
            "m",
            "where machine A's output faces machine B's input, the robot has 0.26 m before its \
             back reaches the other's dividers",
        );
        c.within(
            "back_out_speed_m_s",
            self.back_out_speed_m_s,
            0.01,
            2.0,
            "m/s",
            "the default wheels reach 0.73 m/s",
        );
        c.within(
            "back_out_accel_m_s2",
            self.back_out_accel_m_s2,
            0.01,
            15.0,
            "m/s²",
            "1.5 g: more than rubber's friction gives on any floor",
        );
        c.within(
            "lost_part_debounce_s",
            self.lost_part_debounce_s,
            0.02,
            2.0,
            "s",
            "from one telemetry batch (20 ms) to a time in which the robot crosses the floor",
        );
        c.within(
            "regrip_brake_s",
            self.regrip_brake_s,
            0.0,
            5.0,
            "s",
            "the robot stops from its top speed in well under a second",
        );
        c.within(
            "regrip_reach_m",
            self.regrip_reach_m,
            0.0,
            0.3,
            "m",
            "a part further than a body length away was not lost at the face",
        );
        c.within(
            "regrip_backoff_m",
            self.regrip_backoff_m,
            0.0,
            0.15,
            "m",
            "a look starts near where the part was last held: half a body length behind it at most",
        );
        c.within(
            "regrip_sweep_m",
            self.regrip_sweep_m,
            0.0,
            0.1,
            "m",
            "looks further apart than the 8 cm plate leave parts between them unseen",
        );
        c.within_int(
            "regrip_looks",
            self.regrip_looks,
            1,
            crate::mission::MAX_LOOKS as i128,
            "",
            "each look takes about 3 s; the search keeps at most this many",
        );
        c.within(
            "stall_s",
            self.stall_s,
            0.0,
            30.0,
            "s",
            "0 turns the watch off; longer than drive_timeout_s never fires",
        );
        c.within(
            "server_word_wait_s",
            self.server_word_wait_s,
            0.0,
            30.0,
            "s",
            "the robot stands still meanwhile: longer than a few tries of a request is a round lost",
        );
        c.within(
            "regrip_speed_m_s",
            self.regrip_speed_m_s,
            0.01,
            0.5,
            "m/s",
            "a creep: the switch must close before the face passes the plate",
        );
        c.within_int(
            "max_attempts",
            self.max_attempts,
            1,
            10,
            "",
            "ten approaches of one action fill the slot",
        );
    }
}

#[cfg(test)]
mod tests {
    use crate::config::{Config, ConfigError};

    /// The issues of `text`, as printed; empty when it is accepted.
    fn issues(text: &str) -> Vec<String> {
        match Config::from_toml_str(text) {
            Ok(_) => Vec::new(),
            Err(ConfigError::Invalid { issues, .. }) => {
                issues.iter().map(ToString::to_string).collect()
            }
            Err(other) => vec![other.to_string()],
        }
    }

    #[test]
    fn the_search_keys_are_read_and_bounded() {
        let config = Config::from_toml_str(
            "[mission]\nregrip_backoff_m = 0.05\nregrip_sweep_m = 0.0\nregrip_looks = 1\n",
        )
        .expect("within bounds");
        assert_eq!(config.mission.regrip_backoff_m, 0.05);
        assert_eq!(config.mission.regrip_sweep_m, 0.0);
        assert_eq!(config.mission.regrip_looks, 1);
        for (text, key) in [
            ("regrip_backoff_m = 0.5", "mission.regrip_backoff_m"),
            ("regrip_backoff_m = -0.01", "mission.regrip_backoff_m"),
            ("regrip_sweep_m = 0.2", "mission.regrip_sweep_m"),
            ("regrip_looks = 0", "mission.regrip_looks"),
            ("regrip_looks = 9", "mission.regrip_looks"),
        ] {
            let found = issues(&format!("[mission]\n{text}\n"));
            assert_eq!(found.len(), 1, "{text}: {found:?}");
            assert!(found[0].starts_with(key), "{text}: {}", found[0]);
        }
    }
}
