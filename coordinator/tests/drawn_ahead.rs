//! Candidates drawn ahead of their generation (the scheduler's `ahead` module): whatever
//! the workers and the order their results come in, the libraries and every stored
//! result are those of a scheduler that never draws ahead; a candidate drawn ahead that
//! its generation draws otherwise leaves no trace, and its late result is ignored.

use std::collections::HashMap;
use std::time::{Duration, Instant};
use strider_common::rng::CandidateSeed;
use strider_common::{CandidateKey, EvalContext, Experiment, Outcome, RunId, WorkerId};
use strider_coordinator::qd::changes::Write;
use strider_coordinator::qd::library::{InfeasibleLibrary, Library};
use strider_coordinator::qd::run::RunRecord;
use strider_coordinator::qd::scheduler::{Accepted, Assignment, Scheduler};
use strider_worker::synthetic::instant_outcome;

/// Both constraint handlings: the paper's (feasible library only) and feasible-infeasible
/// search, whose parents come from two libraries.
fn experiment(constraints: &str) -> Experiment {
    Experiment::from_toml(&format!(
        r#"
name = "ahead"
schemes = ["static", "genome"]
repeats = 1
seed = 11
[run]
initial_population = 6
offspring_per_generation = 10
generations = 8
[search]
constraints = "{constraints}"
"#
    ))
    .unwrap()
}

fn scheduler(e: &Experiment, ahead: bool) -> Scheduler {
    let runs = e
        .runs()
        .into_iter()
        .enumerate()
        .map(|(i, spec)| RunRecord::new(RunId::from_index(i), spec))
        .collect();
    let mut s = Scheduler::new(e.clone(), runs, Vec::new(), Duration::from_secs(10), 3);
    s.draw_ahead(ahead);
    s
}

/// The made-up but deterministic outcome a benchmark worker would send (a pure function
/// of the candidate and its bar, as a trial is), marked `outranked` as a real trial is when
/// it meets the brief no fitter than its bar, and with the bar in its energy or the time it
/// ended: so the bar a candidate is leased with shows in what is written, and a candidate
/// drawn ahead against another bar than its generation gives it must not be kept (the test
/// below fails if one is).
fn outcome_of(e: &Experiment, a: &Assignment) -> Outcome {
    let mut outcome = instant_outcome(
        &EvalContext::of(e),
        &a.genome,
        a.scheme,
        CandidateSeed::new(a.run_seed.0, a.key.number.0),
        a.to_beat,
    );
    let bar = a.to_beat.unwrap_or(0.0);
    match &mut outcome {
        Outcome::Valid {
            fitness,
            outranked,
            stats,
            ..
        } => {
            *outranked = a.to_beat.is_some_and(|b| *fitness <= b);
            stats.energy += bar;
        }
        Outcome::Rejected {
            stats: Some(stats), ..
        } => stats.energy += bar,
        Outcome::Invalid { at_time, .. } => *at_time += bar,
        Outcome::Rejected { stats: None, .. } => {}
    }
    outcome
}

/// What a run leaves: every run's libraries, and every result written to the database
/// (run, number, generation, outcome), sorted.
type Ending = (
    Vec<(Library, InfeasibleLibrary)>,
    Vec<(RunId, u64, u32, Outcome)>,
);

/// Runs to the end: each round, `workers` workers lease up to `slots` each; the results
/// of the round come back in the order `reorder` gives, except that the candidates drawn
/// ahead among those `hold` picks come back only after the next round's leases (so some
/// are answered after their generation opened). Returns what the run leaves and the
/// scheduler.
fn drive(
    e: &Experiment,
    ahead: bool,
    workers: u64,
    slots: usize,
    reorder: impl Fn(&mut [(WorkerId, Assignment)]),
    hold: impl Fn(usize) -> bool,
) -> (Ending, Scheduler) {
    let mut s = scheduler(e, ahead);
    let now = Instant::now();
    let mut held_back: Vec<(WorkerId, Assignment)> = Vec::new();
    let mut stored = Vec::new();
    let mut rounds = 0;
    while !s.finished() {
        rounds += 1;
        assert!(rounds < 10_000, "no progress");
        let mut round = Vec::new();
        for w in 0..workers {
            for a in s.lease(WorkerId(w), now, slots) {
                round.push((WorkerId(w), a));
            }
        }
        reorder(&mut round);
        let late = std::mem::take(&mut held_back);
        for (k, (w, a)) in round.into_iter().enumerate() {
            if a.key.drawn_ahead && hold(k) {
                held_back.push((w, a));
                continue;
            }
            s.accept(w, a.key, outcome_of(e, &a), 0.0).unwrap();
        }
        for (w, a) in late {
            s.accept(w, a.key, outcome_of(e, &a), 0.0).unwrap();
        }
        for w in s.take_writes() {
            if let Write::Resolved {
                run,
                number,
                generation,
                outcome,
                ..
            } = w
            {
                stored.push((run, number.0, generation, outcome));
            }
        }
    }
    stored.sort_by_key(|a| (a.0, a.1, a.2));
    let libraries = (0..e.runs().len())
        .map(|i| {
            let r = s.run(RunId::from_index(i)).unwrap();
            (r.library.clone(), r.infeasible.clone())
        })
        .collect();
    ((libraries, stored), s)
}

fn reverse(h: &mut [(WorkerId, Assignment)]) {
    h.reverse();
}

fn shuffle(h: &mut [(WorkerId, Assignment)]) {
    let n = h.len();
    for i in 0..n {
        h.swap(i, (i * 7 + 3) % n);
    }
}

#[test]
fn drawing_ahead_changes_no_library_and_no_stored_result_whatever_the_workers() {
    let mut for_bar = 0;
    for constraints in ["reject", "feasible-infeasible"] {
        let e = experiment(constraints);
        let (reference, s) = drive(&e, false, 1, 1, |_| {}, |_| false);
        assert_eq!(s.ahead_counts().leased, 0, "off: nothing drawn ahead");
        assert!(reference.0.iter().all(|(l, _)| l.len() >= 3));
        let (mut kept, mut dropped) = (0, 0);
        for (workers, slots) in [(3, 4), (2, 7), (1, 25)] {
            for (order, reorder) in [
                ("as leased", (|_: &mut [_]| {}) as fn(&mut [_])),
                ("reversed", reverse),
                ("shuffled", shuffle),
            ] {
                // Without drawing ahead, these workers draw spare initial designs as they
                // lease them: the results written must be those, no more, no fewer.
                let (off, _) = drive(&e, false, workers, slots, reorder, |_| false);
                for (held, hold) in [
                    ("none held", (|_| false) as fn(usize) -> bool),
                    ("every other held", |k| k % 2 == 0),
                ] {
                    let (ending, s) = drive(&e, true, workers, slots, reorder, hold);
                    let case = format!("{constraints}, {workers} x {slots}, {order}, {held}");
                    assert_eq!(ending.0, reference.0, "libraries: {case}");
                    // None of a candidate dropped, none twice.
                    assert_eq!(ending.1, off.1, "written results: {case}");
                    let c = s.ahead_counts();
                    assert!(c.kept + c.dropped <= c.leased, "{case}: {c:?}");
                    assert!(c.dropped_for_bar <= c.dropped, "{case}: {c:?}");
                    kept += c.kept;
                    dropped += c.dropped;
                    for_bar += c.dropped_for_bar;
                }
            }
        }
        // Both ways a candidate drawn ahead can go were taken.
        assert!(
            kept > 0 && dropped > 0,
            "{constraints}: kept {kept}, dropped {dropped}"
        );
    }
    // Among the dropped, designs drawn the same against another bar (outcomes here depend
    // on the bar, as a trial's do: keeping one would write another outcome than the
    // reference's).
    assert!(for_bar > 0);
}

#[test]
fn a_candidate_drawn_ahead_and_dropped_is_drawn_again_and_its_late_result_ignored() {
    let e = experiment("reject");
    let mut s = scheduler(&e, true);
    let now = Instant::now();
    let w = WorkerId(0);
    // Each round a worker leases one at a time until nothing is left: the open generations
    // first, then the next ones' candidates drawn ahead. Played on until one is dropped.
    for _ in 0..100 {
        let (mut open, mut ahead) = (Vec::new(), Vec::new());
        while let Some(a) = s.lease(w, now, 1).pop() {
            if a.key.drawn_ahead {
                ahead.push(a);
            } else {
                assert!(ahead.is_empty(), "the open generations are leased first");
                open.push(a);
            }
        }
        if open.is_empty() && ahead.is_empty() {
            break;
        }
        for a in &open {
            s.accept(w, a.key, outcome_of(&e, a), 0.0).unwrap();
        }
        // The generations opened: those they drew otherwise are answered (their keys
        // name nothing now) and wait again under their own keys.
        let dropped: Vec<&Assignment> = ahead.iter().filter(|a| s.answered(a.key)).collect();
        for a in &ahead {
            let late = s.accept(w, a.key, outcome_of(&e, a), 0.0);
            let was_dropped = dropped.iter().any(|d| d.key == a.key);
            let expected = if was_dropped {
                Accepted::Duplicate
            } else {
                Accepted::Stored
            };
            assert_eq!(late, Ok(expected), "{}", a.key);
        }
        if !dropped.is_empty() {
            let again = s.lease(w, now, 1000);
            for d in dropped {
                let own = CandidateKey {
                    drawn_ahead: false,
                    ..d.key
                };
                // Leased again as its generation drew it, unless that one is settled
                // without a trial.
                match again.iter().find(|a| a.key == own) {
                    Some(a) => assert!(
                        a.genome != d.genome || a.to_beat != d.to_beat,
                        "dropped only because its generation drew another candidate"
                    ),
                    None => assert!(s.answered(own), "{own} neither leased nor settled"),
                }
            }
            return;
        }
    }
    panic!("no candidate drawn ahead was dropped in the whole run");
}

#[test]
fn a_candidate_drawn_ahead_is_never_drawn_again_once_leased_whatever_comes_in_meanwhile() {
    let e = experiment("reject");
    let mut s = scheduler(&e, true);
    let mut now = Instant::now();
    let w = WorkerId(0);
    // What each candidate drawn ahead was when first leased.
    let mut first: HashMap<CandidateKey, Assignment> = HashMap::new();
    let mut leased_again = 0;
    let mut rounds = 0;
    while !s.finished() {
        rounds += 1;
        assert!(rounds < 10_000, "no progress");
        // Each round: everything leasable is leased, one candidate of the open generations
        // answered (so the guess changes), and every other lease left to expire, so that
        // candidates drawn ahead come back to wait while results arrive.
        let mut answered_one = false;
        for a in s.lease(w, now, 1000) {
            if a.key.drawn_ahead {
                match first.get(&a.key) {
                    None => {
                        first.insert(a.key, a.clone());
                    }
                    Some(f) => {
                        assert_eq!((f.genome, f.to_beat), (a.genome, a.to_beat), "{}", a.key);
                        leased_again += 1;
                        s.accept(w, a.key, outcome_of(&e, &a), 0.0).unwrap();
                    }
                }
            } else if !answered_one {
                answered_one = true;
                s.accept(w, a.key, outcome_of(&e, &a), 0.0).unwrap();
            }
        }
        now += Duration::from_secs(11);
        s.expire(now);
    }
    assert!(leased_again > 0, "no candidate drawn ahead came back");
}
