//! Strider's coordinator: the MAP-Elites library, how candidates are bred, the scheduler
//! that leases them to workers, the database, the gRPC service and the analysis.

pub mod analysis;
pub mod changes;
pub mod commands;
pub mod db;
pub mod evolution;
pub mod export;
pub mod library;
pub mod report;
pub mod scheduler;
pub mod service;
pub mod verify;
