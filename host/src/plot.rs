//! SVG plots of the shop floor with paths, footprints and markers drawn on it.
//!
//! The drawing is in world coordinates (metres, +y up), mapped to SVG pixels at
//! [`PIXELS_PER_M`] with y flipped. Numbers are written with fixed precision (0.1 px), so the
//! same run gives the same file byte for byte.

use std::fmt::Write;

use ratf_core::field::Field;
use ratf_core::field::geometry::{Rect, Vec2};

/// Drawing scale, SVG pixels per metre.
pub const PIXELS_PER_M: f64 = 500.0;

/// The part of the world drawn: the printed floor plus the beacons just outside it, and a
/// band above for the title and the legend.
const VIEW: Rect = Rect {
    min: Vec2::new(-0.95, -0.66),
    max: Vec2::new(0.95, 0.80),
};

/// An SVG drawing of the field with things added on top.
#[derive(Clone, Debug)]
pub struct FieldPlot {
    body: String,
    legend: Vec<(String, String)>,
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
        }
        plot
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
    fn labels_are_escaped() {
        let mut plot = FieldPlot::new(&Field::competition());
        plot.mark(Vec2::ZERO, "red", "a<b & c");
        let svg = plot.finish("t");
        assert!(svg.contains("a&lt;b &amp; c"));
    }
}
