//! A time-series SVG: one panel per series pair (measured against modelled), shared time
//! axis. Numbers are written with fixed precision so the same data gives the same file.

use std::fmt::Write;

/// One panel: a title and two curves over time (s).
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Title, e.g. `wheel 0: K 2.19 (rad/s)/V, τ 0.10 s, R² 0.97`.
    pub title: String,
    /// Sample times, s.
    pub time_s: Vec<f64>,
    /// Measured values (drawn in grey).
    pub measured: Vec<f64>,
    /// Model values (drawn in red).
    pub modelled: Vec<f64>,
}

const WIDTH: f64 = 1200.0;
const PANEL_H: f64 = 180.0;
const MARGIN: f64 = 50.0;

/// The SVG of `panels` stacked, with `unit` on the vertical axes.
pub fn time_series(panels: &[Panel], unit: &str) -> String {
    let height = PANEL_H * panels.len() as f64 + MARGIN;
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH:.0}" height="{height:.0}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(svg, r#"<rect width="100%" height="100%" fill="white"/>"#);
    for (i, panel) in panels.iter().enumerate() {
        let top = MARGIN / 2.0 + i as f64 * PANEL_H;
        let (t0, t1) = range(&panel.time_s);
        let all: Vec<f64> = panel
            .measured
            .iter()
            .chain(&panel.modelled)
            .copied()
            .collect();
        let (v0, v1) = range(&all);
        let x = |t: f64| MARGIN + (t - t0) / (t1 - t0) * (WIDTH - 2.0 * MARGIN);
        let y = |v: f64| top + PANEL_H - 30.0 - (v - v0) / (v1 - v0) * (PANEL_H - 50.0);
        let _ = writeln!(
            svg,
            r#"<text x="{MARGIN:.1}" y="{:.1}">{} — grey measured, red model ({unit}); {:.1} … {:.1} {unit}, {:.1} … {:.1} s</text>"#,
            top + 12.0,
            escape(&panel.title),
            v0,
            v1,
            t0,
            t1
        );
        let _ = writeln!(
            svg,
            r##"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="#999"/>"##,
            x(t0),
            y(0.0_f64.clamp(v0, v1)),
            x(t1),
            y(0.0_f64.clamp(v0, v1))
        );
        for (values, color) in [(&panel.measured, "#888"), (&panel.modelled, "#d22")] {
            let points: Vec<String> = panel
                .time_s
                .iter()
                .zip(values.iter())
                .map(|(t, v)| format!("{:.1},{:.1}", x(*t), y(*v)))
                .collect();
            let _ = writeln!(
                svg,
                r#"<polyline fill="none" stroke="{color}" stroke-width="1" points="{}"/>"#,
                points.join(" ")
            );
        }
    }
    svg.push_str("</svg>\n");
    svg
}

fn range(values: &[f64]) -> (f64, f64) {
    let (lo, hi) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
    if !lo.is_finite() || !hi.is_finite() {
        (0.0, 1.0)
    } else if hi - lo < 1e-9 {
        (lo - 1.0, hi + 1.0)
    } else {
        (lo, hi)
    }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_one_polyline_per_curve() {
        let panel = Panel {
            title: "wheel <0>".to_owned(),
            time_s: vec![0.0, 0.02, 0.04],
            measured: vec![0.0, 1.0, 2.0],
            modelled: vec![0.0, 1.1, 1.9],
        };
        let svg = time_series(&[panel.clone(), panel], "rad/s");
        assert_eq!(svg.matches("<polyline").count(), 4);
        assert!(svg.contains("wheel &lt;0&gt;"));
        assert!(svg.ends_with("</svg>\n"));
    }
}
