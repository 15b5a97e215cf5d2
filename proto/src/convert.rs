//! Conversions between wire messages and the model's types. Everything coming off the wire
//! is validated here: vector sizes, finiteness and ranges through the parameter table, so
//! a malformed message is refused with the field's name before it reaches the library.

use crate::v1;
use strider_common::brief::{Constraint, Violation};
use strider_common::features::{CellIndex, Features, FEATURE_COUNT};
use strider_common::genome::{GenomeError, ParamVector};
use strider_common::ids::{CandidateKey, CandidateNumber};
use strider_common::{
    Controller, Fall, GaitStats, Genome, InvalidReason, Morphology, Outcome, Scheme, Skate,
    TrialStats,
};

/// `Invalid.quantity` of a REASON_FELL: how the robot fell.
const FALL_TILTED: &str = "tilted";
const FALL_SANK: &str = "sank";
const FALL_DRAGGED: &str = "dragged";
/// `Invalid.quantity` of a REASON_SKATING: how the feet skated.
const SKATE_SLID: &str = "slid";
const SKATE_SHUFFLED: &str = "shuffled";

/// A message that does not describe a valid model value; names the field.
#[derive(Debug, thiserror::Error)]
#[error("{field}: {problem}")]
pub struct WireError {
    /// Dotted path of the offending field.
    pub field: String,
    /// What is wrong with it.
    pub problem: String,
}

fn wire_err(field: impl std::fmt::Display, problem: impl ToString) -> WireError {
    WireError {
        field: field.to_string(),
        problem: problem.to_string(),
    }
}

/// `v` if finite. The field's name is only formatted when it is not (every result passes
/// through here: names built eagerly cost more than the rest of the decoding).
fn finite(field: impl std::fmt::Display, v: f64) -> Result<f64, WireError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(wire_err(field, format!("{v} is not a finite number")))
    }
}

fn vector<V: ParamVector>(field: &str, values: &[f64]) -> Result<V, WireError> {
    V::from_values(values).map_err(|e| match e {
        GenomeError::WrongLength { expected, found } => {
            wire_err(field, format!("expected {expected} values, found {found}"))
        }
        other => wire_err(field, other),
    })
}

impl From<&Genome> for v1::Genome {
    fn from(g: &Genome) -> Self {
        v1::Genome {
            morphology: g.morphology.values().to_vec(),
            controller: g.controller.values().to_vec(),
        }
    }
}

impl TryFrom<&v1::Genome> for Genome {
    type Error = WireError;
    fn try_from(g: &v1::Genome) -> Result<Self, WireError> {
        Ok(Genome {
            morphology: vector::<Morphology>("genome.morphology", &g.morphology)?,
            controller: vector::<Controller>("genome.controller", &g.controller)?,
        })
    }
}

impl From<CandidateKey> for v1::CandidateId {
    fn from(k: CandidateKey) -> Self {
        v1::CandidateId {
            run: k.run.0,
            generation: k.generation,
            number: k.number.0,
            drawn_ahead: k.drawn_ahead,
        }
    }
}

impl From<&v1::CandidateId> for CandidateKey {
    fn from(id: &v1::CandidateId) -> Self {
        CandidateKey {
            run: strider_common::RunId(id.run),
            generation: id.generation,
            number: CandidateNumber(id.number),
            drawn_ahead: id.drawn_ahead,
        }
    }
}

/// The candidate a message names; refused when the id is missing.
pub fn key_from_wire(field: &str, id: Option<&v1::CandidateId>) -> Result<CandidateKey, WireError> {
    id.map(CandidateKey::from)
        .ok_or_else(|| wire_err(field, "missing"))
}

/// The wire form of a scheme.
pub fn scheme_to_wire(s: Scheme) -> v1::Scheme {
    match s {
        Scheme::Static => v1::Scheme::Static,
        Scheme::Genome => v1::Scheme::Genome,
        Scheme::Es => v1::Scheme::Es,
    }
}

/// A scheme from its wire value.
pub fn scheme_from_wire(value: i32) -> Result<Scheme, WireError> {
    match v1::Scheme::try_from(value) {
        Ok(v1::Scheme::Static) => Ok(Scheme::Static),
        Ok(v1::Scheme::Genome) => Ok(Scheme::Genome),
        Ok(v1::Scheme::Es) => Ok(Scheme::Es),
        _ => Err(wire_err("scheme", format!("{value} is not a scheme"))),
    }
}

fn stats_to_wire(s: &TrialStats) -> v1::TrialStats {
    v1::TrialStats {
        distance: s.distance,
        energy: s.energy,
        speed: s.speed,
        mass: s.mass,
        cost_of_transport: s.cost_of_transport,
        duration: s.duration,
        peak_torque_ratio: s.gait.peak_torque_ratio,
        foot_slip: s.gait.foot_slip,
        low_forward_share: s.gait.low_forward_share,
        duty_factor: s.gait.duty_factor,
    }
}

fn stats_from_wire(field: &str, s: &v1::TrialStats) -> Result<TrialStats, WireError> {
    let f = |name: &str, v: f64| finite(format_args!("{field}.{name}"), v);
    Ok(TrialStats {
        distance: f("distance", s.distance)?,
        energy: f("energy", s.energy)?,
        speed: f("speed", s.speed)?,
        mass: f("mass", s.mass)?,
        cost_of_transport: f("cost_of_transport", s.cost_of_transport)?,
        duration: f("duration", s.duration)?,
        gait: GaitStats {
            peak_torque_ratio: f("peak_torque_ratio", s.peak_torque_ratio)?,
            foot_slip: f("foot_slip", s.foot_slip)?,
            low_forward_share: f("low_forward_share", s.low_forward_share)?,
            duty_factor: f("duty_factor", s.duty_factor)?,
        },
    })
}

fn constraint_to_wire(c: Constraint) -> v1::violation::Constraint {
    match c {
        Constraint::Mass => v1::violation::Constraint::Mass,
        Constraint::Height => v1::violation::Constraint::Height,
        Constraint::Speed => v1::violation::Constraint::Speed,
    }
}

impl From<&Outcome> for v1::Outcome {
    fn from(o: &Outcome) -> Self {
        use v1::invalid::Reason;
        let kind = match o {
            Outcome::Valid {
                fitness,
                stats,
                features,
                cell,
                outranked,
                ..
            } => v1::outcome::Kind::Valid(v1::Valid {
                fitness: *fitness,
                stats: Some(stats_to_wire(stats)),
                features: features.0.to_vec(),
                cell: cell.0,
                outranked: *outranked,
            }),
            Outcome::Rejected {
                violations, stats, ..
            } => v1::outcome::Kind::Rejected(v1::Rejected {
                violations: violations
                    .iter()
                    .map(|v| v1::Violation {
                        constraint: constraint_to_wire(v.constraint).into(),
                        value: v.value,
                        limit: v.limit,
                    })
                    .collect(),
                stats: stats.as_ref().map(stats_to_wire),
            }),
            Outcome::Invalid {
                reason, at_time, ..
            } => {
                let mut w = v1::Invalid {
                    at_time: *at_time,
                    ..Default::default()
                };
                match reason {
                    InvalidReason::SelfContact { first, second } => {
                        w.reason = Reason::SelfContact.into();
                        w.first_part = first.clone();
                        w.second_part = second.clone();
                    }
                    InvalidReason::NonFinite { what } => {
                        w.reason = Reason::NonFinite.into();
                        w.quantity = what.clone();
                    }
                    InvalidReason::Fell { fall } => {
                        w.reason = Reason::Fell.into();
                        match fall {
                            Fall::Tilted { degrees, limit } => {
                                w.quantity = FALL_TILTED.into();
                                w.value = *degrees;
                                w.limit = *limit;
                            }
                            Fall::Sank { height, limit } => {
                                w.quantity = FALL_SANK.into();
                                w.value = *height;
                                w.limit = *limit;
                            }
                            Fall::Dragged { part } => {
                                w.quantity = FALL_DRAGGED.into();
                                w.first_part = part.clone();
                            }
                        }
                    }
                    InvalidReason::Skating { skate } => {
                        w.reason = Reason::Skating.into();
                        let (quantity, value, limit) = match skate {
                            Skate::Slid { ratio, limit } => (SKATE_SLID, ratio, limit),
                            Skate::Shuffled { share, limit } => (SKATE_SHUFFLED, share, limit),
                        };
                        w.quantity = quantity.into();
                        w.value = *value;
                        w.limit = *limit;
                    }
                    InvalidReason::StartPoseContact { first, second } => {
                        w.reason = Reason::StartPoseContact.into();
                        w.first_part = first.clone();
                        w.second_part = second.clone();
                    }
                    InvalidReason::BlowUp { speed } => {
                        w.reason = Reason::BlowUp.into();
                        w.value = *speed;
                    }
                    InvalidReason::NoForwardProgress { distance } => {
                        w.reason = Reason::NoForwardProgress.into();
                        w.value = *distance;
                    }
                    InvalidReason::StepSensitive { substeps, verdict } => {
                        w.reason = Reason::StepSensitive.into();
                        w.value = f64::from(*substeps);
                        w.quantity = verdict.clone();
                    }
                    InvalidReason::FrictionSensitive { friction, verdict } => {
                        w.reason = Reason::FrictionSensitive.into();
                        w.value = *friction;
                        w.quantity = verdict.clone();
                    }
                    InvalidReason::EvaluationFailed { attempts, last } => {
                        w.reason = Reason::EvaluationFailed.into();
                        w.value = f64::from(*attempts);
                        w.quantity = last.clone();
                    }
                }
                v1::outcome::Kind::Invalid(w)
            }
        };
        v1::Outcome {
            kind: Some(kind),
            controller: o.controller().values().to_vec(),
        }
    }
}

impl TryFrom<&v1::Outcome> for Outcome {
    type Error = WireError;
    fn try_from(o: &v1::Outcome) -> Result<Self, WireError> {
        use v1::invalid::Reason;
        let controller = vector::<Controller>("outcome.controller", &o.controller)?;
        match o
            .kind
            .as_ref()
            .ok_or_else(|| wire_err("outcome.kind", "missing"))?
        {
            v1::outcome::Kind::Valid(v) => {
                let fitness = finite("outcome.valid.fitness", v.fitness)?;
                if fitness <= 0.0 {
                    return Err(wire_err(
                        "outcome.valid.fitness",
                        format!("{fitness} is not positive"),
                    ));
                }
                let stats = v
                    .stats
                    .as_ref()
                    .ok_or_else(|| wire_err("outcome.valid.stats", "missing"))?;
                if v.features.len() != FEATURE_COUNT {
                    return Err(wire_err(
                        "outcome.valid.features",
                        format!(
                            "expected {FEATURE_COUNT} values, found {}",
                            v.features.len()
                        ),
                    ));
                }
                let mut features = [0.0; FEATURE_COUNT];
                for (i, (slot, &x)) in features.iter_mut().zip(&v.features).enumerate() {
                    *slot = finite(format_args!("outcome.valid.features[{i}]"), x)?;
                }
                Ok(Outcome::Valid {
                    fitness,
                    stats: stats_from_wire("outcome.valid.stats", stats)?,
                    features: Features(features),
                    cell: CellIndex(v.cell),
                    controller,
                    outranked: v.outranked,
                })
            }
            v1::outcome::Kind::Rejected(r) => {
                let mut violations = Vec::with_capacity(r.violations.len());
                for (i, v) in r.violations.iter().enumerate() {
                    let field = format_args!("outcome.rejected.violations[{i}]");
                    let constraint = match v1::violation::Constraint::try_from(v.constraint) {
                        Ok(v1::violation::Constraint::Mass) => Constraint::Mass,
                        Ok(v1::violation::Constraint::Height) => Constraint::Height,
                        Ok(v1::violation::Constraint::Speed) => Constraint::Speed,
                        _ => {
                            return Err(wire_err(
                                format_args!("{field}.constraint"),
                                format!("{} is not a constraint", v.constraint),
                            ))
                        }
                    };
                    violations.push(Violation {
                        constraint,
                        value: finite(format_args!("{field}.value"), v.value)?,
                        limit: finite(format_args!("{field}.limit"), v.limit)?,
                    });
                }
                if violations.is_empty() {
                    return Err(wire_err(
                        "outcome.rejected.violations",
                        "empty: a rejection names its constraint",
                    ));
                }
                Ok(Outcome::Rejected {
                    violations,
                    stats: r
                        .stats
                        .as_ref()
                        .map(|s| stats_from_wire("outcome.rejected.stats", s))
                        .transpose()?,
                    controller,
                })
            }
            v1::outcome::Kind::Invalid(i) => {
                let reason = match Reason::try_from(i.reason) {
                    Ok(Reason::SelfContact) => InvalidReason::SelfContact {
                        first: i.first_part.clone(),
                        second: i.second_part.clone(),
                    },
                    Ok(Reason::NonFinite) => InvalidReason::NonFinite {
                        what: i.quantity.clone(),
                    },
                    Ok(Reason::Fell) => InvalidReason::Fell {
                        fall: match i.quantity.as_str() {
                            FALL_TILTED => Fall::Tilted {
                                degrees: finite("outcome.invalid.value", i.value)?,
                                limit: finite("outcome.invalid.limit", i.limit)?,
                            },
                            FALL_SANK => Fall::Sank {
                                height: finite("outcome.invalid.value", i.value)?,
                                limit: finite("outcome.invalid.limit", i.limit)?,
                            },
                            FALL_DRAGGED => Fall::Dragged {
                                part: i.first_part.clone(),
                            },
                            other => {
                                return Err(wire_err(
                                    "outcome.invalid.quantity",
                                    format!(
                                        "{other:?} is not a fall; expected {FALL_TILTED:?}, {FALL_SANK:?} or {FALL_DRAGGED:?}"
                                    ),
                                ))
                            }
                        },
                    },
                    Ok(Reason::Skating) => {
                        let value = finite("outcome.invalid.value", i.value)?;
                        let limit = finite("outcome.invalid.limit", i.limit)?;
                        InvalidReason::Skating {
                            skate: match i.quantity.as_str() {
                                SKATE_SLID => Skate::Slid {
                                    ratio: value,
                                    limit,
                                },
                                SKATE_SHUFFLED => Skate::Shuffled {
                                    share: value,
                                    limit,
                                },
                                other => {
                                    return Err(wire_err(
                                        "outcome.invalid.quantity",
                                        format!(
                                            "{other:?} is not a way of skating; expected {SKATE_SLID:?} or {SKATE_SHUFFLED:?}"
                                        ),
                                    ))
                                }
                            },
                        }
                    }
                    Ok(Reason::StartPoseContact) => InvalidReason::StartPoseContact {
                        first: i.first_part.clone(),
                        second: i.second_part.clone(),
                    },
                    Ok(Reason::BlowUp) => InvalidReason::BlowUp {
                        speed: finite("outcome.invalid.value", i.value)?,
                    },
                    Ok(Reason::NoForwardProgress) => InvalidReason::NoForwardProgress {
                        distance: finite("outcome.invalid.value", i.value)?,
                    },
                    Ok(Reason::StepSensitive) => {
                        let substeps = finite("outcome.invalid.value", i.value)?;
                        if !(1.0..=512.0).contains(&substeps) || substeps.fract() != 0.0 {
                            return Err(wire_err(
                                "outcome.invalid.value",
                                format!("{substeps} is not a number of physics steps per control step (1 to 512)"),
                            ));
                        }
                        InvalidReason::StepSensitive {
                            substeps: substeps as u32,
                            verdict: i.quantity.clone(),
                        }
                    }
                    Ok(Reason::FrictionSensitive) => {
                        let friction = finite("outcome.invalid.value", i.value)?;
                        if !(friction > 0.0 && friction <= 10.0) {
                            return Err(wire_err(
                                "outcome.invalid.value",
                                format!("{friction} is not a friction coefficient (above 0, at most 10)"),
                            ));
                        }
                        InvalidReason::FrictionSensitive {
                            friction,
                            verdict: i.quantity.clone(),
                        }
                    }
                    Ok(Reason::EvaluationFailed) => {
                        return Err(wire_err(
                            "outcome.invalid.reason",
                            "EVALUATION_FAILED is the coordinator's to set, not a worker's",
                        ))
                    }
                    _ => {
                        return Err(wire_err(
                            "outcome.invalid.reason",
                            format!("{} is not a reason", i.reason),
                        ))
                    }
                };
                Ok(Outcome::Invalid {
                    reason,
                    at_time: finite("outcome.invalid.at_time", i.at_time)?,
                    controller,
                })
            }
        }
    }
}
