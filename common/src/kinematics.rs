//! What the commanded gait does, computed without physics: the body held still and level,
//! every joint exactly at its target. The survey uses these figures to explain why a design
//! fails its trial with a computed cause (docs/model.md section 15): parts the gait itself
//! sweeps into each other, lifting motors too weak to hold the stance, a foot motion that
//! pushes backward or too slowly.

use crate::body_plan::{BodyPlan, LegPlan, TripodSet};
use crate::contact::{first_touch, part_boxes, Touch};
use crate::gait::leg_targets;
use crate::genome::Controller;
use crate::hull::convex_hull;
use crate::params::{C, GAIT_VERTICAL_OFFSET, LINKS_PER_LEG};
use nalgebra::{Isometry3, Point3, Vector3};
use std::f64::consts::PI;

/// Standard gravity, m/s^2 (the trial's).
const GRAVITY: f64 = 9.81;

/// A leg's foot: the centre of the lower leg's tip, in the body frame.
pub fn foot(leg: &LegPlan, q: [f64; LINKS_PER_LEG]) -> Vector3<f64> {
    let poses = leg.link_poses(q);
    (poses[2] * Point3::new(0.0, 0.0, leg.links[2].length)).coords
}

/// The stance posture: every joint at its vertical offset (the sinusoids' centre).
pub fn stance_angles(controller: &Controller) -> [f64; LINKS_PER_LEG] {
    std::array::from_fn(|k| controller.get(GAIT_VERTICAL_OFFSET[k]))
}

/// The hip reach r of the leg: the distance from its foot to the hip's hinge axis in the
/// stance posture (the radius the foot sweeps on).
pub fn hip_reach(leg: &LegPlan, controller: &Controller) -> f64 {
    let hip = &leg.links[0];
    let rel = foot(leg, stance_angles(controller)) - hip.anchor;
    let a = hip.axis.into_inner();
    (rel - a * a.dot(&rel)).norm()
}

/// The simple kinematic speed estimate of a leg sweeping at its hip motor's rated speed:
/// `(2 / pi) r wmax`, m/s (a foot sweeping +-A at frequency sf covers `2 r A` each half
/// cycle of `pi / sf` s, and `A = wmax / sf`).
pub fn speed_estimate(plan: &BodyPlan, controller: &Controller) -> f64 {
    mean(
        plan.legs
            .iter()
            .map(|leg| 2.0 / PI * hip_reach(leg, controller) * leg.links[0].drive.max_speed),
    )
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// The torque each lifting joint of `leg` needs, over its limit, to hold the body with the
/// foot pushing straight up with `force` N at joint angles `q` (the body level): the
/// largest of the upper and lower leg's ratios.
fn lifting_load(leg: &LegPlan, q: [f64; LINKS_PER_LEG], force: f64) -> f64 {
    let poses = leg.link_poses(q);
    let f = (poses[2] * Point3::new(0.0, 0.0, leg.links[2].length)).coords;
    let up = Vector3::new(0.0, force, 0.0);
    (1..LINKS_PER_LEG)
        .map(|k| {
            // Joint k sits in link k-1's frame; its axis turns with that link.
            let parent = poses[k - 1];
            let joint = (parent * Point3::from(leg.links[k].anchor)).coords;
            let axis = parent.rotation * leg.links[k].axis.into_inner();
            axis.dot(&(f - joint).cross(&up)).abs() / leg.links[k].drive.max_torque
        })
        .fold(0.0, f64::max)
}

/// The robot's centre of mass in the body frame at joint angles `q` (one triple per leg).
fn centre_of_mass(plan: &BodyPlan, q: &[[f64; LINKS_PER_LEG]]) -> Vector3<f64> {
    let mut sum = plan.body_mass.com * plan.body_mass.mass;
    let mut mass = plan.body_mass.mass;
    for (leg, q) in plan.legs.iter().zip(q) {
        for (link, pose) in leg.links.iter().zip(leg.link_poses(*q)) {
            sum += (pose * Point3::from(link.mass.com)).coords * link.mass.mass;
            mass += link.mass.mass;
        }
    }
    sum / mass
}

/// The signed distance (m) from `p` to the convex hull of `points` in the ground plane
/// (x, z): positive inside, negative outside. Two points make a segment and one a point,
/// whose inside is empty: the result is then minus the distance to them.
pub fn support_margin(points: &[(f64, f64)], p: (f64, f64)) -> f64 {
    let hull = convex_hull(points);
    let dist_to_segment = |a: (f64, f64), b: (f64, f64)| {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len2 = dx * dx + dy * dy;
        let t = if len2 > 0.0 {
            (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        ((p.0 - a.0 - t * dx).powi(2) + (p.1 - a.1 - t * dy).powi(2)).sqrt()
    };
    let n = hull.len();
    if n == 0 {
        return f64::NEG_INFINITY;
    }
    let edges = (0..n).map(|i| (hull[i], hull[(i + 1) % n]));
    let nearest = edges
        .clone()
        .map(|(a, b)| dist_to_segment(a, b))
        .fold(f64::INFINITY, f64::min);
    if n < 3 {
        return -nearest;
    }
    // Counter-clockwise hull: inside is left of every edge.
    let inside = edges
        .clone()
        .all(|(a, b)| (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0) >= 0.0);
    if inside {
        nearest
    } else {
        -nearest
    }
}

/// The commanded gait over a trial, with the body held still and level.
#[derive(Clone, Debug, PartialEq)]
pub struct GaitSweep {
    /// The first contact between two parts not joined by a hinge, and when (s): the gait
    /// itself sweeps them into each other.
    pub contact: Option<(f64, Touch)>,
    /// The distance the body would cover if the feet of the lower tripod set never slipped:
    /// at every instant the body moves opposite to the mean forward velocity of the lower
    /// set's feet, m.
    pub distance: f64,
    /// The largest height difference between the two sets' mean foot heights over the
    /// trial: how far the gait lifts the swing feet above the stance feet, m.
    pub lift: f64,
    /// The largest ratio, over the trial, over the lower set's legs and their two lifting
    /// joints, of the torque needed to carry the robot's weight (shared equally by the
    /// lower set's feet, pushing straight up) to the joint's limit. Above 1 a lifting
    /// motor cannot hold the stance the gait commands: the leg folds under the body.
    pub stance_load: f64,
    /// The smallest margin, over the trial, of the robot's centre of mass inside the
    /// polygon of the lower set's feet (ground plane), m: negative when the centre of mass
    /// leaves it (a statically unstable stance; always so on two feet, a line).
    pub support_margin: f64,
}

impl GaitSweep {
    /// Samples `controller`'s targets at `hz` for `seconds`.
    pub fn of(plan: &BodyPlan, controller: &Controller, seconds: f64, hz: f64) -> Self {
        let steps = (seconds * hz).round() as usize;
        let dt = 1.0 / hz;
        let still = Isometry3::identity();
        let in_a: Vec<bool> = plan
            .legs
            .iter()
            .map(|l| l.phase == TripodSet::A.phase())
            .collect();
        let weight = plan.total_mass() * GRAVITY;
        let angles_at = |t: f64| -> Vec<[f64; LINKS_PER_LEG]> {
            plan.legs
                .iter()
                .map(|leg| leg_targets(controller, leg, t))
                .collect()
        };
        let feet_of = |q: &[[f64; LINKS_PER_LEG]]| -> Vec<Vector3<f64>> {
            plan.legs
                .iter()
                .zip(q)
                .map(|(leg, q)| foot(leg, *q))
                .collect()
        };
        // Mean foot height of each set; the lower set is in stance.
        let set_mean = |feet: &[Vector3<f64>], a: bool| {
            let (sum, n) = feet
                .iter()
                .zip(&in_a)
                .filter(|(_, &is_a)| is_a == a)
                .fold((Vector3::zeros(), 0.0), |(s, n), (f, _)| (s + f, n + 1.0));
            sum / n
        };
        let mut contact = None;
        let (mut distance, mut lift) = (0.0, 0.0f64);
        let (mut load, mut margin) = (0.0f64, f64::INFINITY);
        let mut q = angles_at(0.0);
        let mut feet = feet_of(&q);
        for step in 0..=steps {
            let t = step as f64 * dt;
            if contact.is_none() {
                let poses: Vec<_> = plan
                    .legs
                    .iter()
                    .zip(&q)
                    .map(|(leg, q)| leg.link_poses(*q))
                    .collect();
                contact = first_touch(&part_boxes(plan, &still, &poses), false).map(|c| (t, c));
            }
            let (a, b) = (set_mean(&feet, true), set_mean(&feet, false));
            let stance_is_a = a.y <= b.y;
            lift = lift.max((a.y - b.y).abs());
            let stance: Vec<usize> = (0..plan.legs.len())
                .filter(|&i| in_a[i] == stance_is_a)
                .collect();
            let share = weight / stance.len() as f64;
            for &i in &stance {
                load = load.max(lifting_load(&plan.legs[i], q[i], share));
            }
            let com = centre_of_mass(plan, &q);
            let support: Vec<(f64, f64)> = stance.iter().map(|&i| (feet[i].x, feet[i].z)).collect();
            margin = margin.min(support_margin(&support, (com.x, com.z)));
            if step == steps {
                break;
            }
            let next_q = angles_at(t + dt);
            let next = feet_of(&next_q);
            // The body moves against the stance feet (the lower set over the step).
            let (a1, b1) = (set_mean(&next, true), set_mean(&next, false));
            let (s0, s1) = if a.y + a1.y <= b.y + b1.y {
                (a, a1)
            } else {
                (b, b1)
            };
            distance -= s1.x - s0.x;
            q = next_q;
            feet = next;
        }
        Self {
            contact,
            distance,
            lift,
            stance_load: load,
            support_margin: margin,
        }
    }
}

/// The sinusoids' period, s.
pub fn gait_period(controller: &Controller) -> f64 {
    2.0 * PI / controller.get(C::StrideFrequency)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::genome::Genome;

    fn max() -> (Genome, BodyPlan) {
        let g = crate::reference::max();
        let plan = BodyPlan::new(&g.morphology, 10.0);
        (g, plan)
    }

    #[test]
    fn max_sweeps_forward_without_contact_at_about_the_estimate() {
        let (_, plan) = max();
        let c = Controller::static_default();
        let sweep = GaitSweep::of(&plan, &c, 5.0, 30.0);
        assert_eq!(sweep.contact, None);
        let estimate = speed_estimate(&plan, &c) * 5.0;
        // Two whole cycles of a clean tripod: the no-slip distance is the estimate, less the
        // part of the sweep at the ends where both sets are nearly level.
        assert!(
            sweep.distance > 0.7 * estimate && sweep.distance < 1.1 * estimate,
            "{} vs {estimate}",
            sweep.distance
        );
        assert!(sweep.lift > 0.1, "swing feet lifted {} m", sweep.lift);
    }

    #[test]
    fn max_carries_its_stance_within_its_motors_on_a_stable_tripod() {
        // 64 kg on three feet, up to 0.9 m from the upper-leg joint: about 190 Nm of its
        // 200 Nm; the centre of mass stays inside every stance triangle, 9 cm inside at
        // the ends of the sweep, where the feet have moved 0.43 m.
        let (_, plan) = max();
        let sweep = GaitSweep::of(&plan, &Controller::static_default(), 5.0, 30.0);
        assert!(
            sweep.stance_load > 0.8 && sweep.stance_load < 1.0,
            "{}",
            sweep.stance_load
        );
        assert!(sweep.support_margin > 0.05, "{}", sweep.support_margin);
    }

    #[test]
    fn support_margin_is_signed_distance_to_the_hull() {
        let square = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0), (1.0, 1.0)];
        assert!((support_margin(&square, (1.0, 1.0)) - 1.0).abs() < 1e-12);
        assert!((support_margin(&square, (1.5, 1.0)) - 0.5).abs() < 1e-12);
        assert!((support_margin(&square, (3.0, 1.0)) + 1.0).abs() < 1e-12);
        // Two feet: a line, never inside.
        let line = [(0.0, 0.0), (2.0, 2.0)];
        assert!(support_margin(&line, (1.0, 1.0)).abs() < 1e-12);
        assert!(support_margin(&line, (2.0, 0.0)) < -1.0);
    }
}
