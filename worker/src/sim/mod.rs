//! The physics: building a robot's world and running its trial.

pub mod drive;
mod falls;
pub mod feet;
pub mod trial;
pub mod world;
