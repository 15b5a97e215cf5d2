//! The physics: building a robot's world and running its trial.

pub mod trial;
pub mod world;
