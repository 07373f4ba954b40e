//! What a round's collisions were: each one classed by what the robot was doing (going to a
//! pick, carrying a part, anything else) and by what it touched, so the gap to issue 11's
//! "0 collisions" can be read by cause, as [`crate::apps::time_split`] reads the gap to the
//! time bound.
//!
//! What it touched:
//!
//! | class | what |
//! |---|---|
//! | crowded neighbour | a part beside the slot the robot was going to pick, in its slot or knocked out of it onto the floor, where the parts' places crowd that pick (`ratf_sim::World::crowded_picks`: the body, square on the slot's line with its magnet on the part, overlaps it) |
//! | part | any other part (a neighbour that does not crowd the pick, a part elsewhere on the floor or in the outgoing warehouse) |
//! | warehouse | a warehouse's back wall or divider |
//! | machine | a machine block's wall or divider |
//! | pole | a beacon's pole |

use ratf_core::field::{Field, ObstacleKind, WaypointId};
use ratf_core::runtime::Event;
use ratf_sim::world::{Collision, Obstruction};
use serde::Serialize;

use crate::apps::round::RoundEvent;

/// Collisions by what the robot touched (module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Struck {
    /// A neighbour part that crowds the pick the robot was going to.
    pub crowded_neighbour: u32,
    /// Any other part.
    pub part: u32,
    /// A warehouse's wall or divider.
    pub warehouse: u32,
    /// A machine's wall or divider.
    pub machine: u32,
    /// A beacon pole.
    pub pole: u32,
}

impl Struck {
    /// All of them.
    pub fn total(&self) -> u32 {
        self.crowded_neighbour + self.part + self.warehouse + self.machine + self.pole
    }
}

impl std::ops::AddAssign for Struck {
    fn add_assign(&mut self, other: Self) {
        self.crowded_neighbour += other.crowded_neighbour;
        self.part += other.part;
        self.warehouse += other.warehouse;
        self.machine += other.machine;
        self.pole += other.pole;
    }
}

/// Collisions by what the robot was doing, then what it touched.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CollisionCauses {
    /// From an action's start until its part is held (docking included).
    pub to_pick: Struck,
    /// From the pick until the part is placed (backing out of the pick included).
    pub carrying: Struck,
    /// Anything else: before the first action, after a placement, after a part was lost.
    pub elsewhere: Struck,
}

impl CollisionCauses {
    /// All of them.
    pub fn total(&self) -> u32 {
        self.to_pick.total() + self.carrying.total() + self.elsewhere.total()
    }
}

impl std::ops::AddAssign for CollisionCauses {
    fn add_assign(&mut self, other: Self) {
        self.to_pick += other.to_pick;
        self.carrying += other.carrying;
        self.elsewhere += other.elsewhere;
    }
}

/// What the robot is doing, from the mission's events.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Doing {
    ToPick(WaypointId),
    Carrying,
    Elsewhere,
}

/// Hears a round's events in order and classes each collision.
#[derive(Debug)]
pub struct CollisionClassifier {
    field: Field,
    crowded: Vec<(WaypointId, usize)>,
    doing: Doing,
    causes: CollisionCauses,
}

impl CollisionClassifier {
    /// A classifier for a round on `field` whose parts crowd the picks `crowded` (slot,
    /// part), as `ratf_sim::World::crowded_picks` found them at the start.
    pub fn new(field: Field, crowded: Vec<(WaypointId, usize)>) -> Self {
        Self {
            field,
            crowded,
            doing: Doing::Elsewhere,
            causes: CollisionCauses::default(),
        }
    }

    /// The picks the parts' places crowd from now on (slot, part), as
    /// `ratf_sim::World::crowded_picks` finds them now: parts move in a round (knocked out of
    /// a slot, pushed), so the round asks again as the robot sets out for each pick.
    pub fn crowd(&mut self, crowded: Vec<(WaypointId, usize)>) {
        self.crowded = crowded;
    }

    /// Hear the next event.
    pub fn hear(&mut self, event: &RoundEvent) {
        match event {
            RoundEvent::Core { event, .. } => match event {
                Event::ActionStarted { pick, .. } => self.doing = Doing::ToPick(*pick),
                Event::Picked { .. } | Event::Regripped { .. } => self.doing = Doing::Carrying,
                Event::Placed { .. }
                | Event::Skipped { .. }
                | Event::PartSlipped { .. }
                | Event::PartLetGoInHold { .. }
                | Event::PartLetGoNearDrop { .. } => self.doing = Doing::Elsewhere,
                _ => {}
            },
            RoundEvent::Collision(collision) => self.class(collision),
            _ => {}
        }
    }

    /// The collisions heard so far, classed.
    pub fn causes(&self) -> CollisionCauses {
        self.causes
    }

    fn class(&mut self, collision: &Collision) {
        let doing = self.doing;
        let struck = match doing {
            Doing::ToPick(_) => &mut self.causes.to_pick,
            Doing::Carrying => &mut self.causes.carrying,
            Doing::Elsewhere => &mut self.causes.elsewhere,
        };
        let count = match collision.with {
            Obstruction::Part(part) => match doing {
                Doing::ToPick(slot) if self.crowded.contains(&(slot, part)) => {
                    &mut struck.crowded_neighbour
                }
                _ => &mut struck.part,
            },
            Obstruction::Beacon(_) => &mut struck.pole,
            Obstruction::Wall(index) => match self.field.obstacles().get(index).map(|o| o.kind) {
                Some(ObstacleKind::MachineWall | ObstacleKind::MachineDivider) => {
                    &mut struck.machine
                }
                _ => &mut struck.warehouse,
            },
        };
        *count += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratf_core::field::PartColor;
    use ratf_core::field::geometry::Pose2;
    use ratf_core::runtime::Timestamp;

    fn core(event: Event) -> RoundEvent {
        RoundEvent::Core {
            time: Timestamp::from_us(0),
            event,
        }
    }

    fn hit(with: Obstruction) -> RoundEvent {
        RoundEvent::Collision(Collision {
            time_us: 0,
            with,
            pose: Pose2::new(0.0, 0.0, 0.0),
        })
    }

    #[test]
    fn each_collision_is_classed_by_the_leg_and_what_it_touched() {
        let field = Field::competition();
        let machine_wall = field
            .obstacles()
            .iter()
            .position(|o| o.kind == ObstacleKind::MachineWall)
            .unwrap();
        let divider = field
            .obstacles()
            .iter()
            .position(|o| o.kind == ObstacleKind::WarehouseDivider)
            .unwrap();
        let mut classifier = CollisionClassifier::new(field, vec![(WaypointId(50), 1)]);
        classifier.hear(&hit(Obstruction::Beacon(3)));
        classifier.hear(&core(Event::ActionStarted {
            pick: WaypointId(50),
            drop: WaypointId(62),
            color: Some(PartColor::Blue),
            attempt: 1,
        }));
        // Part 1 crowds slot 50's pick; part 2 does not.
        classifier.hear(&hit(Obstruction::Part(1)));
        classifier.hear(&hit(Obstruction::Part(2)));
        classifier.hear(&core(Event::Picked {
            slot: WaypointId(50),
            color: Some(PartColor::Blue),
        }));
        // Carrying, part 1 is just a part.
        classifier.hear(&hit(Obstruction::Part(1)));
        classifier.hear(&hit(Obstruction::Wall(divider)));
        classifier.hear(&hit(Obstruction::Wall(machine_wall)));
        let causes = classifier.causes();
        assert_eq!(
            causes.to_pick,
            Struck {
                crowded_neighbour: 1,
                part: 1,
                ..Struck::default()
            }
        );
        assert_eq!(
            causes.carrying,
            Struck {
                part: 1,
                warehouse: 1,
                machine: 1,
                ..Struck::default()
            }
        );
        assert_eq!(
            causes.elsewhere,
            Struck {
                pole: 1,
                ..Struck::default()
            }
        );
        assert_eq!(causes.total(), 6);
    }

    #[test]
    fn a_part_that_came_to_crowd_a_pick_counts_as_crowding_it_from_then_on() {
        let mut classifier = CollisionClassifier::new(Field::competition(), Vec::new());
        let going_for_51 = core(Event::ActionStarted {
            pick: WaypointId(51),
            drop: WaypointId(62),
            color: Some(PartColor::Blue),
            attempt: 1,
        });
        classifier.hear(&going_for_51);
        classifier.hear(&hit(Obstruction::Part(2)));
        // Part 2 knocked out of its slot beside 51 since: it crowds 51's pick now.
        classifier.crowd(vec![(WaypointId(51), 2)]);
        classifier.hear(&going_for_51);
        classifier.hear(&hit(Obstruction::Part(2)));
        assert_eq!(
            classifier.causes().to_pick,
            Struck {
                crowded_neighbour: 1,
                part: 1,
                ..Struck::default()
            }
        );
    }
}
