//! The reference design, MAX (`designs/max.json`, docs/model.md section 14): the design
//! the library maps mark, `check` calibrates its estimate with, and the tests measure
//! against. Built into the binaries, so it needs no file at run time.

use crate::Genome;

/// MAX's genome file, as `designs/max.json` holds it.
pub const MAX_JSON: &str = include_str!("../../designs/max.json");

/// MAX's genome.
pub fn max() -> Genome {
    serde_json::from_str(MAX_JSON).expect("designs/max.json is a valid genome")
}
