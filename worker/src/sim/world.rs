//! Builds a rapier3d world from a body plan in its start pose.
//!
//! One multibody: the body is its free root; every link hangs on a revolute joint whose
//! rapier angle is exactly the model's joint angle q (see `docs/model.md`). Joints are
//! implicit springs with joint damping (the approach `docs/rapier.md` records
//! stable); the trial sets each spring and damping before every step to drive the joint
//! by its servo law and clamp it (`super::drive`).

use ::nalgebra::{Isometry3, Matrix3, Unit, UnitQuaternion, Vector3};
use rapier3d::prelude::*;
use strider_common::body_plan::{BodyPlan, JointDrive};
use strider_common::contact::Part;
use strider_common::experiment::DEFAULT_FRICTION;
use strider_common::mass::MassProperties as ModelMass;
use strider_common::params::LINKS_PER_LEG;
use strider_common::StartPose;

/// Collider `user_data` of the ground.
pub const GROUND_TAG: u128 = u128::MAX;
/// Collider `user_data` of the body; links are `1 + 3 * leg + k`.
pub const BODY_TAG: u128 = 0;
/// The revolute joint's free axis in rapier's spatial layout (angular x).
pub const HINGE_DOF_AXIS: usize = 3;

/// One driven joint of the robot.
#[derive(Clone, Copy, Debug)]
pub struct JointSlot {
    /// The link's id in the multibody.
    pub link_id: usize,
    /// Its index in the multibody's generalized coordinates.
    pub dof: usize,
    /// The drive's law: stiffness, servo damping and torque limit.
    pub drive: JointDrive,
}

/// A robot standing in a rapier world, ready to step.
pub struct RobotWorld {
    pub world: PhysicsWorld,
    /// The multibody holding the robot.
    pub multibody: MultibodyJointHandle,
    /// Joints leg by leg, three per leg, in the plan's leg order.
    pub joints: Vec<JointSlot>,
    /// Each part's rigid body with its local centre of mass and mass (body first, then
    /// links leg by leg), to compute the robot's centre of mass.
    pub parts: Vec<(RigidBodyHandle, Vector3<f64>, f64)>,
}

fn vec3(v: Vector3<f64>) -> Vector {
    Vector::new(v.x as f32, v.y as f32, v.z as f32)
}

fn quat(q: UnitQuaternion<f64>) -> Rotation {
    Rotation::from_xyzw(q.i as f32, q.j as f32, q.k as f32, q.w as f32)
}

fn pose(iso: &Isometry3<f64>) -> Pose {
    Pose::from_parts(vec3(iso.translation.vector), quat(iso.rotation))
}

fn mass_props(m: &ModelMass) -> MassProperties {
    let i: Matrix3<f64> = m.inertia;
    let mat = Matrix::from_cols_array(&[
        i[(0, 0)] as f32,
        i[(1, 0)] as f32,
        i[(2, 0)] as f32,
        i[(0, 1)] as f32,
        i[(1, 1)] as f32,
        i[(2, 1)] as f32,
        i[(0, 2)] as f32,
        i[(1, 2)] as f32,
        i[(2, 2)] as f32,
    ]);
    MassProperties::with_inertia_matrix(vec3(m.com), m.mass as f32, mat)
}

/// The collider tag of a robot part.
pub fn tag_of(part: Part) -> u128 {
    match part {
        Part::Body => BODY_TAG,
        Part::Link { leg, link } => 1 + (leg * LINKS_PER_LEG + link) as u128,
    }
}

/// The robot part a collider tag stands for (not the ground's).
pub fn part_of_tag(tag: u128) -> Part {
    if tag == BODY_TAG {
        return Part::Body;
    }
    let i = (tag - 1) as usize;
    Part::Link {
        leg: i / LINKS_PER_LEG,
        link: i % LINKS_PER_LEG,
    }
}

/// A rotation whose x axis is `axis` (the revolute joint turns about its frame's x).
fn frame_with_x_axis(axis: &Unit<Vector3<f64>>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(&Vector3::x(), axis).unwrap_or_else(|| {
        // axis = -x: any half-turn about an axis perpendicular to x.
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI)
    })
}

impl RobotWorld {
    /// The robot of `plan` in `start`, on flat ground, stepping every `dt` seconds, with
    /// the default friction ([`DEFAULT_FRICTION`]).
    pub fn new(plan: &BodyPlan, start: &StartPose, dt: f64) -> Self {
        Self::with_friction(plan, start, dt, DEFAULT_FRICTION)
    }

    /// [`RobotWorld::new`] with `friction` the coefficient of every part and of the ground
    /// (rapier averages the two: so the contact's coefficient is `friction`).
    pub fn with_friction(plan: &BodyPlan, start: &StartPose, dt: f64, friction: f64) -> Self {
        let friction = friction as f32;
        let mut world = PhysicsWorld::new();
        let p = &mut world.integration_parameters;
        p.dt = dt as f32;
        // One solver substep: rapier's solver iterations are TGS substeps, each re-solving the
        // multibody dynamics (4x the cost), and the trial's torque accounting assumes the
        // spring acts over exactly one step of `dt`. Internal PGS iterations resolve the
        // contacts within it (docs/rapier.md: 1 to 4 stand still and walk smoothly).
        p.num_solver_iterations = 1;
        p.num_internal_pgs_iterations = 4;
        p.max_ccd_substeps = 0;

        let ground = world
            .bodies
            .insert(RigidBodyBuilder::fixed().translation(Vector::new(0.0, -0.5, 0.0)));
        world.colliders.insert_with_parent(
            ColliderBuilder::cuboid(1000.0, 0.5, 1000.0)
                .friction(friction)
                .user_data(GROUND_TAG),
            ground,
            &mut world.bodies,
        );

        let mut parts = Vec::with_capacity(1 + plan.legs.len() * LINKS_PER_LEG);
        let body = world.bodies.insert(
            RigidBodyBuilder::dynamic()
                .pose(pose(&start.body))
                .additional_mass_properties(mass_props(&plan.body_mass))
                .can_sleep(false),
        );
        let h = plan.body_half_extents;
        world.colliders.insert_with_parent(
            ColliderBuilder::cuboid(h.x as f32, h.y as f32, h.z as f32)
                .density(0.0)
                .friction(friction)
                .user_data(BODY_TAG),
            body,
            &mut world.bodies,
        );
        parts.push((body, plan.body_mass.com, plan.body_mass.mass));

        let mut handles = Vec::with_capacity(plan.legs.len() * LINKS_PER_LEG);
        let mut multibody = None;
        for (leg_index, (leg, poses)) in plan.legs.iter().zip(&start.link_poses).enumerate() {
            let mut parent = body;
            for (k, (link, link_pose)) in leg.links.iter().zip(poses).enumerate() {
                let rb = world.bodies.insert(
                    RigidBodyBuilder::dynamic()
                        .pose(pose(link_pose))
                        .additional_mass_properties(mass_props(&link.mass))
                        .can_sleep(false),
                );
                let half_w = (0.5 * link.width) as f32;
                world.colliders.insert_with_parent(
                    ColliderBuilder::cuboid(half_w, half_w, (0.5 * link.length) as f32)
                        .translation(Vector::new(0.0, 0.0, (0.5 * link.length) as f32))
                        .density(0.0)
                        .friction(friction)
                        .user_data(tag_of(Part::Link {
                            leg: leg_index,
                            link: k,
                        })),
                    rb,
                    &mut world.bodies,
                );
                parts.push((rb, link.mass.com, link.mass.mass));
                // Joint frame in the parent: at the anchor, its x along the hinge axis. In the
                // child: the same frame seen from the link at q = 0.
                let j = frame_with_x_axis(&link.axis);
                let frame1 = Isometry3::from_parts(link.anchor.into(), j);
                let frame2 =
                    Isometry3::from_parts(Vector3::zeros().into(), link.rest.inverse() * j);
                let joint = RevoluteJointBuilder::new(Vector::X)
                    .contacts_enabled(false)
                    .build();
                let mut generic: GenericJoint = joint.into();
                generic.set_local_frame1(pose(&frame1));
                generic.set_local_frame2(pose(&frame2));
                let handle = world
                    .multibody_joints
                    .insert(parent, rb, generic, true)
                    .expect("a tree of links always makes a valid multibody");
                multibody.get_or_insert(handle);
                handles.push((handle, link.drive));
                parent = rb;
            }
        }

        // rapier computes mass properties lazily; forward kinematics below needs them now.
        for (handle, _, _) in &parts {
            world.bodies[*handle].recompute_mass_properties_from_colliders(&world.colliders);
        }

        // Put every joint at its start angle and configure its spring and damping.
        let mut joints = Vec::with_capacity(handles.len());
        let angles = start.joint_angles.iter().flatten();
        let root = multibody.expect("a robot has legs");
        for ((handle, drive), &q) in handles.iter().zip(angles) {
            let (mb, link_id) = world
                .multibody_joints
                .get_mut(*handle)
                .expect("joint exists");
            let link = mb.link_mut(link_id).expect("link exists");
            link.joint.apply_displacement(&[q as f32]);
            // The trial sets each joint's spring and damping before every step.
            let dof = link.assembly_id();
            joints.push(JointSlot {
                link_id,
                dof,
                drive: *drive,
            });
        }
        let (mb, _) = world
            .multibody_joints
            .get_mut(root)
            .expect("root joint exists");
        mb.forward_kinematics(&world.bodies, true);
        mb.update_rigid_bodies(&mut world.bodies, true);

        Self {
            world,
            multibody: root,
            joints,
            parts,
        }
    }

    /// The robot's multibody.
    pub fn robot(&self) -> &Multibody {
        self.world
            .multibody_joints
            .get(self.multibody)
            .expect("the robot's multibody exists")
            .0
    }

    /// The robot's multibody, mutably.
    pub fn robot_mut(&mut self) -> &mut Multibody {
        self.world
            .multibody_joints
            .get_mut(self.multibody)
            .expect("the robot's multibody exists")
            .0
    }

    /// Total simulated mass of the robot, kg.
    pub fn mass(&self) -> f64 {
        self.parts
            .iter()
            .map(|(h, _, _)| f64::from(self.world.bodies[*h].mass()))
            .sum()
    }
}
