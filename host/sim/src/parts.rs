//! The parts on the shop floor and how the robot handles them: the box micro-switch, the
//! electromagnet, and the machines that turn parts.
//!
//! Gripper model (assumptions, see [`Gripper`]): the switch's roller lever and the magnet sit
//! on the robot's centre line and reach a little beyond its 30 × 30 cm footprint, far enough
//! to touch a box whose plate is recessed 10 mm behind the dividers (`field::PICK_STANDOFF_M`
//! leaves 15 mm). The switch closes when a part's plate is within that reach, roughly square
//! and centred; the magnet, when energised with the switch closed, pulls the plate flat
//! against its face (where the plate is at a slot's pick pose; the world stops it part-way
//! where a neighbour or a wall is in the way, `World`'s contact) and holds the part rigidly;
//! released, the part drops where it is and stands in a slot if it lands between the slot's
//! dividers (see `SLOT_CAPTURE_*`).
//!
//! Each part standing in a slot has its own pose there: the referee's placement (drawn per
//! seed, [`crate::truth::PartSeat`]), or where the robot released it. The world pushes a
//! free part the robot runs into ([`Shop::push`]); a part pushed out of its slot's capture
//! zone stands on the floor and is no longer that slot's part.
//!
//! Machines (competition.md §2): a part dropped on a machine's input is turned after the
//! processing delay and appears on the same row's output once that is free. Machine A turns
//! red into green (and, when allowed, green into blue: round 2 lets greens use either
//! machine); machine B turns green into blue. A part a machine does not take stays on its
//! input unchanged.

use ratf_core::field::Field;
use ratf_core::field::OrientedRect;
use ratf_core::field::geometry::{Pose2, Vec2, wrap_angle};
use ratf_core::field::stations::{
    MachineKind, PART_DEPTH_M, PART_WIDTH_M, PartColor, Slot, SlotKind, pick_standoff_m,
};
use ratf_core::field::waypoints::WaypointId;
use std::f64::consts::PI;

use crate::truth::PartSeat;
#[cfg(doc)]
use ratf_core::field::PICK_STANDOFF_M;

/// Where a part is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PartPlace {
    /// Standing in a slot (named by the slot's waypoint, 50–65).
    Slot(WaypointId),
    /// Held by the magnet; the part's centre and orientation in the robot frame.
    Carried(Pose2),
    /// Standing on the floor outside any slot; centre and orientation in the world.
    Floor(Pose2),
}

/// One part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Part {
    /// Current type.
    pub color: PartColor,
    /// Current place.
    pub place: PartPlace,
}

/// Where the switch and the magnet reach. Assumptions (the original's gripper is not
/// documented beyond "micro-switch with roller lever" and "Grove electromagnet").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gripper {
    /// Distance from the robot centre to its front face, m (half the footprint length).
    pub front_m: f64,
    /// How far beyond the front face the lever and magnet reach, m. 0.020: assumption.
    pub reach_m: f64,
    /// Largest sideways offset of the plate centre from the robot's centre line, m. 0.025:
    /// the 80 mm plate still covers a magnet this far off centre.
    pub lateral_tolerance_m: f64,
    /// Largest angle between the robot's heading and the plate's inward normal, rad (15°).
    pub angle_tolerance_rad: f64,
    /// Distance from the robot centre to the magnet's face, m: 15 mm beyond the front face
    /// ([`pick_standoff_m`]; [`PICK_STANDOFF_M`] on the default 30 cm body), so a held plate
    /// is where it is at the pick pose of a robot that knows its outline.
    pub magnet_m: f64,
}

impl Gripper {
    /// The default gripper on a robot whose front face is `front_m` from its centre.
    pub fn new(front_m: f64) -> Self {
        Self {
            front_m,
            reach_m: 0.020,
            lateral_tolerance_m: 0.025,
            angle_tolerance_rad: 15f64.to_radians(),
            magnet_m: pick_standoff_m(front_m),
        }
    }
}

/// Something that happened to the parts in one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PartEvent {
    /// The magnet took hold of part `part`.
    Picked {
        /// Index into [`Shop::parts`].
        part: usize,
        /// The slot it stood in (`None` if it was on the floor).
        from: Option<WaypointId>,
    },
    /// Part `part` was released and now stands in a slot.
    Placed {
        /// Index into [`Shop::parts`].
        part: usize,
        /// The slot's waypoint.
        slot: WaypointId,
        /// Its colour when placed (a machine may turn it later).
        color: PartColor,
    },
    /// Part `part` was released outside every slot.
    Dropped {
        /// Index into [`Shop::parts`].
        part: usize,
    },
    /// A machine turned part `part` into `color` and moved it to its output.
    Processed {
        /// Index into [`Shop::parts`].
        part: usize,
        /// Its new colour.
        color: PartColor,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Processing {
    part: usize,
    input: WaypointId,
    output: WaypointId,
    new_color: PartColor,
    ready_at_us: u64,
}

/// The parts, the machines' work in progress, and the robot's gripper.
#[derive(Clone, Debug)]
pub struct Shop {
    slots: Vec<Slot>,
    /// Every machine row: (input slot, machine type, output slot).
    machine_rows: Vec<(WaypointId, MachineKind, WaypointId)>,
    parts: Vec<Part>,
    /// Each part's pose in the world while it stands in a slot.
    seated: Vec<Pose2>,
    /// A released part stands where it was let go (false: centred in its slot, the ideal
    /// world's way).
    where_released: bool,
    processing: Vec<Processing>,
    machine_delay_us: u64,
    green_to_blue_at_a: bool,
    gripper: Gripper,
}

/// How far across the slot (m) a released part's centre may be from the slot's and still
/// stand between its dividers: (130 mm slot − 90 mm part) / 2 (competition.md §1.2).
const SLOT_CAPTURE_ACROSS_M: f64 = 0.020;
/// How far out of the slot (m) the part's centre may be and still count as in it: at least
/// half of its 60 mm depth inside the dividers' 70 mm (70 − 30). An assumption about how a
/// referee judges a part left short of the wall; the rules do not say.
const SLOT_CAPTURE_OUT_M: f64 = 0.040;
/// How far into the wall (m) the centre may be (a part pushed flush cannot go further).
const SLOT_CAPTURE_IN_M: f64 = 0.005;
/// How far (m) a part on the floor may be from a slot's box centre and still be that
/// slot's part to the referee when it is picked up: 50 mm, beyond the 30 mm a knock moves it
/// (assumption: the server's vision counts a part by the slot it is nearest).
const NEAR_SLOT_M: f64 = 0.050;
/// Largest angle between the part's plate and the slot's, rad (20°).
const SLOT_CAPTURE_RAD: f64 = 0.35;

impl Shop {
    /// The floor with one part per incoming slot (`None` = an empty slot, `X`).
    pub fn new(
        field: &Field,
        incoming: [Option<PartColor>; 4],
        machine_delay_us: u64,
        green_to_blue_at_a: bool,
        gripper: Gripper,
    ) -> Self {
        let parts: Vec<Part> = incoming
            .iter()
            .enumerate()
            .filter_map(|(i, color)| {
                let slot = field.incoming_slot(i)?;
                color.map(|color| Part {
                    color,
                    place: PartPlace::Slot(slot.waypoint),
                })
            })
            .collect();
        let machine_rows = [MachineKind::A, MachineKind::B]
            .into_iter()
            .flat_map(|kind| {
                field
                    .machine_block(kind)
                    .machines
                    .iter()
                    .map(move |m| (m.input.waypoint, kind, m.output.waypoint))
            })
            .collect();
        let slots: Vec<Slot> = field.slots().copied().collect();
        let seated = parts
            .iter()
            .map(|part| match part.place {
                PartPlace::Slot(id) => slots
                    .iter()
                    .find(|s| s.waypoint == id)
                    .map_or(Pose2::default(), slot_frame),
                _ => Pose2::default(),
            })
            .collect();
        Self {
            slots,
            machine_rows,
            parts,
            seated,
            where_released: false,
            processing: Vec::new(),
            machine_delay_us,
            green_to_blue_at_a,
            gripper,
        }
    }

    /// Every part.
    pub fn parts(&self) -> &[Part] {
        &self.parts
    }

    /// The index of the part the magnet holds, if any.
    pub fn carried(&self) -> Option<usize> {
        self.parts
            .iter()
            .position(|p| matches!(p.place, PartPlace::Carried(_)))
    }

    /// The part standing in the slot with waypoint `slot`, if any.
    pub fn part_in(&self, slot: WaypointId) -> Option<usize> {
        self.parts
            .iter()
            .position(|p| p.place == PartPlace::Slot(slot))
    }

    /// The server's four letters for a group of slots (`X` = empty), in slot order.
    pub fn letters(&self, slots: [WaypointId; 4]) -> String {
        slots
            .iter()
            .map(|&s| {
                self.part_in(s)
                    .map_or('X', |i| self.parts[i].color.letter())
            })
            .collect()
    }

    fn slot(&self, id: WaypointId) -> Option<&Slot> {
        self.slots.iter().find(|s| s.waypoint == id)
    }

    /// Moves each incoming part to where the referee placed it in its slot (`seats` in
    /// incoming slot order; an empty slot's seat is unused). The world then pushes a part
    /// drawn into a divider or the wall clear of it.
    pub fn seat_incoming(&mut self, seats: &[PartSeat; 4]) {
        let incoming: Vec<Slot> = self
            .slots
            .iter()
            .filter(|s| s.kind == SlotKind::Incoming)
            .copied()
            .collect();
        for (slot, seat) in incoming.iter().zip(seats) {
            if let Some(part) = self.part_in(slot.waypoint) {
                let yaw = seat.yaw_deg.to_radians();
                // Out from the wall by the gap, plus what a turned part's back corner needs.
                let corner = PART_DEPTH_M / 2.0 * yaw.cos() + PART_WIDTH_M / 2.0 * yaw.sin().abs();
                let out = seat.gap_m + corner - PART_DEPTH_M / 2.0;
                self.seated[part] = slot_frame(slot).compose(Pose2::new(out, seat.across_m, yaw));
            }
        }
    }

    /// Whether a part released into a slot stands where it was let go (worlds with contact)
    /// or centred against the slot's wall (the ideal world, as before contact).
    pub fn set_standing_where_released(&mut self, where_released: bool) {
        self.where_released = where_released;
    }

    /// Where the switch and the magnet reach.
    pub fn gripper(&self) -> Gripper {
        self.gripper
    }

    /// A part's footprint in the world, given the robot's pose (for a carried part).
    pub fn footprint(&self, part: usize, robot: Pose2) -> OrientedRect {
        let pose = match self.parts[part].place {
            PartPlace::Slot(_) => self.seated[part],
            PartPlace::Carried(local) => robot.compose(local),
            PartPlace::Floor(pose) => pose,
        };
        // Local x along the plate normal: depth along x, width along y.
        OrientedRect::new(pose, PART_DEPTH_M, PART_WIDTH_M)
    }

    /// The part whose plate the switch touches, if any: the carried part, or a standing part
    /// square in front of the robot within reach.
    pub fn switch_contact(&self, robot: Pose2) -> Option<usize> {
        if let Some(carried) = self.carried() {
            return Some(carried);
        }
        let g = self.gripper;
        (0..self.parts.len()).find(|&i| {
            let rect = self.footprint(i, robot);
            // The plate is the part's +x face.
            let plate = rect.pose.transform_point(Vec2::new(rect.half_x_m, 0.0));
            let local = robot.inverse_transform_point(plate);
            let facing = wrap_angle(rect.pose.yaw_rad + PI - robot.yaw_rad).abs();
            local.x >= g.front_m - 0.005
                && local.x <= g.front_m + g.reach_m
                && local.y.abs() <= g.lateral_tolerance_m
                && facing <= g.angle_tolerance_rad
        })
    }

    /// Advance to `now_us`: the magnet follows `solenoid_on`, machines work. Returns what
    /// happened, in order.
    pub fn step(&mut self, now_us: u64, robot: Pose2, solenoid_on: bool) -> Vec<PartEvent> {
        let mut events = Vec::new();
        match (self.carried(), solenoid_on) {
            (None, true) => {
                if let Some(part) = self.switch_contact(robot) {
                    let from = match self.parts[part].place {
                        PartPlace::Slot(id) => Some(id),
                        // Knocked a little out of its slot: the referee still counts it as
                        // that slot's part, and sees the slot empty once it is taken.
                        PartPlace::Floor(pose) => self.slot_near(pose.position()),
                        PartPlace::Carried(_) => None,
                    };
                    // The magnet pulls the plate flat against its face, where the plate is
                    // when the robot stands at a slot's pick pose; the part keeps its
                    // sideways offset.
                    let world = self.footprint(part, robot).pose;
                    let lateral = robot.relative(world).y.clamp(
                        -self.gripper.lateral_tolerance_m,
                        self.gripper.lateral_tolerance_m,
                    );
                    let held = Pose2::new(self.gripper.magnet_m + PART_DEPTH_M / 2.0, lateral, PI);
                    self.parts[part].place = PartPlace::Carried(held);
                    self.processing.retain(|p| p.part != part);
                    events.push(PartEvent::Picked { part, from });
                }
            }
            (Some(part), false) => {
                let world = self.footprint(part, robot).pose;
                events.push(self.release(part, world, now_us));
            }
            _ => {}
        }
        self.run_machines(now_us, &mut events);
        events
    }

    /// The slot whose box centre is within [`NEAR_SLOT_M`] of `point`, if any.
    fn slot_near(&self, point: Vec2) -> Option<WaypointId> {
        self.slots
            .iter()
            .find(|s| s.box_center.distance(point) <= NEAR_SLOT_M)
            .map(|s| s.waypoint)
    }

    /// Where the carried part `part` sits on the magnet, in the robot's frame (`None` if it
    /// is not carried).
    pub fn held_at(&self, part: usize) -> Option<Pose2> {
        match self.parts.get(part)?.place {
            PartPlace::Carried(local) => Some(local),
            _ => None,
        }
    }

    /// Contact: the carried part `part` sits at `local` (robot frame) on the magnet instead,
    /// where something on the floor stopped the magnet pulling it flat. No-op if the part is
    /// not carried.
    pub fn hold_at(&mut self, part: usize, local: Pose2) {
        if let Some(p) = self.parts.get_mut(part)
            && matches!(p.place, PartPlace::Carried(_))
        {
            p.place = PartPlace::Carried(local);
        }
    }

    /// Fault injection: put part `part` on the floor at `world` (knocked out of its slot, or
    /// slipped off the magnet); a machine working on it lets it go.
    pub fn put_on_floor(&mut self, part: usize, world: Pose2) {
        if let Some(p) = self.parts.get_mut(part) {
            p.place = PartPlace::Floor(world);
            self.processing.retain(|w| w.part != part);
        }
    }

    /// Contact: the world moves standing part `part` by `by` (m, world frame) to keep it out
    /// of the robot, a wall or another part. It stays its slot's part while it stands within
    /// the slot's capture zone ([`Self::slot_at`]); pushed beyond, it stands on the floor
    /// (and a machine working on it lets it go). A push never puts a part into a slot: only a
    /// release does. A carried part is not pushed (the robot carries it).
    pub fn push(&mut self, part: usize, by: Vec2) {
        let Some(place) = self.parts.get(part).map(|p| p.place) else {
            return;
        };
        let moved = |pose: Pose2| Pose2::new(pose.x + by.x, pose.y + by.y, pose.yaw_rad);
        match place {
            PartPlace::Slot(id) => {
                let pose = moved(self.seated[part]);
                if self.slot_at(pose).is_some_and(|s| s.waypoint == id) {
                    self.seated[part] = pose;
                } else {
                    self.put_on_floor(part, pose);
                }
            }
            PartPlace::Floor(pose) => self.parts[part].place = PartPlace::Floor(moved(pose)),
            PartPlace::Carried(_) => {}
        }
    }

    /// The slot a part standing at `world` would be in (between its dividers, plate facing
    /// the slot's way), if any.
    pub fn slot_at(&self, world: Pose2) -> Option<&Slot> {
        self.slots.iter().find(|slot| {
            let offset = world.position() - slot.box_center;
            let outward = offset.dot(Vec2::from_angle(slot.face_normal_rad));
            let across = offset.cross(Vec2::from_angle(slot.face_normal_rad)).abs();
            let centre_ok = across <= SLOT_CAPTURE_ACROSS_M
                && (-SLOT_CAPTURE_IN_M..=SLOT_CAPTURE_OUT_M).contains(&outward);
            // A part is symmetric under a half turn only in its footprint, not its plate:
            // require the plate to face the slot's way.
            let angle_ok =
                wrap_angle(world.yaw_rad - slot.face_normal_rad).abs() <= SLOT_CAPTURE_RAD;
            centre_ok && angle_ok
        })
    }

    fn release(&mut self, part: usize, world: Pose2, now_us: u64) -> PartEvent {
        let capture = self.slot_at(world);
        match capture.copied() {
            Some(slot) if self.part_in(slot.waypoint).is_none() => {
                self.parts[part].place = PartPlace::Slot(slot.waypoint);
                self.seated[part] = if self.where_released {
                    world
                } else {
                    slot_frame(&slot)
                };
                let row = self
                    .machine_rows
                    .iter()
                    .find(|r| r.0 == slot.waypoint)
                    .copied();
                if let Some((input, kind, output)) = row {
                    self.start_processing(part, kind, input, output, now_us);
                }
                PartEvent::Placed {
                    part,
                    slot: slot.waypoint,
                    color: self.parts[part].color,
                }
            }
            _ => {
                self.parts[part].place = PartPlace::Floor(world);
                PartEvent::Dropped { part }
            }
        }
    }

    fn start_processing(
        &mut self,
        part: usize,
        kind: MachineKind,
        input: WaypointId,
        output: WaypointId,
        now_us: u64,
    ) {
        let new_color = match (kind, self.parts[part].color) {
            (MachineKind::A, PartColor::Red) => Some(PartColor::Green),
            (MachineKind::A, PartColor::Green) if self.green_to_blue_at_a => Some(PartColor::Blue),
            (MachineKind::B, PartColor::Green) => Some(PartColor::Blue),
            _ => None,
        };
        if let Some(new_color) = new_color {
            self.processing.push(Processing {
                part,
                input,
                output,
                new_color,
                ready_at_us: now_us + self.machine_delay_us,
            });
        }
    }

    fn run_machines(&mut self, now_us: u64, events: &mut Vec<PartEvent>) {
        let mut k = 0;
        while k < self.processing.len() {
            let job = self.processing[k];
            let still_there = self.parts[job.part].place == PartPlace::Slot(job.input);
            if !still_there {
                self.processing.remove(k);
            } else if now_us >= job.ready_at_us && self.part_in(job.output).is_none() {
                self.parts[job.part] = Part {
                    color: job.new_color,
                    place: PartPlace::Slot(job.output),
                };
                // The machine's output: centred against the wall (the mover is not
                // specified; competition.md §1.3).
                if let Some(output) = self.slot(job.output) {
                    self.seated[job.part] = slot_frame(output);
                }
                events.push(PartEvent::Processed {
                    part: job.part,
                    color: job.new_color,
                });
                self.processing.remove(k);
            } else {
                k += 1;
            }
        }
    }
}

/// A slot's frame: at the centre of a part standing centred against the slot's back wall,
/// x along the plate's outward normal.
fn slot_frame(slot: &Slot) -> Pose2 {
    Pose2::new(slot.box_center.x, slot.box_center.y, slot.face_normal_rad)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shop(field: &Field, delay_us: u64) -> Shop {
        use PartColor::*;
        Shop::new(
            field,
            [Some(Red), Some(Green), None, Some(Blue)],
            delay_us,
            false,
            Gripper::new(0.15),
        )
    }

    #[test]
    fn letters_follow_the_slots_and_empty_is_x() {
        let field = Field::competition();
        let shop = shop(&field, 0);
        let incoming = [50, 51, 52, 53].map(WaypointId);
        assert_eq!(shop.letters(incoming), "RGXB");
        assert_eq!(shop.letters([62, 63, 64, 65].map(WaypointId)), "XXXX");
    }

    #[test]
    fn the_switch_closes_only_at_the_pick_pose() {
        let field = Field::competition();
        let shop = shop(&field, 0);
        let slot = *field.incoming_slot(0).unwrap();
        assert_eq!(shop.switch_contact(slot.pick_pose), Some(0));
        // 2 cm short of the pick pose: out of reach.
        let short = slot.pose_at_standoff(0.185);
        assert_eq!(shop.switch_contact(short), None);
        // Square but 4 cm to the side: the magnet misses the plate.
        let mut aside = slot.pick_pose;
        aside.x += 0.04;
        assert_eq!(shop.switch_contact(aside), None);
        // Turned 30°: not square.
        let mut turned = slot.pick_pose;
        turned.yaw_rad += 30f64.to_radians();
        assert_eq!(shop.switch_contact(turned), None);
        // An empty slot closes nothing.
        assert_eq!(
            shop.switch_contact(field.incoming_slot(2).unwrap().pick_pose),
            None
        );
    }

    #[test]
    fn pick_carry_and_place_in_a_machine_that_turns_the_part() {
        let field = Field::competition();
        let mut shop = shop(&field, 2_000_000);
        let from = *field.incoming_slot(0).unwrap();
        let to = field.machine(MachineKind::A, 0).unwrap().input;
        assert_eq!(
            shop.step(0, from.pick_pose, true),
            [PartEvent::Picked {
                part: 0,
                from: Some(from.waypoint)
            }]
        );
        assert_eq!(shop.letters([50, 51, 52, 53].map(WaypointId)), "XGXB");
        // Carried to the machine with the magnet on: it follows the robot.
        assert!(shop.step(1_000, to.pick_pose, true).is_empty());
        assert_eq!(
            shop.step(2_000, to.pick_pose, false),
            [PartEvent::Placed {
                part: 0,
                slot: to.waypoint,
                color: PartColor::Red
            }]
        );
        assert_eq!(shop.part_in(to.waypoint), Some(0));
        // Before the delay nothing happens; after it the part is green on the output.
        assert!(shop.step(1_000_000, to.pick_pose, false).is_empty());
        assert_eq!(
            shop.step(2_002_000, to.pick_pose, false),
            [PartEvent::Processed {
                part: 0,
                color: PartColor::Green
            }]
        );
        assert_eq!(shop.part_in(WaypointId(to.waypoint.0 + 1)), Some(0));
    }

    #[test]
    fn a_part_counts_as_in_a_slot_while_it_stands_between_the_dividers() {
        let field = Field::competition();
        let from = *field.incoming_slot(0).unwrap();
        let to = *field.outgoing_slot(1).unwrap();
        // Released with the robot backed off along the slot's normal, or moved across it.
        let outcome = |out_m: f64, across_m: f64| {
            let mut shop = shop(&field, 0);
            shop.step(0, from.pick_pose, true);
            let normal = ratf_core::field::geometry::Vec2::from_angle(to.face_normal_rad);
            let side = normal.rotated(std::f64::consts::FRAC_PI_2);
            let p = to.pick_pose.position() + normal * out_m + side * across_m;
            let pose = Pose2::new(p.x, p.y, to.pick_pose.yaw_rad);
            shop.step(10, pose, true);
            shop.step(20, pose, false)[0]
        };
        assert!(matches!(outcome(0.0, 0.0), PartEvent::Placed { .. }));
        assert!(matches!(outcome(0.035, 0.0), PartEvent::Placed { .. }));
        assert!(matches!(outcome(0.0, 0.015), PartEvent::Placed { .. }));
        assert!(matches!(outcome(0.05, 0.0), PartEvent::Dropped { .. }));
        assert!(matches!(outcome(0.0, 0.03), PartEvent::Dropped { .. }));
    }

    #[test]
    fn a_part_released_away_from_slots_stays_on_the_floor() {
        let field = Field::competition();
        let mut shop = shop(&field, 0);
        let from = *field.incoming_slot(3).unwrap();
        shop.step(0, from.pick_pose, true);
        let middle = Pose2::new(0.0, 0.0, 0.0);
        assert_eq!(
            shop.step(10, middle, false),
            [PartEvent::Dropped { part: 2 }]
        );
        assert!(matches!(shop.parts()[2].place, PartPlace::Floor(_)));
        assert_eq!(shop.switch_contact(middle), Some(2)); // still right in front of the robot
    }

    #[test]
    fn a_part_seated_off_centre_stands_there_and_is_picked_at_the_pick_pose() {
        let field = Field::competition();
        let slot = *field.incoming_slot(0).unwrap();
        // A realistic placement picked at the pick pose; the harshest drawn (20 mm across,
        // 15 mm from the wall, 8° turned) stands 21 mm proud, into where the body would be at
        // the pick pose: the switch closes 15 mm short of it.
        for (across_m, gap_m, yaw_deg, standoff_m) in
            [(0.01, 0.005, 3.0, 0.165), (-0.02, 0.015, -8.0, 0.18)]
        {
            let robot = slot.pose_at_standoff(standoff_m);
            let mut shop = shop(&field, 0);
            let seat = PartSeat {
                across_m,
                gap_m,
                yaw_deg,
            };
            shop.seat_incoming(&[seat; 4]);
            let at = slot_frame(&slot).relative(shop.footprint(0, slot.pick_pose).pose);
            assert!((at.y - across_m).abs() < 1e-12, "{at:?}");
            assert!((at.yaw_rad.to_degrees() - yaw_deg).abs() < 1e-9);
            // Its back corner is the gap from the wall (x = −30 mm in the slot's frame).
            let yaw = yaw_deg.to_radians();
            let back = at.x - (0.03 * yaw.cos() + 0.045 * yaw.sin().abs());
            assert!((back + 0.03 - gap_m).abs() < 1e-12, "{at:?}");
            assert_eq!(shop.part_in(slot.waypoint), Some(0));
            assert_eq!(shop.switch_contact(robot), Some(0));
            assert_eq!(
                shop.step(0, robot, true),
                [PartEvent::Picked {
                    part: 0,
                    from: Some(slot.waypoint)
                }]
            );
        }
    }

    #[test]
    fn a_pushed_part_stays_its_slots_until_it_leaves_the_slot() {
        let field = Field::competition();
        let slot = *field.incoming_slot(1).unwrap();
        let mut shop = shop(&field, 0);
        let out = Vec2::from_angle(slot.face_normal_rad);
        // 1 cm out of the slot: still there, 1 cm further out.
        shop.push(1, out * 0.01);
        assert_eq!(shop.part_in(slot.waypoint), Some(1));
        let at = shop.footprint(1, slot.pick_pose).pose;
        assert!((at.position() - slot.box_center - out * 0.01).norm() < 1e-12);
        // 5 cm more: on the floor, the slot empty for the server.
        shop.push(1, out * 0.05);
        assert_eq!(shop.part_in(slot.waypoint), None);
        assert!(matches!(shop.parts()[1].place, PartPlace::Floor(_)));
        assert_eq!(shop.letters([50, 51, 52, 53].map(WaypointId)), "RXXB");
        // Pushed back in, it stays on the floor: only a release puts a part into a slot.
        shop.push(1, out * -0.06);
        assert!(matches!(shop.parts()[1].place, PartPlace::Floor(_)));
    }

    #[test]
    fn machine_b_refuses_red_and_a_waits_for_a_free_output() {
        let field = Field::competition();
        let mut shop = shop(&field, 0);
        let b_in = field.machine(MachineKind::B, 0).unwrap().input;
        let from = *field.incoming_slot(0).unwrap();
        shop.step(0, from.pick_pose, true);
        shop.step(1, b_in.pick_pose, true);
        shop.step(2, b_in.pick_pose, false);
        let events = shop.step(100, b_in.pick_pose, false);
        assert!(events.is_empty(), "{events:?}");
        assert_eq!(shop.part_in(b_in.waypoint), Some(0));
        assert_eq!(shop.parts()[0].color, PartColor::Red);
    }
}
