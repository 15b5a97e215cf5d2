//! How far the runs have come: each run's progress now, and the fraction of the
//! experiment done (what the progress bar, `status` and the metrics show).

use super::*;

/// Progress of one run, now.
#[derive(Clone, Debug, PartialEq)]
pub struct RunProgress {
    pub run: RunId,
    pub scheme: Scheme,
    pub repeat: u32,
    pub seed: RunSeed,
    /// Last completed generation.
    pub generation: u32,
    /// Candidates of the initial population that count toward its size (valid ones under
    /// the paper's method; simulated ones under feasible-infeasible search).
    pub initial_passed: u32,
    /// Candidates settled (applied or with a result in hand): simulated, or refused by the
    /// checks before simulating.
    pub trials_done: u64,
    /// Candidates of the current step still waiting or leased.
    pub trials_pending: u64,
    pub library: GenerationStats,
    /// Whether the run is finished.
    pub finished: bool,
}

/// How much of an experiment is done, 0 to 1: each run's initial designs counted and
/// generations completed, over its budget (`initial_population` + `generations` x
/// `offspring_per_generation` candidates).
pub fn fraction_done(runs: &[RunProgress], settings: &RunSettings) -> f64 {
    let initial = u64::from(settings.initial_population);
    let budget = settings.candidates_per_run();
    if runs.is_empty() || budget == 0 {
        return 1.0;
    }
    let done: u64 = runs
        .iter()
        .map(|r| {
            if r.finished {
                budget
            } else {
                // The initial population as far as it has come, then whole generations.
                u64::from(r.initial_passed).min(initial) + settings.candidates_by(r.generation)
                    - initial
            }
        })
        .sum();
    (done as f64 / (budget * runs.len() as u64) as f64).min(1.0)
}

impl Scheduler {
    /// Every run's progress.
    pub fn progress(&self) -> Vec<RunProgress> {
        let cells = self.experiment.features.cell_count();
        self.runs
            .iter()
            .enumerate()
            .map(|(i, r)| {
                // Candidates drawn ahead count once their generation keeps them.
                let open = r.open_step().count() as u64;
                let resolved = r
                    .open_step()
                    .filter(|(_, p)| matches!(p.state, State::Resolved(_)))
                    .count() as u64;
                RunProgress {
                    run: RunId::from_index(i),
                    scheme: r.record.spec.scheme,
                    repeat: r.record.spec.repeat,
                    seed: r.record.spec.seed,
                    generation: r.record.generation,
                    initial_passed: r.record.initial_passed,
                    trials_done: r.record.next_candidate + resolved,
                    trials_pending: open - resolved,
                    library: r.record.summary(GenerationStats::default(), cells),
                    finished: r.record.finished,
                }
            })
            .collect()
    }
}
