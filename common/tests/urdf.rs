//! URDF export checked with a standard parser (urdf-rs, the one the Rust robotics stack
//! uses): every part and motor is there, masses and inertias round-trip, and forward
//! kinematics through the parsed joints (origins, axes) puts every link where the body
//! plan's start pose does.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::path::Path;
use strider_common::body_plan::BLOW_UP_SPEED;
use strider_common::urdf::{joint_name, link_name, to_urdf, urdf_from_model, UrdfStartPose};
use strider_common::{BodyPlan, Genome, StartPose};

fn design(path: &str) -> Genome {
    Genome::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(path)).unwrap()
}

fn v(a: &[f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

fn pose(p: &urdf_rs::Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(v(&p.xyz.0)),
        UnitQuaternion::from_euler_angles(p.rpy.0[0], p.rpy.0[1], p.rpy.0[2]),
    )
}

fn check(genome: &Genome) {
    let plan = BodyPlan::new(&genome.morphology, 10.0);
    let text = to_urdf("design <1>", &plan);
    let robot = urdf_rs::read_from_string(&text).expect("the URDF parses");
    // Spaces and markup become `_`: URDF tools take the name as it is.
    assert_eq!(robot.name, "design__1_");
    assert_eq!(robot.links.len(), 1 + 3 * plan.legs.len());
    assert_eq!(robot.joints.len(), 3 * plan.legs.len());

    // Masses: every part, and the total.
    let total: f64 = robot.links.iter().map(|l| l.inertial.mass.value).sum();
    assert!(
        (total - plan.total_mass()).abs() < 1e-9,
        "{total} vs {}",
        plan.total_mass()
    );
    let link = |name: &str| robot.links.iter().find(|l| l.name == name).unwrap();
    let joint = |name: &str| robot.joints.iter().find(|j| j.name == name).unwrap();
    for (l, leg) in plan.legs.iter().enumerate() {
        for (k, part) in leg.links.iter().enumerate() {
            let parsed = link(&link_name(l, k));
            assert_eq!(parsed.inertial.mass.value, part.mass.mass);
            assert!((v(&parsed.inertial.origin.xyz.0) - part.mass.com).norm() < 1e-12);
            assert_eq!(parsed.inertial.inertia.ixx, part.mass.inertia[(0, 0)]);
            assert_eq!(parsed.inertial.inertia.iyz, part.mass.inertia[(1, 2)]);
            let j = joint(&joint_name(l, k));
            assert_eq!(j.joint_type, urdf_rs::JointType::Revolute);
            assert_eq!(j.limit.effort, part.drive.max_torque);
            // The model bounds joint speeds only by its blow-up check: a tool enforcing the
            // URDF's limits must not clamp the walk (which passes wmax; docs/model.md
            // section 6), nor freeze a joint whose wmax is 0.
            assert_eq!(j.limit.velocity, BLOW_UP_SPEED);
            // The servo's whole velocity gain: what a second engine needs to drive the
            // joint by the same law (docs/model.md section 6).
            let damping = j.dynamics.as_ref().map(|d| d.damping);
            assert_eq!(damping, Some(part.drive.servo_damping()));
            assert!(part.drive.servo_damping() > part.drive.damping);
            assert_eq!(j.child.link, link_name(l, k));
        }
    }

    // Forward kinematics through the parsed joints at the start pose's angles lands every
    // link where the model puts it (in URDF axes).
    let start = StartPose::new(&plan, &genome.controller);
    let to_urdf = Isometry3::from_parts(Translation3::identity(), urdf_from_model());
    for (l, leg) in plan.legs.iter().enumerate() {
        let q = start.joint_angles[l];
        let expected = leg.link_poses(q);
        let mut at = Isometry3::identity();
        for k in 0..3 {
            let j = joint(&joint_name(l, k));
            let axis = nalgebra::Unit::new_normalize(v(&j.axis.xyz.0));
            at = at * pose(&j.origin) * UnitQuaternion::from_axis_angle(&axis, q[k]);
            let want = to_urdf * expected[k];
            assert!(
                (at.translation.vector - want.translation.vector).norm() < 1e-9,
                "leg {l} link {k}: {:?} vs {:?}",
                at.translation,
                want.translation
            );
            assert!(
                at.rotation.angle_to(&want.rotation) < 1e-9,
                "leg {l} link {k}"
            );
        }
    }
    // The start pose written beside the URDF: its base pose and joint angles, through the
    // parsed joints, put every foot where the model's start pose does, in a world with
    // URDF's axes, with the body at its start height above the ground (z = 0).
    let json = UrdfStartPose::new(&plan, &start).to_json();
    let written: UrdfStartPose = serde_json::from_str(&json).unwrap();
    assert_eq!(written.joints.len(), robot.joints.len());
    let base = Isometry3::from_parts(
        Translation3::from(v(&written.base_xyz)),
        UnitQuaternion::from_euler_angles(
            written.base_rpy[0],
            written.base_rpy[1],
            written.base_rpy[2],
        ),
    );
    let world_to_urdf = Isometry3::from_parts(Translation3::identity(), urdf_from_model());
    assert!((written.base_xyz[2] - start.body_height).abs() < 1e-12);
    assert!(
        start.lowest_point.y.abs() < 1e-9,
        "the model stands on y = 0"
    );
    for (l, leg) in plan.legs.iter().enumerate() {
        let mut at = base;
        for k in 0..3 {
            let j = joint(&joint_name(l, k));
            let axis = nalgebra::Unit::new_normalize(v(&j.axis.xyz.0));
            let q = written.joints[&joint_name(l, k)];
            at = at * pose(&j.origin) * UnitQuaternion::from_axis_angle(&axis, q);
        }
        let foot = at * nalgebra::Point3::new(0.0, 0.0, leg.links[2].length);
        let want = world_to_urdf
            * start.link_poses[l][2]
            * nalgebra::Point3::new(0.0, 0.0, leg.links[2].length);
        assert!(
            (foot - want).norm() < 1e-9,
            "leg {l} foot: {foot} vs {want}"
        );
        // The feet the JSON states, for other tools to check against, are these.
        let stated = &written.feet[l];
        assert_eq!(stated.link, link_name(l, 2));
        assert!(
            (v(&stated.start_xyz) - foot.coords).norm() < 1e-9,
            "leg {l}"
        );
        assert!((at * nalgebra::Point3::from(v(&stated.tip_in_link)) - foot).norm() < 1e-9);
    }
    assert_eq!(written.feet.len(), plan.legs.len());

    // The body's mass sits where the model's does, turned into URDF axes (y up -> z up).
    let body = link("body");
    let com = urdf_from_model() * plan.body_mass.com;
    assert!((v(&body.inertial.origin.xyz.0) - com).norm() < 1e-12);
}

#[test]
fn max_exports_to_urdf_that_parses_and_round_trips() {
    check(&design("../designs/max.json"));
}

#[test]
fn the_hand_calculated_hexapod_round_trips_too() {
    check(&design("tests/fixtures/hand_calc.json"));
}
