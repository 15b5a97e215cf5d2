//! Strider's coordinator: the MAP-Elites library and how candidates are bred. The database,
//! the gRPC service and the analysis come with the service and design-assist issues.

pub mod analysis;
pub mod db;
pub mod evolution;
pub mod library;
pub mod runner;
