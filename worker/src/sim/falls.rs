//! What ends a trial early besides a blow-up: the body's fall (tilt, sinking) and the
//! contacts that end it (a self-contact, a part other than a lower leg on the ground).

use super::world::{part_of_tag, RobotWorld, GROUND_TAG};
use rapier3d::geometry::ContactPair;
use strider_common::body_plan::BodyPlan;
use strider_common::contact::Part;
use strider_common::experiment::TrialLimits;
use strider_common::outcome::{Fall, InvalidReason};
use strider_common::StartPose;

/// The body's tilt and height limits of a trial, precomputed.
pub(super) struct FallCheck {
    /// The tilt limits during the trial and after it, degrees.
    max_tilt: [f64; 2],
    /// cos of each tilt limit: the smallest y component of the body's up axis.
    min_up_y: [f32; 2],
    /// The lowest body-centre height, m.
    min_height: f32,
}

impl FallCheck {
    pub(super) fn new(limits: &TrialLimits, start: &StartPose) -> Self {
        let max_tilt = [
            limits.max_tilt_degrees,
            limits
                .max_tilt_degrees
                .min(limits.upright_after_max_tilt_degrees),
        ];
        Self {
            max_tilt,
            min_up_y: max_tilt.map(|t| t.to_radians().cos() as f32),
            min_height: (limits.min_height_fraction * start.body_height) as f32,
        }
    }

    /// A fall of the body (tilt or height), if any; `after` the trial the tilt limit is
    /// the one for staying up.
    pub(super) fn check(&self, rw: &RobotWorld, after: bool) -> Option<Fall> {
        let p = rw.world.bodies[rw.parts[0].0].position();
        let r = p.rotation;
        // The y component of the body's rotated up axis: cos of its tilt.
        let up_y = 1.0 - 2.0 * (r.x * r.x + r.z * r.z);
        let k = usize::from(after);
        if up_y < self.min_up_y[k] {
            return Some(Fall::Tilted {
                degrees: f64::from(up_y.clamp(-1.0, 1.0)).acos().to_degrees(),
                limit: self.max_tilt[k],
            });
        }
        if p.translation.y < self.min_height {
            return Some(Fall::Sank {
                height: f64::from(p.translation.y),
                limit: f64::from(self.min_height),
            });
        }
        None
    }
}

/// Contacts that end the trial, from the pairs in contact (a merely predicted contact is
/// not one): when `self_contacts`, two robot parts not joined by a hinge (hinged pairs have
/// contacts off), else, when `feet_only`, a part other than a lower leg on the ground. Sets
/// `feet_down[leg]` for every lower leg on the ground.
///
/// A pair is in contact when one of its points overlaps (`dist <= 0`) or the solver pushed
/// its parts apart in the step ([`pushed`]): rapier's predictive contacts hold a pressed
/// part a fraction of a millimetre short of what it presses on. A shuffling elite's feet
/// carried load at 0 < dist <= 0.5 mm in 7,272 of their 12,390 loaded contact points;
/// counted by overlap alone its feet were down a quarter of the trial where PyBullet has
/// them down 59 % of it, and two legs pressed together a hair apart did not touch
/// (docs/model.md section 6, "Feet that step" and "Two parts pressed together touch").
pub(super) fn contacts(
    rw: &RobotWorld,
    feet_only: bool,
    self_contacts: bool,
    plan: &BodyPlan,
    feet_down: &mut [bool],
) -> Option<InvalidReason> {
    let colliders = &rw.world.colliders;
    let mut dragged = None;
    feet_down.fill(false);
    for pair in rw.world.narrow_phase.contact_pairs() {
        let a = colliders[pair.collider1].user_data;
        let b = colliders[pair.collider2].user_data;
        let on_ground = a == GROUND_TAG || b == GROUND_TAG;
        if !on_ground && !self_contacts {
            continue;
        }
        let touches = pair
            .manifolds()
            .iter()
            .flat_map(|m| m.points.iter())
            .any(|p| p.dist <= 0.0)
            || pushed(pair);
        if on_ground {
            let part = part_of_tag(a.min(b));
            match part {
                Part::Link { leg, .. } if part.may_touch_ground() => {
                    feet_down[leg] |= touches;
                }
                _ if feet_only && touches => {
                    dragged.get_or_insert(part);
                }
                _ => {}
            }
        } else if touches {
            let (first, second) = (part_of_tag(a.min(b)), part_of_tag(a.max(b)));
            return Some(InvalidReason::SelfContact {
                first: first.name(plan),
                second: second.name(plan),
            });
        }
    }
    dragged.map(|part: Part| InvalidReason::Fell {
        fall: Fall::Dragged {
            part: part.name(plan),
        },
    })
}

/// Whether the solver pushed the pair's parts apart in the last step: a normal impulse above
/// 0 on a contact the solver used in it. Only those contacts' impulses are of that step (a
/// point the solver left out keeps the one it had), and where rapier clusters a pair's
/// manifolds the solver's are the clusters.
fn pushed(pair: &ContactPair) -> bool {
    pair.solver_manifolds().iter().any(|m| {
        m.data.solver_contacts.iter().any(|c| {
            m.points
                .get(c.contact_indices()[0] as usize)
                .is_some_and(|p| p.data.impulse > 0.0)
        })
    })
}
