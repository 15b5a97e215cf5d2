//! Design-assist analysis (the paper's sections 6 and 7): plain functions over plain data.

pub mod mann_whitney;
pub mod rules;
pub mod summary;
