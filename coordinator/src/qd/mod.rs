//! The quality-diversity core: plain functions and state over plain data, with no
//! storage, network or simulator. The libraries of a run, where its candidates come from,
//! the scheduler that leases them and places their results, the changes it emits for
//! storage to write, and the replay that `verify` re-drives.

pub mod changes;
pub mod evolution;
pub mod library;
pub mod run;
pub mod scheduler;
pub mod verify;
