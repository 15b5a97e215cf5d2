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

/// The Strider build: trials are bit-identical only within one build (see docs/rapier.md),
/// so the database records it and the coordinator refuses workers of another. The build is
/// the version, the commit (`build.rs`: two commits of one version may simulate
/// differently), the architecture and the profile. It names no CPU: the physics' matrix
/// products are fused multiply-adds on every CPU (the vendored rapier's patch; before it,
/// the `matrixmultiply` crate chose by the CPU and the identity had to name which).
pub fn build_id() -> String {
    format!(
        "strider {} (commit {}, {}, {})",
        env!("CARGO_PKG_VERSION"),
        env!("STRIDER_COMMIT"),
        std::env::consts::ARCH,
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        },
    )
}

/// [`build_id`] without the leading "strider ": what `--version` prints after the program's
/// name. Computed once and kept for the program's life, as clap wants.
pub fn build_version() -> &'static str {
    static VERSION: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    VERSION.get_or_init(|| {
        let id = build_id();
        id.strip_prefix("strider ").unwrap_or(&id).to_owned()
    })
}
