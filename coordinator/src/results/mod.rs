//! What a finished or running experiment gives a user: the design-assist analysis, the
//! report built from it, and the exports (CSV, JSON, genome files).

pub mod analysis;
pub mod export;
pub mod report;
