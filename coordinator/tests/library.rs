//! The MAP-Elites library and breeding, on synthetic outcomes (no simulation needed).

use strider_common::brief::{Constraint, Violation};
use strider_common::ids::CandidateNumber;
use strider_common::initial_designs::InitialDesigns;
use strider_common::rng::CandidateSeed;
use strider_common::{
    CellIndex, Controller, Features, Genome, InvalidReason, MutationRates, Outcome, Scheme,
    TrialStats,
};
use strider_coordinator::qd::evolution::{initial_candidate, offspring, Parents};
use strider_coordinator::qd::library::{GenerationStats, Library, Placement};

fn genome(i: u64) -> Genome {
    initial_candidate(
        Scheme::Static,
        CandidateSeed::new(1, i),
        &InitialDesigns::None,
    )
}

fn valid(fitness: f64, cell: u32) -> Outcome {
    Outcome::Valid {
        fitness,
        stats: TrialStats {
            distance: 5.0,
            energy: 100.0,
            speed: 1.0,
            mass: 60.0,
            cost_of_transport: 1.0 / fitness,
            duration: 5.0,
            ..Default::default()
        },
        features: Features([2.4, 60.0, 3.0, 0.005, 0.0, 0.0]),
        cell: CellIndex(cell),
        controller: Controller::static_default(),
        outranked: false,
    }
}

fn rejected() -> Outcome {
    Outcome::Rejected {
        violations: vec![Violation {
            constraint: Constraint::Speed,
            value: 0.5,
            limit: 1.0,
        }],
        stats: None,
        controller: Controller::static_default(),
    }
}

fn invalid() -> Outcome {
    Outcome::Invalid {
        reason: InvalidReason::BlowUp { speed: 1e3 },
        at_time: 1.0,
        controller: Controller::static_default(),
    }
}

#[test]
fn a_result_fills_an_empty_cell_or_replaces_a_strictly_weaker_elite() {
    let mut lib = Library::new();
    let c = |i| CandidateNumber(i);
    assert_eq!(lib.apply(c(0), &genome(0), &valid(1.0, 7)), Placement::New);
    assert_eq!(
        lib.apply(c(1), &genome(1), &valid(1.0, 7)),
        Placement::Discarded,
        "a tie keeps the incumbent"
    );
    assert_eq!(
        lib.apply(c(2), &genome(2), &valid(0.5, 7)),
        Placement::Discarded
    );
    assert_eq!(
        lib.apply(c(3), &genome(3), &valid(2.0, 7)),
        Placement::Improved
    );
    assert_eq!(
        lib.apply(c(4), &genome(4), &rejected()),
        Placement::Rejected
    );
    assert_eq!(lib.apply(c(5), &genome(5), &invalid()), Placement::Invalid);
    assert_eq!(lib.len(), 1);
    let e = lib.get(CellIndex(7)).unwrap();
    assert_eq!((e.candidate, e.fitness), (c(3), 2.0));
    assert_eq!(e.genome.morphology, genome(3).morphology);
}

#[test]
fn the_elite_keeps_the_controller_that_earned_its_fitness() {
    let mut lib = Library::new();
    let mut tuned = Controller::static_default();
    tuned.set_clamped(strider_common::params::C::StrideFrequency, 3.0);
    let Outcome::Valid {
        fitness,
        stats,
        features,
        cell,
        ..
    } = valid(1.5, 3)
    else {
        unreachable!()
    };
    let outcome = Outcome::Valid {
        fitness,
        stats,
        features,
        cell,
        controller: tuned,
        outranked: false,
    };
    lib.apply(CandidateNumber(0), &genome(0), &outcome);
    assert_eq!(lib.get(CellIndex(3)).unwrap().genome.controller, tuned);
}

#[test]
fn generation_statistics() {
    let mut lib = Library::new();
    let genomes: Vec<Genome> = (0..6).map(genome).collect();
    let outcomes = [
        valid(1.0, 1),
        valid(3.0, 2),
        valid(2.0, 1),
        rejected(),
        invalid(),
        valid(0.5, 2),
    ];
    // As the scheduler applies a step: each result in candidate order, counted, then the
    // library's figures.
    let mut counts = GenerationStats::default();
    for i in 0..6 {
        counts.record(lib.apply(CandidateNumber(i as u64), &genomes[i], &outcomes[i]));
    }
    let stats = lib.summary(counts, 100);
    assert_eq!(
        stats,
        GenerationStats {
            coverage: 0.02,
            elites: 2,
            max_fitness: 3.0,
            mean_fitness: 2.5,
            min_fitness: 2.0,
            qd_score: 5.0,
            new: 2,
            improved: 1,
            discarded: 1,
            rejected: 1,
            invalid: 1,
            ..GenerationStats::default()
        }
    );
}

#[test]
fn offspring_are_reproducible_and_draw_parents_uniformly() {
    let rates = MutationRates::default();
    assert!(offspring(
        &Parents::Feasible(&Library::new()),
        Scheme::Static,
        &rates,
        CandidateSeed::new(1, 0)
    )
    .is_none());
    let mut lib = Library::new();
    for i in 0..4 {
        lib.apply(CandidateNumber(i), &genome(i), &valid(1.0, i as u32 * 10));
    }
    let seed = CandidateSeed::new(1, 500);
    assert_eq!(
        offspring(&Parents::Feasible(&lib), Scheme::Static, &rates, seed),
        offspring(&Parents::Feasible(&lib), Scheme::Static, &rates, seed)
    );
    // With every rate at 0 a STATIC child is its parent, which identifies the parent.
    let still = MutationRates::uniform(0.0);
    let mut counts = [0usize; 4];
    for n in 0..4000 {
        let child = offspring(
            &Parents::Feasible(&lib),
            Scheme::Static,
            &still,
            CandidateSeed::new(1, 1000 + n),
        )
        .unwrap();
        let parent = (0..4)
            .position(|i| genome(i).morphology == child.morphology)
            .unwrap();
        counts[parent] += 1;
    }
    // Binomial(4000, 1/4): mean 1000, sd 27; +-150 is over 5 sd.
    assert!(
        counts.iter().all(|&c| (850..=1150).contains(&c)),
        "{counts:?}"
    );
}

#[test]
fn genome_scheme_offspring_evolve_their_controller() {
    let mut lib = Library::new();
    let parent = initial_candidate(
        Scheme::Genome,
        CandidateSeed::new(2, 0),
        &InitialDesigns::None,
    );
    let Outcome::Valid {
        fitness,
        stats,
        features,
        cell,
        ..
    } = valid(1.0, 0)
    else {
        unreachable!()
    };
    lib.apply(
        CandidateNumber(0),
        &parent,
        &Outcome::Valid {
            fitness,
            stats,
            features,
            cell,
            controller: parent.controller,
            outranked: false,
        },
    );
    let rates = MutationRates::default();
    let child = offspring(
        &Parents::Feasible(&lib),
        Scheme::Genome,
        &rates,
        CandidateSeed::new(2, 1),
    )
    .unwrap();
    assert_ne!(child.controller, parent.controller);
    let child = offspring(
        &Parents::Feasible(&lib),
        Scheme::Static,
        &rates,
        CandidateSeed::new(2, 1),
    )
    .unwrap();
    assert_eq!(child.controller, parent.controller);
}

#[test]
fn every_placement_has_one_stored_name_and_other_text_names_none() {
    use strider_coordinator::qd::library::CellChange;
    for p in Placement::ALL {
        assert_eq!(Placement::named(p.name()), Some(p));
    }
    let names: std::collections::HashSet<_> = Placement::ALL.iter().map(|p| p.name()).collect();
    assert_eq!(names.len(), Placement::ALL.len());
    assert_eq!(Placement::named("bogus"), None);
    assert_eq!(Placement::named("Invalid"), None);
    assert_eq!(CellChange::named("rejected"), None);
}
