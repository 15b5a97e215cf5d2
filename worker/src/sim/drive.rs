//! The joint drives: each joint's servo law `clamp(k (q* - q) - D qdot, ±τmax)` (with
//! `D = d + k T_v`, `JointDrive::servo_damping`) put into rapier for one physics step, and
//! the torque rapier then actually applied.
//!
//! Rapier integrates a multibody joint spring of stiffness `s` and joint damping `c` by
//! backward Euler: over a step of length `dt` the joint receives
//! `tau = s (rest - q_n) - (s dt + c) v_{n+1}` (`q_n` the angle before the step, `v_{n+1}`
//! the speed after it; docs/rapier.md). So:
//!
//! - **Within the limit**: spring `s = k` at rest `q*`, damping `c = D - k dt`, so the joint
//!   gets `k (q* - q_n) - D v_{n+1}`: the servo's damping `D` whatever the step. (Before,
//!   `c = d` and the step added `k dt` of damping that no model stated.) Stiffness explicit,
//!   damping implicit: stable for any step up to `2 T_v`.
//! - **At the limit**: a constant torque of exactly `±τmax` over the step: a spring of
//!   stiffness `τmax` with its rest 1 rad away and damping `-τmax dt`, which cancels the
//!   spring's implicit `s dt`, so nothing depends on `v_{n+1}`.
//!
//! Which joints are at the limit is decided with the speed before the step; a joint whose
//! speed then changes much within the step (a foot striking the ground) would receive more
//! than its limit through the implicit damping. So every step is checked after it is taken:
//! if any joint within the limit received more, the world is put back as it was before the
//! step and the step taken again with those joints at their limit, until none does (at
//! most once per joint). Measured on MAX at 240 Hz: about one step in 50 is taken twice,
//! and a snapshot costs about a tenth of a step (BENCHMARKS.md). So the world is copied
//! only every [`SNAPSHOT_EVERY`] steps, and put back as it was before a step by restoring
//! the copy and taking again the steps since, with the targets and limits they had: a
//! step is a function of the world and its drives alone, so the replayed steps are the
//! same bit for bit and so is the trial. Each copy is taken into the last one's buffers
//! (the vendored rapier's `clone_from`), not allocated afresh. A robot whose velocities or
//! poses changed between steps (the trial's shove), or a step of another length, is
//! copied afresh: the state a step finds is compared with the one the last step left.
//! Any other change to the world between steps (forces on its bodies, other bodies, joint
//! settings besides the drives) must be followed by [`DrivenStepper::world_changed`], or a
//! retake would undo it.

use super::world::{RobotWorld, HINGE_DOF_AXIS};
use rapier3d::prelude::*;

/// A joint within its limit may receive this much more than the limit, relative: the
/// rounding of rapier's f32 arithmetic, not a torque a motor would notice.
pub const LIMIT_ROUNDING: f64 = 1e-5;

/// How one joint is driven over one physics step: the torque it receives is
/// `stiffness (rest - angle) - implicit v_{n+1}`.
#[derive(Clone, Copy, Debug, Default)]
pub struct StepDrive {
    /// The angle before the step, rad (as rapier holds it).
    pub angle: f64,
    /// The spring's stiffness, Nm/rad.
    pub stiffness: f64,
    /// The spring's rest angle, rad (as rapier holds it).
    pub rest: f64,
    /// The damping acting on the speed after the step, Nms/rad.
    pub implicit: f64,
    /// Held at its limit over the step (+1 or -1), or driven by its law (0).
    pub at_limit: f64,
}

impl StepDrive {
    /// The torque applied over the step, given the joint's speed after it.
    pub fn torque(&self, speed_after: f64) -> f64 {
        self.stiffness * (self.rest - self.angle) - self.implicit * speed_after
    }
}

/// Steps between copies of the world (the replays a retaken step costs grow with it, the
/// copies shrink: 4 measured best on MAX, BENCHMARKS.md).
pub const SNAPSHOT_EVERY: usize = 4;

/// The parts of the world a step changes: enough to take the step again.
struct Snapshot {
    bodies: RigidBodySet,
    colliders: ColliderSet,
    multibody_joints: MultibodyJointSet,
    islands: IslandManager,
    broad_phase: BroadPhaseBvh,
    narrow_phase: NarrowPhase,
}

impl Snapshot {
    fn take(world: &PhysicsWorld) -> Self {
        Self {
            bodies: world.bodies.clone(),
            colliders: world.colliders.clone(),
            multibody_joints: world.multibody_joints.clone(),
            islands: world.islands.clone(),
            broad_phase: world.broad_phase.clone(),
            narrow_phase: world.narrow_phase.clone(),
        }
    }

    /// Copies the world into this snapshot's own buffers (the vendored rapier's
    /// `clone_from` reuses them where it can): the same copy as [`Snapshot::take`].
    fn retake(&mut self, world: &PhysicsWorld) {
        self.bodies.clone_from(&world.bodies);
        self.colliders.clone_from(&world.colliders);
        self.multibody_joints.clone_from(&world.multibody_joints);
        self.islands.clone_from(&world.islands);
        self.broad_phase.clone_from(&world.broad_phase);
        self.narrow_phase.clone_from(&world.narrow_phase);
    }

    fn restore(&self, world: &mut PhysicsWorld) {
        world.bodies.clone_from(&self.bodies);
        world.colliders.clone_from(&self.colliders);
        world.multibody_joints.clone_from(&self.multibody_joints);
        world.islands.clone_from(&self.islands);
        world.broad_phase.clone_from(&self.broad_phase);
        world.narrow_phase.clone_from(&self.narrow_phase);
    }
}

/// Steps a robot's world with every joint driven by its law and held within its limit.
pub struct DrivenStepper {
    /// Each joint's drive over the last step.
    pub drives: Vec<StepDrive>,
    /// Each joint's speed after the last step, rad/s.
    pub speeds: Vec<f64>,
    /// Each joint's torque over the last step, Nm.
    pub torques: Vec<f64>,
    /// Steps taken again because a joint passed its limit.
    pub retaken: u32,
    /// Steps replayed from the last copy of the world to take a step again.
    pub replayed: u32,
    /// Copies of the world taken.
    pub copies: u32,
    /// Steps between copies ([`SNAPSHOT_EVERY`]).
    every: usize,
    forced: Vec<f64>,
    /// The world before the steps in `since` (unless `stale`), its buffers kept for the
    /// next copy.
    snapshot: Option<Snapshot>,
    /// The snapshot is not of this world's last state: the next step copies it afresh.
    stale: bool,
    /// The targets and held limits of each step since the snapshot (the first
    /// `since_len` of them; the vectors are kept to be reused).
    since: Vec<(Vec<f64>, Vec<f64>)>,
    since_len: usize,
    /// The drives of a replayed step (the stepper's own describe the last step).
    replay_drives: Vec<StepDrive>,
    /// The robot's state as the last step left it, and as the next step finds it.
    left: Vec<u32>,
    found: Vec<u32>,
}

impl DrivenStepper {
    /// A stepper for `joints` joints.
    pub fn new(joints: usize) -> Self {
        Self::with_snapshot_every(joints, SNAPSHOT_EVERY)
    }

    /// A stepper that copies the world every `every` steps (at least 1): the trial is the
    /// same bit for bit whatever `every`, only its cost changes.
    pub fn with_snapshot_every(joints: usize, every: usize) -> Self {
        let every = every.max(1);
        Self {
            drives: vec![StepDrive::default(); joints],
            speeds: vec![0.0; joints],
            torques: vec![0.0; joints],
            retaken: 0,
            replayed: 0,
            copies: 0,
            every,
            forced: vec![0.0; joints],
            snapshot: None,
            stale: true,
            since: vec![(vec![0.0; joints], vec![0.0; joints]); every],
            since_len: 0,
            replay_drives: vec![StepDrive::default(); joints],
            left: Vec::new(),
            found: Vec::new(),
        }
    }

    /// Takes the next step from a fresh copy of the world: to be called after changing the
    /// world between steps in any way besides the robot's velocities and poses.
    pub fn world_changed(&mut self) {
        self.stale = true;
    }

    /// One physics step of `dt` toward `targets`. Afterwards `drives`, `speeds` and
    /// `torques` describe it; no joint's torque passed its limit (to `LIMIT_ROUNDING`).
    /// The stepper must step one world only, from its start (the copies are of it).
    pub fn step(&mut self, rw: &mut RobotWorld, dt: f64, targets: &[f64]) {
        state_bits(rw, dt, &mut self.found);
        if self.stale || self.since_len == self.every || self.found != self.left {
            match &mut self.snapshot {
                Some(snapshot) => snapshot.retake(&rw.world),
                None => self.snapshot = Some(Snapshot::take(&rw.world)),
            }
            self.stale = false;
            self.since_len = 0;
            self.copies += 1;
        }
        self.forced.fill(0.0);
        loop {
            set_drives(rw, dt, targets, &self.forced, &mut self.drives);
            rw.world.step();
            let mb = rw.robot();
            let mut passed = false;
            for (i, slot) in rw.joints.iter().enumerate() {
                let link = mb.link(slot.link_id).expect("joint link");
                let v1 = f64::from(mb.joint_velocity(link)[0]);
                let tau = self.drives[i].torque(v1);
                self.speeds[i] = v1;
                self.torques[i] = tau;
                let limit = slot.drive.max_torque;
                // A non-finite speed is the trial's to report, not a limit to hold.
                if self.drives[i].at_limit == 0.0 && tau.abs() > limit * (1.0 + LIMIT_ROUNDING) {
                    self.forced[i] = tau.signum();
                    passed = true;
                }
            }
            if !passed {
                state_bits(rw, dt, &mut self.left);
                let (t, f) = &mut self.since[self.since_len];
                t.copy_from_slice(targets);
                f.copy_from_slice(&self.forced);
                self.since_len += 1;
                return;
            }
            self.retaken += 1;
            self.snapshot
                .as_ref()
                .expect("taken before the first step")
                .restore(&mut rw.world);
            for (t, f) in &self.since[..self.since_len] {
                set_drives(rw, dt, t, f, &mut self.replay_drives);
                rw.world.step();
                self.replayed += 1;
            }
        }
    }
}

/// The bits of the robot's state a step starts from: its generalized velocities, every
/// part's pose, and the step's length. Changed between two steps only by something
/// besides the stepper.
fn state_bits(rw: &RobotWorld, dt: f64, out: &mut Vec<u32>) {
    out.clear();
    let dt = dt.to_bits();
    out.extend([dt as u32, (dt >> 32) as u32]);
    out.extend(
        rw.robot()
            .generalized_velocity()
            .iter()
            .map(|v| v.to_bits()),
    );
    for (handle, _, _) in &rw.parts {
        let pose = rw.world.bodies[*handle].position();
        out.extend(pose.translation.to_array().iter().map(|v| v.to_bits()));
        out.extend(pose.rotation.to_array().iter().map(|v| v.to_bits()));
    }
}

/// Sets every joint's spring and damping for the coming step of `dt` toward `targets`;
/// joints with a non-zero `forced` sign are held at that limit. Records each in `drives`.
fn set_drives(
    rw: &mut RobotWorld,
    dt: f64,
    targets: &[f64],
    forced: &[f64],
    drives: &mut [StepDrive],
) {
    let RobotWorld {
        world,
        multibody,
        joints,
        ..
    } = rw;
    let (mb, _) = world
        .multibody_joints
        .get_mut(*multibody)
        .expect("the robot's multibody exists");
    for (i, slot) in joints.iter().enumerate() {
        let link = mb.link(slot.link_id).expect("joint link");
        let q = f64::from(link.joint.coords()[HINGE_DOF_AXIS]);
        let v = f64::from(mb.joint_velocity(link)[0]);
        let law = &slot.drive;
        let servo = law.servo_damping();
        let wanted = law.stiffness * (targets[i] - q) - servo * v;
        let at_limit = if forced[i] != 0.0 {
            forced[i]
        } else if wanted.abs() >= law.max_torque {
            wanted.signum()
        } else {
            0.0
        };
        let (stiffness, rest, damping) = if at_limit == 0.0 {
            let k = law.stiffness;
            (k, targets[i], servo - k * dt)
        } else {
            let limit = law.max_torque;
            (limit, q + at_limit, -limit * dt)
        };
        let (s32, r32, c32) = (stiffness as f32, rest as f32, damping as f32);
        drives[i] = StepDrive {
            angle: q,
            stiffness: f64::from(s32),
            rest: f64::from(r32),
            // What rapier applies on v_{n+1}: s dt + c, in its own precision.
            implicit: f64::from(s32) * f64::from(dt as f32) + f64::from(c32),
            at_limit,
        };
        mb.damping_mut()[slot.dof] = c32;
        mb.link_mut(slot.link_id)
            .expect("joint link")
            .joint
            .set_spring(HINGE_DOF_AXIS, s32, r32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strider_common::{BodyPlan, Controller, EvalContext, StartPose};

    /// MAX on the ground, stepping at 240 Hz.
    fn max_world() -> RobotWorld {
        let g = strider_common::reference::max();
        let plan = BodyPlan::new(&g.morphology, EvalContext::paper().brief.payload);
        let start = StartPose::new(&plan, &Controller::static_default());
        RobotWorld::new(&plan, &start, 1.0 / 240.0)
    }

    /// MAX stepped `steps` times at 240 Hz toward targets swung hard enough that joints
    /// reach their limits and steps are taken again, shoved sideways before step
    /// `shove_at`; every step's state and torques, and the stepper.
    fn stepped(every: usize, steps: usize, shove_at: usize) -> (Vec<Vec<u32>>, DrivenStepper) {
        let dt = 1.0 / 240.0;
        let mut rw = max_world();
        let n = rw.joints.len();
        let mut stepper = DrivenStepper::with_snapshot_every(n, every);
        let mut targets = vec![0.0; n];
        let mut states = Vec::with_capacity(steps);
        for step in 0..steps {
            let t = step as f64 * dt;
            for (i, target) in targets.iter_mut().enumerate() {
                *target = 1.2 * (9.0 * t + i as f64).sin();
            }
            if step == shove_at {
                rw.robot_mut().generalized_velocity_mut()[2] += 0.5;
            }
            stepper.step(&mut rw, dt, &targets);
            let mut bits = Vec::new();
            state_bits(&rw, dt, &mut bits);
            // Each f64 torque whole, as two 32-bit words.
            bits.extend(stepper.torques.iter().flat_map(|t| {
                let b = t.to_bits();
                [b as u32, (b >> 32) as u32]
            }));
            states.push(bits);
        }
        (states, stepper)
    }

    #[test]
    fn a_copy_every_few_steps_steps_as_a_copy_every_step() {
        let (steps, shove_at) = (600, 250);
        let (reference, each) = stepped(1, steps, shove_at);
        assert!(each.retaken > 5, "only {} steps retaken", each.retaken);
        assert_eq!(each.replayed, 0);
        for every in [4, 1000] {
            let (states, stepper) = stepped(every, steps, shove_at);
            assert_eq!(stepper.retaken, each.retaken, "every {every}");
            assert!(stepper.replayed > 0, "every {every}: nothing replayed");
            // Every `every` steps, and once more after the shove.
            assert!(
                stepper.copies as usize <= steps / every + 2,
                "every {every}"
            );
            for (step, (a, b)) in reference.iter().zip(&states).enumerate() {
                assert!(a == b, "every {every}: step {step} differs");
            }
        }
    }

    #[test]
    fn a_world_changed_between_steps_is_copied_afresh() {
        let (_, plain) = stepped(1000, 300, usize::MAX);
        let (_, shoved) = stepped(1000, 300, 150);
        assert_eq!(plain.copies, 1);
        assert_eq!(shoved.copies, 2);
        // Told so, or with another step length.
        let mut rw = max_world();
        let mut stepper = DrivenStepper::new(rw.joints.len());
        let targets = vec![0.0; rw.joints.len()];
        stepper.step(&mut rw, 1.0 / 240.0, &targets);
        stepper.world_changed();
        stepper.step(&mut rw, 1.0 / 240.0, &targets);
        stepper.step(&mut rw, 1.0 / 480.0, &targets);
        assert_eq!(stepper.copies, 3);
    }
}
