//! Drawings of a design, to scale, as SVG: side, front and top views of the body plan in
//! a pose (the start pose for `eval --svg` and the report), and an animated side view
//! of a trial (the replay). Every part is a cuboid; a view draws each as the outline of
//! its projected corners, far parts first. World frame: x forward, y up, z to the right.

use crate::body_plan::{BodyPlan, Side};
use crate::hull::convex_hull;
use crate::params::LINKS_PER_LEG;
use crate::pose::StartPose;
use crate::xml::{escape, svg_document};
use nalgebra::{Isometry3, Vector3};
use std::fmt::Write;

/// Pixels per metre in the drawings.
pub const PX_PER_M: f64 = 160.0;
const MARGIN: f64 = 30.0;

/// What a part is, for its colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PartKind {
    /// The body cuboid.
    Body,
    /// A leg link on this side.
    Leg(Side),
}

impl PartKind {
    fn fill(self) -> &'static str {
        match self {
            PartKind::Body => "#9aa4ae",
            PartKind::Leg(Side::Right) => "#2f6db5",
            PartKind::Leg(Side::Left) => "#e08a2e",
        }
    }
}

/// One rigid part's corners in the world.
#[derive(Clone, Debug)]
pub struct Part {
    /// Body or leg link.
    pub kind: PartKind,
    /// The cuboid's eight corners, world frame, m.
    pub corners: [Vector3<f64>; 8],
}

/// Every part of `plan` with the body at `body` and joint angles `angles` (one triple per
/// leg, in the plan's order).
pub fn parts(plan: &BodyPlan, body: &Isometry3<f64>, angles: &[[f64; LINKS_PER_LEG]]) -> Vec<Part> {
    let mut out = vec![Part {
        kind: PartKind::Body,
        corners: plan
            .body_corners()
            .map(|c| body * nalgebra::Point3::from(c))
            .map(|p| p.coords),
    }];
    for (leg, q) in plan.legs.iter().zip(angles) {
        for (link, pose) in leg.links.iter().zip(leg.link_poses(*q)) {
            let world = body * pose;
            out.push(Part {
                kind: PartKind::Leg(leg.side),
                corners: link
                    .corners()
                    .map(|c| (world * nalgebra::Point3::from(c)).coords),
            });
        }
    }
    out
}

/// The parts of a start pose.
pub fn start_parts(plan: &BodyPlan, pose: &StartPose) -> Vec<Part> {
    parts(plan, &pose.body, &pose.joint_angles)
}

/// A direction to look from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    /// From the robot's right: forward to the right of the picture, up is up.
    Side,
    /// From the front: the robot's right on the picture's left, up is up.
    Front,
    /// From above: forward to the right, the robot's right at the bottom.
    Top,
}

impl View {
    /// Every view, in the order drawings show them.
    pub const ALL: [View; 3] = [View::Side, View::Front, View::Top];

    /// The view's name.
    pub fn name(self) -> &'static str {
        match self {
            View::Side => "side",
            View::Front => "front",
            View::Top => "top",
        }
    }

    /// (across, up, towards the viewer) of a world point in this view.
    pub fn project(self, p: &Vector3<f64>) -> (f64, f64, f64) {
        match self {
            View::Side => (p.x, p.y, p.z),
            View::Front => (-p.z, p.y, p.x),
            View::Top => (p.x, -p.z, p.y),
        }
    }

    /// Whether the ground (y = 0) is a line in this view.
    fn shows_ground(self) -> bool {
        self != View::Top
    }
}

/// The region a view of some parts covers: (min across, max across, min up, max up), m.
fn extent(view: View, parts: &[Part]) -> (f64, f64, f64, f64) {
    let mut e = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for c in parts.iter().flat_map(|p| &p.corners) {
        let (a, u, _) = view.project(c);
        e = (e.0.min(a), e.1.max(a), e.2.min(u), e.3.max(u));
    }
    if view.shows_ground() {
        e.2 = e.2.min(0.0);
    }
    e
}

/// A picture frame: maps metres of one view to pixels.
struct Frame {
    left: f64,
    top: f64,
    min_across: f64,
    max_up: f64,
    /// Pixels per metre.
    scale: f64,
}

impl Frame {
    fn px(&self, across: f64, up: f64) -> (f64, f64) {
        (
            self.left + (across - self.min_across) * self.scale,
            self.top + (self.max_up - up) * self.scale,
        )
    }
}

/// Draws `parts` in `view` into `out`, far parts first.
fn draw_parts(out: &mut String, view: View, parts: &[Part], frame: &Frame) {
    let mut order: Vec<(f64, &Part)> = parts
        .iter()
        .map(|p| {
            let depth = p.corners.iter().map(|c| view.project(c).2).sum::<f64>() / 8.0;
            (depth, p)
        })
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (_, part) in order {
        let outline = convex_hull(
            &part
                .corners
                .iter()
                .map(|c| {
                    let (a, u, _) = view.project(c);
                    frame.px(a, u)
                })
                .collect::<Vec<_>>(),
        );
        let points: Vec<String> = outline
            .iter()
            .map(|(x, y)| format!("{x:.1},{y:.1}"))
            .collect();
        let _ = writeln!(
            out,
            r##"<polygon points="{}" fill="{}" fill-opacity="0.85" stroke="#1d232a" stroke-width="1"/>"##,
            points.join(" "),
            part.kind.fill()
        );
    }
}

fn ground(out: &mut String, frame: &Frame, from: f64, to: f64) {
    let (x0, y) = frame.px(from, 0.0);
    let (x1, _) = frame.px(to, 0.0);
    let _ = writeln!(
        out,
        r##"<line x1="{x0:.1}" y1="{y:.1}" x2="{x1:.1}" y2="{y:.1}" stroke="#5b4a3a" stroke-width="2"/>"##
    );
}

/// A 1 m scale bar with its left end at (x, y) px.
fn scale_bar(out: &mut String, x: f64, y: f64) {
    let _ = writeln!(
        out,
        r##"<g><line x1="{x:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="black" stroke-width="3"/><line x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}" stroke="black" stroke-width="2"/><line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="black" stroke-width="2"/><text x="{:.1}" y="{:.1}" font-family="sans-serif" font-size="13" text-anchor="middle">1 m</text></g>"##,
        x + PX_PER_M,
        y - 5.0,
        y + 5.0,
        x + PX_PER_M,
        y - 5.0,
        x + PX_PER_M,
        y + 5.0,
        x + PX_PER_M / 2.0,
        y - 9.0
    );
}

/// Side, front and top views of `parts` side by side, to one scale, with the ground, a
/// 1 m bar and `title` (an SVG document).
pub fn views_svg(parts: &[Part], title: &str) -> String {
    let mut body = String::new();
    let mut left = MARGIN;
    let mut height: f64 = 0.0;
    let extents: Vec<_> = View::ALL.iter().map(|&v| (v, extent(v, parts))).collect();
    let tallest = extents.iter().map(|(_, e)| e.3 - e.2).fold(0.0, f64::max);
    let top = MARGIN + 30.0;
    for (view, e) in &extents {
        let frame = Frame {
            left,
            // Views share a baseline: each view's lowest point on one line.
            top: top + (tallest - (e.3 - e.2)) * PX_PER_M,
            min_across: e.0,
            max_up: e.3,
            scale: PX_PER_M,
        };
        let _ = writeln!(
            body,
            r##"<text x="{:.1}" y="{:.1}" font-family="sans-serif" font-size="14" font-weight="bold">{}</text>"##,
            left,
            top - 8.0,
            view.name()
        );
        if view.shows_ground() {
            ground(&mut body, &frame, e.0 - 0.1, e.1 + 0.1);
        }
        draw_parts(&mut body, *view, parts, &frame);
        left += (e.1 - e.0) * PX_PER_M + 2.0 * MARGIN;
        height = height.max(tallest * PX_PER_M);
    }
    let width = left.max(MARGIN * 2.0 + PX_PER_M);
    let bar_y = top + height + 30.0;
    scale_bar(&mut body, MARGIN, bar_y);
    let total_height = bar_y + 20.0;
    let _ = writeln!(
        body,
        r##"<text x="{:.1}" y="{:.1}" font-family="sans-serif" font-size="12" fill="#444">right legs blue, left legs orange; views to scale</text>"##,
        MARGIN + PX_PER_M + 20.0,
        bar_y + 4.0
    );
    svg_document(
        width,
        total_height,
        &format!(
            r#"<text x="{MARGIN}" y="22" font-family="sans-serif" font-size="15">{}</text>
{body}"#,
            escape(title)
        ),
    )
}

/// The design drawing of a start pose (what `eval --svg` writes).
pub fn design_svg(plan: &BodyPlan, pose: &StartPose, title: &str) -> String {
    views_svg(&start_parts(plan, pose), title)
}

/// One moment of a trial: time, body pose, joint angles per leg.
#[derive(Clone, Debug)]
pub struct Frame3 {
    /// Simulated time, s.
    pub time: f64,
    /// The body frame's world pose.
    pub body: Isometry3<f64>,
    /// Joint angles, one triple per leg.
    pub angles: Vec<[f64; LINKS_PER_LEG]>,
}

/// An animated side view of a trial (SVG with SMIL animation, looping; opens in any
/// browser): the robot over the whole stretch it walks, a ground line, the time, and a
/// 1 m bar.
pub fn replay_svg(plan: &BodyPlan, frames: &[Frame3], title: &str) -> String {
    let all: Vec<Vec<Part>> = frames
        .iter()
        .map(|f| parts(plan, &f.body, &f.angles))
        .collect();
    let mut e = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64, f64::NEG_INFINITY);
    for p in &all {
        let x = extent(View::Side, p);
        e = (e.0.min(x.0), e.1.max(x.1), e.2.min(x.2), e.3.max(x.3));
    }
    if frames.is_empty() {
        e = (0.0, 1.0, 0.0, 1.0);
    }
    let frame = Frame {
        left: MARGIN,
        top: MARGIN + 40.0,
        min_across: e.0 - 0.1,
        max_up: e.3,
        scale: PX_PER_M,
    };
    let duration = frames.last().map_or(1.0, |f| f.time).max(1e-3);
    let mut body = String::new();
    ground(&mut body, &frame, e.0 - 0.1, e.1 + 0.1);
    for (i, (f, parts)) in frames.iter().zip(&all).enumerate() {
        let start = f.time / duration;
        let end = frames.get(i + 1).map_or(1.0, |n| n.time / duration);
        // Visible from its time to the next frame's, then hidden until the loop restarts.
        let (values, times) = if i == 0 {
            ("inline;none".to_string(), format!("0;{end:.5}"))
        } else {
            (
                "none;inline;none".to_string(),
                format!("0;{start:.5};{end:.5}"),
            )
        };
        let _ = writeln!(
            body,
            r#"<g display="{}"><animate attributeName="display" values="{values}" keyTimes="{times}" dur="{duration:.3}s" calcMode="discrete" repeatCount="indefinite"/>"#,
            if i == 0 { "inline" } else { "none" }
        );
        draw_parts(&mut body, View::Side, parts, &frame);
        let _ = writeln!(
            body,
            r#"<text x="{MARGIN}" y="{:.1}" font-family="sans-serif" font-size="13">t = {:.2} s, x = {:.2} m</text></g>"#,
            MARGIN + 22.0,
            f.time,
            f.body.translation.x
        );
    }
    let width = 2.0 * MARGIN + (e.1 - e.0 + 0.2) * PX_PER_M;
    let bar_y = frame.top + (e.3 - e.2) * PX_PER_M + 30.0;
    scale_bar(&mut body, MARGIN, bar_y);
    let height = bar_y + 20.0;
    svg_document(
        width,
        height,
        &format!(
            r#"<text x="{MARGIN}" y="18" font-family="sans-serif" font-size="15">{}</text>
{body}"#,
            escape(title)
        ),
    )
}

/// Pixels per metre in filmstrips.
const FILMSTRIP_PX_PER_M: f64 = 60.0;

/// A trial as a still picture: one row per frame (time, forward distance and body tilt),
/// each with the side, front and top views to one scale that holds the whole trial, the
/// views following the body. For looking at a trial on paper or in a report; `eval
/// --filmstrip` writes one.
pub fn filmstrip_svg(plan: &BodyPlan, frames: &[Frame3], title: &str) -> String {
    let scale = FILMSTRIP_PX_PER_M;
    let all: Vec<Vec<Part>> = frames
        .iter()
        .map(|f| parts(plan, &f.body, &f.angles))
        .collect();
    // Every view's extent about the body's own position, over all frames, so that rows
    // line up and a robot that topples or spreads stays in its box.
    let mut ext: Vec<(f64, f64, f64, f64)> =
        vec![(f64::INFINITY, f64::NEG_INFINITY, 0.0, f64::NEG_INFINITY); View::ALL.len()];
    let follow = |view: View, f: &Frame3| {
        let b = f.body.translation.vector;
        match view {
            View::Side => (b.x, 0.0),
            View::Front => (-b.z, 0.0),
            View::Top => (b.x, -b.z),
        }
    };
    for (f, p) in frames.iter().zip(&all) {
        for (i, view) in View::ALL.iter().enumerate() {
            let (da, du) = follow(*view, f);
            let e = extent(*view, p);
            let x = &mut ext[i];
            *x = (
                x.0.min(e.0 - da),
                x.1.max(e.1 - da),
                x.2.min(e.2 - du),
                x.3.max(e.3 - du),
            );
        }
    }
    let row_height = ext.iter().map(|e| e.3 - e.2).fold(0.5f64, f64::max) * scale + 26.0;
    let label_width = 150.0;
    let mut body = String::new();
    let mut width: f64 = 0.0;
    for (r, (f, p)) in frames.iter().zip(&all).enumerate() {
        let top = MARGIN + 30.0 + r as f64 * row_height;
        let up = f.body.rotation * Vector3::y();
        let tilt = up.y.clamp(-1.0, 1.0).acos().to_degrees();
        let _ = writeln!(
            body,
            r#"<text x="{MARGIN}" y="{:.1}" font-family="sans-serif" font-size="12">t = {:.2} s</text><text x="{MARGIN}" y="{:.1}" font-family="sans-serif" font-size="12">x = {:.2} m, tilt {tilt:.0}°</text>"#,
            top + 14.0,
            f.time,
            top + 30.0,
            f.body.translation.x
        );
        let mut left = MARGIN + label_width;
        for (i, view) in View::ALL.iter().enumerate() {
            let (da, du) = follow(*view, f);
            let e = ext[i];
            let frame = Frame {
                left,
                top: top
                    + 18.0
                    + (ext.iter().map(|e| e.3 - e.2).fold(0.5f64, f64::max) - (e.3 - e.2)) * scale,
                min_across: e.0 + da,
                max_up: e.3 + du,
                scale,
            };
            if r == 0 {
                let _ = writeln!(
                    body,
                    r##"<text x="{left:.1}" y="{:.1}" font-family="sans-serif" font-size="13" font-weight="bold">{}</text>"##,
                    top + 8.0,
                    view.name()
                );
            }
            if view.shows_ground() {
                ground(&mut body, &frame, e.0 + da, e.1 + da);
            }
            draw_parts(&mut body, *view, p, &frame);
            left += (e.1 - e.0) * scale + MARGIN;
        }
        width = width.max(left);
    }
    let bar_y = MARGIN + 30.0 + frames.len() as f64 * row_height + 20.0;
    let mut bar = String::new();
    let _ = writeln!(
        bar,
        r##"<g><line x1="{MARGIN}" y1="{bar_y:.1}" x2="{:.1}" y2="{bar_y:.1}" stroke="black" stroke-width="3"/><text x="{:.1}" y="{:.1}" font-family="sans-serif" font-size="12">1 m; right legs blue, left legs orange</text></g>"##,
        MARGIN + scale,
        MARGIN + scale + 10.0,
        bar_y + 4.0
    );
    svg_document(
        width.max(400.0),
        bar_y + 20.0,
        &format!(
            r#"<text x="{MARGIN}" y="22" font-family="sans-serif" font-size="15">{}</text>
{body}{bar}"#,
            escape(title)
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hull_of_a_projected_cube_is_its_square() {
        let pts = vec![
            (0.0, 0.0),
            (1.0, 0.0),
            (1.0, 1.0),
            (0.0, 1.0),
            (0.5, 0.5),
            (1.0, 1.0),
        ];
        let h = convex_hull(&pts);
        assert_eq!(h.len(), 4);
        assert!(h.contains(&(0.0, 0.0)) && h.contains(&(1.0, 1.0)));
    }

    #[test]
    fn views_look_from_the_right_the_front_and_above() {
        let p = Vector3::new(1.0, 2.0, 3.0);
        // From the right (+z towards the viewer), forward across, up up.
        assert_eq!(View::Side.project(&p), (1.0, 2.0, 3.0));
        // From the front (+x towards the viewer): the robot's right (+z) on the left.
        assert_eq!(View::Front.project(&p), (-3.0, 2.0, 1.0));
        // From above (+y towards the viewer): the right side at the bottom.
        assert_eq!(View::Top.project(&p), (1.0, -3.0, 2.0));
    }
}
