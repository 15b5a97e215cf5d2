//! Strider's robot model: the genome and its parameter table, the body plan and mass model,
//! the gait, the start pose, features and cells, the design brief, random generation and
//! mutation, and the experiment file. Plain data and pure functions; no I/O beyond reading
//! files, no physics engine.

pub mod body_plan;
pub mod brief;
pub mod experiment;
pub mod features;
pub mod gait;
pub mod genome;
pub mod inspect;
pub mod mass;
pub mod outcome;
pub mod params;
pub mod pose;
pub mod rng;
pub mod variation;

pub use body_plan::BodyPlan;
pub use brief::DesignBrief;
pub use experiment::Experiment;
pub use features::{CellIndex, FeatureGrid, Features};
pub use genome::{Controller, Genome, Morphology};
pub use outcome::{InvalidReason, Outcome, TrialStats};
pub use pose::StartPose;
pub use variation::{MutationRates, Scheme};
