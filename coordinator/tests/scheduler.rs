//! The scheduler's rules, without a network or a database: results in any order, from any
//! number of workers, lost leases and duplicates all give the same libraries; a candidate
//! that keeps losing its lease fails and its generation goes on.

use std::time::{Duration, Instant};
use strider_common::ids::CandidateNumber;
use strider_common::rng::CandidateSeed;
use strider_common::EvalContext;
use strider_common::{
    CandidateKey, Controller, Experiment, Genome, InvalidReason, Outcome, Scheme,
};
use strider_common::{RunId, WorkerId};
use strider_coordinator::qd::changes::Write;
use strider_coordinator::qd::library::{InfeasibleLibrary, Library, Placement};
use strider_coordinator::qd::run::RunRecord;
use strider_coordinator::qd::scheduler::{
    fair_share, fraction_done, Accepted, Assignment, Refusal, RunProgress, Scheduler,
};
use strider_worker::synthetic::instant_outcome;

const EXPERIMENT: &str = r#"
name = "scheduler"
schemes = ["static", "genome"]
repeats = 1
seed = 5
[run]
initial_population = 6
offspring_per_generation = 10
generations = 5
"#;

const LEASE: Duration = Duration::from_secs(10);

fn experiment() -> Experiment {
    Experiment::from_toml(EXPERIMENT).unwrap()
}

fn fresh(e: &Experiment, max_attempts: u32) -> Scheduler {
    let runs = e
        .runs()
        .into_iter()
        .enumerate()
        .map(|(i, spec)| RunRecord::new(RunId::from_index(i), spec))
        .collect();
    Scheduler::new(e.clone(), runs, Vec::new(), LEASE, max_attempts)
}

/// The made-up but deterministic outcome a benchmark worker would send.
fn outcome_of(e: &Experiment, a: &Assignment) -> Outcome {
    instant_outcome(
        &EvalContext::of(e),
        &a.genome,
        a.scheme,
        CandidateSeed::new(a.run_seed.0, a.key.number.0),
        a.to_beat,
    )
}

/// Runs to the end with `workers` workers each holding up to `slots`, answering in the
/// order `reorder` gives; returns every run's libraries.
fn drive(
    workers: u64,
    slots: usize,
    reorder: impl Fn(&mut Vec<(WorkerId, Assignment)>),
) -> Vec<(Library, InfeasibleLibrary)> {
    drive_experiment(&experiment(), workers, slots, reorder).0
}

/// [`drive`] for any experiment; also returns the scheduler at the end.
fn drive_experiment(
    e: &Experiment,
    workers: u64,
    slots: usize,
    reorder: impl Fn(&mut Vec<(WorkerId, Assignment)>),
) -> (Vec<(Library, InfeasibleLibrary)>, Scheduler) {
    let e = e.clone();
    let mut s = fresh(&e, 3);
    let now = Instant::now();
    let mut rounds = 0;
    while !s.finished() {
        rounds += 1;
        assert!(rounds < 100_000, "no progress");
        let mut held = Vec::new();
        for w in 0..workers {
            for a in s.lease(WorkerId(w), now, slots) {
                held.push((WorkerId(w), a));
            }
        }
        reorder(&mut held);
        for (w, a) in held {
            let o = outcome_of(&e, &a);
            s.accept(w, a.key, o, 0.0).unwrap();
        }
    }
    let libraries = (0..e.runs().len())
        .map(|i| {
            let r = s.run(RunId::from_index(i)).unwrap();
            (r.library.clone(), r.infeasible.clone())
        })
        .collect();
    (libraries, s)
}

#[test]
fn libraries_do_not_depend_on_workers_or_the_order_results_arrive() {
    let reference = drive(1, 1, |_| {});
    // Both libraries fill (the synthetic outcomes are a third feasible).
    assert!(reference.iter().all(|(l, i)| l.len() >= 3 && i.len() >= 3));
    assert_eq!(drive(3, 4, |h| h.reverse()), reference);
    assert_eq!(
        drive(2, 7, |h| {
            // A fixed shuffle.
            let n = h.len();
            for i in 0..n {
                h.swap(i, (i * 7 + 3) % n);
            }
        }),
        reference
    );
    assert_eq!(drive(5, 64, |_| {}), reference);
}

#[test]
fn a_result_that_comes_twice_is_applied_once() {
    let e = experiment();
    let mut s = fresh(&e, 3);
    let now = Instant::now();
    let a = s.lease(WorkerId(1), now, 1).pop().unwrap();
    let o = outcome_of(&e, &a);
    assert_eq!(
        s.accept(WorkerId(1), a.key, o.clone(), 0.0),
        Ok(Accepted::Stored)
    );
    assert_eq!(
        s.accept(WorkerId(1), a.key, o, 0.0),
        Ok(Accepted::Duplicate)
    );
    let stored = s
        .take_writes()
        .iter()
        .filter(|w| matches!(w, Write::Resolved { .. }))
        .count();
    assert_eq!(stored, 1);
}

#[test]
fn unknown_candidates_and_runs_are_refused() {
    let e = experiment();
    let mut s = fresh(&e, 3);
    let now = Instant::now();
    let a = s.lease(WorkerId(1), now, 1).pop().unwrap();
    let o = outcome_of(&e, &a);
    let far = CandidateKey {
        number: CandidateNumber(1_000_000),
        ..a.key
    };
    assert_eq!(
        s.accept(WorkerId(1), far, o.clone(), 0.0),
        Err(Refusal::Unknown(far))
    );
    let no_run = CandidateKey {
        run: RunId(7),
        ..a.key
    };
    assert_eq!(
        s.accept(WorkerId(1), no_run, o, 0.0),
        Err(Refusal::NoSuchRun(RunId(7)))
    );
}

#[test]
fn a_valid_outcome_in_a_cell_its_features_do_not_fall_in_is_refused_and_changes_nothing() {
    let e = experiment();
    let mut s = fresh(&e, 3);
    let now = Instant::now();
    let (a, good) = std::iter::from_fn(|| s.lease(WorkerId(1), now, 1).pop())
        .take(10_000)
        .map(|a| {
            let o = outcome_of(&e, &a);
            (a, o)
        })
        .find(|(_, o)| matches!(o, Outcome::Valid { .. }))
        .expect("a valid design among the first leases");
    let mut bad = good.clone();
    let Outcome::Valid { cell, .. } = &mut bad else {
        unreachable!()
    };
    let right = *cell;
    cell.0 = (right.0 + 1) % e.features.cell_count();
    assert_eq!(
        s.accept(WorkerId(1), a.key, bad, 0.0),
        Err(Refusal::CellMismatch {
            stated: (right.0 + 1) % e.features.cell_count(),
            expected: Some(right.0),
        })
    );
    // Still leased and unanswered: the true result is taken as the first.
    assert!(!s.answered(a.key));
    assert_eq!(
        s.accept(WorkerId(1), a.key, good, 0.0),
        Ok(Accepted::Stored)
    );
}

#[test]
fn an_offspring_is_drawn_with_its_cells_elite_as_the_bar_and_outranked_only_below_it() {
    let e = experiment();
    let mut s = fresh(&e, 3);
    let now = Instant::now();
    // The initial population has no bar: its library grows as it is applied.
    let mut a = s.lease(WorkerId(0), now, 1).pop().unwrap();
    while a.key.generation == 0 {
        assert_eq!(a.to_beat, None);
        let o = outcome_of(&e, &a);
        s.accept(WorkerId(0), a.key, o, 0.0).unwrap();
        a = s.lease(WorkerId(0), now, 1).pop().unwrap();
    }
    // Every offspring's bar is the elite its cell holds as the generation is drawn.
    let mut held = vec![a];
    held.extend(s.lease(WorkerId(0), now, 100));
    let run_of = |a: &Assignment| s.run(a.key.run).unwrap().library.clone();
    let ctx = EvalContext::of(&e);
    let mut barred = None;
    for a in held.iter().filter(|a| a.key.generation > 0) {
        let cell = strider_coordinator::qd::scheduler::cell_of(&ctx, &a.genome);
        let elite = run_of(a).get(cell).map(|x| x.fitness);
        assert_eq!(a.to_beat, elite, "{:?}", a.key);
        if barred.is_none() && elite.is_some() {
            barred = Some(a.clone());
        }
    }
    let a = barred.expect("an offspring drawn into an occupied cell");
    let bar = a.to_beat.unwrap();
    let outranked = |fitness: f64| {
        let mut o = outcome_valid(&e, &a);
        if let Outcome::Valid {
            fitness: f,
            outranked: m,
            ..
        } = &mut o
        {
            (*f, *m) = (fitness, true);
        }
        o
    };
    // Above the bar, its confirming trials were owed: refused, and still unanswered.
    let above = bar * (1.0 + 1e-9);
    assert_eq!(
        s.accept(WorkerId(0), a.key, outranked(above), 0.0),
        Err(Refusal::NotOutranked {
            fitness: above,
            to_beat: Some(bar),
        })
    );
    assert!(!s.answered(a.key));
    // At the bar it is taken, and never placed.
    assert_eq!(
        s.accept(WorkerId(0), a.key, outranked(bar), 0.0),
        Ok(Accepted::Stored)
    );
    for b in held.iter().filter(|b| b.key != a.key) {
        let o = outcome_of(&e, b);
        s.accept(WorkerId(0), b.key, o, 0.0).unwrap();
    }
    let placed = s
        .take_writes()
        .into_iter()
        .flat_map(|w| match w {
            Write::Step(step) if step.run == a.key.run => step.candidates,
            _ => Vec::new(),
        })
        .find(|c| c.number == a.key.number)
        .expect("the generation was applied");
    assert_eq!(placed.placement, Placement::Discarded);
}

/// A valid outcome for `a`'s design (made up, in its true cell).
fn outcome_valid(e: &Experiment, a: &Assignment) -> Outcome {
    match outcome_of(e, a) {
        v @ Outcome::Valid { .. } => v,
        _ => {
            let ctx = EvalContext::of(e);
            let cell = strider_coordinator::qd::scheduler::cell_of(&ctx, &a.genome);
            let plan = strider_common::BodyPlan::new(&a.genome.morphology, ctx.brief.payload);
            Outcome::Valid {
                fitness: 1.0,
                stats: strider_common::TrialStats::default(),
                features: strider_common::Features::of(&a.genome.morphology, &plan),
                cell,
                controller: a.genome.controller,
                outranked: false,
            }
        }
    }
}

#[test]
fn expired_leases_are_handed_out_again_and_late_results_change_nothing() {
    let e = experiment();
    let mut s = fresh(&e, 3);
    let t0 = Instant::now();
    let first = s.lease(WorkerId(1), t0, 1).pop().unwrap();
    // Nothing has expired yet: worker 2 gets something else.
    assert_ne!(s.lease(WorkerId(2), t0, 1).pop().unwrap().key, first.key);
    // Worker 1 stops answering; its lease runs out.
    let later = t0 + LEASE + Duration::from_secs(1);
    assert!(s.expire(later) >= 1);
    let again = s.lease(WorkerId(3), later, 1).pop().unwrap();
    assert_eq!(
        again.key, first.key,
        "the lowest waiting candidate goes first"
    );
    let o = outcome_of(&e, &again);
    assert_eq!(
        s.accept(WorkerId(3), again.key, o.clone(), 0.0),
        Ok(Accepted::Stored)
    );
    // Worker 1 wakes up and sends the same result: ignored.
    assert_eq!(
        s.accept(WorkerId(1), first.key, o, 0.0),
        Ok(Accepted::Duplicate)
    );
}

#[test]
fn heartbeats_keep_long_trials_leased() {
    let e = experiment();
    let mut s = fresh(&e, 3);
    let t0 = Instant::now();
    let a = s.lease(WorkerId(1), t0, 1).pop().unwrap();
    let t1 = t0 + LEASE - Duration::from_secs(1);
    s.heartbeat(WorkerId(1), &[a.key], t1);
    assert_eq!(s.expire(t0 + LEASE + Duration::from_secs(1)), 0);
    assert_eq!(s.expire(t1 + LEASE + Duration::from_secs(1)), 1);
}

#[test]
fn a_candidate_that_keeps_killing_workers_fails_and_its_generation_goes_on() {
    let e = experiment();
    let mut s = fresh(&e, 2);
    let now = Instant::now();
    // Finish the initial population of both runs.
    while s.progress().iter().any(|p| p.initial_passed < 6) {
        for a in s.lease(WorkerId(0), now, 8) {
            let o = outcome_of(&e, &a);
            s.accept(WorkerId(0), a.key, o, 0.0).unwrap();
        }
    }
    // The next candidate of generation 1 kills every worker that takes it.
    let victim = loop {
        let a = s.lease(WorkerId(0), now, 1).pop().unwrap();
        if a.key.generation == 1 {
            break a;
        }
        let o = outcome_of(&e, &a);
        s.accept(WorkerId(0), a.key, o, 0.0).unwrap();
    };
    s.started(WorkerId(0), &[victim.key]);
    s.disconnect(WorkerId(0), "connection lost");
    let again = s.lease(WorkerId(1), now, 100);
    assert!(again.iter().any(|a| a.key == victim.key));
    s.started(WorkerId(1), &[victim.key]);
    s.disconnect(WorkerId(1), "connection lost");
    s.take_writes();
    // Two lost leases (the limit here): failed, with the reason, and never leased again.
    while !s.finished() {
        for a in s.lease(WorkerId(2), now, 8) {
            assert_ne!(a.key, victim.key);
            let o = outcome_of(&e, &a);
            s.accept(WorkerId(2), a.key, o, 0.0).unwrap();
        }
        let writes = s.take_writes();
        for w in writes {
            if let Write::Step(step) = w {
                for c in &step.candidates {
                    if c.number == victim.key.number && step.run == victim.key.run {
                        match &c.outcome {
                            Outcome::Invalid {
                                reason: InvalidReason::EvaluationFailed { attempts, last },
                                ..
                            } => {
                                assert_eq!(*attempts, 2);
                                assert!(last.contains("connection lost"), "{last}");
                            }
                            other => panic!("the victim was applied as {other:?}"),
                        }
                    }
                }
            }
        }
    }
    assert!(s.progress().iter().all(|p| p.generation == 5));
}

#[test]
fn a_late_result_for_an_unneeded_initial_draw_is_not_taken_for_an_offspring() {
    let e = experiment();
    let mut s = fresh(&e, 3);
    let now = Instant::now();
    // More draws of run 0 than its population needs (every trial passes here).
    let draws: Vec<Assignment> = s
        .lease(WorkerId(0), now, 40)
        .into_iter()
        .filter(|a| a.key.run == RunId(0))
        .collect();
    assert!(draws.len() > 10);
    let mut spare = Vec::new();
    for a in draws {
        if s.progress()[0].initial_passed < 6 {
            s.accept(WorkerId(0), a.key, outcome_of(&e, &a), 0.0)
                .unwrap();
        } else {
            spare.push(a);
        }
    }
    assert_eq!(s.progress()[0].generation, 0);
    assert!(!spare.is_empty());
    // Generation 1 reuses the spare draws' numbers.
    let offspring: Vec<Assignment> = s
        .lease(WorkerId(1), now, 100)
        .into_iter()
        .filter(|a| a.key.run == RunId(0))
        .collect();
    assert!(offspring.iter().all(|a| a.key.generation == 1));
    assert!(offspring
        .iter()
        .any(|o| spare.iter().any(|a| a.key.number == o.key.number)));
    // The spare draws' late results are ignored...
    for a in &spare {
        assert_eq!(
            s.accept(WorkerId(0), a.key, outcome_of(&e, a), 0.0),
            Ok(Accepted::Duplicate)
        );
    }
    // ...so every offspring still takes its own.
    for a in &offspring {
        assert_eq!(
            s.accept(WorkerId(1), a.key, outcome_of(&e, a), 0.0),
            Ok(Accepted::Stored)
        );
    }
}

#[test]
fn the_initial_population_is_the_first_designs_that_pass_the_checks_before_simulating() {
    // Feasible-infeasible search: the first `initial_population` designs that pass mass,
    // height and start-pose checks are simulated and placed, whatever their trials show.
    let e = experiment();
    let (_, s) = drive_experiment(&e, 2, 3, |_| {});
    for i in 0..2 {
        let r = s.run(RunId(i)).unwrap();
        assert_eq!(r.initial_passed, e.run.initial_population);
    }
}

#[test]
fn an_experiments_initial_designs_are_its_first_initial_candidates_then_random_ones_follow() {
    // MAX twice: candidates 0 and 1 of every run, with the STATIC gait under STATIC and
    // MAX's own under GENOME; candidate 2 is random, as it would be without them.
    let max_json =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../designs/max.json"))
            .unwrap();
    let max: Genome = serde_json::from_str(&max_json).unwrap();
    let text = format!("initial_designs = \"max.json\"\n{EXPERIMENT}");
    let e =
        Experiment::from_toml_reading(&text, |_| Ok(format!("[{max_json}, {max_json}]"))).unwrap();
    let (mut seeded, mut plain) = (fresh(&e, 3), fresh(&experiment(), 3));
    let now = Instant::now();
    // What each run hands out first (a random design that fails the checks before
    // simulating is settled without a lease, so it is missing here).
    let first = |s: &mut Scheduler| -> std::collections::BTreeMap<CandidateKey, Assignment> {
        s.lease(WorkerId(0), now, 100)
            .into_iter()
            .map(|a| (a.key, a))
            .collect()
    };
    let (seeded, plain) = (first(&mut seeded), first(&mut plain));
    let mut random_alike = 0;
    for run in 0..2 {
        for number in 0..2 {
            let key = CandidateKey {
                run: RunId::from_index(run),
                generation: 0,
                number: CandidateNumber(number),
                drawn_ahead: false,
            };
            let a = &seeded[&key];
            let controller = match a.scheme {
                Scheme::Genome => max.controller,
                _ => Controller::static_default(),
            };
            assert_eq!(a.genome.morphology, max.morphology, "{key:?}");
            assert_eq!(a.genome.controller, controller, "{key:?}");
        }
    }
    for (key, a) in &seeded {
        if key.number.0 >= 2 {
            if let Some(b) = plain.get(key) {
                assert_eq!(a.genome, b.genome, "{key:?}");
                random_alike += 1;
            }
        }
    }
    assert!(random_alike >= 2, "{random_alike}");
}

#[test]
fn under_the_papers_method_only_designs_that_meet_the_brief_are_placed() {
    let mut e = experiment();
    e.search.constraints = strider_common::experiment::ConstraintHandling::Reject;
    let (libraries, s) = drive_experiment(&e, 2, 3, |_| {});
    for (i, (feasible, infeasible)) in libraries.iter().enumerate() {
        assert!(
            infeasible.is_empty(),
            "run {i}: nothing enters an infeasible library"
        );
        assert!(!feasible.is_empty());
        let r = s.run(RunId::from_index(i)).unwrap();
        // The initial population was drawn until that many designs passed every check.
        assert_eq!(r.initial_passed, e.run.initial_population);
    }
    // The same experiment with both libraries draws other parents: the method matters.
    let (both, _) = drive_experiment(&experiment(), 2, 3, |_| {});
    assert_ne!(both, libraries);
}

/// Leases until the first candidate of generation 1 comes up (the initial population
/// done), answering everything else.
fn first_offspring(e: &Experiment, s: &mut Scheduler, now: Instant) -> Assignment {
    loop {
        let a = s.lease(WorkerId(0), now, 1).pop().unwrap();
        if a.key.generation == 1 {
            return a;
        }
        let o = outcome_of(e, &a);
        s.accept(WorkerId(0), a.key, o, 0.0).unwrap();
    }
}

/// Whether `key` was ever written as failed.
fn failed_in(writes: &[Write], key: CandidateKey) -> bool {
    writes.iter().any(|w| match w {
        Write::Resolved {
            number, outcome, ..
        } => {
            *number == key.number
                && matches!(
                    outcome,
                    Outcome::Invalid {
                        reason: InvalidReason::EvaluationFailed { .. },
                        ..
                    }
                )
        }
        _ => false,
    })
}

#[test]
fn losing_workers_that_never_began_a_candidate_or_stalled_costs_it_no_attempt() {
    let e = experiment();
    let mut s = fresh(&e, 2);
    let now = Instant::now();
    let victim = first_offspring(&e, &mut s, now);
    s.disconnect(WorkerId(0), "stream dropped");
    s.take_writes();
    // Ten sessions take it and drop their streams before starting it, ten more stall
    // past the lease, ten hand it back: none of it says anything about the candidate.
    let mut t = now;
    for w in 1..=30u64 {
        let got = s.lease(WorkerId(w), t, 100);
        assert!(got.iter().any(|a| a.key == victim.key), "round {w}");
        match w % 3 {
            0 => s.disconnect(WorkerId(w), "stream dropped"),
            1 => {
                t += LEASE + Duration::from_secs(1);
                assert!(s.expire(t) >= 1);
            }
            _ => {
                let keys: Vec<CandidateKey> = got.iter().map(|a| a.key).collect();
                s.release(WorkerId(w), &keys);
            }
        }
    }
    let writes = s.take_writes();
    assert!(!failed_in(&writes, victim.key));
    assert!(
        !writes.iter().any(|w| matches!(w, Write::LeaseLost { .. })),
        "no attempt was counted"
    );
    // A worker that began it and died does count.
    let got = s.lease(WorkerId(99), t, 100);
    assert!(got.iter().any(|a| a.key == victim.key));
    s.started(WorkerId(99), &[victim.key]);
    s.disconnect(WorkerId(99), "connection lost");
    let writes = s.take_writes();
    assert!(writes.iter().any(|w| matches!(
        w,
        Write::LeaseLost { number, attempts: 1, .. } if *number == victim.key.number
    )));
}

#[test]
fn a_late_result_after_an_expiry_is_taken_when_no_other_worker_answered() {
    let e = experiment();
    let mut s = fresh(&e, 3);
    let t0 = Instant::now();
    let a = s.lease(WorkerId(1), t0, 1).pop().unwrap();
    let later = t0 + LEASE + Duration::from_secs(1);
    assert_eq!(s.expire(later), 1);
    // Leased again, to a worker that has not answered yet; the stalled one answers first.
    let again = s.lease(WorkerId(2), later, 100);
    assert!(again.iter().any(|b| b.key == a.key));
    let o = outcome_of(&e, &a);
    assert_eq!(
        s.accept(WorkerId(1), a.key, o.clone(), 0.0),
        Ok(Accepted::Stored)
    );
    assert_eq!(
        s.accept(WorkerId(2), a.key, o, 0.0),
        Ok(Accepted::Duplicate)
    );
}

#[test]
fn a_stalled_worker_is_charged_once_and_a_candidate_that_stalls_three_fails() {
    let e = experiment();
    let mut s = fresh(&e, 3);
    let now = Instant::now();
    let victim = first_offspring(&e, &mut s, now);
    s.disconnect(WorkerId(0), "stream dropped");
    s.take_writes();
    let mut t = now;
    // Worker 1 takes it, begins it, and stalls past the lease twice (it comes back to
    // worker 1 the second time): one attempt, not two.
    for _ in 0..2 {
        let got = s.lease(WorkerId(1), t, 100);
        assert!(got.iter().any(|a| a.key == victim.key));
        s.started(WorkerId(1), &[victim.key]);
        t += LEASE + Duration::from_secs(1);
        s.expire(t);
    }
    let lost = |writes: &[Write]| {
        writes
            .iter()
            .filter_map(|w| match w {
                Write::LeaseLost {
                    number, attempts, ..
                } if *number == victim.key.number => Some(*attempts),
                _ => None,
            })
            .max()
    };
    let writes = s.take_writes();
    assert_eq!(lost(&writes), Some(1));
    // Two more workers stall on it: the third attempt fails it.
    for w in 2..=3u64 {
        let got = s.lease(WorkerId(w), t, 100);
        assert!(got.iter().any(|a| a.key == victim.key));
        s.started(WorkerId(w), &[victim.key]);
        t += LEASE + Duration::from_secs(1);
        s.expire(t);
    }
    assert!(failed_in(&s.take_writes(), victim.key));
}

#[test]
fn a_candidate_is_answered_once_it_has_a_result_and_unknown_ones_never_are() {
    let e = experiment();
    let mut s = fresh(&e, 2);
    let now = Instant::now();
    let a = first_offspring(&e, &mut s, now);
    assert!(!s.answered(a.key), "leased, not answered");
    let o = outcome_of(&e, &a);
    assert_eq!(s.accept(WorkerId(0), a.key, o, 0.0), Ok(Accepted::Stored));
    assert!(s.answered(a.key));
    let unknown = CandidateKey {
        number: CandidateNumber(1_000_000),
        ..a.key
    };
    assert!(!s.answered(unknown));
    let no_run = CandidateKey {
        run: RunId(99),
        ..a.key
    };
    assert!(!s.answered(no_run));
}

#[test]
fn the_fraction_done_counts_initial_designs_and_generations_over_the_budget() {
    let e = experiment();
    // Budget per run: 6 initial designs + 5 generations x 10 = 56 candidates.
    let at = |initial_passed, generation, finished| RunProgress {
        run: RunId(0),
        scheme: strider_common::Scheme::Static,
        repeat: 0,
        seed: strider_common::rng::RunSeed(1),
        generation,
        initial_passed,
        trials_done: 0,
        trials_pending: 0,
        library: Default::default(),
        finished,
    };
    let runs = [at(3, 0, false), at(6, 2, false), at(6, 5, true)];
    let got = fraction_done(&runs, &e.run);
    assert!((got - (3.0 + 26.0 + 56.0) / 168.0).abs() < 1e-12, "{got}");
    assert_eq!(fraction_done(&[], &e.run), 1.0);

    // A real run climbs from 0 to 1 and never goes back.
    let mut s = fresh(&e, 3);
    let now = Instant::now();
    let mut seen = vec![fraction_done(&s.progress(), &e.run)];
    while !s.finished() {
        for a in s.lease(WorkerId(0), now, 4) {
            let o = outcome_of(&e, &a);
            s.accept(WorkerId(0), a.key, o, 0.0).unwrap();
        }
        seen.push(fraction_done(&s.progress(), &e.run));
    }
    assert_eq!(seen[0], 0.0);
    assert_eq!(*seen.last().unwrap(), 1.0);
    assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
    assert!(seen.iter().any(|&f| f > 0.3 && f < 0.7), "{seen:?}");
}

#[test]
fn workers_share_a_scarce_step_by_their_slots_and_the_shares_cover_it() {
    // One run's generation of 60 and two workers of 32 threads (64 slots): 30 each, not 60
    // to whichever asks first.
    assert_eq!(fair_share(60, 64, 128), 30);
    // Alone, a worker may take all of it.
    assert_eq!(fair_share(60, 4, 4), 60);
    // A worker of 2 threads beside one of 32.
    assert_eq!(fair_share(60, 4, 68), 4);
    assert_eq!(fair_share(60, 64, 68), 57);
    for demand in 0..200 {
        for mix in [
            &[4, 4][..],
            &[2, 64, 64],
            &[4, 8, 16, 128],
            &[1, 1, 1, 1, 1, 1, 1],
        ] {
            let all: usize = mix.iter().sum();
            let shares: usize = mix.iter().map(|&s| fair_share(demand, s, all)).sum();
            assert!(shares >= demand, "{demand} over {mix:?}: {shares}");
            for &s in mix {
                assert!(fair_share(demand, s, all) <= demand);
            }
        }
    }
}

#[test]
fn a_workers_lease_is_capped_at_its_share_of_a_scarce_step_only() {
    // One run; two workers of 64 slots each.
    let e = Experiment::from_toml(
        r#"
name = "shares"
schemes = ["static"]
repeats = 1
seed = 5
[run]
initial_population = 6
offspring_per_generation = 10
generations = 3
"#,
    )
    .unwrap();
    let mut s = fresh(&e, 3);
    let now = Instant::now();
    let (a, b) = (WorkerId(0), WorkerId(1));
    assert_eq!(
        s.lease_cap(a, 64, 128),
        None,
        "initial designs are drawn as asked"
    );
    for _ in 0..1000 {
        if s.lease_cap(a, 64, 128).is_some() {
            break;
        }
        for l in s.lease(a, now, 1) {
            s.accept(a, l.key, outcome_of(&e, &l), 0.0).unwrap();
        }
    }
    // Generation 1: 10 offspring (fewer once the prechecks settle some), half each.
    let Some(half) = s.lease_cap(a, 64, 128) else {
        panic!("generation 1 never opened");
    };
    assert!((1..=5).contains(&half), "{half}");
    let leased = s.lease(a, now, half);
    assert_eq!(leased.len(), half);
    assert_eq!(s.lease_cap(a, 64, 128), Some(0), "a holds its share");
    assert_eq!(
        s.lease_cap(b, 64, 128),
        Some(half),
        "b's share is untouched"
    );
    // Answered candidates leave the demand: a's share shrinks with it.
    for l in &leased {
        s.accept(a, l.key, outcome_of(&e, l), 0.0).unwrap();
    }
    assert!(s.lease_cap(a, 64, 128).unwrap() < half);
    // Slots fewer than the candidates: no cap.
    assert_eq!(s.lease_cap(a, 1, 1), None);
}
