//! The HMI's runtime tap: follows every step and publishes a [`Snapshot`] to the [`Hub`]
//! every [`PUBLISH_PERIOD`] of wall time (20 a second), whatever the loop's pace.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use ratf_core::config::Config;
use ratf_core::drivers::x4::scan::Scan;
use ratf_core::field::geometry::{Pose2, Vec2};
use ratf_core::field::{Field, PartColor, WaypointId};
use ratf_core::robot::InputCounts;
use ratf_core::runtime::{Core, Event, Input, StepView, Tap, slot_name};

use super::hub::Hub;
use super::snapshot::{
    BeaconsView, EventLine, HealthView, PartView, PoseView, ReplayView, Snapshot, Target,
    WheelsView, color_letter, event_kind,
};

/// Wall time between snapshots: 20 a second, above the ≥ 10 the issue asks.
pub const PUBLISH_PERIOD: Duration = Duration::from_millis(50);
/// Timeline lines a snapshot carries (the latest).
pub const TIMELINE_LINES: usize = 200;
/// Robot time over which the device rates are measured, µs.
const RATE_WINDOW_US: u64 = 500_000;

/// Lines from outside the core for the timeline (the simulator's collisions and points),
/// shared with whoever hears them.
#[derive(Clone, Debug, Default)]
pub struct Notes(Arc<Mutex<Vec<Note>>>);

/// A timeline line, with the new points total when it scores.
type Note = (EventLine, Option<u32>);

impl Notes {
    /// Add a line; `points` is the new total when the line scores.
    pub fn push(&self, line: EventLine, points: Option<u32>) {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push((line, points));
    }

    fn drain(&self) -> Vec<Note> {
        std::mem::take(&mut *self.0.lock().unwrap_or_else(PoisonError::into_inner))
    }
}

/// See the module documentation.
pub struct HmiTap {
    hub: Arc<Hub>,
    mode: &'static str,
    field: Field,
    config: Config,
    last_publish: Option<Instant>,
    events: Vec<EventLine>,
    notes: Notes,
    points: Option<u32>,
    scan: Option<(Scan, Pose2)>,
    scans_with_dropped_packets: u64,
    wheels: WheelsView,
    magnet: bool,
    action: Option<(WaypointId, WaypointId)>,
    carrying: Option<Option<PartColor>>,
    parts: BTreeMap<u8, Option<PartColor>>,
    faults: Vec<String>,
    rate_base: Option<(u64, InputCounts)>,
    rates: (f64, f64, f64),
    truth: Option<Pose2>,
    /// The replay player's state, shown with the snapshot.
    pub replay: Option<ReplayView>,
    /// The simulated round and seed, shown with the snapshot.
    pub round: Option<(u8, u64)>,
}

impl HmiTap {
    /// A tap publishing to `hub` for a run of `mode` (`sim`, `robot`, `replay`) of a robot
    /// configured by `config`.
    pub fn new(hub: Arc<Hub>, mode: &'static str, config: &Config) -> Self {
        Self {
            hub,
            mode,
            field: config.field.field(),
            config: config.clone(),
            last_publish: None,
            events: Vec::new(),
            notes: Notes::default(),
            points: (mode == "sim").then_some(0),
            scan: None,
            scans_with_dropped_packets: 0,
            wheels: WheelsView::default(),
            magnet: false,
            action: None,
            carrying: None,
            parts: BTreeMap::new(),
            faults: Vec::new(),
            rate_base: None,
            rates: (0.0, 0.0, 0.0),
            truth: None,
            replay: None,
            round: None,
        }
    }

    /// The handle for lines from outside the core (the simulator's collisions and points).
    pub fn notes(&self) -> Notes {
        self.notes.clone()
    }

    fn on_event(&mut self, t_s: f64, event: &Event) {
        match event {
            Event::PartList { parts, .. } => {
                self.parts.clear();
                for (i, color) in parts.iter().enumerate() {
                    if let (Some(color), Some(slot)) = (color, self.field.incoming_slot(i)) {
                        self.parts.insert(slot.waypoint.0, Some(*color));
                    }
                }
            }
            Event::ActionStarted { pick, drop, .. } => {
                self.action = Some((*pick, *drop));
            }
            Event::Picked { slot, color } => {
                self.parts.remove(&slot.0);
                self.carrying = Some(*color);
            }
            Event::Placed { slot, color } => {
                self.parts.insert(slot.0, *color);
                self.carrying = None;
                self.action = None;
            }
            Event::PartSlipped { .. }
            | Event::PartJammed { .. }
            | Event::PartLetGoInHold { .. }
            | Event::PartLetGoNearDrop { .. } => self.carrying = None,
            Event::Regripped { color } => self.carrying = Some(*color),
            Event::Skipped { .. } | Event::Finished => {
                self.action = None;
            }
            Event::DeviceFault { .. } => self.faults.push(event.describe(&self.field)),
            _ => {}
        }
        self.events.push(EventLine {
            t_s,
            kind: event_kind(event),
            text: event.describe(&self.field),
        });
    }

    fn target(&self) -> Option<Target> {
        let (pick, drop) = self.action?;
        let (id, what) = if self.carrying.is_some() {
            (drop, "drop")
        } else {
            (pick, "pick")
        };
        let at = self.field.waypoints().position(id)?;
        Some(Target {
            waypoint: id.0,
            at: [at.x, at.y],
            what,
            name: slot_name(&self.field, id),
        })
    }

    fn scan_points(&self) -> Vec<[f32; 2]> {
        let Some((scan, pose)) = &self.scan else {
            return Vec::new();
        };
        let lidar = pose.compose(self.config.robot.lidar_mount());
        scan.points
            .iter()
            .map(|p| {
                let r = self.config.lidar.corrected_range_m(p.range_m);
                let w = lidar.transform_point(Vec2::from_angle(p.angle_rad) * r);
                [
                    ((w.x * 1e3).round() * 1e-3) as f32,
                    ((w.y * 1e3).round() * 1e-3) as f32,
                ]
            })
            .collect()
    }

    fn update_rates(&mut self, now_us: u64, counts: InputCounts) {
        match self.rate_base {
            Some((base_us, base)) if now_us >= base_us + RATE_WINDOW_US => {
                let dt = (now_us - base_us) as f64 * 1e-6;
                let per_s = |a: u64, b: u64| a.saturating_sub(b) as f64 / dt;
                self.rates = (
                    per_s(counts.wheel_batches, base.wheel_batches),
                    per_s(counts.scans, base.scans),
                    per_s(counts.imu_samples, base.imu_samples),
                );
                self.rate_base = Some((now_us, counts));
            }
            Some((base_us, _)) if now_us >= base_us => {}
            _ => self.rate_base = Some((now_us, counts)),
        }
    }

    /// What the page shows now of `core`.
    pub fn snapshot(&mut self, core: &Core) -> Snapshot {
        let status = core.status();
        self.update_rates(status.time.as_us(), status.inputs);
        let covariance = core.robot().estimation().estimator().covariance();
        let health = core.localisation_health();
        let last = health.last_scan;
        let measured = core
            .robot()
            .last_odometry()
            .map_or([0.0; 4], |o| o.wheel_speeds_rad_s);
        Snapshot {
            mode: self.mode,
            round: self.round,
            time_s: status.time.as_secs_f64(),
            clock_s: status
                .started
                .map(|s| status.time.as_secs_f64() - s.as_secs_f64()),
            phase: status.phase,
            stopped: status.stopped,
            manual: status.manual,
            placed: status.placed,
            points: self.points,
            pose: status.pose.into(),
            covariance_m2: [covariance[(0, 0)], covariance[(0, 1)], covariance[(1, 1)]],
            heading_std_rad: status.pose_std.1,
            truth: self.truth.map(PoseView::from),
            scan: self.scan_points(),
            beacons: BeaconsView {
                used: last.beacons_used,
                gated: last.beacons_gated,
                rejected: last.clusters_rejected,
                unseen: last.beacons_unseen,
                seen: last.nis.map(|n| n.is_some()),
            },
            target: self.target(),
            path: core
                .brain()
                .planned_route()
                .map(|route| route.points().iter().map(|p| [p.x, p.y]).collect())
                .unwrap_or_default(),
            parts: self
                .parts
                .iter()
                .filter_map(|(&waypoint, &color)| {
                    let slot = self.field.slot_for_waypoint(WaypointId(waypoint))?;
                    Some(PartView {
                        waypoint,
                        at: [slot.box_center.x, slot.box_center.y],
                        color: color_letter(color),
                    })
                })
                .collect(),
            carrying: self.carrying.map(color_letter),
            magnet: self.magnet,
            switch_pressed: status.switch_pressed,
            wheels: WheelsView {
                measured_rad_s: measured,
                ..self.wheels
            },
            health: HealthView {
                wheel_hz: self.rates.0,
                scan_hz: self.rates.1,
                imu_hz: self.rates.2,
                mega_resets: status.inputs.mega_resets,
                scans_with_dropped_packets: self.scans_with_dropped_packets,
                scans_without_beacons: health.scans_without_beacons,
                lost: health.relocking,
                faults: self.faults.clone(),
            },
            events: self.events[self.events.len().saturating_sub(TIMELINE_LINES)..].to_vec(),
            replay: self.replay,
        }
    }

    /// Publish what the page shows of `core` now, whatever the time since the last.
    pub fn publish(&mut self, core: &Core) {
        let snapshot = self.snapshot(core);
        if let Ok(json) = serde_json::to_string(&snapshot) {
            self.hub.publish(json);
        }
        self.last_publish = Some(Instant::now());
    }
}

impl Tap for HmiTap {
    fn on_step(&mut self, step: &StepView<'_>) {
        let t_s = step.input.time.as_secs_f64();
        for (line, points) in self.notes.drain() {
            self.points = points.or(self.points);
            self.events.push(line);
        }
        for event in &step.outputs.events {
            self.on_event(t_s, event);
        }
        if let Input::Scan(scan) = &step.input.input {
            if scan.packets_dropped > 0 {
                self.scans_with_dropped_packets += 1;
            }
            self.scan = Some((scan.clone(), step.core.pose()));
        }
        if let Some(wheels) = step.outputs.wheels {
            self.wheels.reference_rad_s = wheels.wheel_speeds_rad_s;
            self.magnet = wheels.solenoid_on;
        }
        if step.ground_truth.is_some() {
            self.truth = step.ground_truth;
        }
        // At once when something happened, so the page never misses the last state.
        let due = self
            .last_publish
            .is_none_or(|at| at.elapsed() >= PUBLISH_PERIOD);
        if due || !step.outputs.events.is_empty() {
            self.publish(step.core);
        }
    }
}
