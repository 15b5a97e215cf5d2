//! Wire conversions: exact round trips, and malformed messages refused by field name.

use prost::Message;
use strider_common::brief::{Constraint, Violation};
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::{
    CellIndex, Controller, Features, Genome, InvalidReason, Outcome, Scheme, TrialStats,
};
use strider_proto::convert::{scheme_from_wire, scheme_to_wire};
use strider_proto::v1;

fn genome(i: u64) -> Genome {
    Genome::random(
        Scheme::Genome,
        &mut CandidateSeed::new(3, i).rng(Purpose::RandomGenome),
    )
}

/// Encodes to protobuf bytes and back, as the network would.
fn through_the_wire<M: Message + Default>(m: &M) -> M {
    M::decode(m.encode_to_vec().as_slice()).unwrap()
}

fn stats() -> TrialStats {
    TrialStats {
        distance: 5.5,
        energy: 1234.5,
        speed: 1.1,
        mass: 61.2,
        cost_of_transport: 0.37,
        duration: 5.0,
        gait: strider_common::GaitStats {
            peak_torque_ratio: 0.97,
            foot_slip: 0.12,
            low_forward_share: 0.3,
            duty_factor: 0.55,
        },
    }
}

fn outcomes() -> Vec<Outcome> {
    let c = genome(9).controller;
    vec![
        Outcome::Valid {
            fitness: 2.7,
            stats: stats(),
            features: Features([2.3, 61.2, 3.0, 0.004, 0.1, -0.05]),
            cell: CellIndex(777),
            controller: c,
            outranked: false,
        },
        Outcome::Valid {
            fitness: 1.3,
            stats: stats(),
            features: Features([2.3, 61.2, 3.0, 0.004, 0.1, -0.05]),
            cell: CellIndex(777),
            controller: c,
            outranked: true,
        },
        Outcome::Rejected {
            violations: vec![
                Violation {
                    constraint: Constraint::Height,
                    value: 1.8,
                    limit: 2.0,
                },
                Violation {
                    constraint: Constraint::Mass,
                    value: 65.0,
                    limit: 60.0,
                },
            ],
            stats: None,
            controller: c,
        },
        Outcome::Rejected {
            violations: vec![Violation {
                constraint: Constraint::Speed,
                value: 0.6,
                limit: 1.0,
            }],
            stats: Some(stats()),
            controller: c,
        },
        Outcome::Invalid {
            reason: InvalidReason::SelfContact {
                first: "left leg 0 link 2".into(),
                second: "left leg 1 link 2".into(),
            },
            at_time: 0.3,
            controller: c,
        },
        Outcome::Invalid {
            reason: InvalidReason::NonFinite {
                what: "energy".into(),
            },
            at_time: 1.0,
            controller: c,
        },
        Outcome::Invalid {
            reason: InvalidReason::BlowUp { speed: 123.0 },
            at_time: 2.0,
            controller: c,
        },
        Outcome::Invalid {
            reason: InvalidReason::NoForwardProgress { distance: -0.2 },
            at_time: 5.0,
            controller: Controller::static_default(),
        },
        Outcome::Invalid {
            reason: InvalidReason::Skating {
                skate: strider_common::Skate::Slid {
                    ratio: 0.73,
                    limit: 0.5,
                },
            },
            at_time: 5.0,
            controller: c,
        },
        Outcome::Invalid {
            reason: InvalidReason::Skating {
                skate: strider_common::Skate::Shuffled {
                    share: 0.55,
                    limit: 0.4,
                },
            },
            at_time: 5.0,
            controller: c,
        },
        Outcome::Invalid {
            reason: InvalidReason::FrictionSensitive {
                friction: 1.0000000000000002,
                verdict: "fell: body tilted 20.0 degrees (limit 20.0)".into(),
            },
            at_time: 16.4,
            controller: c,
        },
        // Last: the refusal test below takes it.
        Outcome::Invalid {
            reason: InvalidReason::StepSensitive {
                substeps: 16,
                verdict: "fell: body tilted 20.1 degrees (limit 20.0)".into(),
            },
            at_time: 6.685,
            controller: c,
        },
    ]
}

#[test]
fn genomes_round_trip_bit_exactly() {
    for i in 0..50 {
        let g = genome(i);
        let wire = through_the_wire(&v1::Genome::from(&g));
        assert_eq!(wire.morphology.len(), 43);
        assert_eq!(wire.controller.len(), 7);
        assert_eq!(Genome::try_from(&wire).unwrap(), g);
    }
}

#[test]
fn outcomes_round_trip() {
    for o in outcomes() {
        let wire = through_the_wire(&v1::Outcome::from(&o));
        assert_eq!(Outcome::try_from(&wire).unwrap(), o);
    }
}

#[test]
fn schemes_round_trip_and_unknown_ones_are_refused() {
    for s in Scheme::ALL {
        assert_eq!(scheme_from_wire(scheme_to_wire(s).into()).unwrap(), s);
    }
    let e = scheme_from_wire(0).unwrap_err().to_string();
    assert_eq!(e, "scheme: 0 is not a scheme");
    assert!(scheme_from_wire(42).is_err());
}

#[test]
fn a_genome_of_the_wrong_size_is_refused_by_field() {
    let mut wire = v1::Genome::from(&genome(1));
    wire.morphology.pop();
    let e = Genome::try_from(&wire).unwrap_err().to_string();
    assert_eq!(e, "genome.morphology: expected 43 values, found 42");
}

#[test]
fn a_genome_value_out_of_range_or_nan_is_refused_by_name() {
    let mut wire = v1::Genome::from(&genome(1));
    wire.morphology[5] = 9.0; // legs_per_side
    let e = Genome::try_from(&wire).unwrap_err().to_string();
    assert!(
        e.starts_with(
            "genome.morphology: parameter `legs_per_side` = 9 is outside its range [2, 6]"
        ),
        "{e}"
    );
    let mut wire = v1::Genome::from(&genome(1));
    wire.controller[0] = f64::NAN;
    let e = Genome::try_from(&wire).unwrap_err().to_string();
    assert!(
        e.contains("genome.controller: parameter `stride_frequency` is NaN"),
        "{e}"
    );
}

#[test]
fn a_nan_fitness_or_malformed_outcome_is_refused_by_field() {
    let valid = v1::Outcome::from(&outcomes()[0]);
    let mut bad = valid.clone();
    if let Some(v1::outcome::Kind::Valid(v)) = bad.kind.as_mut() {
        v.fitness = f64::NAN;
    }
    assert_eq!(
        Outcome::try_from(&bad).unwrap_err().to_string(),
        "outcome.valid.fitness: NaN is not a finite number"
    );
    let mut bad = valid.clone();
    if let Some(v1::outcome::Kind::Valid(v)) = bad.kind.as_mut() {
        v.features.push(1.0);
    }
    assert_eq!(
        Outcome::try_from(&bad).unwrap_err().to_string(),
        "outcome.valid.features: expected 6 values, found 7"
    );
    let mut bad = valid.clone();
    if let Some(v1::outcome::Kind::Valid(v)) = bad.kind.as_mut() {
        v.stats.as_mut().unwrap().energy = f64::INFINITY;
    }
    assert_eq!(
        Outcome::try_from(&bad).unwrap_err().to_string(),
        "outcome.valid.stats.energy: inf is not a finite number"
    );
    let mut bad = valid.clone();
    bad.kind = None;
    assert_eq!(
        Outcome::try_from(&bad).unwrap_err().to_string(),
        "outcome.kind: missing"
    );
    let mut bad = valid;
    bad.controller.clear();
    assert_eq!(
        Outcome::try_from(&bad).unwrap_err().to_string(),
        "outcome.controller: expected 7 values, found 0"
    );
    let step_sensitive = outcomes().pop().unwrap();
    assert!(matches!(
        step_sensitive,
        strider_common::Outcome::Invalid {
            reason: InvalidReason::StepSensitive { .. },
            ..
        }
    ));
    let mut bad = v1::Outcome::from(&step_sensitive);
    if let Some(v1::outcome::Kind::Invalid(i)) = bad.kind.as_mut() {
        i.value = 2.5;
    }
    assert_eq!(
        Outcome::try_from(&bad).unwrap_err().to_string(),
        "outcome.invalid.value: 2.5 is not a number of physics steps per control step (1 to 512)"
    );
    let mut bad = v1::Outcome::from(&step_sensitive);
    if let Some(v1::outcome::Kind::Invalid(i)) = bad.kind.as_mut() {
        i.reason = v1::invalid::Reason::FrictionSensitive.into();
        i.value = 0.0;
    }
    assert_eq!(
        Outcome::try_from(&bad).unwrap_err().to_string(),
        "outcome.invalid.value: 0 is not a friction coefficient (above 0, at most 10)"
    );
}
