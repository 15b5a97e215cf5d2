//! Parents for feasible-infeasible search: drawn from the feasible library with the share
//! the experiment sets (all of them while the infeasible library is empty, none while the
//! feasible one is), uniformly within a library, reproducibly from the candidate's stream.

use strider_common::rng::{CandidateNumber, CandidateSeed, Purpose};
use strider_common::{CellIndex, Genome, Scheme, Shortfall, Standing};
use strider_coordinator::evolution::{Parents, Source};
use strider_coordinator::library::{Elite, InfeasibleElite, InfeasibleLibrary, Library};

fn genome(k: u64) -> Genome {
    Genome::random(
        Scheme::Static,
        &mut CandidateSeed::new(99, k).rng(Purpose::RandomGenome),
    )
}

fn libraries(feasible: u32, infeasible: u32) -> (Library, InfeasibleLibrary) {
    let mut f = Library::new();
    for c in 0..feasible {
        f.restore(
            CellIndex(c),
            Elite {
                candidate: CandidateNumber(u64::from(c)),
                genome: genome(u64::from(c)),
                fitness: 1.0,
            },
        );
    }
    let mut i = InfeasibleLibrary::default();
    for c in 0..infeasible {
        i.restore(
            CellIndex(1000 + c),
            InfeasibleElite {
                candidate: CandidateNumber(1000 + u64::from(c)),
                genome: genome(1000 + u64::from(c)),
                standing: Standing::TooSlow { speed: 0.5 },
                shortfall: Shortfall::Speed,
            },
        );
    }
    (f, i)
}

/// Share of `draws` parents that came from the feasible library.
fn feasible_share(parents: &Parents<'_>, draws: u64) -> f64 {
    let feasible = (0..draws)
        .filter(|&n| {
            let mut rng = CandidateSeed::new(7, n).rng(Purpose::Reproduction);
            parents.draw(&mut rng).unwrap().0 == Source::Feasible
        })
        .count();
    feasible as f64 / draws as f64
}

#[test]
fn parents_come_from_each_library_in_the_set_share() {
    let (f, i) = libraries(30, 50);
    for share in [0.5, 0.2, 0.9] {
        let got = feasible_share(
            &Parents::Both {
                feasible: &f,
                infeasible: &i,
                share,
            },
            20_000,
        );
        // Binomial sd at 20,000 draws is at most 0.0036: five of them.
        assert!((got - share).abs() < 0.018, "share {share}: drew {got}");
    }
}

#[test]
fn an_empty_library_gives_no_parents_and_the_other_gives_all() {
    let (f, empty_i) = libraries(30, 0);
    let all_feasible = Parents::Both {
        feasible: &f,
        infeasible: &empty_i,
        share: 0.5,
    };
    assert_eq!(feasible_share(&all_feasible, 2000), 1.0);
    let (empty_f, i) = libraries(0, 40);
    let all_infeasible = Parents::Both {
        feasible: &empty_f,
        infeasible: &i,
        share: 0.5,
    };
    assert_eq!(feasible_share(&all_infeasible, 2000), 0.0);
    let (none_f, none_i) = libraries(0, 0);
    let nothing = Parents::Both {
        feasible: &none_f,
        infeasible: &none_i,
        share: 0.5,
    };
    let mut rng = CandidateSeed::new(7, 0).rng(Purpose::Reproduction);
    assert!(nothing.draw(&mut rng).is_none());
}

#[test]
fn every_elite_of_a_library_can_be_drawn() {
    let (f, i) = libraries(5, 7);
    let parents = Parents::Both {
        feasible: &f,
        infeasible: &i,
        share: 0.5,
    };
    let mut seen = std::collections::HashSet::new();
    for n in 0..5000 {
        let mut rng = CandidateSeed::new(3, n).rng(Purpose::Reproduction);
        let (_, g) = parents.draw(&mut rng).unwrap();
        seen.insert(serde_json::to_string(&g).unwrap());
    }
    assert_eq!(seen.len(), 12);
}
