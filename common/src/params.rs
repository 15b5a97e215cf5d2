//! The parameter table: every genome scalar's name, range, unit, kind and mutation group.
//!
//! This is the single source of truth for the encoding. Random generation, mutation,
//! validation, (de)serialisation, the docs and the wire format all read these tables;
//! nothing else in the project repeats a range.

use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;

/// Whether a parameter takes any real value in its range or only integers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamKind {
    /// Any finite value in `[min, max]`; mutated by a clamped Gaussian step.
    Real,
    /// An integer in `[min, max]`; mutated by +-1, clamped.
    Integer,
}

/// The mutation group a parameter belongs to; each group has its own per-parameter
/// mutation probability (docs/model.md section 12, the paper's Table 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MutationGroup {
    /// Body half-extents and payload position.
    Body,
    /// Legs per side.
    LegCount,
    /// Where and how legs attach to the body.
    LegOffset,
    /// Per-leg scalars: wall thickness and the quadratic multipliers.
    Leg,
    /// Per-link geometry: length, tube width, hinge axis.
    Link,
    /// Per-joint motor: stiffness, damping, torque limit and rated speed.
    Motor,
    /// Gait controller parameters (mutated all together by the GENOME and ES schemes).
    Controller,
}

impl MutationGroup {
    /// All morphology groups, in the order the docs list them.
    pub const MORPHOLOGY: [MutationGroup; 6] = [
        MutationGroup::Body,
        MutationGroup::LegCount,
        MutationGroup::LegOffset,
        MutationGroup::Leg,
        MutationGroup::Link,
        MutationGroup::Motor,
    ];

    /// The group's name as used in experiment files.
    pub fn name(self) -> &'static str {
        match self {
            MutationGroup::Body => "body",
            MutationGroup::LegCount => "leg_count",
            MutationGroup::LegOffset => "leg_offset",
            MutationGroup::Leg => "leg",
            MutationGroup::Link => "link",
            MutationGroup::Motor => "motor",
            MutationGroup::Controller => "controller",
        }
    }
}

/// One row of the parameter table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// Name used in genome files, the database and the wire format.
    pub name: &'static str,
    /// Inclusive lower bound.
    pub min: f64,
    /// Inclusive upper bound.
    pub max: f64,
    /// SI unit, or "" for dimensionless.
    pub unit: &'static str,
    /// Real or integer.
    pub kind: ParamKind,
    pub group: MutationGroup,
    /// What the parameter does to the robot, one line.
    pub doc: &'static str,
}

impl ParamSpec {
    /// Width of the range, `max - min`.
    pub fn span(&self) -> f64 {
        self.max - self.min
    }

    /// Midpoint of the range (the STATIC controller uses these).
    pub fn midpoint(&self) -> f64 {
        0.5 * (self.min + self.max)
    }

    /// Clamps a value into the range (integers are also rounded).
    pub fn clamp(&self, v: f64) -> f64 {
        let v = v.clamp(self.min, self.max);
        match self.kind {
            ParamKind::Real => v,
            ParamKind::Integer => v.round(),
        }
    }

    /// Checks one value against this row; the error names the parameter.
    pub fn check(&self, v: f64) -> Result<(), ParamError> {
        if !v.is_finite() {
            return Err(ParamError::NotFinite {
                name: self.name,
                value: v,
            });
        }
        if v < self.min || v > self.max {
            return Err(ParamError::OutOfRange {
                name: self.name,
                value: v,
                min: self.min,
                max: self.max,
                unit: self.unit,
            });
        }
        if self.kind == ParamKind::Integer && v.fract() != 0.0 {
            return Err(ParamError::NotInteger {
                name: self.name,
                value: v,
            });
        }
        Ok(())
    }
}

/// A value that does not fit its parameter's row.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ParamError {
    #[error("parameter `{name}` is {value}, which is not a finite number")]
    NotFinite { name: &'static str, value: f64 },
    #[error("parameter `{name}` = {value} is outside its range [{min}, {max}] {unit}")]
    OutOfRange {
        name: &'static str,
        value: f64,
        min: f64,
        max: f64,
        unit: &'static str,
    },
    #[error("parameter `{name}` = {value} must be an integer")]
    NotInteger { name: &'static str, value: f64 },
}

/// Declares an index enum and its table together, so the two cannot drift apart.
macro_rules! param_table {
    (
        $(#[$meta:meta])*
        $index:ident, $table:ident {
            $( $variant:ident => ($name:literal, $min:expr, $max:expr, $unit:literal, $kind:ident, $group:ident, $doc:literal) ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        #[repr(usize)]
        pub enum $index { $( #[doc = $doc] $variant ),* }

        impl $index {
            /// Position of this parameter in its table (and in the value vector).
            pub const fn idx(self) -> usize { self as usize }
            /// This parameter's row of the table.
            pub fn spec(self) -> &'static ParamSpec { &$table[self as usize] }
        }

        #[doc = concat!("The table behind [`", stringify!($index), "`], in index order.")]
        pub const $table: &[ParamSpec] = &[
            $( ParamSpec {
                name: $name, min: $min, max: $max, unit: $unit,
                kind: ParamKind::$kind, group: MutationGroup::$group, doc: $doc,
            } ),*
        ];
    };
}

param_table! {
    /// Morphology parameters (docs/model.md sections 2-5). Links are numbered from the body: 0 is the hip
    /// link (coxa), 1 the upper leg (femur), 2 the lower leg (tibia).
    M, MORPHOLOGY_PARAMS {
        BodyHalfX => ("body_half_x", 0.4, 1.0, "m", Real, Body, "body half-length (forward)"),
        BodyHalfY => ("body_half_y", 0.025, 0.15, "m", Real, Body, "body half-height"),
        BodyHalfZ => ("body_half_z", 0.05, 0.3, "m", Real, Body, "body half-width (right)"),
        PayloadX => ("payload_x", -0.5, 0.5, "", Real, Body, "payload and battery position along x, fraction of the half-length"),
        PayloadZ => ("payload_z", -0.5, 0.5, "", Real, Body, "payload and battery position along z, fraction of the half-width"),
        LegsPerSide => ("legs_per_side", 2.0, 6.0, "", Integer, LegCount, "legs on each side"),
        AttachHeight => ("attach_height", -1.0, 1.0, "", Real, LegOffset, "leg attach height on the body side, fraction of the half-height"),
        AttachPitch => ("attach_pitch", -0.6, 0.6, "rad", Real, LegOffset, "tilt of the leg root (the hip link) about the forward axis; positive tilts it up"),
        SpreadLinFwd => ("spread_lin_fwd", 0.7, 1.0, "", Real, LegOffset, "linear term of the attach point along the body, fraction of the half-length"),
        SpreadLinRight => ("spread_lin_right", -0.2, 0.2, "m", Real, LegOffset, "linear term of the attach point's outward offset from the side face"),
        SpreadQuadFwd => ("spread_quad_fwd", -0.1, 0.1, "", Real, LegOffset, "quadratic term of the attach point along the body, fraction of the half-length"),
        SpreadQuadRight => ("spread_quad_right", -0.1, 0.1, "m", Real, LegOffset, "quadratic term of the attach point's outward offset from the side face"),
        WallThickness => ("wall_thickness", 0.001, 0.01, "m", Real, Leg, "carbon-fibre tube wall thickness, all links of all legs"),
        LengthMult => ("length_mult", -0.2, 0.2, "", Real, Leg, "quadratic leg length multiplier mL: links scale by 1 + mL u^2"),
        WidthMult => ("width_mult", -0.2, 0.2, "", Real, Leg, "quadratic tube width multiplier mW: widths scale by 1 + mW u^2"),
        StrengthMult => ("strength_mult", -5.0, 5.0, "", Real, Leg, "quadratic strength multiplier mS: stiffness and torque scale by 1 + 0.1 mS u^2"),
        Link0Length => ("link0_length", 0.1, 0.8, "m", Real, Link, "hip link length"),
        Link0Width => ("link0_width", 0.025, 0.1, "m", Real, Link, "hip link square tube outer width"),
        Link0AxisX => ("link0_axis_x", -0.2, 0.2, "", Real, Link, "hip hinge axis x, in the body frame, right side (normalised)"),
        Link0AxisY => ("link0_axis_y", 0.8, 1.0, "", Real, Link, "hip hinge axis y, in the body frame, right side (normalised)"),
        Link0AxisZ => ("link0_axis_z", -0.2, 0.2, "", Real, Link, "hip hinge axis z, in the body frame, right side (normalised)"),
        Link1Length => ("link1_length", 0.4, 1.6, "m", Real, Link, "upper leg link length"),
        Link1Width => ("link1_width", 0.025, 0.1, "m", Real, Link, "upper leg square tube outer width"),
        Link1AxisX => ("link1_axis_x", 0.8, 1.0, "", Real, Link, "upper leg hinge axis x, in the hip link frame (normalised)"),
        Link1AxisY => ("link1_axis_y", -0.2, 0.2, "", Real, Link, "upper leg hinge axis y, in the hip link frame (normalised)"),
        Link1AxisZ => ("link1_axis_z", -0.2, 0.2, "", Real, Link, "upper leg hinge axis z, in the hip link frame (normalised)"),
        Link2Length => ("link2_length", 0.4, 1.6, "m", Real, Link, "lower leg link length"),
        Link2Width => ("link2_width", 0.025, 0.1, "m", Real, Link, "lower leg square tube outer width"),
        Link2AxisX => ("link2_axis_x", 0.8, 1.0, "", Real, Link, "lower leg hinge axis x, in the upper leg frame (normalised)"),
        Link2AxisY => ("link2_axis_y", -0.2, 0.2, "", Real, Link, "lower leg hinge axis y, in the upper leg frame (normalised)"),
        Link2AxisZ => ("link2_axis_z", -0.2, 0.2, "", Real, Link, "lower leg hinge axis z, in the upper leg frame (normalised)"),
        Motor0Stiffness => ("motor0_stiffness", 2000.0, 6000.0, "Nm/rad", Real, Motor, "hip joint spring stiffness"),
        Motor0Damping => ("motor0_damping", 1.0, 40.0, "Nms/rad", Real, Motor, "hip joint damping"),
        Motor0MaxTorque => ("motor0_max_torque", 50.0, 200.0, "Nm", Real, Motor, "hip joint torque limit"),
        Motor0MaxSpeed => ("motor0_max_speed", 0.0, 1.5, "rad/s", Real, Motor, "hip motor rated speed wmax: the gait's peak target speed (amplitude wmax/sf), sizes the motor; not a bound on the joint"),
        Motor1Stiffness => ("motor1_stiffness", 2000.0, 6000.0, "Nm/rad", Real, Motor, "upper leg joint spring stiffness"),
        Motor1Damping => ("motor1_damping", 1.0, 40.0, "Nms/rad", Real, Motor, "upper leg joint damping"),
        Motor1MaxTorque => ("motor1_max_torque", 50.0, 200.0, "Nm", Real, Motor, "upper leg joint torque limit"),
        Motor1MaxSpeed => ("motor1_max_speed", 0.0, 1.5, "rad/s", Real, Motor, "upper leg motor rated speed wmax"),
        Motor2Stiffness => ("motor2_stiffness", 2000.0, 6000.0, "Nm/rad", Real, Motor, "lower leg joint spring stiffness"),
        Motor2Damping => ("motor2_damping", 1.0, 40.0, "Nms/rad", Real, Motor, "lower leg joint damping"),
        Motor2MaxTorque => ("motor2_max_torque", 50.0, 200.0, "Nm", Real, Motor, "lower leg joint torque limit"),
        Motor2MaxSpeed => ("motor2_max_speed", 0.0, 1.5, "rad/s", Real, Motor, "lower leg motor rated speed wmax"),
    }
}

param_table! {
    /// Gait controller parameters (docs/model.md section 7).
    C, CONTROLLER_PARAMS {
        StrideFrequency => ("stride_frequency", 1.0, 4.0, "rad/s", Real, Controller, "stride frequency sf of every joint's sinusoid"),
        VerticalOffset0 => ("vertical_offset0", -1.0, 2.0, "rad", Real, Controller, "hip sinusoid centre vo0"),
        VerticalOffset1 => ("vertical_offset1", -1.0, 2.0, "rad", Real, Controller, "upper leg sinusoid centre vo1"),
        VerticalOffset2 => ("vertical_offset2", -1.0, 2.0, "rad", Real, Controller, "lower leg sinusoid centre vo2"),
        PhaseOffset0 => ("phase_offset0", -FRAC_PI_2, FRAC_PI_2, "rad", Real, Controller, "hip sinusoid phase po0"),
        PhaseOffset1 => ("phase_offset1", -FRAC_PI_2, FRAC_PI_2, "rad", Real, Controller, "upper leg sinusoid phase po1 (relative to the lifting reference)"),
        PhaseOffset2 => ("phase_offset2", -FRAC_PI_2, FRAC_PI_2, "rad", Real, Controller, "lower leg sinusoid phase po2 (relative to the lifting reference)"),
    }
}

/// Number of morphology scalars.
pub const MORPHOLOGY_LEN: usize = 43;
/// Number of controller scalars.
pub const CONTROLLER_LEN: usize = 7;

const _: () = assert!(MORPHOLOGY_PARAMS.len() == MORPHOLOGY_LEN);
const _: () = assert!(CONTROLLER_PARAMS.len() == CONTROLLER_LEN);

/// Links per leg.
pub const LINKS_PER_LEG: usize = 3;

/// Per-link parameter indices, link 0 first.
pub const LINK_LENGTH: [M; LINKS_PER_LEG] = [M::Link0Length, M::Link1Length, M::Link2Length];
/// Per-link tube width indices.
pub const LINK_WIDTH: [M; LINKS_PER_LEG] = [M::Link0Width, M::Link1Width, M::Link2Width];
/// Per-link hinge axis indices (x, y, z).
pub const LINK_AXIS: [[M; 3]; LINKS_PER_LEG] = [
    [M::Link0AxisX, M::Link0AxisY, M::Link0AxisZ],
    [M::Link1AxisX, M::Link1AxisY, M::Link1AxisZ],
    [M::Link2AxisX, M::Link2AxisY, M::Link2AxisZ],
];
/// Per-joint stiffness indices.
pub const MOTOR_STIFFNESS: [M; LINKS_PER_LEG] =
    [M::Motor0Stiffness, M::Motor1Stiffness, M::Motor2Stiffness];
/// Per-joint damping indices.
pub const MOTOR_DAMPING: [M; LINKS_PER_LEG] =
    [M::Motor0Damping, M::Motor1Damping, M::Motor2Damping];
/// Per-joint torque limit indices.
pub const MOTOR_MAX_TORQUE: [M; LINKS_PER_LEG] =
    [M::Motor0MaxTorque, M::Motor1MaxTorque, M::Motor2MaxTorque];
/// Per-joint speed limit indices.
pub const MOTOR_MAX_SPEED: [M; LINKS_PER_LEG] =
    [M::Motor0MaxSpeed, M::Motor1MaxSpeed, M::Motor2MaxSpeed];
/// Per-joint controller vertical offsets.
pub const GAIT_VERTICAL_OFFSET: [C; LINKS_PER_LEG] =
    [C::VerticalOffset0, C::VerticalOffset1, C::VerticalOffset2];
/// Per-joint controller phase offsets.
pub const GAIT_PHASE_OFFSET: [C; LINKS_PER_LEG] =
    [C::PhaseOffset0, C::PhaseOffset1, C::PhaseOffset2];

/// Looks a parameter up by name in a table.
pub fn find(table: &'static [ParamSpec], name: &str) -> Option<usize> {
    table.iter().position(|p| p.name == name)
}

/// The parameter tables as Markdown (for `docs/model.md`, which a test keeps identical).
pub fn markdown_table() -> String {
    let mut out = String::from(
        "| parameter | min | max | unit | kind | mutation group | what it does |\n|---|---|---|---|---|---|---|\n",
    );
    for p in MORPHOLOGY_PARAMS.iter().chain(CONTROLLER_PARAMS) {
        let kind = match p.kind {
            ParamKind::Real => "real",
            ParamKind::Integer => "integer",
        };
        out.push_str(&format!(
            "| `{}` | {} | {} | {} | {} | {} | {} |\n",
            p.name,
            fmt_bound(p.min),
            fmt_bound(p.max),
            if p.unit.is_empty() { "-" } else { p.unit },
            kind,
            p.group.name(),
            p.doc
        ));
    }
    out
}

fn fmt_bound(v: f64) -> String {
    if (v.abs() - FRAC_PI_2).abs() < 1e-15 {
        format!("{}pi/2", if v < 0.0 { "-" } else { "" })
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_ranges_ordered() {
        for table in [MORPHOLOGY_PARAMS, CONTROLLER_PARAMS] {
            for (i, p) in table.iter().enumerate() {
                assert!(p.min < p.max, "{} has an empty range", p.name);
                assert_eq!(find(table, p.name), Some(i), "{} is not unique", p.name);
            }
        }
        for p in MORPHOLOGY_PARAMS {
            assert!(
                find(CONTROLLER_PARAMS, p.name).is_none(),
                "{} is in both tables",
                p.name
            );
        }
    }

    #[test]
    fn index_enums_match_their_tables() {
        assert_eq!(M::Motor2MaxSpeed.idx(), MORPHOLOGY_LEN - 1);
        assert_eq!(M::LegsPerSide.spec().name, "legs_per_side");
        assert_eq!(C::PhaseOffset2.spec().name, "phase_offset2");
        assert_eq!(LINK_AXIS[2][1].spec().name, "link2_axis_y");
    }

    #[test]
    fn check_names_the_parameter() {
        let spec = M::LegsPerSide.spec();
        assert!(spec.check(4.0).is_ok());
        let e = spec.check(7.0).unwrap_err().to_string();
        assert!(e.contains("legs_per_side") && e.contains("[2, 6]"), "{e}");
        let e = spec.check(3.5).unwrap_err().to_string();
        assert!(e.contains("integer"), "{e}");
        let e = spec.check(f64::NAN).unwrap_err().to_string();
        assert!(e.contains("legs_per_side") && e.contains("NaN"), "{e}");
    }
}
