//! Strider's worker: simulates candidates in rapier3d and evaluates them under a scheme.

pub mod batch;
pub mod calibrate;
pub mod client;
pub mod commands;
pub mod es;
pub mod evaluate;
pub mod fidelity;
pub mod help;
pub mod pool;
pub mod reference_trial;
pub mod replay;
pub mod sim;
pub mod survey;
pub mod synthetic;
pub mod trace;
pub mod trial_outcome;
