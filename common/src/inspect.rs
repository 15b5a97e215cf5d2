//! What can be said of a genome without simulating it: masses, start pose, features, cell
//! and the brief's static checks. `strider-worker inspect` prints this.

use crate::body_plan::BodyPlan;
use crate::brief::{DesignBrief, Violation};
use crate::features::{Bins, CellIndex, FeatureGrid, Features, FEATURE_NAMES};
use crate::genome::Genome;
use crate::pose::StartPose;
use serde::Serialize;
use std::fmt;

/// A genome's static summary.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Inspection {
    pub legs_per_side: usize,
    /// Body foam + avionics + payload, kg.
    pub body_mass: f64,
    /// All legs, kg.
    pub legs_mass: f64,
    /// Mass without payload, kg (the brief's mass).
    pub mass_without_payload: f64,
    /// Total mass with payload, kg (feature d2).
    pub total_mass: f64,
    /// Highest point of the start pose above the ground, m.
    pub height: f64,
    /// Body centre height in the start pose, m.
    pub body_height: f64,
    /// Features d1..d6.
    pub features: Features,
    pub bins: Bins,
    pub cell: CellIndex,
    /// Failed static constraints.
    pub violations: Vec<Violation>,
}

impl Inspection {
    /// Inspects a genome under a brief and a grid.
    pub fn of(genome: &Genome, brief: &DesignBrief, grid: &FeatureGrid) -> Self {
        let plan = BodyPlan::new(&genome.morphology, brief.payload);
        let pose = StartPose::new(&plan, &genome.controller);
        let features = Features::of(&genome.morphology, &plan);
        // Features of a valid genome are always finite.
        let bins = grid
            .bins_of(&features)
            .expect("features of a valid genome are finite");
        let total_mass = plan.total_mass();
        Self {
            legs_per_side: plan.legs_per_side(),
            body_mass: plan.body_mass.mass,
            legs_mass: total_mass - plan.body_mass.mass,
            mass_without_payload: plan.mass_without_payload(),
            total_mass,
            height: pose.height,
            body_height: pose.body_height,
            features,
            bins,
            cell: grid.cell_index(bins),
            violations: brief.check_model(&plan, &pose),
        }
    }
}

impl fmt::Display for Inspection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "legs per side         {}", self.legs_per_side)?;
        writeln!(
            f,
            "body mass             {:.2} kg (foam, avionics, payload)",
            self.body_mass
        )?;
        writeln!(f, "legs mass             {:.2} kg", self.legs_mass)?;
        writeln!(
            f,
            "mass without payload  {:.2} kg",
            self.mass_without_payload
        )?;
        writeln!(f, "total mass            {:.2} kg", self.total_mass)?;
        writeln!(f, "height (start pose)   {:.3} m", self.height)?;
        writeln!(f, "body centre height    {:.3} m", self.body_height)?;
        for (j, name) in FEATURE_NAMES.iter().enumerate() {
            writeln!(
                f,
                "d{} {:<18} {:<10.4} bin {}",
                j + 1,
                name,
                self.features.0[j],
                self.bins.0[j]
            )?;
        }
        writeln!(f, "cell                  {}", self.cell.0)?;
        if self.violations.is_empty() {
            write!(f, "static brief checks   pass")
        } else {
            write!(f, "static brief checks   FAIL")?;
            for v in &self.violations {
                write!(f, "\n  - {v}")?;
            }
            Ok(())
        }
    }
}
