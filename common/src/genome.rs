//! The genome: a morphology vector and a controller vector, both laid out by the
//! parameter tables in [`crate::params`].
//!
//! On disk (JSON or TOML) each vector is a flat map from parameter name to number. Reading
//! one refuses unknown names, missing names, non-numbers, non-finite values, values out of
//! range and fractional integers, naming the parameter; so every `Genome` value in memory
//! is valid.

use crate::params::{
    ParamError, ParamKind, ParamSpec, C, CONTROLLER_LEN, CONTROLLER_PARAMS, M, MORPHOLOGY_LEN,
    MORPHOLOGY_PARAMS,
};
use serde::de::{self, IgnoredAny, MapAccess, Visitor};
use serde::ser::SerializeMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;
use std::path::Path;

/// A fixed-size vector of parameter values laid out by a table.
pub trait ParamVector: Sized {
    /// The table that lays out this vector.
    const TABLE: &'static [ParamSpec];
    /// What the vector is called in error messages.
    const WHAT: &'static str;
    /// The values, in table order.
    fn values(&self) -> &[f64];
    /// Builds the vector from values in table order, checking every value.
    fn from_values(values: &[f64]) -> Result<Self, GenomeError>;
}

/// Checks a slice of values against a table.
fn check_values(table: &'static [ParamSpec], values: &[f64]) -> Result<(), GenomeError> {
    if values.len() != table.len() {
        return Err(GenomeError::WrongLength {
            expected: table.len(),
            found: values.len(),
        });
    }
    for (spec, &v) in table.iter().zip(values) {
        spec.check(v)?;
    }
    Ok(())
}

macro_rules! param_vector {
    ($(#[$meta:meta])* $ty:ident, $index:ident, $len:ident, $table:ident, $what:literal) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct $ty([f64; $len]);

        impl $ty {
            /// One parameter's value.
            #[inline]
            pub fn get(&self, p: $index) -> f64 {
                self.0[p.idx()]
            }

            /// Sets one parameter, clamped (and rounded for integers) into its range.
            pub fn set_clamped(&mut self, p: $index, v: f64) {
                self.0[p.idx()] = p.spec().clamp(v);
            }

            /// The midpoint of every range.
            pub fn midpoints() -> Self {
                let mut v = [0.0; $len];
                for (x, spec) in v.iter_mut().zip($table) {
                    *x = spec.clamp(spec.midpoint());
                }
                Self(v)
            }

            /// Mutable access for the variation operators, which clamp as they write.
            pub(crate) fn raw_mut(&mut self) -> &mut [f64; $len] {
                &mut self.0
            }
        }

        impl ParamVector for $ty {
            const TABLE: &'static [ParamSpec] = $table;
            const WHAT: &'static str = $what;
            fn values(&self) -> &[f64] {
                &self.0
            }
            fn from_values(values: &[f64]) -> Result<Self, GenomeError> {
                check_values($table, values)?;
                let mut v = [0.0; $len];
                v.copy_from_slice(values);
                Ok(Self(v))
            }
        }

        impl Serialize for $ty {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                serialize_vector(self, s)
            }
        }

        impl<'de> Deserialize<'de> for $ty {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let values = d.deserialize_map(VectorVisitor { table: $table, what: $what })?;
                $ty::from_values(&values).map_err(de::Error::custom)
            }
        }
    };
}

param_vector!(
    /// The robot's body, legs and motors (docs/model.md sections 2-5).
    Morphology,
    M,
    MORPHOLOGY_LEN,
    MORPHOLOGY_PARAMS,
    "morphology"
);
param_vector!(
    /// The gait controller (docs/model.md section 7).
    Controller,
    C,
    CONTROLLER_LEN,
    CONTROLLER_PARAMS,
    "controller"
);

impl Morphology {
    /// Legs on each side of the body.
    pub fn legs_per_side(&self) -> usize {
        self.get(M::LegsPerSide) as usize
    }
}

impl Controller {
    /// The STATIC controller: every parameter at the midpoint of its range
    /// (sf 2.5 rad/s, vo 0.5 rad, po 0).
    pub fn static_default() -> Self {
        Self::midpoints()
    }
}

/// A complete candidate: morphology plus gait controller.
///
/// Under the STATIC and ES schemes the stored controller is the STATIC one (ES reports its
/// tuned controller with the result); under GENOME it evolves with the body.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Genome {
    /// Body, legs, motors.
    pub morphology: Morphology,
    /// Gait.
    pub controller: Controller,
}

impl Genome {
    /// Reads a genome from a `.json` or `.toml` file (chosen by extension; JSON otherwise).
    pub fn load(path: &Path) -> Result<Self, GenomeError> {
        let text = std::fs::read_to_string(path).map_err(|e| GenomeError::Io {
            path: path.display().to_string(),
            source: e,
        })?;
        let is_toml = path.extension().is_some_and(|e| e == "toml");
        let parsed = if is_toml {
            toml::from_str(&text).map_err(|e| e.to_string())
        } else {
            serde_json::from_str(&text).map_err(|e| e.to_string())
        };
        parsed.map_err(|message| GenomeError::Parse {
            path: path.display().to_string(),
            message,
        })
    }

    /// Pretty JSON, the form written to genome files.
    pub fn to_json_pretty(&self) -> String {
        serde_json::to_string_pretty(self).expect("a genome always serialises")
    }
}

/// Anything wrong with a genome.
#[derive(Debug, thiserror::Error)]
pub enum GenomeError {
    #[error(transparent)]
    Param(#[from] ParamError),
    #[error("expected {expected} values, found {found}")]
    WrongLength { expected: usize, found: usize },
    #[error("cannot read genome file {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("invalid genome file {path}: {message}")]
    Parse { path: String, message: String },
}

fn serialize_vector<V: ParamVector, S: Serializer>(v: &V, s: S) -> Result<S::Ok, S::Error> {
    let mut map = s.serialize_map(Some(V::TABLE.len()))?;
    for (spec, &x) in V::TABLE.iter().zip(v.values()) {
        match spec.kind {
            ParamKind::Integer => map.serialize_entry(spec.name, &(x as i64))?,
            ParamKind::Real => map.serialize_entry(spec.name, &x)?,
        }
    }
    map.end()
}

/// Reads a name -> number map into table order, naming any bad entry.
struct VectorVisitor {
    table: &'static [ParamSpec],
    what: &'static str,
}

impl<'de> Visitor<'de> for VectorVisitor {
    type Value = Vec<f64>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "a {} map from parameter name to number", self.what)
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Vec<f64>, A::Error> {
        let mut values: Vec<Option<f64>> = vec![None; self.table.len()];
        while let Some(key) = map.next_key::<String>()? {
            let Some(i) = crate::params::find(self.table, &key) else {
                return Err(de::Error::custom(format!(
                    "unknown {} parameter `{key}`",
                    self.what
                )));
            };
            let value = match map.next_value::<AnyScalar>()? {
                AnyScalar::Number(v) => v,
                AnyScalar::Other(found) => {
                    return Err(de::Error::custom(format!(
                        "{} parameter `{key}` must be a number, found {found}",
                        self.what
                    )))
                }
            };
            // Checked here, not only once the map is read, so that a parser that knows
            // positions (serde_json, toml) names this value's line, not the map's end.
            self.table[i].check(value).map_err(de::Error::custom)?;
            if values[i].replace(value).is_some() {
                return Err(de::Error::custom(format!(
                    "{} parameter `{key}` is given twice",
                    self.what
                )));
            }
        }
        let missing: Vec<&str> = self
            .table
            .iter()
            .zip(&values)
            .filter(|(_, v)| v.is_none())
            .map(|(spec, _)| spec.name)
            .collect();
        if !missing.is_empty() {
            return Err(de::Error::custom(format!(
                "missing {} parameter(s): {}",
                self.what,
                missing.join(", ")
            )));
        }
        Ok(values.into_iter().map(|v| v.unwrap_or_default()).collect())
    }
}

/// A map value: a number, or a description of whatever else was found, so that the
/// error can name the parameter rather than only the position.
enum AnyScalar {
    Number(f64),
    Other(String),
}

impl<'de> Deserialize<'de> for AnyScalar {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(AnyScalarVisitor)
    }
}

struct AnyScalarVisitor;

impl<'de> Visitor<'de> for AnyScalarVisitor {
    type Value = AnyScalar;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a number")
    }
    fn visit_f64<E>(self, v: f64) -> Result<AnyScalar, E> {
        Ok(AnyScalar::Number(v))
    }
    fn visit_i64<E>(self, v: i64) -> Result<AnyScalar, E> {
        Ok(AnyScalar::Number(v as f64))
    }
    fn visit_u64<E>(self, v: u64) -> Result<AnyScalar, E> {
        Ok(AnyScalar::Number(v as f64))
    }
    fn visit_bool<E>(self, v: bool) -> Result<AnyScalar, E> {
        Ok(AnyScalar::Other(format!("boolean {v}")))
    }
    fn visit_str<E>(self, v: &str) -> Result<AnyScalar, E> {
        Ok(AnyScalar::Other(format!("string {v:?}")))
    }
    fn visit_unit<E>(self) -> Result<AnyScalar, E> {
        Ok(AnyScalar::Other("null".into()))
    }
    fn visit_none<E>(self) -> Result<AnyScalar, E> {
        Ok(AnyScalar::Other("null".into()))
    }
    fn visit_seq<A: de::SeqAccess<'de>>(self, mut seq: A) -> Result<AnyScalar, A::Error> {
        while seq.next_element::<IgnoredAny>()?.is_some() {}
        Ok(AnyScalar::Other("a list".into()))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<AnyScalar, A::Error> {
        while map.next_entry::<IgnoredAny, IgnoredAny>()?.is_some() {}
        Ok(AnyScalar::Other("a table".into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn max_json() -> String {
        crate::reference::MAX_JSON.to_string()
    }

    fn parse_err(json: &str) -> String {
        serde_json::from_str::<Genome>(json)
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn a_value_out_of_range_is_named_at_its_own_line() {
        // Before, the range was checked when the whole map had been read, and serde_json
        // named the map's last line.
        let text = max_json();
        let (at, line) = text
            .lines()
            .enumerate()
            .find(|(_, l)| l.contains("\"link1_length\""))
            .expect("MAX has link1_length");
        let key = line.split(':').next().unwrap();
        let bad: Vec<String> = text
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i == at {
                    format!("{key}: 9.5,")
                } else {
                    l.to_string()
                }
            })
            .collect();
        let err = parse_err(&bad.join("\n"));
        assert!(
            err.contains("`link1_length` = 9.5 is outside its range"),
            "{err}"
        );
        assert!(err.contains(&format!("at line {}", at + 1)), "{err}");
    }

    #[test]
    fn json_round_trip_is_exact() {
        let g: Genome = serde_json::from_str(&max_json()).unwrap();
        let back: Genome = serde_json::from_str(&g.to_json_pretty()).unwrap();
        assert_eq!(g, back);
    }

    proptest::proptest! {
        /// Genomes travel through JSON (files, the database, the wire): every bit survives.
        #[test]
        fn random_genomes_round_trip_json_bit_exactly(run in proptest::prelude::any::<u64>(), cand in proptest::prelude::any::<u64>()) {
            use crate::rng::{CandidateSeed, Purpose};
            let g = Genome::random(crate::Scheme::Genome, &mut CandidateSeed::new(run, cand).rng(Purpose::RandomGenome));
            let back: Genome = serde_json::from_str(&serde_json::to_string(&g).unwrap()).unwrap();
            for (a, b) in g.morphology.values().iter().chain(g.controller.values()).zip(back.morphology.values().iter().chain(back.controller.values())) {
                proptest::prop_assert_eq!(a.to_bits(), b.to_bits());
            }
        }
    }

    #[test]
    fn toml_round_trip_is_exact() {
        let g: Genome = serde_json::from_str(&max_json()).unwrap();
        let text = toml::to_string(&g).unwrap();
        let back: Genome = toml::from_str(&text).unwrap();
        assert_eq!(g, back);
    }

    #[test]
    fn integers_are_written_as_integers() {
        let g: Genome = serde_json::from_str(&max_json()).unwrap();
        assert!(g.to_json_pretty().contains("\"legs_per_side\": 3,"));
    }

    #[test]
    fn missing_parameter_is_named() {
        let json = max_json().replace("\"body_half_y\"", "\"_gone\"");
        let e = parse_err(&json);
        assert!(e.contains("unknown morphology parameter `_gone`"), "{e}");
        let v: serde_json::Value = serde_json::from_str(&max_json()).unwrap();
        let mut v = v;
        v["morphology"]
            .as_object_mut()
            .unwrap()
            .remove("motor1_damping");
        let e = parse_err(&v.to_string());
        assert!(
            e.contains("missing morphology parameter(s): motor1_damping"),
            "{e}"
        );
    }

    #[test]
    fn missing_section_is_named() {
        let mut v: serde_json::Value = serde_json::from_str(&max_json()).unwrap();
        v.as_object_mut().unwrap().remove("controller");
        let e = parse_err(&v.to_string());
        assert!(e.contains("missing field `controller`"), "{e}");
    }

    #[test]
    fn out_of_range_is_named_with_its_range() {
        let mut v: serde_json::Value = serde_json::from_str(&max_json()).unwrap();
        v["morphology"]["link1_length"] = serde_json::json!(2.5);
        let e = parse_err(&v.to_string());
        assert!(
            e.contains("`link1_length` = 2.5 is outside its range [0.4, 1.6] m"),
            "{e}"
        );
    }

    #[test]
    fn wrong_type_is_named() {
        let mut v: serde_json::Value = serde_json::from_str(&max_json()).unwrap();
        v["controller"]["stride_frequency"] = serde_json::json!("fast");
        let e = parse_err(&v.to_string());
        assert!(
            e.contains(
                "controller parameter `stride_frequency` must be a number, found string \"fast\""
            ),
            "{e}"
        );
    }

    #[test]
    fn nan_is_named() {
        // JSON has no NaN; TOML does.
        let g: Genome = serde_json::from_str(&max_json()).unwrap();
        let mut doc: toml::Table = toml::from_str(&toml::to_string(&g).unwrap()).unwrap();
        doc["morphology"]["body_half_x"] = toml::Value::Float(f64::NAN);
        let text = toml::to_string(&doc).unwrap();
        assert!(text.contains("body_half_x = nan"), "{text}");
        let e = toml::from_str::<Genome>(&text).unwrap_err().to_string();
        assert!(
            e.contains("`body_half_x` is NaN, which is not a finite number"),
            "{e}"
        );
    }

    #[test]
    fn fractional_integer_is_refused() {
        let mut v: serde_json::Value = serde_json::from_str(&max_json()).unwrap();
        v["morphology"]["legs_per_side"] = serde_json::json!(3.5);
        let e = parse_err(&v.to_string());
        assert!(
            e.contains("`legs_per_side` = 3.5 must be an integer"),
            "{e}"
        );
    }

    #[test]
    fn static_controller_is_the_midpoints() {
        let c = Controller::static_default();
        assert_eq!(c.get(C::StrideFrequency), 2.5);
        assert_eq!(c.get(C::VerticalOffset1), 0.5);
        assert_eq!(c.get(C::PhaseOffset2), 0.0);
    }
}
