//! Strider's coordinator: the quality-diversity core (`qd`: the MAP-Elites library, how
//! candidates are bred, the scheduler that leases them to workers), the database (`db`),
//! the gRPC service (`service`), what a user reads (`results`: analysis, report, exports)
//! and the command lines (`commands`).

pub mod commands;
pub mod db;
pub mod qd;
pub mod results;
pub mod service;
