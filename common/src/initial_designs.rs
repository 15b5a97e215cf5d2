//! Designs a run's initial population starts from (`initial_designs` in an experiment
//! file): a warm start from designs already known, say the elites of an earlier run, drawn
//! before any random design. In an experiment file it names a JSON file (an array of
//! genomes, relative to the experiment file); the database stores the genomes themselves,
//! so a run goes on from its database alone, whatever became of that file.

use crate::genome::Genome;
use crate::variation::Scheme;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::{Deserialize, Serialize, Serializer};
use std::fmt;

/// An experiment's initial designs: none, a file not yet read, or the designs.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum InitialDesigns {
    /// Every initial candidate is random.
    #[default]
    None,
    /// A JSON file of genomes, as the experiment file names it; [`InitialDesigns::read`]
    /// turns it into [`InitialDesigns::Designs`] (an experiment, once loaded, holds no
    /// file).
    File(String),
    /// The genomes, in the order they are drawn: candidate `i` of every run's initial
    /// population is design `i` while there are designs.
    Designs(Vec<Genome>),
}

impl InitialDesigns {
    /// True when the initial population is random throughout.
    pub fn is_none(&self) -> bool {
        matches!(self, Self::None)
    }

    /// The designs (none for a file not yet read).
    pub fn designs(&self) -> &[Genome] {
        match self {
            Self::Designs(d) => d,
            Self::None | Self::File(_) => &[],
        }
    }

    /// Reads a named file with `read` (its text from its name); `Err` is a message naming
    /// the file and what is wrong with it.
    pub fn read(
        &mut self,
        read: impl FnOnce(&str) -> Result<String, String>,
    ) -> Result<(), String> {
        let Self::File(name) = self else {
            return Ok(());
        };
        let text = read(name)?;
        let designs: Vec<Genome> = serde_json::from_str(&text).map_err(|e| {
            format!("file {name}: {e} (it must be a JSON array of genomes, each as `export --elite RUN:CELL --genome FILE` writes one)")
        })?;
        if designs.is_empty() {
            return Err(format!(
                "file {name} holds no design: leave `initial_designs` out for a random initial population"
            ));
        }
        *self = Self::Designs(designs);
        Ok(())
    }

    /// Initial candidate `number` of a run under `scheme`: design `number` with the
    /// controller the scheme starts from (the STATIC gait under STATIC and ES, whose
    /// strategy starts from it; the design's own under GENOME, as a random GENOME design
    /// has its own), or `None` past the last design.
    pub fn candidate(&self, scheme: Scheme, number: u64) -> Option<Genome> {
        let design = self.designs().get(usize::try_from(number).ok()?)?;
        let mut genome = *design;
        if scheme != Scheme::Genome {
            genome.controller = crate::genome::Controller::static_default();
        }
        Some(genome)
    }
}

impl Serialize for InitialDesigns {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Self::None => s.serialize_none(),
            Self::File(name) => s.serialize_str(name),
            Self::Designs(d) => d.serialize(s),
        }
    }
}

impl<'de> Deserialize<'de> for InitialDesigns {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(InitialDesignsVisitor)
    }
}

/// A file name or an array of genomes.
struct InitialDesignsVisitor;

impl<'de> Visitor<'de> for InitialDesignsVisitor {
    type Value = InitialDesigns;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "a JSON file of genomes, or an array of genomes")
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<InitialDesigns, E> {
        if v.trim().is_empty() {
            return Err(E::custom("names no file"));
        }
        Ok(InitialDesigns::File(v.to_owned()))
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<InitialDesigns, A::Error> {
        let mut designs = Vec::new();
        while let Some(g) = seq.next_element::<Genome>()? {
            designs.push(g);
        }
        if designs.is_empty() {
            return Err(de::Error::custom(
                "is an empty list: leave it out for a random initial population",
            ));
        }
        Ok(InitialDesigns::Designs(designs))
    }
}
