//! Line charts of per-generation figures: one line per scheme (the mean over its
//! repeats) with a band of one standard deviation either side (the paper's Figure 3).

use super::svg::{document, text, ticks, vertical_text};
use std::fmt::Write;

/// One scheme's curve: per generation, mean and standard deviation over repeats.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend name.
    pub name: String,
    /// Line colour.
    pub colour: &'static str,
    /// (generation, mean, sd).
    pub points: Vec<(f64, f64, f64)>,
}

/// Colours of schemes, in order (colour-blind safe).
pub const SCHEME_COLOURS: [&str; 4] = ["#0072b2", "#d55e00", "#009e73", "#cc79a7"];

const W: f64 = 520.0;
const H: f64 = 300.0;
const LEFT: f64 = 70.0;
const RIGHT: f64 = 20.0;
const TOP: f64 = 36.0;
const BOTTOM: f64 = 50.0;

/// A chart titled `title` of `series`, axes labelled `x_label` and `y_label`.
pub fn line_chart(title: &str, x_label: &str, y_label: &str, series: &[Series]) -> String {
    let pts = series.iter().flat_map(|s| &s.points);
    // Every figure drawn (QD score, fitness, coverage) is never negative: a band reaching
    // below zero (mean 0.1, sd 0.15) would show values that cannot occur, so it stops at 0.
    let floor = if pts.clone().all(|&(_, m, _)| m >= 0.0) {
        0.0
    } else {
        f64::NEG_INFINITY
    };
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(g, m, sd) in pts {
        x0 = x0.min(g);
        x1 = x1.max(g);
        y0 = y0.min((m - sd).max(floor));
        y1 = y1.max(m + sd);
    }
    if !x0.is_finite() {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    y0 = y0.min(0.0);
    if y1 <= y0 {
        y1 = y0 + 1.0;
    }
    // Headroom above the highest band, for the legend and the top tick.
    y1 += 0.08 * (y1 - y0);
    let (pw, ph) = (W - LEFT - RIGHT, H - TOP - BOTTOM);
    let px = |g: f64| LEFT + (g - x0) / (x1 - x0) * pw;
    let py = |v: f64| TOP + ph - (v - y0) / (y1 - y0) * ph;
    let mut b = String::new();
    text(&mut b, W / 2.0, 20.0, 14.0, "middle", title);
    for t in ticks(y0, y1) {
        let y = py(t);
        let _ = writeln!(
            b,
            r##"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#e4e4e4"/>"##,
            LEFT + pw
        );
        text(&mut b, LEFT - 6.0, y + 4.0, 11.0, "end", &format!("{t}"));
    }
    for t in ticks(x0, x1) {
        let x = px(t);
        let _ = writeln!(
            b,
            r##"<line x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}" stroke="#333"/>"##,
            TOP + ph,
            TOP + ph + 4.0
        );
        text(&mut b, x, TOP + ph + 17.0, 11.0, "middle", &format!("{t}"));
    }
    let _ = writeln!(
        b,
        r##"<rect x="{LEFT}" y="{TOP}" width="{pw:.1}" height="{ph:.1}" fill="none" stroke="#333"/>"##
    );
    text(&mut b, LEFT + pw / 2.0, H - 12.0, 12.0, "middle", x_label);
    vertical_text(&mut b, 16.0, TOP + ph / 2.0, 12.0, y_label);
    for (k, s) in series.iter().enumerate() {
        if s.points.is_empty() {
            continue;
        }
        let upper: Vec<String> = s
            .points
            .iter()
            .map(|&(g, m, sd)| format!("{:.1},{:.1}", px(g), py(m + sd)))
            .collect();
        let lower: Vec<String> = s
            .points
            .iter()
            .rev()
            .map(|&(g, m, sd)| format!("{:.1},{:.1}", px(g), py((m - sd).max(floor))))
            .collect();
        let _ = writeln!(
            b,
            r#"<polygon points="{} {}" fill="{}" fill-opacity="0.18" stroke="none"/>"#,
            upper.join(" "),
            lower.join(" "),
            s.colour
        );
        let line: Vec<String> = s
            .points
            .iter()
            .map(|&(g, m, _)| format!("{:.1},{:.1}", px(g), py(m)))
            .collect();
        let _ = writeln!(
            b,
            r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="2"/>"#,
            line.join(" "),
            s.colour
        );
        let ly = TOP + 14.0 + 16.0 * k as f64;
        let _ = writeln!(
            b,
            r#"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{}" stroke-width="3"/>"#,
            LEFT + 10.0,
            ly - 4.0,
            LEFT + 28.0,
            ly - 4.0,
            s.colour
        );
        text(
            &mut b,
            LEFT + 33.0,
            ly,
            11.0,
            "start",
            &format!("{} (mean ± sd)", s.name),
        );
    }
    document(W, H, &b)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart(points: Vec<(f64, f64, f64)>) -> String {
        let series = Series {
            name: "static".into(),
            colour: SCHEME_COLOURS[0],
            points,
        };
        line_chart("t", "generation", "fitness", &[series])
    }

    #[test]
    fn a_band_of_a_figure_that_cannot_be_negative_stops_at_zero() {
        // Mean 0.1, sd 0.5: the band would reach -0.4.
        let svg = chart(vec![(0.0, 0.1, 0.5), (1.0, 0.2, 0.5)]);
        assert!(!svg.contains(">-0"), "a negative tick: {svg}");
        // A series that goes negative keeps its whole band.
        let svg = chart(vec![(0.0, -0.1, 0.15), (1.0, 0.2, 0.15)]);
        assert!(svg.contains(">-0.2<"), "{svg}");
    }
}
