//! The part search (`ratf_core::mission::search`) in the simulated world, on the fault
//! bench's tuning seeds. Seed 4: in round 1 the part leaves the magnet (a slip, or a Mega
//! reset that cuts its current) at 15.2 s, on the way from incoming slot 2, as the robot
//! turns at 1.3 rad/s. A creep straight on from where the robot stopped passed 7 cm beside
//! the part, gave it up and then pushed against it on the next legs (2 points of 4); looking
//! where the part was last held finds it. Seeds 75 and 1: see their tests. Realistic world, each robot
//! calibrated first, as `ratf bench faults --seeds 1 --first-seed 4 --calibrated --only
//! part_slip,mega_reset` runs it.

use ratf_core::config::{Config, WorldProfile};
use ratf_host::apps::fault_bench::{Injection, bench};
use ratf_sim::faults::FaultKind;

#[test]
fn a_part_lost_while_the_robot_turns_is_found_and_every_round_of_seed_4_scores_fully() {
    let mut config = Config::default();
    config.sim.world = WorldProfile::Realistic;
    let injections = [
        Injection::One(FaultKind::PartSlip),
        Injection::One(FaultKind::MegaReset),
    ];
    let result = bench(&config, 4..=4, &injections, true, |_| {}).expect("the bench runs");
    assert_eq!(result.fault_free_full_score_rate, 1.0);
    for row in &result.rows {
        assert_eq!(row.injected, 3, "{row:?}");
        assert_eq!(row.full_score_rate_by_round, [1.0; 3], "{row:?}");
        assert_eq!(row.given_up, 0, "{row:?}");
    }
}

/// Tuning seed 75, round 1: a Mega reset at 27.3 s cuts the magnet on the way from incoming
/// slot 3; the part falls, and the first look's switch closes on it beside the magnet's
/// centre. Gripped there (as before the centring), it met a divider of outgoing slot 3 and
/// the carry pushed there until it gave the action up, with the part still on the magnet
/// for the next one (2 points of 4). Centred on the plate first, it is placed: every round
/// of the seed scores every point, nothing given up. (Since the mission's clock stops while
/// the core holds the robot, round 1's search also pushes the first part placed out of
/// outgoing slot 1, so that round ends with 3 parts of 4 in the warehouse: the search's
/// collisions are issue 17's open end, not pinned here.)
#[test]
fn a_part_found_beside_the_magnet_after_a_mega_reset_is_centred_and_placed() {
    let mut config = Config::default();
    config.sim.world = WorldProfile::Realistic;
    let injections = [Injection::One(FaultKind::MegaReset)];
    let result = bench(&config, 75..=75, &injections, true, |_| {}).expect("the bench runs");
    assert_eq!(result.fault_free_full_score_rate, 1.0);
    let row = &result.rows[0];
    assert_eq!(row.injected, 3, "{row:?}");
    // 4, 6 and 8 points in rounds 1, 2 and 3.
    assert_eq!(row.mean_points, 6.0, "{row:?}");
    assert_eq!(row.given_up, 0, "{row:?}");
}

/// Seed 1, round 3: the lidar's cable is pulled as the robot carries a part; the core's
/// hold lets the magnet go, the part falls off, and the robot looks for it where it was
/// last held, grips it again and places it: every round of the seed scores fully, touches
/// nothing, gives nothing up. A hold that lets the part go near its drop asks the server
/// first (`ratf_core::mission`'s unit tests pin that): seed 30's round 3 did until
/// `35cb397` calibrated the lidar's position and moved its run, and no run of the lidar's
/// replug over seeds 1–130 meets that case since (seed 15 did until `5bfd367`).
#[test]
fn a_part_the_lidar_s_replug_let_go_is_looked_for_and_placed() {
    use ratf_host::apps::fault_bench::FaultProgress;
    let mut config = Config::default();
    config.sim.world = WorldProfile::Realistic;
    let injections = [Injection::One(FaultKind::LidarReplug)];
    let (mut asked, mut looked) = (0, 0);
    let result = bench(&config, 1..=1, &injections, true, |progress| {
        if let FaultProgress::Faulted(_, report, story) = progress
            && report.round == 3
        {
            asked += story
                .iter()
                .filter(|line| line.contains("asking the server"))
                .count();
            looked += story
                .iter()
                .filter(|line| line.contains("looking for it where it was last held"))
                .count();
        }
    })
    .expect("the bench runs");
    assert_eq!(
        (asked, looked),
        (0, 1),
        "round 3 looks once, without asking the server"
    );
    let row = &result.rows[0];
    assert_eq!(row.full_score_rate_by_round, [1.0; 3], "{row:?}");
    assert_eq!((row.collisions, row.given_up), (0, 0), "{row:?}");
}
