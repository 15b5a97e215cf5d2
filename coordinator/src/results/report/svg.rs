//! Small SVG building blocks for the report: text, a colour scale for fitness, and
//! tick positions. Everything is plain strings, to scale in user units (px).

use std::fmt::Write;
pub use strider_common::xml::{escape, svg_document as document};

/// `<text>` at (x, y) with an anchor (`start`, `middle`, `end`).
pub fn text(out: &mut String, x: f64, y: f64, size: f64, anchor: &str, s: &str) {
    let _ = writeln!(
        out,
        r#"<text x="{x:.1}" y="{y:.1}" font-family="sans-serif" font-size="{size}" text-anchor="{anchor}">{}</text>"#,
        escape(s)
    );
}

/// Vertical text (rotated a quarter turn) centred on (x, y).
pub fn vertical_text(out: &mut String, x: f64, y: f64, size: f64, s: &str) {
    let _ = writeln!(
        out,
        r#"<text x="{x:.1}" y="{y:.1}" font-family="sans-serif" font-size="{size}" text-anchor="middle" transform="rotate(-90 {x:.1} {y:.1})">{}</text>"#,
        escape(s)
    );
}

/// Colour of empty cells: light grey, unlike any colour of the fitness scale.
pub const EMPTY: &str = "#eeeeee";

/// The fitness colour scale (viridis, dark purple for poor to yellow for good) at
/// `t` in [0, 1].
pub fn colour(t: f64) -> String {
    const STOPS: [(f64, f64, f64); 6] = [
        (68.0, 1.0, 84.0),
        (65.0, 68.0, 135.0),
        (42.0, 120.0, 142.0),
        (34.0, 168.0, 132.0),
        (122.0, 209.0, 81.0),
        (253.0, 231.0, 37.0),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let mix = |p: f64, q: f64| (p + (q - p) * f).round() as u8;
    format!(
        "#{:02x}{:02x}{:02x}",
        mix(a.0, b.0),
        mix(a.1, b.1),
        mix(a.2, b.2)
    )
}

/// A horizontal colour bar for fitness from `lo` to `hi` at (x, y), `w` wide, with the
/// empty-cell swatch beside it and `note` (how the scale was chosen) under it.
pub fn colour_bar(out: &mut String, x: f64, y: f64, w: f64, lo: f64, hi: f64, note: &str) {
    let steps = 50;
    for k in 0..steps {
        let _ = writeln!(
            out,
            r#"<rect x="{:.1}" y="{y:.1}" width="{:.2}" height="12" fill="{}"/>"#,
            x + w * k as f64 / steps as f64,
            w / steps as f64 + 0.3,
            colour((k as f64 + 0.5) / steps as f64)
        );
    }
    text(out, x, y + 26.0, 11.0, "start", &format!("{lo:.2}"));
    text(out, x + w, y + 26.0, 11.0, "end", &format!("{hi:.2}"));
    text(
        out,
        x + w / 2.0,
        y + 26.0,
        11.0,
        "middle",
        "fitness (1 / cost of transport)",
    );
    text(out, x, y + 42.0, 10.0, "start", note);
    let _ = writeln!(
        out,
        r##"<rect x="{:.1}" y="{y:.1}" width="12" height="12" fill="{EMPTY}" stroke="#999"/>"##,
        x + w + 20.0
    );
    text(out, x + w + 36.0, y + 10.0, 11.0, "start", "empty cell");
}

/// About five round tick values covering [lo, hi].
pub fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return vec![lo];
    }
    let raw = (hi - lo) / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    // Round to the step's decimals, so labels read 0.6 and not 0.6000000000000001.
    let decimals = (-step.log10().floor()).max(0.0) as usize + 1;
    let first = (lo / step).ceil() as i64;
    (first..)
        .map(|k| k as f64 * step)
        .take_while(|v| *v <= hi + 1e-9 * step)
        .map(|v| format!("{v:.decimals$}").parse::<f64>().unwrap_or(v) + 0.0)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        assert_eq!(ticks(0.0, 1.0), vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0]);
        assert_eq!(ticks(0.0, 200.0), vec![0.0, 50.0, 100.0, 150.0, 200.0]);
        assert_eq!(ticks(3.0, 3.0), vec![3.0]);
    }

    #[test]
    fn the_scale_runs_from_purple_to_yellow() {
        assert_eq!(colour(0.0), "#440154");
        assert_eq!(colour(1.0), "#fde725");
        assert_ne!(colour(0.0), EMPTY);
    }
}
