//! The start pose: the body plan with every joint at its controller target for t = 0,
//! the body level and its lowest point resting on the ground (y = 0).

use crate::body_plan::BodyPlan;
use crate::contact::{first_touch, part_boxes, Touch};
use crate::gait::leg_targets;
use crate::genome::Controller;
use crate::params::LINKS_PER_LEG;
use nalgebra::{Isometry3, Point3, Translation3, Vector3};

/// Where everything is at t = 0, in the world frame (ground at y = 0).
#[derive(Clone, Debug, PartialEq)]
pub struct StartPose {
    /// The body frame's pose in the world: level, at height `body_height`.
    pub body: Isometry3<f64>,
    /// Height of the body's centre above the ground, m.
    pub body_height: f64,
    /// Joint angles of each leg (same order as the plan's legs), rad.
    pub joint_angles: Vec<[f64; LINKS_PER_LEG]>,
    /// World poses of each leg's links.
    pub link_poses: Vec<[Isometry3<f64>; LINKS_PER_LEG]>,
    /// Highest point of the robot above the ground: the design brief's height, m.
    pub height: f64,
    /// The lowest point of the robot (on the ground), world frame.
    pub lowest_point: Vector3<f64>,
}

impl StartPose {
    /// Poses `plan` with `controller`'s targets at t = 0.
    pub fn new(plan: &BodyPlan, controller: &Controller) -> Self {
        Self::with_angles(
            plan,
            plan.legs
                .iter()
                .map(|leg| leg_targets(controller, leg, 0.0))
                .collect(),
        )
    }

    /// Poses `plan` with explicit joint angles (three per leg, in the plan's leg order).
    pub fn with_angles(plan: &BodyPlan, joint_angles: Vec<[f64; LINKS_PER_LEG]>) -> Self {
        assert_eq!(
            joint_angles.len(),
            plan.legs.len(),
            "one angle triple per leg"
        );
        let in_body: Vec<_> = plan
            .legs
            .iter()
            .zip(&joint_angles)
            .map(|(leg, q)| leg.link_poses(*q))
            .collect();
        // Every corner of every part, in the body frame. Plain loops: iterator chains over
        // the corner arrays copied each array into the adapter's state (memmove was a fifth
        // of a precheck's time; the coordinator prechecks every candidate).
        let (mut lowest, mut top) = (Vector3::new(0.0, f64::INFINITY, 0.0), f64::NEG_INFINITY);
        let mut visit = |c: Vector3<f64>| {
            if c.y < lowest.y {
                lowest = c;
            }
            top = top.max(c.y);
        };
        for c in plan.body_corners() {
            visit(c);
        }
        for (leg, poses) in plan.legs.iter().zip(&in_body) {
            for (link, pose) in leg.links.iter().zip(poses) {
                for c in link.corners() {
                    visit((pose * Point3::from(c)).coords);
                }
            }
        }
        let body_height = -lowest.y;
        let lift = Translation3::new(0.0, body_height, 0.0);
        Self {
            body: Isometry3::from_parts(lift, Default::default()),
            body_height,
            link_poses: in_body
                .iter()
                .map(|poses| poses.map(|p| Isometry3::from_parts(lift, Default::default()) * p))
                .collect(),
            joint_angles,
            height: top + body_height,
            lowest_point: lowest + lift.vector,
        }
    }
}

impl StartPose {
    /// The first contact in this pose that the trial would refuse: two parts not joined
    /// by a hinge, or a part other than a lower leg on the ground.
    pub fn touch(&self, plan: &BodyPlan) -> Option<Touch> {
        first_touch(&part_boxes(plan, &self.body, &self.link_poses), true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lowest_point_is_on_the_ground_and_height_is_the_top() {
        let g = crate::reference::max();
        let plan = BodyPlan::new(&g.morphology, 10.0);
        let pose = StartPose::new(&plan, &g.controller);
        assert!(pose.lowest_point.y.abs() < 1e-12);
        // The body top is at most the height; the height is bounded by the whole leg reach.
        assert!(pose.body_height + plan.body_half_extents.y <= pose.height + 1e-12);
        let reach: f64 = plan.legs[0].links.iter().map(|l| l.length + l.width).sum();
        assert!(pose.height <= 2.0 * plan.body_half_extents.y + 2.0 * reach);
    }
}
