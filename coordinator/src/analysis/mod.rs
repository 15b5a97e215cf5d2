//! Design-assist analysis (spec section 6): plain functions over plain data.

pub mod mann_whitney;
pub mod rules;
pub mod summary;
