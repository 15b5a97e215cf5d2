//! The body plan: a genome expanded into a concrete robot (docs/model.md sections 2-5).
//!
//! Frames: the body frame has its origin at the body cuboid's centre, x forward, y up,
//! z right. Each link's own frame has its origin at its joint, the link running along +z to
//! its tip. A link's pose in its parent's frame at joint angle `q` is
//! `Translation(anchor) * Rotation(axis, q) * rest`: `anchor` and `axis` are in the parent
//! frame, `rest` is the link's orientation at `q = 0`. `docs/model.md` draws all of this.
//!
//! No physics-engine types appear here: the simulator and the drawings both consume this.

use crate::genome::Morphology;
use crate::mass::{self, MassProperties};
use crate::params::{
    LINKS_PER_LEG, LINK_AXIS, LINK_LENGTH, LINK_WIDTH, M, MOTOR_DAMPING, MOTOR_MAX_SPEED,
    MOTOR_MAX_TORQUE, MOTOR_STIFFNESS,
};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use std::f64::consts::{FRAC_PI_2, PI};

/// The stance angle of every joint: at `q = STANCE_ANGLE` each link has its nominal stance
/// orientation relative to its parent, whatever its hinge axis: the hip link straight out
/// from the body side, the upper leg 0.5 rad below the hip link's line, the lower leg at
/// `KNEE_BEND` below the upper leg's line. The controller's midpoint (vo 0.5) is therefore
/// a symmetric standing posture for every genome; a tilted hinge axis changes the plane a
/// link swings in about the stance, not the stance itself (docs/model.md section 5).
pub const STANCE_ANGLE: f64 = 0.5;
/// The hip's neutral angle: the hip link points straight out from the body side.
pub const HIP_NEUTRAL: f64 = STANCE_ANGLE;
/// The knee's bend when the knee is at its stance angle: the lower leg at this angle below
/// the upper leg's line *plus* the upper leg's own slope, so that at the stance (upper
/// leg `STANCE_ANGLE` below horizontal) the lower leg is vertical. A positive `q2` opens
/// the knee (turns the lower leg up and outward), the opposite sense to `q1`, so at
/// `q1 = q2` the lower leg keeps its absolute angle: vertical through the whole stride
/// when both joints follow the same sinusoid, the upper leg alone lifting and lowering
/// the foot.
pub const KNEE_BEND: f64 = FRAC_PI_2;

/// Smallest gap between the hip roots of a left and a right leg, m.
pub const ATTACH_CLEARANCE: f64 = 0.02;

/// Which side of the body a leg is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Side {
    /// +z, the encoded side.
    Right,
    /// -z, the mirror image.
    Left,
}

impl Side {
    /// 0 for the right side, 1 for the left (the `s` of the gait's phase rule).
    pub fn index(self) -> usize {
        match self {
            Side::Right => 0,
            Side::Left => 1,
        }
    }
}

/// The servo's derivative time T_v, s: every drive's velocity gain is the encoded damping
/// plus `stiffness * SERVO_DERIVATIVE_TIME`, a PD position servo whose derivative time is
/// T_v + d / k (docs/model.md section 6). With the encoded damping alone (1 to 40 Nms/rad
/// against 2000 to 6000 Nm/rad) a leg rings at its natural frequency with a damping ratio
/// of a few hundredths; the simulator used to add this damping silently (its backward-Euler
/// spring at a 1/30 s step adds k dt), so the value keeps the damping the designs were found
/// with, now the same at every physics step and written in the URDF.
pub const SERVO_DERIVATIVE_TIME: f64 = 1.0 / 30.0;

/// The only bound the model puts on a joint's speed, rad/s (and on the body's, m/s): past it
/// the trial stops as blown up. A motor's `max_speed` (wmax) sets its gait amplitude and its
/// mass but does not bound the joint's speed, which in a walk reaches a median 2.35x wmax
/// (docs/model.md section 6, "A joint's speed"); the URDF writes this as each joint's
/// velocity limit, so a tool that enforces limits moves the joints as the trial does.
pub const BLOW_UP_SPEED: f64 = 100.0;

/// A joint's drive after the strength multiplier.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointDrive {
    /// Spring stiffness, Nm/rad.
    pub stiffness: f64,
    /// Damping, Nms/rad.
    pub damping: f64,
    /// Torque limit, Nm.
    pub max_torque: f64,
    /// Speed limit wmax, rad/s (sets the gait amplitude).
    pub max_speed: f64,
}

impl JointDrive {
    /// The servo's velocity gain, Nms/rad: the encoded damping plus the velocity loop's
    /// `stiffness * SERVO_DERIVATIVE_TIME`. The drive's torque is
    /// `clamp(k (q* - q) - servo_damping * qdot, -max_torque, max_torque)`.
    pub fn servo_damping(&self) -> f64 {
        self.damping + self.stiffness * SERVO_DERIVATIVE_TIME
    }

    /// The drive's torque at angle `q` and speed `qdot` toward `target`, clamped to the limit.
    pub fn torque(&self, target: f64, q: f64, qdot: f64) -> f64 {
        (self.stiffness * (target - q) - self.servo_damping() * qdot)
            .clamp(-self.max_torque, self.max_torque)
    }
}

/// One link of one leg.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkPlan {
    /// Length along the link's +z, m (after the length multiplier).
    pub length: f64,
    /// Square tube outer width, m (after the width multiplier).
    pub width: f64,
    /// Tube wall thickness, m.
    pub wall: f64,
    /// Joint position in the parent's frame.
    pub anchor: Vector3<f64>,
    /// Hinge axis in the parent's frame (unit).
    pub axis: Unit<Vector3<f64>>,
    /// Orientation of the link frame relative to the parent frame at joint angle 0.
    pub rest: UnitQuaternion<f64>,
    pub drive: JointDrive,
    /// Tube plus the motor at the tip, in the link frame.
    pub mass: MassProperties,
}

impl LinkPlan {
    /// This link's pose in its parent's frame at joint angle `q`.
    pub fn pose_in_parent(&self, q: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.anchor),
            UnitQuaternion::from_axis_angle(&self.axis, q) * self.rest,
        )
    }

    /// The eight corners of the link's cuboid in its own frame.
    pub fn corners(&self) -> [Vector3<f64>; 8] {
        let h = 0.5 * self.width;
        cuboid_corners(Vector3::new(-h, -h, 0.0), Vector3::new(h, h, self.length))
    }
}

/// One leg: three links from the body outwards.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegPlan {
    /// Side of the body.
    pub side: Side,
    /// Position along the side, 0 at the front.
    pub index: usize,
    /// `u = 1 - 2 i / (n - 1)`: +1 at the front leg, -1 at the back.
    pub u: f64,
    /// Gait phase `phi`: 0 or pi by the tripod pattern ([`tripod_set`]).
    pub phase: f64,
    /// Hip (0), upper leg (1), lower leg (2). Link 0's parent is the body.
    pub links: [LinkPlan; LINKS_PER_LEG],
}

impl LegPlan {
    /// Poses of the three links in the body frame for joint angles `q`.
    pub fn link_poses(&self, q: [f64; LINKS_PER_LEG]) -> [Isometry3<f64>; LINKS_PER_LEG] {
        let p0 = self.links[0].pose_in_parent(q[0]);
        let p1 = p0 * self.links[1].pose_in_parent(q[1]);
        let p2 = p1 * self.links[2].pose_in_parent(q[2]);
        [p0, p1, p2]
    }
}

/// A genome expanded into a robot.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyPlan {
    /// Body cuboid half-extents (x, y, z), m.
    pub body_half_extents: Vector3<f64>,
    /// Where avionics and payload sit, body frame, m.
    pub payload_position: Vector3<f64>,
    /// Payload mass, kg (from the design brief).
    pub payload_mass: f64,
    /// Body foam plus avionics plus payload, body frame.
    pub body_mass: MassProperties,
    /// Legs: right side front to back, then left side front to back.
    pub legs: Vec<LegPlan>,
}

/// Mirror in the body's x-y plane (z to -z).
fn mirror_m() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0))
}

/// The flip of a link's own y axis that keeps a mirrored link frame right-handed.
fn mirror_d() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, 1.0))
}

fn rotation(m: Matrix3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

impl BodyPlan {
    /// Expands a morphology, carrying `payload_mass` kg of payload.
    pub fn new(m: &Morphology, payload_mass: f64) -> Self {
        let half = Vector3::new(
            m.get(M::BodyHalfX),
            m.get(M::BodyHalfY),
            m.get(M::BodyHalfZ),
        );
        let payload_position = Vector3::new(
            m.get(M::PayloadX) * half.x,
            0.0,
            m.get(M::PayloadZ) * half.z,
        );
        let n = m.legs_per_side();
        let mut legs = Vec::with_capacity(2 * n);
        for i in 0..n {
            legs.push(right_leg(m, half, i, n));
        }
        for i in 0..n {
            legs.push(mirror_leg(&legs[i], n));
        }
        Self {
            body_half_extents: half,
            payload_position,
            payload_mass,
            body_mass: mass::body(half, payload_position, payload_mass),
            legs,
        }
    }

    /// Total mass including payload, kg.
    pub fn total_mass(&self) -> f64 {
        self.body_mass.mass
            + self
                .legs
                .iter()
                .flat_map(|l| &l.links)
                .map(|l| l.mass.mass)
                .sum::<f64>()
    }

    /// Mass without the payload (what the brief limits), kg.
    pub fn mass_without_payload(&self) -> f64 {
        self.total_mass() - self.payload_mass
    }

    /// Legs per side.
    pub fn legs_per_side(&self) -> usize {
        self.legs.len() / 2
    }

    /// The body cuboid's corners in the body frame.
    pub fn body_corners(&self) -> [Vector3<f64>; 8] {
        cuboid_corners(-self.body_half_extents, self.body_half_extents)
    }
}

fn cuboid_corners(lo: Vector3<f64>, hi: Vector3<f64>) -> [Vector3<f64>; 8] {
    std::array::from_fn(|i| {
        Vector3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// `u_i = 1 - 2 i / (n - 1)`: the leg's position along the body, +1 front, -1 back.
pub fn leg_position(i: usize, n: usize) -> f64 {
    1.0 - 2.0 * i as f64 / (n - 1) as f64
}

/// Which of the two alternating leg sets of the tripod gait a leg belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TripodSet {
    /// Gait phase 0: the right side's front and back legs, the left side's middle legs.
    A,
    /// Gait phase pi: the other legs.
    B,
}

impl TripodSet {
    /// The set's gait phase `phi`, rad.
    pub fn phase(self) -> f64 {
        match self {
            TripodSet::A => 0.0,
            TripodSet::B => PI,
        }
    }
}

/// The paper's tripod pattern for leg `i` (0 at the front) of `n` per side on `side`:
/// "lifts the front and back legs from one side, and the middle leg from the other, per
/// stride phase ... for four and eight-legged robots the pattern of lift-offs is maintained".
/// So for n >= 3 the right side's front and back legs and the left side's middle legs form
/// set A, the rest set B; for n = 2 the diagonal pairs do (a trot). Opposite legs are always
/// in different sets, and middle legs on one side swing together, so they never sweep
/// into each other.
pub fn tripod_set(i: usize, n: usize, side: Side) -> TripodSet {
    let outer = if n == 2 {
        // Diagonals: right front with left back.
        match side {
            Side::Right => i == 0,
            Side::Left => i == 1,
        }
    } else {
        let end = i == 0 || i + 1 == n;
        match side {
            Side::Right => end,
            Side::Left => !end,
        }
    };
    if outer {
        TripodSet::A
    } else {
        TripodSet::B
    }
}

fn right_leg(m: &Morphology, half: Vector3<f64>, i: usize, n: usize) -> LegPlan {
    let u = leg_position(i, n);
    let u2 = u * u;
    let width_scale = 1.0 + m.get(M::WidthMult) * u2;
    // An inward offset may put the leg under the body, but never across the centreline:
    // the two sides' hip roots keep ATTACH_CLEARANCE between them.
    let min_z = 0.5 * m.get(LINK_WIDTH[0]) * width_scale + 0.5 * ATTACH_CLEARANCE;
    let attach = Vector3::new(
        half.x * (m.get(M::SpreadLinFwd) * u + m.get(M::SpreadQuadFwd) * u2),
        m.get(M::AttachHeight) * half.y,
        (half.z + m.get(M::SpreadLinRight) * u + m.get(M::SpreadQuadRight) * u2).max(min_z),
    );
    // Positive pitch tilts the hip link's outward direction (+z) upwards.
    let root = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -m.get(M::AttachPitch));
    let length_scale = 1.0 + m.get(M::LengthMult) * u2;
    let strength_scale = 1.0 + 0.1 * m.get(M::StrengthMult) * u2;
    let wall = m.get(M::WallThickness);

    // A closure called three times rather than `array::from_fn`, which moved each
    // 240-byte link through four temporaries (a fifth of the coordinator's precheck).
    let link = |k: usize| {
        let length = m.get(LINK_LENGTH[k]) * length_scale;
        let width = m.get(LINK_WIDTH[k]) * width_scale;
        let drive = JointDrive {
            stiffness: m.get(MOTOR_STIFFNESS[k]) * strength_scale,
            damping: m.get(MOTOR_DAMPING[k]),
            max_torque: m.get(MOTOR_MAX_TORQUE[k]) * strength_scale,
            max_speed: m.get(MOTOR_MAX_SPEED[k]),
        };
        let genome_axis = Unit::new_normalize(Vector3::from(LINK_AXIS[k].map(|p| m.get(p))));
        // (anchor, hinge axis, stance orientation), all in the parent's frame.
        let (anchor, axis, stance) = match k {
            // The hip's parent is the body: its axis is given in the body frame (about
            // up), and at the stance the hip link points straight out, tilted by the
            // attach pitch.
            0 => (attach, genome_axis, root),
            // The upper leg sits at the hip link's tip, 0.5 rad below horizontal at the
            // stance whatever the pitch; positive turns it down.
            1 => (
                Vector3::new(0.0, 0.0, m.get(LINK_LENGTH[0]) * length_scale),
                genome_axis,
                UnitQuaternion::from_axis_angle(
                    &Vector3::x_axis(),
                    STANCE_ANGLE + m.get(M::AttachPitch),
                ),
            ),
            // The lower leg sits at the upper leg's tip, vertical at the stance; positive
            // opens the knee, so its hinge turns about the reversed axis.
            _ => (
                Vector3::new(0.0, 0.0, m.get(LINK_LENGTH[1]) * length_scale),
                -genome_axis,
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), KNEE_BEND - STANCE_ANGLE),
            ),
        };
        // The joint's zero: the stance orientation turned back by the stance angle about
        // the joint's own hinge, so that q = STANCE_ANGLE is the stance for any axis.
        let rest = UnitQuaternion::from_axis_angle(&axis, -STANCE_ANGLE) * stance;
        LinkPlan {
            length,
            width,
            wall,
            anchor,
            axis,
            rest,
            drive,
            mass: mass::link(length, width, wall, drive.max_torque, drive.max_speed),
        }
    };
    let links = [link(0), link(1), link(2)];
    LegPlan {
        side: Side::Right,
        index: i,
        u,
        phase: tripod_set(i, n, Side::Right).phase(),
        links,
    }
}

/// The left leg opposite `right`. Positions mirror in z; hinge axes mirror as the
/// pseudovectors they are, so equal joint angles give mirror-image poses and the gait
/// drives both sides forward.
fn mirror_leg(right: &LegPlan, n: usize) -> LegPlan {
    let (mm, d) = (mirror_m(), mirror_d());
    let mut links = right.links;
    for (k, link) in links.iter_mut().enumerate() {
        // The hip's parent (the body) is mirrored by M; the other parents are link frames,
        // whose mirror image is re-expressed with D to stay right-handed.
        let (point_map, axis_map) = if k == 0 { (mm, -mm) } else { (d, -d) };
        link.anchor = point_map * link.anchor;
        link.axis = Unit::new_normalize(axis_map * link.axis.into_inner());
        let r = link.rest.to_rotation_matrix().into_inner();
        link.rest = rotation(if k == 0 { mm * r * d } else { d * r * d });
    }
    LegPlan {
        side: Side::Left,
        index: right.index,
        u: right.u,
        phase: tripod_set(right.index, n, Side::Left).phase(),
        links,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::genome::Genome;
    use crate::rng::{CandidateSeed, Purpose};
    use crate::variation::Scheme;
    use proptest::prelude::*;

    pub(crate) fn max_genome() -> Genome {
        crate::reference::max()
    }

    proptest! {
        /// Every point of every left link is the mirror image of the same point on the
        /// right link, at any joint angles.
        #[test]
        fn left_side_mirrors_the_right(
            seed in any::<u64>(),
            q in prop::array::uniform3(-1.5f64..2.5),
        ) {
            let g = Genome::random(Scheme::Static, &mut CandidateSeed::new(seed, 0).rng(Purpose::RandomGenome));
            let plan = BodyPlan::new(&g.morphology, 10.0);
            let n = plan.legs_per_side();
            for i in 0..n {
                let (r, l) = (&plan.legs[i], &plan.legs[n + i]);
                prop_assert_eq!((r.side, l.side), (Side::Right, Side::Left));
                prop_assert_eq!(r.index, l.index);
                prop_assert!(r.phase != l.phase, "opposite legs must be in antiphase");
                for ((pr, pl), (lr, ll)) in r.link_poses(q).iter().zip(l.link_poses(q)).zip(r.links.iter().zip(&l.links)) {
                    prop_assert_eq!(lr.mass, ll.mass);
                    for z in [0.0, lr.length] {
                        let wr = pr * nalgebra::Point3::new(0.0, 0.0, z);
                        let wl = pl * nalgebra::Point3::new(0.0, 0.0, z);
                        prop_assert!((wl.coords - mirror_m() * wr.coords).norm() < 1e-9);
                    }
                    // A point off the axis: (a, b, z) on the right is (a, -b, z) on the left.
                    let wr = pr * nalgebra::Point3::new(0.01, 0.02, 0.3);
                    let wl = pl * nalgebra::Point3::new(0.01, -0.02, 0.3);
                    prop_assert!((wl.coords - mirror_m() * wr.coords).norm() < 1e-9);
                }
            }
        }
    }

    #[test]
    fn stance_conventions_hold_on_a_straight_leg() {
        // Ideal axes, no pitch: at q = (0.5, 0.5, 0.5) the hip points straight out (+z),
        // the upper leg slopes down 0.5 rad, the lower leg hangs vertically.
        let mut g = max_genome();
        let m = &mut g.morphology;
        for (p, v) in [
            (M::AttachPitch, 0.0),
            (M::Link0AxisX, 0.0),
            (M::Link0AxisY, 1.0),
            (M::Link0AxisZ, 0.0),
            (M::Link1AxisX, 1.0),
            (M::Link1AxisY, 0.0),
            (M::Link1AxisZ, 0.0),
            (M::Link2AxisX, 1.0),
            (M::Link2AxisY, 0.0),
            (M::Link2AxisZ, 0.0),
        ] {
            m.set_clamped(p, v);
        }
        let plan = BodyPlan::new(m, 10.0);
        for leg in &plan.legs {
            let out = if leg.side == Side::Right { 1.0 } else { -1.0 };
            let poses = leg.link_poses([0.5; 3]);
            let dir = |k: usize| poses[k].rotation * Vector3::z();
            assert!((dir(0) - Vector3::new(0.0, 0.0, out)).norm() < 1e-12);
            assert!(
                (dir(1) - Vector3::new(0.0, -(0.5f64).sin(), out * (0.5f64).cos())).norm() < 1e-12
            );
            assert!((dir(2) - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
            // A larger hip angle swings the leg forward on both sides.
            let fwd = leg.link_poses([0.8, 0.5, 0.5])[0].rotation * Vector3::z();
            assert!(fwd.x > 0.0);
            // A larger upper-leg angle pushes the foot down on both sides.
            let foot = |q: [f64; 3]| {
                leg.link_poses(q)[2] * nalgebra::Point3::new(0.0, 0.0, leg.links[2].length)
            };
            assert!(foot([0.5, 0.7, 0.5]).y < foot([0.5, 0.5, 0.5]).y);
            // A larger lower-leg angle opens the knee: the foot swings outward.
            assert!(foot([0.5, 0.5, 0.7]).z * out > foot([0.5, 0.5, 0.5]).z * out);
            // Equal upper and lower angles keep the lower leg vertical.
            for q in [0.1, 0.5, 1.1] {
                let d = leg.link_poses([0.5, q, q])[2].rotation * Vector3::z();
                assert!(
                    (d - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12,
                    "{q}: {d}"
                );
            }
        }
    }

    #[test]
    fn tripod_pattern_per_leg_count() {
        use TripodSet::{A, B};
        let sets = |n: usize, side: Side| -> Vec<TripodSet> {
            (0..n).map(|i| tripod_set(i, n, side)).collect()
        };
        // n = 2: a trot, right front with left back.
        assert_eq!(sets(2, Side::Right), [A, B]);
        assert_eq!(sets(2, Side::Left), [B, A]);
        // n >= 3: the right side's front and back legs with every middle leg on the left.
        assert_eq!(sets(3, Side::Right), [A, B, A]);
        assert_eq!(sets(3, Side::Left), [B, A, B]);
        assert_eq!(sets(4, Side::Right), [A, B, B, A]);
        assert_eq!(sets(4, Side::Left), [B, A, A, B]);
        assert_eq!(sets(6, Side::Right), [A, B, B, B, B, A]);
        assert_eq!(sets(6, Side::Left), [B, A, A, A, A, B]);
        for n in 2..=6 {
            let (r, l) = (sets(n, Side::Right), sets(n, Side::Left));
            // Opposite legs always alternate, and the two sets hold n legs each.
            assert!(r.iter().zip(&l).all(|(a, b)| a != b), "n = {n}");
            let in_a = r.iter().chain(&l).filter(|s| **s == A).count();
            assert_eq!(in_a, n, "n = {n}");
        }
        // The body plan carries the phases.
        let mut g = max_genome();
        g.morphology.set_clamped(M::LegsPerSide, 4.0);
        let plan = BodyPlan::new(&g.morphology, 10.0);
        let phases: Vec<f64> = plan.legs.iter().map(|l| l.phase).collect();
        assert_eq!(phases, [0.0, PI, PI, 0.0, PI, 0.0, 0.0, PI]);
    }

    #[test]
    fn hinge_axis_tilts_and_pitch_leave_the_stance_posture_alone() {
        // At the stance angles every link has its nominal orientation in the body frame,
        // whatever the hinge axes: hip link straight out (tilted up by the pitch only),
        // upper leg 0.5 rad below horizontal, lower leg vertical.
        let mut g = max_genome();
        for (p, v) in [
            (M::AttachPitch, 0.4),
            (M::Link0AxisX, 0.2),
            (M::Link0AxisZ, -0.2),
            (M::Link1AxisY, 0.2),
            (M::Link1AxisZ, -0.15),
            (M::Link2AxisY, 0.2),
            (M::Link2AxisZ, 0.2),
        ] {
            g.morphology.set_clamped(p, v);
        }
        let plan = BodyPlan::new(&g.morphology, 10.0);
        for leg in &plan.legs {
            let out = if leg.side == Side::Right { 1.0 } else { -1.0 };
            let poses = leg.link_poses([STANCE_ANGLE; 3]);
            let dir = |k: usize| poses[k].rotation * Vector3::z();
            let pitch = 0.4f64;
            assert!((dir(0) - Vector3::new(0.0, pitch.sin(), out * pitch.cos())).norm() < 1e-12);
            let down = STANCE_ANGLE;
            assert!((dir(1) - Vector3::new(0.0, -down.sin(), out * down.cos())).norm() < 1e-12);
            assert!((dir(2) - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
            // The tilted axes do change how the links move about the stance.
            let moved = leg.link_poses([STANCE_ANGLE, STANCE_ANGLE, STANCE_ANGLE + 0.3])[2]
                .rotation
                * Vector3::z();
            assert!(
                moved.x.abs() > 1e-3,
                "a tilted knee swings partly fore and aft"
            );
        }
    }

    #[test]
    fn quadratic_variations_follow_u() {
        let g = max_genome();
        let m = &g.morphology;
        let plan = BodyPlan::new(m, 10.0);
        let n = plan.legs_per_side();
        for leg in &plan.legs[..n] {
            let u2 = leg.u * leg.u;
            let l1 = m.get(M::Link1Length) * (1.0 + m.get(M::LengthMult) * u2);
            assert!((leg.links[1].length - l1).abs() < 1e-12);
            let k = m.get(M::Motor2Stiffness) * (1.0 + 0.1 * m.get(M::StrengthMult) * u2);
            assert!((leg.links[2].drive.stiffness - k).abs() < 1e-9);
            let x = m.get(M::BodyHalfX)
                * (m.get(M::SpreadLinFwd) * leg.u + m.get(M::SpreadQuadFwd) * u2);
            assert!((leg.links[0].anchor.x - x).abs() < 1e-12);
        }
        assert_eq!(plan.legs[0].u, 1.0);
        assert_eq!(plan.legs[n - 1].u, -1.0);
    }
}
