//! Strider's robot model: the genome and its parameter table, the body plan and mass model,
//! the gait, the start pose, features and cells, the design brief, random generation and
//! mutation, the experiment file, and URDF export. Plain data and pure functions; no I/O beyond reading
//! files, no physics engine.

pub mod body_plan;
pub mod brief;
pub mod contact;
pub mod drawing;
pub mod experiment;
pub mod features;
pub mod gait;
pub mod genome;
pub mod hull;
pub mod ids;
pub mod initial_designs;
pub mod inspect;
pub mod kinematics;
pub mod mass;
pub mod motor_sizing;
pub mod outcome;
pub mod params;
pub mod pose;
pub mod precheck;
pub mod reference;
pub mod rng;
pub mod urdf;
pub mod variation;
pub mod xml;

pub use body_plan::BodyPlan;
pub use brief::DesignBrief;
pub use experiment::Experiment;
pub use features::{CellIndex, FeatureGrid, Features};
pub use genome::{Controller, Genome, Morphology};
pub use ids::{CandidateId, CandidateKey, CandidateNumber, RunId, WorkerId};
pub use outcome::{
    Fall, GaitStats, InvalidReason, Outcome, Shortfall, Skate, Standing, TrialStats,
};
pub use pose::StartPose;
pub use precheck::EvalContext;
pub use variation::{MutationRates, Scheme};

/// The Strider build: trials are bit-identical only within one build (see
/// docs/rapier.md), so the database records it and the coordinator refuses
/// workers of another.
pub fn build_id() -> String {
    format!(
        "strider {} ({}, {})",
        env!("CARGO_PKG_VERSION"),
        std::env::consts::ARCH,
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        }
    )
}
