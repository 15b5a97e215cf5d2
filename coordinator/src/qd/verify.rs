//! `verify`: replays a stored experiment from its candidates and says where the database
//! disagrees with itself. Runs are deterministic, so the whole history can be checked:
//! every run is driven again through the scheduler, which draws and breeds each candidate
//! from the run's seed and library exactly as the live service did; each stored genome
//! must be the one drawn, and, fed the stored outcomes, the replayed libraries and run
//! positions must equal the stored ones. A changed genome, seed, outcome, fitness, cell
//! or position shows up as the first place the replay and the file part. Whether the
//! stored outcomes are what the physics gives is the other half (re-simulating a sample,
//! done by the command line, which owns the simulator). Plain functions over plain data.

use crate::qd::changes::{StoredCandidate, Write};
use crate::qd::library::GenerationStats;
use crate::qd::run::RunRecord;
use crate::qd::scheduler::Scheduler;
use std::collections::HashMap;
use std::collections::HashSet;
use std::time::{Duration, Instant};
use strider_common::{CandidateId, Experiment, RunId, WorkerId};

/// Most problems reported per run (after the first divergence, the rest follow from it).
const MAX_PROBLEMS_PER_RUN: usize = 5;

/// What a replay found.
#[derive(Debug, Default)]
pub struct Verdict {
    /// Stored candidates the replay applied as stored.
    pub replayed: u64,
    /// Where the stored state and the replay part, in run order.
    pub problems: Vec<String>,
    /// Each run's generations as the replay completed them, with their statistics (by
    /// run index; generation 0's placement counts are left out: the service fills them
    /// from every stored draw, the replay sees only the applied ones).
    pub generations: Vec<Vec<(u32, GenerationStats)>>,
}

/// Replays `experiment` from `candidates` and compares with `stored` (the runs as the
/// database holds them, libraries included).
pub fn replay(
    experiment: &Experiment,
    stored: &[RunRecord],
    candidates: &[StoredCandidate],
) -> Verdict {
    let mut verdict = Verdict {
        generations: vec![Vec::new(); stored.len()],
        ..Verdict::default()
    };
    let specs = experiment.runs();
    if specs.len() != stored.len() {
        verdict.problems.push(format!(
            "the experiment has {} runs, the database {}",
            specs.len(),
            stored.len()
        ));
        return verdict;
    }
    for (i, (spec, run)) in specs.iter().zip(stored).enumerate() {
        if *spec != run.spec {
            verdict.problems.push(format!(
                "run {i}: the experiment gives {:?} repeat {} seed {}, the database {:?} repeat {} seed {}",
                spec.scheme, spec.repeat, spec.seed.0, run.spec.scheme, run.spec.repeat, run.spec.seed.0
            ));
        }
    }
    // Each stored run's id to its place in the experiment (the scheduler's run).
    let index: HashMap<RunId, RunId> = stored
        .iter()
        .enumerate()
        .map(|(i, r)| (r.id, RunId::from_index(i)))
        .collect();
    let mut rows: HashMap<CandidateId, &StoredCandidate> = HashMap::new();
    for c in candidates {
        match index.get(&c.run) {
            Some(&run) => {
                rows.insert(
                    CandidateId {
                        run,
                        number: c.number,
                    },
                    c,
                );
            }
            None => verdict.problems.push(format!(
                "candidate {} belongs to no run (run id {})",
                c.number.0, c.run
            )),
        }
    }
    let fresh: Vec<RunRecord> = stored
        .iter()
        .map(|r| RunRecord::new(r.id, r.spec))
        .collect();
    // Nothing expires: leases here are only the replay's bookkeeping.
    let mut s = Scheduler::new(
        experiment.clone(),
        fresh,
        Vec::new(),
        Duration::from_secs(86_400),
        u32::MAX,
    );
    // The replay stops where the stored history does: no initial draw past it (one that
    // fails the checks before simulating would be applied at once).
    for (i, r) in stored.iter().enumerate() {
        s.limit_draws(RunId::from_index(i), r.next_candidate);
    }
    let now = Instant::now();
    let mut problems_of: Vec<usize> = vec![0; stored.len()];
    let mut seen: HashSet<CandidateId> = HashSet::new();
    let mut problem = |problems: &mut Vec<String>, run: RunId, what: String| {
        if problems_of[run.index()] < MAX_PROBLEMS_PER_RUN {
            problems_of[run.index()] += 1;
            problems.push(format!("run {run}: {what}"));
        }
    };
    loop {
        // Small batches: the initial population is drawn (and prechecked) only as far as needed.
        let leased = s.lease(WorkerId(0), now, 64);
        if leased.is_empty() {
            break;
        }
        // Leases left unanswered (past the stored history) stay out: the loop ends when
        // nothing is left to lease.
        for a in leased {
            // A draw past what is stored: the stored run stops here (spare initial draws,
            // or the step still open).
            let Some(c) = rows.get(&CandidateId::from(a.key)) else {
                continue;
            };
            if c.generation != a.key.generation {
                continue;
            }
            let _ = s.accept(WorkerId(0), a.key, c.outcome.clone(), 0.0);
        }
        // What the replay applied (leased candidates and those settled without a trial)
        // must be the stored rows, genome and outcome alike.
        for w in s.take_writes() {
            let Write::Step(step) = w else { continue };
            let Some(&run) = index.get(&step.run) else {
                continue;
            };
            if let Some(completed) = step.completed {
                verdict.generations[run.index()].push(completed);
            }
            for applied in &step.candidates {
                let n = applied.number.0;
                let id = CandidateId {
                    run,
                    number: applied.number,
                };
                match rows.get(&id) {
                    None => problem(
                        &mut verdict.problems,
                        run,
                        format!("the replay applies candidate {n}, which the database does not hold"),
                    ),
                    Some(c) if c.genome != applied.genome => problem(
                        &mut verdict.problems,
                        run,
                        format!("candidate {n}: the stored genome is not the one the run draws from its seed and library"),
                    ),
                    Some(c) if c.outcome != applied.outcome || c.generation != applied.generation => problem(
                        &mut verdict.problems,
                        run,
                        format!("candidate {n}: the stored outcome or generation is not the one the replay applies"),
                    ),
                    Some(c) if !c.columns_agree() => problem(
                        &mut verdict.problems,
                        run,
                        format!("candidate {n}: its kind, fitness or cell column does not say what its outcome says"),
                    ),
                    Some(_) => {
                        seen.insert(id);
                    }
                }
            }
        }
    }
    verdict.replayed = seen.len() as u64;
    for (i, stored_run) in stored.iter().enumerate() {
        let run = RunId::from_index(i);
        let Some(replayed) = s.run(run) else { continue };
        let mut report = |what: String| problem(&mut verdict.problems, run, what);
        if replayed.position() != stored_run.position() {
            report(format!(
                "stored at {:?}, the replay of its candidates reaches {:?}",
                stored_run.position(),
                replayed.position()
            ));
        }
        compare(
            "library",
            stored_run
                .library
                .elites()
                .map(|(c, e)| (c, (e.candidate, e.fitness.to_bits(), e.genome))),
            replayed
                .library
                .elites()
                .map(|(c, e)| (c, (e.candidate, e.fitness.to_bits(), e.genome))),
            &mut report,
        );
        compare(
            "infeasible library",
            stored_run
                .infeasible
                .elites()
                .map(|(c, e)| (c, (e.candidate, e.shortfall, e.genome))),
            replayed
                .infeasible
                .elites()
                .map(|(c, e)| (c, (e.candidate, e.shortfall, e.genome))),
            &mut report,
        );
    }
    let unseen = candidates.len() - seen.len();
    if unseen > 0 {
        verdict.problems.push(format!(
            "{unseen} stored candidates were not applied as stored by the replay (changed, added, or past where a run's history was cut)"
        ));
    }
    verdict
}

/// Reports the first cells where two libraries (as `(cell, what identifies its elite)` in
/// cell order) differ.
fn compare<K: PartialEq + std::fmt::Debug, V: PartialEq>(
    name: &str,
    stored: impl Iterator<Item = (K, V)>,
    replayed: impl Iterator<Item = (K, V)>,
    report: &mut impl FnMut(String),
) {
    let stored: Vec<(K, V)> = stored.collect();
    let replayed: Vec<(K, V)> = replayed.collect();
    if stored.len() != replayed.len() {
        report(format!(
            "the stored {name} has {} elites, the replay {}",
            stored.len(),
            replayed.len()
        ));
        return;
    }
    for ((sc, sv), (rc, rv)) in stored.iter().zip(&replayed) {
        if sc != rc {
            report(format!(
                "the stored {name} holds cell {sc:?} where the replay holds {rc:?}"
            ));
            return;
        }
        if sv != rv {
            report(format!("the stored {name}'s elite of cell {sc:?} differs from the replay's (candidate, fitness or genome)"));
            return;
        }
    }
}

/// Where `stored` (a run's `generations` rows: generation, evaluations, statistics) and
/// `replayed` (what the replay completed) differ, at most `MAX_PROBLEMS_PER_RUN`.
/// Generation 0's placement counts are not compared (see [`Verdict::generations`]); the
/// last stored generation may be one the replay has not completed (its step still open
/// when the history ends) only if nothing follows it.
pub fn generation_problems(
    run: RunId,
    stored: &[(u32, u64, GenerationStats)],
    replayed: &[(u32, GenerationStats)],
) -> Vec<String> {
    let mut out = Vec::new();
    let comparable = |g: u32, mut s: GenerationStats| {
        if g == 0 {
            let stats = GenerationStats {
                coverage: s.coverage,
                elites: s.elites,
                max_fitness: s.max_fitness,
                mean_fitness: s.mean_fitness,
                min_fitness: s.min_fitness,
                qd_score: s.qd_score,
                infeasible_elites: s.infeasible_elites,
                infeasible_only: s.infeasible_only,
                ..GenerationStats::default()
            };
            s = stats;
        }
        s
    };
    if stored.len() != replayed.len() {
        out.push(format!(
            "run {run}: the generations table holds {} generations, the replay completes {}",
            stored.len(),
            replayed.len()
        ));
    }
    for ((g, _, s), (rg, r)) in stored.iter().zip(replayed) {
        if g != rg || comparable(*g, *s) != comparable(*rg, *r) {
            out.push(format!(
                "run {run}: the generations table's row for generation {g} does not hold what the replay gives for generation {rg}: stored {s:?}, replayed {r:?}"
            ));
            if out.len() >= MAX_PROBLEMS_PER_RUN {
                break;
            }
        }
    }
    out
}
