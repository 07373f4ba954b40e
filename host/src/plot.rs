//! SVG plots of the shop floor with paths, footprints and markers drawn on it.
//!
//! The drawing is in world coordinates (metres, +y up), mapped to SVG pixels at
//! [`PIXELS_PER_M`] with y flipped. Numbers are written with fixed precision (0.1 px), so the
//! same run gives the same file byte for byte. The floor carries its labels (warehouses,
//! machines, slots, beacons) and a scale bar; picks and drops have their own marks, and
//! collisions are numbered on the map and listed in words below it, so that marks close
//! together stay readable.

use std::fmt::Write;

use ratf_core::field::geometry::{Rect, Vec2};
use ratf_core::field::stations::SlotKind;
use ratf_core::field::{Field, MachineKind, WarehouseKind};
use ratf_core::runtime::slot_name;

/// Drawing scale, SVG pixels per metre.
pub const PIXELS_PER_M: f64 = 500.0;

/// The part of the world drawn: the printed floor plus the beacons just outside it, a band
/// above for the title and the legend, and one below for the scale bar and the collisions.
const VIEW: Rect = Rect {
    min: Vec2::new(-0.95, -0.74),
    max: Vec2::new(0.95, 0.80),
};

/// Collisions within this distance of each other share one numbered mark, m.
const COLLISION_CLUSTER_M: f64 = 0.05;
/// Collision lines listed under the floor before "and N more".
const COLLISION_LINES: usize = 3;

/// An SVG drawing of the field with things added on top.
#[derive(Clone, Debug)]
pub struct FieldPlot {
    body: String,
    legend: Vec<(String, String)>,
    collisions: Vec<(Vec2, Vec<String>)>,
}

fn px(v: Vec2) -> (f64, f64) {
    (
        (v.x - VIEW.min.x) * PIXELS_PER_M,
        (VIEW.max.y - v.y) * PIXELS_PER_M,
    )
}

fn points_attr(points: &[Vec2]) -> String {
    let mut out = String::new();
    for (i, &p) in points.iter().enumerate() {
        let (x, y) = px(p);
        if i > 0 {
            out.push(' ');
        }
        let _ = write!(out, "{x:.1},{y:.1}");
    }
    out
}

/// Text safe to put inside an SVG element.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

impl FieldPlot {
    /// The floor: printed area, start area, walls and dividers, box slots, beacons.
    pub fn new(field: &Field) -> Self {
        let mut plot = Self {
            body: String::new(),
            legend: Vec::new(),
            collisions: Vec::new(),
        };
        plot.rect(field.printed_area(), "#fafafa", "#999999");
        plot.rect(field.start_area(), "#e3f5e1", "#8bc48a");
        for slot in field.slots() {
            plot.rect(slot.box_rect(), "none", "#cccccc");
        }
        for obstacle in field.obstacles() {
            plot.rect(obstacle.rect, "#555555", "#333333");
        }
        for beacon in field.beacons() {
            let (x, y) = px(beacon.circle.center);
            let r = beacon.circle.radius_m * PIXELS_PER_M;
            let _ = writeln!(
                plot.body,
                r##"<circle cx="{x:.1}" cy="{y:.1}" r="{r:.1}" fill="#f2c14e" stroke="#9a7412"/>"##
            );
            let out = beacon.circle.radius_m + 0.025;
            let dy = if beacon.circle.center.y > 0.0 {
                out
            } else {
                -out
            };
            let at = beacon.circle.center + Vec2::new(0.0, dy);
            plot.label(at, &format!("B{}", beacon.index), 11.0, "#9a7412");
        }
        for slot in field.slots() {
            let name = slot_name(field, slot.waypoint);
            let number = name.chars().last().unwrap_or('?');
            let short = match slot.kind {
                SlotKind::Incoming => format!("I{number}"),
                SlotKind::Outgoing => format!("O{number}"),
                SlotKind::MachineInput => "in".to_owned(),
                SlotKind::MachineOutput => "out".to_owned(),
            };
            plot.label(slot.box_rect().center(), &short, 9.0, "#777777");
        }
        let areas = [
            (
                field.warehouse(WarehouseKind::Incoming).wall.rect,
                "incoming warehouse",
            ),
            (
                field.warehouse(WarehouseKind::Outgoing).wall.rect,
                "outgoing warehouse",
            ),
            (field.machine_block(MachineKind::A).wall.rect, "machine A"),
            (field.machine_block(MachineKind::B).wall.rect, "machine B"),
        ];
        for (rect, name) in areas {
            let y = if rect.min.y > 0.0 {
                rect.max.y + 0.025
            } else {
                rect.min.y - 0.035
            };
            plot.label(Vec2::new(rect.center().x, y), name, 12.0, "#1f2a36");
        }
        plot.label(
            Vec2::new(
                field.start_area().center().x,
                field.start_area().min.y + 0.02,
            ),
            "start",
            10.0,
            "#4a8a49",
        );
        plot.scale_bar();
        plot
    }

    /// Text centred at `at` (world, m).
    fn label(&mut self, at: Vec2, text: &str, size: f64, color: &str) {
        let (x, y) = px(at);
        let _ = writeln!(
            self.body,
            r#"<text x="{x:.1}" y="{y:.1}" font-size="{size:.0}" fill="{color}" text-anchor="middle" dominant-baseline="middle">{}</text>"#,
            escape(text)
        );
    }

    /// A 20 cm bar under the floor, left of centre.
    fn scale_bar(&mut self) {
        let (x, y) = px(Vec2::new(-0.60, -0.685));
        let length = 0.2 * PIXELS_PER_M;
        let _ = writeln!(
            self.body,
            r##"<path d="M{x:.1},{:.1} V{:.1} H{:.1} V{:.1} M{:.1},{:.1} V{:.1}" fill="none" stroke="#222222" stroke-width="2"/><text x="{:.1}" y="{:.1}" font-size="12">20 cm</text>"##,
            y - 5.0,
            y,
            x + length,
            y - 5.0,
            x + length / 2.0,
            y,
            y - 3.0,
            x + length + 6.0,
            y + 1.0
        );
    }

    /// A pick (an upward triangle) or a drop (a downward one) at `at` (world, m), outlined
    /// in the part's colour `color`.
    pub fn pick_or_drop(&mut self, at: Vec2, picked: bool, color: &str) {
        let (x, y) = px(at);
        let s = if picked { 7.0 } else { -7.0 };
        let _ = writeln!(
            self.body,
            r##"<path d="M{x:.1},{:.1} L{:.1},{:.1} L{:.1},{:.1} Z" fill="{color}" stroke="#111111" stroke-width="1.2" opacity="0.9"/>"##,
            y - s,
            x - 6.0,
            y + s * 0.7,
            x + 6.0,
            y + s * 0.7
        );
    }

    /// A collision at `at` (world, m) described by `text`: collisions near each other share
    /// one numbered cross; [`FieldPlot::finish`] lists them under the floor.
    pub fn collision(&mut self, at: Vec2, text: &str) {
        match self
            .collisions
            .iter_mut()
            .find(|(p, _)| p.distance(at) < COLLISION_CLUSTER_M)
        {
            Some((_, texts)) => texts.push(text.to_owned()),
            None => self.collisions.push((at, vec![text.to_owned()])),
        }
    }

    fn draw_collisions(&mut self) {
        let collisions = std::mem::take(&mut self.collisions);
        let bottom = (VIEW.max.y - VIEW.min.y) * PIXELS_PER_M;
        let mut lines = Vec::new();
        for (i, (at, texts)) in collisions.iter().enumerate() {
            let (x, y) = px(*at);
            let s = 6.0;
            let number = i + 1;
            let _ = writeln!(
                self.body,
                r##"<path d="M{:.1},{:.1} L{:.1},{:.1} M{:.1},{:.1} L{:.1},{:.1}" stroke="#d01010" stroke-width="2.5"/><circle cx="{:.1}" cy="{:.1}" r="8" fill="#d01010"/><text x="{:.1}" y="{:.1}" font-size="11" fill="white" text-anchor="middle" dominant-baseline="middle">{number}</text>"##,
                x - s,
                y - s,
                x + s,
                y + s,
                x - s,
                y + s,
                x + s,
                y - s,
                x + s + 6.0,
                y - s - 6.0,
                x + s + 6.0,
                y - s - 6.0,
            );
            let times = if texts.len() > 1 {
                format!(" (×{})", texts.len())
            } else {
                String::new()
            };
            lines.push(format!("{number}: {}{times}", texts[0]));
        }
        if lines.len() > COLLISION_LINES {
            let more = lines.len() - COLLISION_LINES;
            lines.truncate(COLLISION_LINES);
            lines.push(format!("and {more} more"));
        }
        // One column right of the scale bar, in the band under the floor.
        for (i, line) in lines.iter().enumerate() {
            let _ = writeln!(
                self.body,
                r##"<text x="420.0" y="{:.1}" font-size="11" fill="#d01010">{}</text>"##,
                bottom - 48.0 + 13.0 * i as f64,
                escape(line)
            );
        }
    }

    fn rect(&mut self, rect: Rect, fill: &str, stroke: &str) {
        let (x, y) = px(Vec2::new(rect.min.x, rect.max.y));
        let (w, h) = (rect.size_x() * PIXELS_PER_M, rect.size_y() * PIXELS_PER_M);
        let _ = writeln!(
            self.body,
            r#"<rect x="{x:.1}" y="{y:.1}" width="{w:.1}" height="{h:.1}" fill="{fill}" stroke="{stroke}"/>"#
        );
    }

    /// A polyline through `points` (world, m), listed in the legend as `label`.
    pub fn path(&mut self, points: &[Vec2], color: &str, dashed: bool, label: &str) {
        let dash = if dashed {
            r#" stroke-dasharray="6 4""#
        } else {
            ""
        };
        let _ = writeln!(
            self.body,
            r#"<polyline points="{}" fill="none" stroke="{color}" stroke-width="2"{dash}/>"#,
            points_attr(points)
        );
        self.legend.push((color.to_owned(), label.to_owned()));
    }

    /// A line in the legend with no drawing of its own (for marks).
    pub fn legend_entry(&mut self, color: &str, label: &str) {
        self.legend.push((color.to_owned(), label.to_owned()));
    }

    /// A closed outline through `corners` (world, m), e.g. the robot's footprint.
    pub fn outline(&mut self, corners: &[Vec2], color: &str) {
        let _ = writeln!(
            self.body,
            r#"<polygon points="{}" fill="none" stroke="{color}" stroke-width="1" opacity="0.6"/>"#,
            points_attr(corners)
        );
    }

    /// A filled shape through `corners` (world, m), e.g. a part.
    pub fn filled(&mut self, corners: &[Vec2], fill: &str) {
        let _ = writeln!(
            self.body,
            r##"<polygon points="{}" fill="{fill}" stroke="#222222" stroke-width="1"/>"##,
            points_attr(corners)
        );
    }

    /// A cross at `at` (world, m) with a text label, e.g. a collision.
    pub fn mark(&mut self, at: Vec2, color: &str, label: &str) {
        let (x, y) = px(at);
        let s = 6.0;
        let _ = writeln!(
            self.body,
            r#"<path d="M{:.1},{:.1} L{:.1},{:.1} M{:.1},{:.1} L{:.1},{:.1}" stroke="{color}" stroke-width="2"/><text x="{:.1}" y="{:.1}" font-size="11" fill="{color}">{}</text>"#,
            x - s,
            y - s,
            x + s,
            y + s,
            x - s,
            y + s,
            x + s,
            y - s,
            x + s + 2.0,
            y - s,
            escape(label)
        );
    }

    /// The finished SVG document, with `title` and the legend.
    pub fn finish(mut self, title: &str) -> String {
        self.draw_collisions();
        let width = VIEW.size_x() * PIXELS_PER_M;
        let height = VIEW.size_y() * PIXELS_PER_M;
        let _ = writeln!(
            self.body,
            r##"<text x="8" y="18" font-size="14" fill="#222222">{}</text>"##,
            escape(title)
        );
        for (i, (color, label)) in self.legend.iter().enumerate() {
            let y = 38.0 + 16.0 * i as f64;
            // Legend entries run down the band above the floor (0.80 − 0.66 m = 70 px).
            let _ = writeln!(
                self.body,
                r#"<line x1="8" y1="{:.1}" x2="28" y2="{:.1}" stroke="{color}" stroke-width="3"/><text x="34" y="{:.1}" font-size="12">{}</text>"#,
                y - 4.0,
                y - 4.0,
                y,
                escape(label)
            );
        }
        format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width:.0}\" height=\"{height:.0}\" viewBox=\"0 0 {width:.0} {height:.0}\" font-family=\"sans-serif\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n{}</svg>\n",
            self.body
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_field_is_drawn_with_every_wall_and_beacon() {
        let field = Field::competition();
        let svg = FieldPlot::new(&field).finish("test");
        assert!(svg.starts_with("<svg"));
        assert!(svg.trim_end().ends_with("</svg>"));
        let walls = svg.matches(r##"fill="#555555""##).count();
        assert_eq!(walls, field.obstacles().len());
        assert_eq!(svg.matches("<circle").count(), 4);
    }

    #[test]
    fn world_y_is_flipped_and_the_origin_is_centred() {
        let (x, y) = px(Vec2::ZERO);
        assert!((x - 0.95 * PIXELS_PER_M).abs() < 1e-9);
        assert!((y - 0.80 * PIXELS_PER_M).abs() < 1e-9);
        let (_, up) = px(Vec2::new(0.0, 0.5));
        assert!(up < y);
    }

    #[test]
    fn the_floor_is_labelled_and_nearby_collisions_share_a_numbered_mark() {
        let mut plot = FieldPlot::new(&Field::competition());
        for text in ["machine A wall", "machine A wall", "beacon B1"] {
            let at = if text.starts_with("beacon") {
                Vec2::new(0.5, 0.5)
            } else {
                Vec2::new(0.1, 0.1)
            };
            plot.collision(at, text);
        }
        plot.pick_or_drop(Vec2::ZERO, true, "#d03030");
        let svg = plot.finish("t");
        for label in [
            "incoming warehouse",
            "machine B",
            ">I1<",
            ">O4<",
            ">B3<",
            "20 cm",
        ] {
            assert!(svg.contains(label), "{label}");
        }
        assert!(svg.contains("1: machine A wall (×2)"), "{svg}");
        assert!(svg.contains("2: beacon B1"));
        assert!(!svg.contains(">3<"), "two marks, not three");
    }

    #[test]
    fn labels_are_escaped() {
        let mut plot = FieldPlot::new(&Field::competition());
        plot.mark(Vec2::ZERO, "red", "a<b & c");
        let svg = plot.finish("t");
        assert!(svg.contains("a&lt;b &amp; c"));
    }
}
