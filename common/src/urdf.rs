//! A body plan as URDF, the robot description ROS, Gazebo, PyBullet, MuJoCo's importer and
//! most robotics tools read: one link per rigid part (body, and hip, upper and lower leg of
//! every leg) with its mass, centre of mass and inertia; one revolute joint per motor with
//! its axis, torque limit (the motor model), rated speed (in a comment) and damping.
//!
//! Frames: the model's body frame is x forward, y up, z to the right (docs/model.md);
//! URDF's convention (ROS REP 103) is x forward, y left, z up. The root link `body` is in
//! the URDF convention; every leg link keeps the model's own link frame (origin at its
//! joint, the tube along +z), so the numbers match `inspect` and the trace.

use crate::body_plan::{BodyPlan, LinkPlan, BLOW_UP_SPEED, SERVO_DERIVATIVE_TIME};
use crate::mass::MassProperties;
use crate::xml::escape;
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use std::fmt::Write;

/// Names of a leg's three links, body outwards.
pub const LINK_NAMES: [&str; 3] = ["hip", "upper", "lower"];

/// The rotation taking model body-frame coordinates to URDF (REP 103) coordinates:
/// (x, y, z) to (x, -z, y).
pub fn urdf_from_model() -> UnitQuaternion<f64> {
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(Matrix3::new(
        1.0, 0.0, 0.0, //
        0.0, 0.0, -1.0, //
        0.0, 1.0, 0.0,
    )))
}

/// The URDF name of leg `leg`'s link `link` (legs in the plan's order: right side front
/// to back, then left): `leg{leg}_{hip|upper|lower}`.
pub fn link_name(leg: usize, link: usize) -> String {
    format!("leg{leg}_{}", LINK_NAMES[link])
}

/// The URDF name of the joint that moves [`link_name`]`(leg, link)`.
pub fn joint_name(leg: usize, link: usize) -> String {
    format!("{}_joint", link_name(leg, link))
}

/// Where a design starts, for the URDF of it: the root link `body`'s pose in a world with
/// URDF's axes (z up, ground at z = 0) and every joint's angle (rad) by joint name. Written
/// beside the URDF as JSON, since URDF itself has no initial state.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct UrdfStartPose {
    /// The body's position, m (its centre; z is its height above the ground).
    pub base_xyz: [f64; 3],
    /// The body's roll, pitch and yaw, rad (level: zero).
    pub base_rpy: [f64; 3],
    /// Joint angles by joint name ([`joint_name`]), rad.
    pub joints: std::collections::BTreeMap<String, f64>,
    /// Each foot: the tip of a lower leg, where it is in its link and where it stands in
    /// this pose, so that another tool can check it loaded the design as we model it.
    pub feet: Vec<UrdfFoot>,
}

/// A foot of [`UrdfStartPose`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct UrdfFoot {
    /// The lower leg's link name ([`link_name`]).
    pub link: String,
    /// The foot tip in that link's frame, m.
    pub tip_in_link: [f64; 3],
    /// The foot tip in the world in the start pose, m (URDF axes; z = 0 is the ground).
    pub start_xyz: [f64; 3],
}

impl UrdfStartPose {
    /// `pose` (of `plan`) in URDF's axes.
    pub fn new(plan: &BodyPlan, pose: &crate::StartPose) -> Self {
        let at = urdf_from_model() * pose.body.translation.vector;
        let (r, p, y) =
            (urdf_from_model() * pose.body.rotation * urdf_from_model().inverse()).euler_angles();
        let joints = pose
            .joint_angles
            .iter()
            .enumerate()
            .flat_map(|(l, q)| (0..3).map(move |k| (joint_name(l, k), q[k])))
            .collect();
        let feet = plan
            .legs
            .iter()
            .enumerate()
            .map(|(l, leg)| {
                let tip = nalgebra::Point3::new(0.0, 0.0, leg.links[2].length);
                let world = urdf_from_model() * (pose.link_poses[l][2] * tip);
                UrdfFoot {
                    link: link_name(l, 2),
                    tip_in_link: [tip.x, tip.y, tip.z],
                    start_xyz: [world.x, world.y, world.z],
                }
            })
            .collect();
        UrdfStartPose {
            base_xyz: [at.x, at.y, at.z],
            base_rpy: [r, p, y],
            joints,
            feet,
        }
    }

    /// As pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("plain numbers serialise")
    }
}

/// Where the start pose of the URDF at `urdf` goes: beside it, `NAME.start_pose.json`.
pub fn start_pose_path(urdf: &std::path::Path) -> std::path::PathBuf {
    let stem = urdf
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "design".into());
    urdf.with_file_name(format!("{stem}.start_pose.json"))
}

/// The two files of a design for `path`: `plan` as URDF named `name`, and its start pose
/// (with `controller`'s targets at t = 0) beside it ([`start_pose_path`]). The caller
/// writes them, together.
pub fn files(
    name: &str,
    plan: &BodyPlan,
    controller: &crate::Controller,
    path: &std::path::Path,
) -> [(std::path::PathBuf, String); 2] {
    let start = UrdfStartPose::new(plan, &crate::StartPose::new(plan, controller));
    [
        (path.to_path_buf(), to_urdf(name, plan)),
        (start_pose_path(path), start.to_json() + "\n"),
    ]
}

/// A robot name URDF tools take as it is (ROS packages, xacro and several parsers refuse
/// or mangle spaces): letters, digits, `_` and `-`, anything else as `_`.
pub fn robot_name(name: &str) -> String {
    let n: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if n.is_empty() {
        "design".into()
    } else {
        n
    }
}

/// `plan` as a URDF document named `name` (as [`robot_name`] makes it).
pub fn to_urdf(name: &str, plan: &BodyPlan) -> String {
    let mut out = String::new();
    let to_urdf = urdf_from_model();
    let total = plan.total_mass();
    let _ = writeln!(out, r#"<?xml version="1.0"?>"#);
    let _ = writeln!(
        out,
        "<!-- Strider design: total mass {total:.3} kg including {:.3} kg payload. Joints carry\n     \
         the motor model's torque limit (effort, Nm). The model bounds no joint's speed but by\n     \
         its blow-up check ({BLOW_UP_SPEED} rad/s, the velocity written): a motor's rated speed\n     \
         wmax sets its gait amplitude and mass, and the walk passes it (docs/model.md section\n     \
         6). The model has no angle stops, so position limits are +-pi. Spring stiffness and\n     \
         rated speed per joint are in each joint's comment (URDF has no field for them). Each joint is a position servo: torque = clamp(k (q* - q) - D qdot, +-effort),\n     \
         k the dynamics spring_stiffness (Gazebo's attribute), D the dynamics damping (the\n     \
         encoded damping plus k x {T_V:.6} s, the servo's velocity loop; docs/model.md\n     \
         section 6). The start pose (base pose and joint angles) is in NAME.start_pose.json. -->",
        plan.payload_mass,
        T_V = SERVO_DERIVATIVE_TIME,
    );
    let _ = writeln!(out, r#"<robot name="{}">"#, escape(&robot_name(name)));

    // The body, turned into URDF axes.
    let body_mass = rotate(&plan.body_mass, &to_urdf);
    let size = plan.body_half_extents * 2.0;
    let box_size = Vector3::new(size.x, size.z, size.y);
    let _ = writeln!(out, r#"  <link name="body">"#);
    write_inertial(&mut out, &body_mass);
    write_box(&mut out, &box_size, &Vector3::zeros());
    let _ = writeln!(out, "  </link>");

    for (l, leg) in plan.legs.iter().enumerate() {
        for (k, link) in leg.links.iter().enumerate() {
            let parent = if k == 0 {
                "body".to_string()
            } else {
                link_name(l, k - 1)
            };
            // URDF: child = origin * rotation(axis, q). Model: child = T(anchor) * R(axis, q)
            // * rest = T(anchor) * rest * R(rest^-1 axis, q).
            let mut origin = Isometry3::from_parts(Translation3::from(link.anchor), link.rest);
            let mut axis = link.rest.inverse_transform_vector(&link.axis);
            if k == 0 {
                origin = Isometry3::from_parts(Translation3::identity(), to_urdf) * origin;
            }
            axis /= axis.norm();
            write_link(&mut out, &link_name(l, k), link);
            write_joint(&mut out, l, k, &parent, &origin, &axis, link);
        }
    }
    let _ = writeln!(out, "</robot>");
    out
}

fn write_link(out: &mut String, name: &str, link: &LinkPlan) {
    let _ = writeln!(out, r#"  <link name="{name}">"#);
    write_inertial(out, &link.mass);
    write_box(
        out,
        &Vector3::new(link.width, link.width, link.length),
        &Vector3::new(0.0, 0.0, 0.5 * link.length),
    );
    let _ = writeln!(out, "  </link>");
}

fn write_joint(
    out: &mut String,
    leg: usize,
    link: usize,
    parent: &str,
    origin: &Isometry3<f64>,
    axis: &Vector3<f64>,
    plan: &LinkPlan,
) {
    let d = &plan.drive;
    let (r, p, y) = origin.rotation.euler_angles();
    let t = origin.translation.vector;
    let _ = writeln!(
        out,
        r#"  <!-- stiffness {:.6} Nm/rad, encoded damping {} Nms/rad, rated speed {} rad/s (not a limit) -->
  <joint name="{}" type="revolute">
    <parent link="{parent}"/>
    <child link="{}"/>
    <origin xyz="{} {} {}" rpy="{} {} {}"/>
    <axis xyz="{} {} {}"/>
    <limit lower="{}" upper="{}" effort="{}" velocity="{}"/>
    <dynamics damping="{}" friction="0" spring_stiffness="{}"/>
  </joint>"#,
        d.stiffness,
        d.damping,
        d.max_speed,
        joint_name(leg, link),
        link_name(leg, link),
        t.x,
        t.y,
        t.z,
        r,
        p,
        y,
        axis.x,
        axis.y,
        axis.z,
        -std::f64::consts::PI,
        std::f64::consts::PI,
        d.max_torque,
        BLOW_UP_SPEED,
        d.servo_damping(),
        d.stiffness,
    );
}

fn write_inertial(out: &mut String, m: &MassProperties) {
    let i = &m.inertia;
    let _ = writeln!(
        out,
        r#"    <inertial>
      <origin xyz="{} {} {}" rpy="0 0 0"/>
      <mass value="{}"/>
      <inertia ixx="{}" ixy="{}" ixz="{}" iyy="{}" iyz="{}" izz="{}"/>
    </inertial>"#,
        m.com.x,
        m.com.y,
        m.com.z,
        m.mass,
        i[(0, 0)],
        i[(0, 1)],
        i[(0, 2)],
        i[(1, 1)],
        i[(1, 2)],
        i[(2, 2)],
    );
}

/// The same box as visual and collision geometry.
fn write_box(out: &mut String, size: &Vector3<f64>, centre: &Vector3<f64>) {
    for tag in ["visual", "collision"] {
        let _ = writeln!(
            out,
            r#"    <{tag}>
      <origin xyz="{} {} {}" rpy="0 0 0"/>
      <geometry><box size="{} {} {}"/></geometry>
    </{tag}>"#,
            centre.x, centre.y, centre.z, size.x, size.y, size.z
        );
    }
}

/// Mass properties expressed in rotated axes.
fn rotate(m: &MassProperties, r: &UnitQuaternion<f64>) -> MassProperties {
    let rm = r.to_rotation_matrix();
    MassProperties {
        mass: m.mass,
        com: r * m.com,
        inertia: rm.matrix() * m.inertia * rm.matrix().transpose(),
    }
}
