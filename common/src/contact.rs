//! The robot's parts, which pairs of them may touch, and whether they touch in a pose.
//!
//! Every part is a cuboid (docs/model.md section 3). Parts joined by a hinge (body and hip link, hip
//! and upper leg, upper and lower leg) overlap at their joint by construction and never
//! count; any other pair touching is a self-contact. On the ground only lower legs (link
//! 2) may rest. The test here is exact for cuboids (the separating-axis theorem), in f64,
//! with no physics engine: the start-pose check before simulating uses it, and so does the
//! survey's kinematic diagnosis of the commanded gait.

use crate::body_plan::{BodyPlan, Side};
use crate::params::LINKS_PER_LEG;
use nalgebra::{Isometry3, Matrix3, Vector3};
use std::fmt;

/// The lower leg, the only link that may touch the ground.
pub const LOWER_LEG: usize = 2;

/// A part's lowest point at most this far above the ground counts as touching it, m (the
/// start pose puts its lowest point at exactly 0; this absorbs rounding only).
pub const GROUND_TOUCH: f64 = 1e-9;

/// One rigid part of the robot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Part {
    /// The body cuboid.
    Body,
    /// Link `link` (0 hip, 1 upper, 2 lower) of leg `leg` (the plan's leg order).
    Link {
        /// Index into the plan's legs.
        leg: usize,
        /// 0, 1 or 2.
        link: usize,
    },
}

impl Part {
    /// Whether a hinge joins `self` and `other` (their contacts are off).
    pub fn hinged_to(self, other: Part) -> bool {
        match (self, other) {
            (Part::Body, Part::Link { link: 0, .. }) | (Part::Link { link: 0, .. }, Part::Body) => {
                true
            }
            (Part::Link { leg: a, link: i }, Part::Link { leg: b, link: j }) => {
                a == b && i.abs_diff(j) == 1
            }
            _ => false,
        }
    }

    /// Whether this part may rest on the ground (a lower leg).
    pub fn may_touch_ground(self) -> bool {
        matches!(
            self,
            Part::Link {
                link: LOWER_LEG,
                ..
            }
        )
    }

    /// A human name, e.g. "right leg 0 link 2".
    pub fn name(self, plan: &BodyPlan) -> String {
        match self {
            Part::Body => "body".into(),
            Part::Link { leg, link } => {
                let l = &plan.legs[leg];
                let side = match l.side {
                    Side::Right => "right",
                    Side::Left => "left",
                };
                format!("{side} leg {} link {link}", l.index)
            }
        }
    }

    /// The part of `plan` called `name` (the inverse of [`Part::name`]).
    pub fn named(plan: &BodyPlan, name: &str) -> Option<Part> {
        Part::all(plan).find(|p| p.name(plan) == name)
    }

    /// Every part of `plan`: the body, then each leg's links in order.
    pub fn all(plan: &BodyPlan) -> impl Iterator<Item = Part> + '_ {
        std::iter::once(Part::Body).chain(
            (0..plan.legs.len())
                .flat_map(|leg| (0..LINKS_PER_LEG).map(move |link| Part::Link { leg, link })),
        )
    }
}

/// An oriented box: centre, unit axes (columns) and half-extents along them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrientedBox {
    /// Centre, m.
    pub centre: Vector3<f64>,
    /// Unit axes as columns.
    pub axes: Matrix3<f64>,
    /// Half-extents along the axes, m.
    pub half: Vector3<f64>,
}

impl OrientedBox {
    /// The box `[lo, hi]` of a frame placed at `pose`.
    pub fn of(pose: &Isometry3<f64>, lo: Vector3<f64>, hi: Vector3<f64>) -> Self {
        Self {
            centre: (pose * nalgebra::Point3::from(0.5 * (lo + hi))).coords,
            axes: pose.rotation.to_rotation_matrix().into_inner(),
            half: 0.5 * (hi - lo),
        }
    }

    /// Half the box's extent along unit direction `d`.
    fn radius_along(&self, d: &Vector3<f64>) -> f64 {
        (0..3)
            .map(|i| self.half[i] * self.axes.column(i).dot(d).abs())
            .sum()
    }

    /// The lowest point's height (world y), m.
    pub fn lowest_y(&self) -> f64 {
        self.centre.y - self.radius_along(&Vector3::y())
    }

    /// The half-diagonal: a bounding sphere's radius.
    fn bounding_radius(&self) -> f64 {
        self.half.norm()
    }

    /// Whether the two boxes overlap or touch (the separating-axis theorem: no axis among
    /// the 3 + 3 face normals and 9 edge cross products separates them).
    pub fn touches(&self, other: &OrientedBox) -> bool {
        let t = other.centre - self.centre;
        if t.norm() > self.bounding_radius() + other.bounding_radius() {
            return false;
        }
        let separated = |axis: Vector3<f64>| {
            let len = axis.norm();
            // Parallel edges give a null cross product: no axis to test.
            if len < 1e-9 {
                return false;
            }
            let d = axis / len;
            t.dot(&d).abs() > self.radius_along(&d) + other.radius_along(&d)
        };
        for i in 0..3 {
            if separated(self.axes.column(i).into()) || separated(other.axes.column(i).into()) {
                return false;
            }
        }
        for i in 0..3 {
            for j in 0..3 {
                if separated(self.axes.column(i).cross(&other.axes.column(j))) {
                    return false;
                }
            }
        }
        true
    }
}

/// What touches in one pose of the robot.
#[derive(Clone, Debug, PartialEq)]
pub enum Touch {
    /// Two parts not joined by a hinge.
    Parts(Part, Part),
    /// A part other than a lower leg on the ground.
    Ground(Part),
}

impl Touch {
    /// "X and Y", or "X and the ground", naming parts on `plan`.
    pub fn describe(&self, plan: &BodyPlan) -> (String, String) {
        match self {
            Touch::Parts(a, b) => (a.name(plan), b.name(plan)),
            Touch::Ground(a) => (a.name(plan), "ground".into()),
        }
    }
}

impl fmt::Display for Part {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Part::Body => write!(f, "body"),
            Part::Link { leg, link } => write!(f, "leg {leg} link {link}"),
        }
    }
}

/// The boxes of every part of `plan` with the body at `body` and the links at `links`
/// (world poses, one triple per leg), in [`Part::all`] order.
pub fn part_boxes(
    plan: &BodyPlan,
    body: &Isometry3<f64>,
    links: &[[Isometry3<f64>; LINKS_PER_LEG]],
) -> Vec<(Part, OrientedBox)> {
    let h = plan.body_half_extents;
    let mut out = Vec::with_capacity(1 + links.len() * LINKS_PER_LEG);
    out.push((Part::Body, OrientedBox::of(body, -h, h)));
    for (leg, (plan_leg, poses)) in plan.legs.iter().zip(links).enumerate() {
        for (link, (l, pose)) in plan_leg.links.iter().zip(poses).enumerate() {
            let w = 0.5 * l.width;
            out.push((
                Part::Link { leg, link },
                OrientedBox::of(
                    pose,
                    Vector3::new(-w, -w, 0.0),
                    Vector3::new(w, w, l.length),
                ),
            ));
        }
    }
    out
}

/// The first pair of parts that touch among `boxes` (hinged pairs excepted), then the
/// first part other than a lower leg on the ground (y = 0), if `ground` is set.
pub fn first_touch(boxes: &[(Part, OrientedBox)], ground: bool) -> Option<Touch> {
    for (i, (a, box_a)) in boxes.iter().enumerate() {
        for (b, box_b) in &boxes[i + 1..] {
            if !a.hinged_to(*b) && box_a.touches(box_b) {
                return Some(Touch::Parts(*a, *b));
            }
        }
    }
    if ground {
        for (part, b) in boxes {
            if !part.may_touch_ground() && b.lowest_y() <= GROUND_TOUCH {
                return Some(Touch::Ground(*part));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn unit_box(at: Vector3<f64>, rot: UnitQuaternion<f64>) -> OrientedBox {
        OrientedBox::of(
            &Isometry3::from_parts(Translation3::from(at), rot),
            Vector3::repeat(-0.5),
            Vector3::repeat(0.5),
        )
    }

    #[test]
    fn axis_aligned_boxes_touch_when_their_extents_overlap() {
        let a = unit_box(Vector3::zeros(), UnitQuaternion::identity());
        for (x, touch) in [(0.99, true), (1.0, true), (1.01, false)] {
            let b = unit_box(Vector3::new(x, 0.0, 0.0), UnitQuaternion::identity());
            assert_eq!(a.touches(&b), touch, "x = {x}");
        }
    }

    #[test]
    fn an_edge_axis_separates_boxes_no_face_axis_does() {
        // Cube a turned 45 degrees about z reaches x = 0.707 with an edge along z; cube b
        // turned 45 degrees about y reaches back 0.707 with an edge along y. Edge to edge,
        // they part at cx = sqrt 2; every face normal alone would call them touching up
        // to cx = 1.914, so this checks the edge cross products.
        let a = unit_box(
            Vector3::zeros(),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_4),
        );
        let rot_b =
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_4);
        let s2 = std::f64::consts::SQRT_2;
        assert!(a.touches(&unit_box(Vector3::new(s2 - 0.01, 0.0, 0.0), rot_b)));
        assert!(!a.touches(&unit_box(Vector3::new(s2 + 0.01, 0.0, 0.0), rot_b)));
    }

    #[test]
    fn hinged_pairs_are_body_hip_and_neighbouring_links_of_one_leg() {
        let l = |leg, link| Part::Link { leg, link };
        assert!(Part::Body.hinged_to(l(3, 0)));
        assert!(l(3, 0).hinged_to(l(3, 1)) && l(3, 2).hinged_to(l(3, 1)));
        assert!(
            !l(3, 0).hinged_to(l(3, 2)),
            "hip and lower leg are not hinged"
        );
        assert!(!l(3, 0).hinged_to(l(4, 1)));
        assert!(!Part::Body.hinged_to(l(0, 1)));
        assert!(l(1, 2).may_touch_ground() && !l(1, 1).may_touch_ground());
    }
}
