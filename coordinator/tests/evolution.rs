//! Parents for feasible-infeasible search: drawn from the feasible library with the share
//! the experiment sets (all of them while the infeasible library is empty, none while the
//! feasible one is), uniformly within the feasible library and by tournament on closeness
//! to the brief within the infeasible one, reproducibly from the candidate's stream.

use strider_common::ids::CandidateNumber;
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::{CellIndex, Genome, Scheme, Shortfall, Standing};
use strider_coordinator::qd::evolution::{Parents, Source};
use strider_coordinator::qd::library::{Elite, InfeasibleElite, InfeasibleLibrary, Library};

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
                tournament: 4,
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
        tournament: 4,
    };
    assert_eq!(feasible_share(&all_feasible, 2000), 1.0);
    let (empty_f, i) = libraries(0, 40);
    let all_infeasible = Parents::Both {
        feasible: &empty_f,
        infeasible: &i,
        share: 0.5,
        tournament: 4,
    };
    assert_eq!(feasible_share(&all_infeasible, 2000), 0.0);
    let (none_f, none_i) = libraries(0, 0);
    let nothing = Parents::Both {
        feasible: &none_f,
        infeasible: &none_i,
        share: 0.5,
        tournament: 4,
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
        tournament: 4,
    };
    let mut seen = std::collections::HashSet::new();
    for n in 0..5000 {
        let mut rng = CandidateSeed::new(3, n).rng(Purpose::Reproduction);
        let (_, g) = parents.draw(&mut rng).unwrap();
        seen.insert(serde_json::to_string(&g).unwrap());
    }
    assert_eq!(seen.len(), 12);
}

/// An infeasible library of `n` designs in cells 0..n, design `c` walking at `c / n` m/s
/// (the nearest the brief in the highest cell).
fn graded_infeasible(n: u32) -> InfeasibleLibrary {
    let mut i = InfeasibleLibrary::default();
    for c in 0..n {
        i.restore(
            CellIndex(c),
            InfeasibleElite {
                candidate: CandidateNumber(u64::from(c)),
                genome: genome(u64::from(c)),
                standing: Standing::TooSlow {
                    speed: f64::from(c) / f64::from(n),
                },
                shortfall: Shortfall::Speed,
            },
        );
    }
    i
}

/// The cells of `draws` infeasible parents (the libraries of `graded_infeasible`).
fn drawn_cells(infeasible: &InfeasibleLibrary, tournament: u32, draws: u64) -> Vec<u32> {
    let by_genome: std::collections::HashMap<String, u32> = infeasible
        .elites()
        .map(|(c, e)| (serde_json::to_string(&e.genome).unwrap(), c.0))
        .collect();
    let feasible = Library::new();
    let parents = Parents::Both {
        feasible: &feasible,
        infeasible,
        share: 0.5,
        tournament,
    };
    (0..draws)
        .map(|n| {
            let mut rng = CandidateSeed::new(11, n).rng(Purpose::Reproduction);
            let (source, g) = parents.draw(&mut rng).unwrap();
            assert_eq!(source, Source::Infeasible);
            by_genome[&serde_json::to_string(&g).unwrap()]
        })
        .collect()
}

#[test]
fn infeasible_parents_are_won_by_the_design_nearest_the_brief() {
    let n = 100;
    let infeasible = graded_infeasible(n);
    let draws = 20_000;
    // The winner of k uniform draws is in the top quarter with probability 1 - (3/4)^k:
    // 0.25 (uniform), 0.4375, 0.684, 0.900. Binomial sd at 20,000 draws <= 0.0036.
    for (k, expected) in [(1, 0.25), (2, 0.4375), (4, 0.6836), (8, 0.8999)] {
        let cells = drawn_cells(&infeasible, k, draws);
        let top = cells.iter().filter(|&&c| c >= 3 * n / 4).count() as f64 / draws as f64;
        assert!(
            (top - expected).abs() < 0.018,
            "tournament {k}: {top} of parents from the top quarter, expected {expected}"
        );
    }
    // Even the farthest design can win a tournament of 2 (when drawn twice).
    assert!(drawn_cells(&infeasible, 2, draws).contains(&0));
}

#[test]
fn a_tournament_of_one_draws_exactly_as_uniform_selection_did() {
    // Databases made before tournaments store `infeasible_tournament = 1` and must resume
    // with the very parents they would have drawn: one library draw, one uniform index.
    let infeasible = graded_infeasible(37);
    let cells = drawn_cells(&infeasible, 1, 500);
    for (n, cell) in cells.into_iter().enumerate() {
        let mut rng = CandidateSeed::new(11, n as u64).rng(Purpose::Reproduction);
        let _library: f64 = rand::Rng::random(&mut rng);
        let index = rand::Rng::random_range(&mut rng, 0..37usize);
        assert_eq!(cell, index as u32, "draw {n}");
    }
}

#[test]
fn equal_standings_are_drawn_uniformly() {
    // Equal standings: a tournament changes nothing, so it draws uniformly.
    let mut i = InfeasibleLibrary::default();
    for c in 0..10 {
        i.restore(
            CellIndex(c),
            InfeasibleElite {
                candidate: CandidateNumber(u64::from(c)),
                genome: genome(u64::from(c)),
                standing: Standing::EndedEarly { at_time: 2.0 },
                shortfall: Shortfall::Fell,
            },
        );
    }
    let draws = 20_000;
    let cells = drawn_cells(&i, 4, draws);
    for c in 0..10 {
        let share = cells.iter().filter(|&&x| x == c).count() as f64 / draws as f64;
        assert!((share - 0.1).abs() < 0.012, "cell {c}: {share}");
    }
}
