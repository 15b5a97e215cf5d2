//! How the feet step: slip on the ground, forward travel close to it, and time on it,
//! measured every physics step over the trial (docs/model.md section 6, "Feet that step").
//!
//! A foot is the tip of a lower leg (the centre of its end face); it is on the ground when
//! the lower leg's collider touches the ground (a contact point that overlaps it, or that
//! the ground pushed on in the step: `falls::contacts`). Its height is the tip's less half
//! the tube's width, so a vertical lower leg standing on the ground has height 0.

use super::world::RobotWorld;
use strider_common::body_plan::BodyPlan;
use strider_common::outcome::GaitStats;
use strider_common::params::LINKS_PER_LEG;

/// Forward foot travel below this height counts as travel along the ground, m: a foot
/// that steps lifts clear of it (a few centimetres), one that skates stays under it.
pub const GROUND_CLEARANCE: f64 = 0.03;

/// One foot's previous position and the running sums.
#[derive(Clone, Copy, Debug, Default)]
struct Foot {
    /// Position at the last step, world frame, m.
    at: [f64; 3],
    /// On the ground at the last step.
    down: bool,
    /// Distance slid on the ground, m.
    slip: f64,
    /// Forward travel, m, and the part of it within the clearance.
    forward: f64,
    forward_low: f64,
    /// Steps on the ground.
    steps_down: u32,
}

/// Accumulates the feet's figures over a trial.
pub struct FootTracker {
    feet: Vec<Foot>,
    /// Each lower leg's part index in `RobotWorld::parts`, its length and half width.
    links: Vec<(usize, f64, f64)>,
    steps: u32,
}

impl FootTracker {
    /// Feet of `plan` standing in `rw` (all taken as off the ground until a step says).
    pub fn new(plan: &BodyPlan, rw: &RobotWorld) -> Self {
        let links: Vec<(usize, f64, f64)> = plan
            .legs
            .iter()
            .enumerate()
            .map(|(leg, l)| {
                let lower = &l.links[LINKS_PER_LEG - 1];
                (
                    1 + leg * LINKS_PER_LEG + LINKS_PER_LEG - 1,
                    lower.length,
                    0.5 * lower.width,
                )
            })
            .collect();
        let mut tracker = Self {
            feet: vec![Foot::default(); links.len()],
            links,
            steps: 0,
        };
        for i in 0..tracker.feet.len() {
            tracker.feet[i].at = tracker.position(rw, i);
        }
        tracker
    }

    fn position(&self, rw: &RobotWorld, foot: usize) -> [f64; 3] {
        let (part, length, half_width) = self.links[foot];
        let pose = rw.world.bodies[rw.parts[part].0].position();
        let tip = pose.transform_point(rapier3d::prelude::Vector::new(0.0, 0.0, length as f32));
        [
            f64::from(tip.x),
            f64::from(tip.y) - half_width,
            f64::from(tip.z),
        ]
    }

    /// Records a physics step: `down[i]` says whether foot `i` is on the ground after it.
    pub fn step(&mut self, rw: &RobotWorld, down: &[bool]) {
        self.steps += 1;
        for (i, &on_ground) in down.iter().enumerate().take(self.feet.len()) {
            let now = self.position(rw, i);
            let foot = &mut self.feet[i];
            let [dx, _, dz] = [
                now[0] - foot.at[0],
                now[1] - foot.at[1],
                now[2] - foot.at[2],
            ];
            if foot.down && on_ground {
                foot.slip += (dx * dx + dz * dz).sqrt();
            }
            if dx > 0.0 {
                foot.forward += dx;
                if now[1].min(foot.at[1]) < GROUND_CLEARANCE {
                    foot.forward_low += dx;
                }
            }
            foot.steps_down += u32::from(on_ground);
            foot.at = now;
            foot.down = on_ground;
        }
    }

    /// The trial's figures so far (torque left at 0 for the caller to fill).
    pub fn stats(&self) -> GaitStats {
        let n = self.feet.len().max(1) as f64;
        let forward: f64 = self.feet.iter().map(|f| f.forward).sum();
        let low: f64 = self.feet.iter().map(|f| f.forward_low).sum();
        GaitStats {
            peak_torque_ratio: 0.0,
            foot_slip: self.feet.iter().map(|f| f.slip).sum::<f64>() / n,
            low_forward_share: if forward > 0.0 { low / forward } else { 0.0 },
            duty_factor: self
                .feet
                .iter()
                .map(|f| f64::from(f.steps_down) / f64::from(self.steps.max(1)))
                .sum::<f64>()
                / n,
        }
    }
}
