//! The sinusoidal tripod gait (docs/model.md section 7): a pure function of time.
//!
//! Target of link `k` on a leg with phase `phi`:
//! `vo_k + (wmax_k / sf) * sin(sf * t + po_k + phi + ref_k)`.
//! `ref_0 = 0` for the hip and `ref_1 = ref_2 = -pi/2` for the lifting joints: with
//! `po = 0` the lifting joints are at their highest (smallest angle, positive is down) in
//! the middle of the hip's forward swing and push down in the middle of its backward swing,
//! so a foot is on the ground while it sweeps backward.

use crate::body_plan::LegPlan;
use crate::genome::Controller;
use crate::params::{C, GAIT_PHASE_OFFSET, GAIT_VERTICAL_OFFSET, LINKS_PER_LEG};
use std::f64::consts::FRAC_PI_2;

/// Phase reference of each joint relative to the hip.
pub const PHASE_REFERENCE: [f64; LINKS_PER_LEG] = [0.0, -FRAC_PI_2, -FRAC_PI_2];

/// Target angles (rad) of a leg's three joints at time `t` (s).
pub fn leg_targets(controller: &Controller, leg: &LegPlan, t: f64) -> [f64; LINKS_PER_LEG] {
    let sf = controller.get(C::StrideFrequency);
    std::array::from_fn(|k| {
        let amplitude = leg.links[k].drive.max_speed / sf;
        let phase = sf * t + controller.get(GAIT_PHASE_OFFSET[k]) + leg.phase + PHASE_REFERENCE[k];
        controller.get(GAIT_VERTICAL_OFFSET[k]) + amplitude * phase.sin()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body_plan::BodyPlan;
    use crate::genome::Genome;

    fn max() -> (Genome, BodyPlan) {
        let g = crate::reference::max();
        let plan = BodyPlan::new(&g.morphology, 10.0);
        (g, plan)
    }

    #[test]
    fn the_two_tripod_sets_swing_in_antiphase() {
        let (g, plan) = max();
        let t = 0.3;
        let hip = |leg: &LegPlan| {
            leg_targets(&g.controller, leg, t)[0] - g.controller.get(C::VerticalOffset0)
        };
        let a = hip(&plan.legs[0]);
        assert!(a.abs() > 1e-3);
        for leg in &plan.legs {
            // Set A (phase 0) and set B (phase pi) are mirror images in time.
            let expected = if leg.phase == 0.0 { a } else { -a };
            assert!((hip(leg) - expected).abs() < 1e-12);
        }
    }

    #[test]
    fn lifting_joints_lift_during_the_forward_swing() {
        let (g, plan) = max();
        let leg = &plan.legs[0];
        let sf = g.controller.get(C::StrideFrequency);
        // Middle of the forward swing: hip phase 0 (hip angle rising through vo).
        let t_fwd = (2.0 * std::f64::consts::PI - leg.phase) / sf;
        let q = leg_targets(&g.controller, leg, t_fwd);
        let dq0 = leg_targets(&g.controller, leg, t_fwd + 1e-6)[0] - q[0];
        assert!(dq0 > 0.0, "hip should be swinging forward");
        assert!(
            q[1] < g.controller.get(C::VerticalOffset1),
            "upper leg raised"
        );
        // Half a cycle later (backward swing) the leg pushes down.
        let q = leg_targets(&g.controller, leg, t_fwd + std::f64::consts::PI / sf);
        assert!(
            q[1] > g.controller.get(C::VerticalOffset1),
            "upper leg pushed down"
        );
    }

    #[test]
    fn peak_joint_speed_is_wmax() {
        let (g, plan) = max();
        let leg = &plan.legs[0];
        let dt = 1e-5;
        let mut peak = 0.0f64;
        for s in 0..5000 {
            let t = s as f64 * 1e-3;
            let a = leg_targets(&g.controller, leg, t)[0];
            let b = leg_targets(&g.controller, leg, t + dt)[0];
            peak = peak.max(((b - a) / dt).abs());
        }
        assert!((peak - leg.links[0].drive.max_speed).abs() < 1e-3, "{peak}");
    }
}
