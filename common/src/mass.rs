//! The mass model (docs/model.md section 8): uniform cuboids, hollow square tubes and point masses,
//! combined into one rigid part's mass, centre of mass and inertia.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Density of the body's foam-like structure, kg/m^3.
pub const BODY_DENSITY: f64 = 170.0;
/// Batteries and avionics, a point mass at the payload position, kg.
pub const AVIONICS_MASS: f64 = 7.5;
/// Carbon-fibre density of the leg tubes, kg/m^3.
pub const CARBON_DENSITY: f64 = 1600.0;
/// Fixed mass of a motor mechanism (linkages, housing), kg.
pub const MOTOR_BASE_MASS: f64 = 0.2;
/// Motor power-to-squared-mass ratio, W/kg^2 (the paper's Table 2, rounded).
pub const MOTOR_POWER_PER_MASS_SQUARED: f64 = 13000.0;

/// Mass, centre of mass and inertia (about the centre of mass) of a rigid part, all in the
/// part's own frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MassProperties {
    /// Mass, kg.
    pub mass: f64,
    /// Centre of mass in the part frame, m.
    pub com: Vector3<f64>,
    /// Inertia tensor about the centre of mass, in part-frame axes, kg m^2.
    pub inertia: Matrix3<f64>,
}

impl MassProperties {
    /// Nothing.
    pub fn zero() -> Self {
        Self {
            mass: 0.0,
            com: Vector3::zeros(),
            inertia: Matrix3::zeros(),
        }
    }

    /// A solid uniform cuboid of full dimensions `size`, centred at `centre`.
    pub fn cuboid(mass: f64, size: Vector3<f64>, centre: Vector3<f64>) -> Self {
        let (a2, b2, c2) = (size.x * size.x, size.y * size.y, size.z * size.z);
        let k = mass / 12.0;
        Self {
            mass,
            com: centre,
            inertia: Matrix3::from_diagonal(&Vector3::new(
                k * (b2 + c2),
                k * (a2 + c2),
                k * (a2 + b2),
            )),
        }
    }

    /// A point mass.
    pub fn point(mass: f64, at: Vector3<f64>) -> Self {
        Self {
            mass,
            com: at,
            inertia: Matrix3::zeros(),
        }
    }

    /// Inertia of this part about a point `p` (parallel-axis theorem).
    fn inertia_about(&self, p: Vector3<f64>) -> Matrix3<f64> {
        let d = self.com - p;
        self.inertia + self.mass * (Matrix3::identity() * d.dot(&d) - d * d.transpose())
    }

    /// Two parts rigidly joined into one.
    pub fn combine(&self, other: &Self) -> Self {
        let mass = self.mass + other.mass;
        if mass == 0.0 {
            return Self::zero();
        }
        let com = (self.com * self.mass + other.com * other.mass) / mass;
        Self {
            mass,
            com,
            inertia: self.inertia_about(com) + other.inertia_about(com),
        }
    }

    /// Removes `other` from this part (for the hollow of a tube).
    fn subtract(&self, other: &Self) -> Self {
        let mass = self.mass - other.mass;
        let com = (self.com * self.mass - other.com * other.mass) / mass;
        Self {
            mass,
            com,
            inertia: self.inertia_about(com) - other.inertia_about(com),
        }
    }
}

/// A hollow square carbon-fibre tube of outer `width`, `wall` thickness and `length`, lying
/// along +z from the origin. A wall of at least half the width makes it solid.
pub fn tube(length: f64, width: f64, wall: f64) -> MassProperties {
    let centre = Vector3::new(0.0, 0.0, 0.5 * length);
    let outer = MassProperties::cuboid(
        CARBON_DENSITY * width * width * length,
        Vector3::new(width, width, length),
        centre,
    );
    let inner_width = width - 2.0 * wall;
    if inner_width <= 0.0 {
        return outer;
    }
    let inner = MassProperties::cuboid(
        CARBON_DENSITY * inner_width * inner_width * length,
        Vector3::new(inner_width, inner_width, length),
        centre,
    );
    outer.subtract(&inner)
}

/// Mass of a motor mechanism able to deliver `max_torque` (Nm) at `max_speed` (rad/s).
pub fn motor_mass(max_torque: f64, max_speed: f64) -> f64 {
    MOTOR_BASE_MASS + (max_torque * max_speed / MOTOR_POWER_PER_MASS_SQUARED).sqrt()
}

/// A leg link: its tube plus the motor mechanism as a point mass at its tip.
pub fn link(length: f64, width: f64, wall: f64, max_torque: f64, max_speed: f64) -> MassProperties {
    tube(length, width, wall).combine(&MassProperties::point(
        motor_mass(max_torque, max_speed),
        Vector3::new(0.0, 0.0, length),
    ))
}

/// The body: a uniform foam cuboid of half-extents `half` centred at the origin, plus
/// avionics and payload as point masses at `payload_at`.
pub fn body(half: Vector3<f64>, payload_at: Vector3<f64>, payload: f64) -> MassProperties {
    let size = 2.0 * half;
    MassProperties::cuboid(
        BODY_DENSITY * size.x * size.y * size.z,
        size,
        Vector3::zeros(),
    )
    .combine(&MassProperties::point(AVIONICS_MASS + payload, payload_at))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * b.abs().max(1e-12)
    }

    #[test]
    fn tube_matches_closed_form() {
        // 1 m tube, 0.05 m outer, 0.002 m wall: area 0.05^2 - 0.046^2 = 0.000384 m^2,
        // mass 1600 * 0.000384 * 1 = 0.6144 kg. Transverse inertia about the centre:
        // m L^2 / 12 + (rho L / 12) (w^4 - wi^4) / 1 ... = (1/12)(rho L (w^4 - wi^4))/1
        // computed as difference of solids: Ixx = mo/12 (w^2 + L^2) - mi/12 (wi^2 + L^2).
        let p = tube(1.0, 0.05, 0.002);
        assert!(close(p.mass, 0.6144, 1e-12));
        let (mo, mi) = (1600.0 * 0.05 * 0.05, 1600.0 * 0.046 * 0.046);
        let ixx = mo / 12.0 * (0.05f64.powi(2) + 1.0) - mi / 12.0 * (0.046f64.powi(2) + 1.0);
        let izz = mo / 12.0 * (2.0 * 0.05f64.powi(2)) - mi / 12.0 * (2.0 * 0.046f64.powi(2));
        assert!(close(p.inertia[(0, 0)], ixx, 1e-9));
        assert!(close(p.inertia[(1, 1)], ixx, 1e-9));
        assert!(close(p.inertia[(2, 2)], izz, 1e-9));
        assert!(close(p.com.z, 0.5, 1e-12));
    }

    #[test]
    fn thick_wall_makes_a_solid_tube() {
        let p = tube(0.5, 0.02, 0.01);
        assert!(close(p.mass, 1600.0 * 0.02 * 0.02 * 0.5, 1e-12));
    }

    #[test]
    fn combine_is_mass_weighted_and_uses_parallel_axes() {
        // Two 1 kg points 2 m apart: com in the middle, I = 2 * 1 * 1^2 = 2 about the
        // perpendicular axes, 0 along the line.
        let a = MassProperties::point(1.0, Vector3::new(0.0, 0.0, 0.0));
        let b = MassProperties::point(1.0, Vector3::new(2.0, 0.0, 0.0));
        let c = a.combine(&b);
        assert_eq!(c.mass, 2.0);
        assert_eq!(c.com, Vector3::new(1.0, 0.0, 0.0));
        assert!(close(c.inertia[(1, 1)], 2.0, 1e-12));
        assert!(close(c.inertia[(2, 2)], 2.0, 1e-12));
        assert!(c.inertia[(0, 0)].abs() < 1e-12);
    }

    #[test]
    fn motor_mass_follows_the_power_law() {
        // 200 Nm at 1.5 rad/s = 300 W: 0.2 + sqrt(300 / 13000) = 0.2 + 0.15191 kg.
        assert!(close(motor_mass(200.0, 1.5), 0.351_910, 1e-5));
        assert_eq!(motor_mass(100.0, 0.0), 0.2);
    }
}
