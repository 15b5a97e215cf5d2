//! Reading experiments: from TOML text, from a file (its initial designs from the file's
//! folder), and the shipped ones.

use super::{invalid, Experiment, ExperimentError};
use std::path::Path;

impl Experiment {
    /// Parses and validates TOML text; an `initial_designs` file is read from the current
    /// directory.
    pub fn from_toml(text: &str) -> Result<Self, ExperimentError> {
        Self::from_toml_reading(text, |name| {
            std::fs::read_to_string(name).map_err(|e| format!("cannot read {name}: {e}"))
        })
    }

    /// Parses and validates TOML text, reading an `initial_designs` file with `read` (its
    /// text from the name the experiment gives).
    pub fn from_toml_reading(
        text: &str,
        read: impl FnOnce(&str) -> Result<String, String>,
    ) -> Result<Self, ExperimentError> {
        let mut e: Experiment = toml::from_str(text).map_err(|e| ExperimentError::Parse {
            path: "<text>".into(),
            message: e.to_string(),
        })?;
        e.initial_designs
            .read(read)
            .map_err(|problem| invalid("initial_designs", problem))?;
        e.validate()?;
        Ok(e)
    }

    /// Reads, parses and validates an experiment file (an `initial_designs` file is read
    /// from the experiment file's folder).
    pub fn load(path: &Path) -> Result<Self, ExperimentError> {
        let text = std::fs::read_to_string(path).map_err(|e| ExperimentError::Io {
            path: path.display().to_string(),
            source: e,
        })?;
        let folder = path.parent().unwrap_or(Path::new(""));
        Self::from_toml_reading(&text, |name| {
            let file = folder.join(name);
            std::fs::read_to_string(&file)
                .map_err(|e| format!("cannot read {}: {e}", file.display()))
        })
        .map_err(|e| match e {
            ExperimentError::Parse { message, .. } => ExperimentError::Parse {
                path: path.display().to_string(),
                message,
            },
            other => other,
        })
    }

    /// The paper's full experiment (3 schemes x 20 repeats, 4000 generations).
    pub fn paper() -> Self {
        Self::from_toml(include_str!("../../../experiments/paper.toml"))
            .expect("the shipped paper experiment is valid")
    }

    /// The built-in quick experiment (`experiments/quick.toml`), its initial designs
    /// built in too.
    pub fn quick() -> Self {
        Self::from_toml_reading(
            include_str!("../../../experiments/quick.toml"),
            |name| match name {
                "quick-designs.json" => {
                    Ok(include_str!("../../../experiments/quick-designs.json").to_owned())
                }
                other => Err(format!("{other} is not built in")),
            },
        )
        .expect("the shipped quick experiment is valid")
    }
}
