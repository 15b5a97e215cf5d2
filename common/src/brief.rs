//! The design brief (docs/model.md section 11): the constraints a design must meet to enter the
//! library. Configurable; the defaults are the paper's.

use crate::body_plan::BodyPlan;
use crate::pose::StartPose;
use serde::{Deserialize, Serialize};
use std::fmt;

/// The design brief.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DesignBrief {
    /// Largest mass without payload, kg.
    pub max_mass: f64,
    /// Smallest height of the start pose (highest point above the ground), m.
    pub min_height: f64,
    /// Smallest average forward speed over the trial, m/s.
    pub min_speed: f64,
    /// Payload carried, kg (a point mass at the payload position).
    pub payload: f64,
}

impl Default for DesignBrief {
    fn default() -> Self {
        Self {
            max_mass: 60.0,
            min_height: 2.0,
            min_speed: 1.0,
            payload: 10.0,
        }
    }
}

/// A constraint of the brief.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Constraint {
    /// Mass without payload at most `max_mass`.
    Mass,
    /// Start-pose height at least `min_height`.
    Height,
    /// Average forward speed at least `min_speed` (needs the simulation).
    Speed,
}

impl Constraint {
    /// All constraints in the order they are checked.
    pub const ALL: [Constraint; 3] = [Constraint::Mass, Constraint::Height, Constraint::Speed];

    /// The constraint's name.
    pub fn name(self) -> &'static str {
        match self {
            Constraint::Mass => "mass",
            Constraint::Height => "height",
            Constraint::Speed => "speed",
        }
    }
}

/// A failed constraint and by how much.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Violation {
    pub constraint: Constraint,
    /// The design's value (kg, m or m/s).
    pub value: f64,
    /// The brief's limit.
    pub limit: f64,
}

impl Violation {
    /// How far past the limit, always positive, in the constraint's unit.
    pub fn excess(&self) -> f64 {
        (self.value - self.limit).abs()
    }
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.constraint {
            Constraint::Mass => write!(
                f,
                "mass without payload {:.2} kg exceeds {:.2} kg by {:.2} kg",
                self.value,
                self.limit,
                self.excess()
            ),
            Constraint::Height => write!(
                f,
                "height {:.3} m is below {:.3} m by {:.3} m",
                self.value,
                self.limit,
                self.excess()
            ),
            Constraint::Speed => write!(
                f,
                "average speed {:.3} m/s is below {:.3} m/s by {:.3} m/s",
                self.value,
                self.limit,
                self.excess()
            ),
        }
    }
}

impl DesignBrief {
    /// The checks that need no simulation: mass and height. Returns every failure.
    pub fn check_model(&self, plan: &BodyPlan, pose: &StartPose) -> Vec<Violation> {
        let mut out = Vec::new();
        let mass = plan.mass_without_payload();
        if mass > self.max_mass {
            out.push(Violation {
                constraint: Constraint::Mass,
                value: mass,
                limit: self.max_mass,
            });
        }
        if pose.height < self.min_height {
            out.push(Violation {
                constraint: Constraint::Height,
                value: pose.height,
                limit: self.min_height,
            });
        }
        out
    }

    /// The speed a trial asks for: `min_speed` raised by the fraction `margin`.
    pub fn required_speed(&self, margin: f64) -> f64 {
        self.min_speed * (1.0 + margin)
    }

    /// The simulated check: average forward speed over the trial, which must beat
    /// `min_speed` by the fraction `margin` (the trial's safety factor for the physics
    /// step's error; 0 checks the brief as written). The violation's limit is the
    /// speed asked for, margin included.
    pub fn check_speed(&self, speed: f64, margin: f64) -> Option<Violation> {
        let limit = self.required_speed(margin);
        (speed < limit).then_some(Violation {
            constraint: Constraint::Speed,
            value: speed,
            limit,
        })
    }
}
