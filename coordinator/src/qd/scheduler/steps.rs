//! How a run's steps advance: drawing the initial population, opening a generation,
//! adding candidates to the open step, and applying a complete step to the run's
//! libraries in candidate order. Part of the scheduler's one state machine (the methods
//! below extend [`Scheduler`]); kept apart because it is where results become libraries.

use super::*;

impl Scheduler {
    pub(super) fn initial_phase(&self, i: usize) -> bool {
        self.runs[i].record.initial_passed < self.experiment.run.initial_population
    }

    fn seed(&self, i: usize, number: u64) -> CandidateSeed {
        CandidateSeed::new(self.runs[i].record.spec.seed.0, number)
    }

    /// Draws initial-population candidates until one needs a worker or the window is full.
    pub(super) fn draw_initial(&mut self, i: usize) {
        let scheme = self.runs[i].record.spec.scheme;
        while self.runs[i].waiting.is_empty()
            && self.runs[i].frontier - self.runs[i].record.next_candidate < INITIAL_WINDOW
            && self.runs[i].frontier < self.runs[i].draw_limit
        {
            let number = self.runs[i].frontier;
            self.runs[i].frontier += 1;
            let genome = initial_candidate(
                scheme,
                self.seed(i, number),
                &self.experiment.initial_designs,
            );
            self.add(i, number, 0, genome);
        }
    }

    /// Breeds the run's next generation from its library, keeping the candidates drawn
    /// ahead that it draws exactly as they were.
    pub(super) fn open_generation(&mut self, i: usize) {
        let r = &self.runs[i].record;
        let (first, generation) = (r.next_candidate, r.generation + 1);
        let count = u64::from(self.experiment.run.offspring_per_generation);
        let genomes = self.breed(i, &self.runs[i].record, first..first + count);
        self.runs[i].ahead = None;
        for (number, genome) in (first..first + count).zip(genomes) {
            if !self.keep_drawn_ahead(i, number, generation, &genome) {
                self.add(i, number, generation, genome);
            }
        }
        // Never lower: spare initial draws above this range may still send late results.
        let r = &mut self.runs[i];
        r.frontier = r.frontier.max(first + count);
    }

    /// Offspring `numbers` of run `i` bred from `record`'s libraries.
    pub(super) fn breed(
        &self,
        i: usize,
        record: &RunRecord,
        numbers: impl IntoIterator<Item = u64>,
    ) -> Vec<Genome> {
        let parents = match self.experiment.search.constraints {
            ConstraintHandling::Reject => Parents::Feasible(&record.library),
            ConstraintHandling::FeasibleInfeasible => Parents::Both {
                feasible: &record.library,
                infeasible: &record.infeasible,
                share: self.experiment.search.feasible_parent_share,
                tournament: self.experiment.search.infeasible_tournament,
            },
        };
        numbers
            .into_iter()
            .map(|number| {
                offspring(
                    &parents,
                    record.spec.scheme,
                    &self.experiment.mutation,
                    self.seed(i, number),
                )
                .expect("the libraries hold the initial population")
            })
            .collect()
    }

    /// The bar a candidate of `generation` must pass to enter `library`: the elite its
    /// cell holds when it is drawn, which stays until the generation's end (none in the
    /// initial population, whose library grows as it is applied). ES takes none (it
    /// confirms only a child that beats its parent).
    pub(super) fn to_beat(
        &self,
        library: &Library,
        scheme: Scheme,
        generation: u32,
        genome: &Genome,
    ) -> Option<f64> {
        if generation == 0 || scheme == Scheme::Es || library.is_empty() {
            None
        } else {
            library.get(cell_of(&self.ctx, genome)).map(|e| e.fitness)
        }
    }

    /// Adds a candidate to the step: its stored result if the database has one, else
    /// settled at once when it fails the brief's static checks, else waiting.
    fn add(&mut self, i: usize, number: u64, generation: u32, genome: Genome) {
        let run = self.runs[i].record.id;
        let scheme = self.runs[i].record.spec.scheme;
        let key = CandidateKey {
            run,
            generation,
            number: CandidateNumber(number),
            drawn_ahead: false,
        };
        let (attempts, state) = match self.stored.remove(&key) {
            Some(stored) => (
                stored.attempts,
                stored.outcome.map_or(State::Waiting, State::Resolved),
            ),
            // Settled without a trial, or waiting: nothing to store until it is applied
            // (a restart redraws it identically).
            None => (
                0,
                precheck(&self.ctx, &genome, scheme).map_or(State::Waiting, State::Resolved),
            ),
        };
        let to_beat = self.to_beat(&self.runs[i].record.library, scheme, generation, &genome);
        let r = &mut self.runs[i];
        if state == State::Waiting {
            r.waiting.insert(number);
        }
        r.step.insert(
            number,
            Pending::new(generation, genome, to_beat, attempts, state, false),
        );
    }

    /// Applies whatever the run's results allow, opening next generations as they complete.
    pub(super) fn advance(&mut self, i: usize) {
        loop {
            if self.runs[i].record.finished {
                return;
            }
            let applied = if self.initial_phase(i) {
                self.apply_initial_prefix(i)
            } else {
                self.apply_generation(i)
            };
            if !applied {
                return;
            }
        }
    }

    /// Applies the initial population's resolved candidates from the first unapplied one
    /// on, in order, stopping at the target; returns whether it applied any.
    fn apply_initial_prefix(&mut self, i: usize) -> bool {
        let target = self.experiment.run.initial_population;
        let cells = self.experiment.features.cell_count();
        let generations = self.experiment.run.generations;
        let mode = self.experiment.search.constraints;
        let r = &mut self.runs[i];
        let mut applied = Vec::new();
        let mut stats = GenerationStats::default();
        let mut changed = Changed::default();
        while r.record.initial_passed < target {
            let n = r.record.next_candidate;
            let resolved = matches!(
                r.step.get(&n),
                Some(Pending {
                    state: State::Resolved(_),
                    ..
                })
            );
            if !resolved {
                break;
            }
            let p = r.step.remove(&n).expect("checked above");
            let State::Resolved(outcome) = p.state else {
                unreachable!()
            };
            let placed = place(&self.ctx, mode, &mut r.record, n, &p.genome, &outcome);
            placed.count(&mut stats, &mut changed);
            let counts = match mode {
                ConstraintHandling::Reject => matches!(outcome, Outcome::Valid { .. }),
                ConstraintHandling::FeasibleInfeasible => {
                    outcome.standing() != Standing::NotSimulated
                }
            };
            r.record.initial_passed += u32::from(counts);
            r.record.next_candidate = n + 1;
            applied.push(AppliedCandidate {
                number: CandidateNumber(n),
                generation: 0,
                genome: p.genome,
                outcome,
                placement: placed.feasible,
                infeasible: placed.infeasible,
            });
        }
        if applied.is_empty() {
            return false;
        }
        let complete = r.record.initial_passed == target;
        if complete {
            // The population is complete: later draws are not part of the run.
            r.step.clear();
            r.waiting.clear();
            r.record.generation = 0;
            r.record.finished = generations == 0;
        }
        let completed = complete.then(|| (0, r.record.summary(stats, cells)));
        self.commit_step(i, applied, changed, completed);
        if complete && !self.runs[i].record.finished {
            self.open_generation(i);
        }
        true
    }

    /// Applies the current generation when every result is in; returns whether it did.
    fn apply_generation(&mut self, i: usize) -> bool {
        let cells = self.experiment.features.cell_count();
        let generations = self.experiment.run.generations;
        let mode = self.experiment.search.constraints;
        let r = &mut self.runs[i];
        let ahead_from = r.ahead_from();
        let complete = r.open_step().next().is_some()
            && r.open_step()
                .all(|(_, p)| matches!(p.state, State::Resolved(_)));
        if !complete {
            return false;
        }
        let generation = r.record.generation + 1;
        let mut stats = GenerationStats::default();
        let mut changed = Changed::default();
        // What was drawn ahead stays for the next generation to keep or drop.
        let drawn_ahead = r.step.split_off(&ahead_from);
        let step = std::mem::replace(&mut r.step, drawn_ahead);
        let mut applied = Vec::with_capacity(step.len());
        for (n, p) in step {
            let State::Resolved(outcome) = p.state else {
                unreachable!()
            };
            let placed = place(&self.ctx, mode, &mut r.record, n, &p.genome, &outcome);
            placed.count(&mut stats, &mut changed);
            r.record.next_candidate = n + 1;
            applied.push(AppliedCandidate {
                number: CandidateNumber(n),
                generation,
                genome: p.genome,
                outcome,
                placement: placed.feasible,
                infeasible: placed.infeasible,
            });
        }
        r.record.generation = generation;
        r.record.finished = generation == generations;
        let stats = r.record.summary(stats, cells);
        self.commit_step(i, applied, changed, Some((generation, stats)));
        if !self.runs[i].record.finished {
            self.open_generation(i);
        }
        true
    }

    fn commit_step(
        &mut self,
        i: usize,
        candidates: Vec<AppliedCandidate>,
        changed: Changed,
        completed: Option<(u32, GenerationStats)>,
    ) {
        let r = &self.runs[i].record;
        let infeasible = changed
            .infeasible
            .into_iter()
            .map(|c| {
                (
                    c,
                    r.infeasible
                        .get(c)
                        .expect("changed cells hold an elite")
                        .clone(),
                )
            })
            .collect();
        let elites = changed
            .feasible
            .into_iter()
            .map(|c| {
                (
                    c,
                    r.library
                        .get(c)
                        .expect("changed cells hold an elite")
                        .clone(),
                )
            })
            .collect();
        self.writes.push(Write::Step(Box::new(StepCommit {
            run: r.id,
            position: r.position(),
            candidates,
            elites,
            infeasible,
            completed,
        })));
        if completed.is_some() {
            self.steps_applied += 1;
        }
    }
}

/// The cells a step changed, in each library.
#[derive(Default)]
struct Changed {
    feasible: BTreeSet<CellIndex>,
    infeasible: BTreeSet<CellIndex>,
}

/// What one result did to a run's libraries.
pub(super) struct Placed {
    feasible: Placement,
    infeasible: Option<CellChange>,
    /// The cell it was placed in, when it changed a library.
    cell: Option<CellIndex>,
}

impl Placed {
    /// Counts it into a step's statistics and changed cells.
    fn count(&self, stats: &mut GenerationStats, changed: &mut Changed) {
        stats.record(self.feasible);
        stats.record_infeasible(self.infeasible);
        if let Some(cell) = self.cell {
            if matches!(self.feasible, Placement::New | Placement::Improved) {
                changed.feasible.insert(cell);
            }
            if matches!(
                self.infeasible,
                Some(CellChange::New | CellChange::Improved)
            ) {
                changed.infeasible.insert(cell);
            }
        }
    }
}

/// Applies one result to a run's libraries: a valid design to the feasible library; under
/// feasible-infeasible search, a simulated design that missed the brief to the infeasible
/// library, in its features' cell.
pub(super) fn place(
    ctx: &EvalContext,
    mode: ConstraintHandling,
    record: &mut RunRecord,
    number: u64,
    genome: &Genome,
    outcome: &Outcome,
) -> Placed {
    let candidate = CandidateNumber(number);
    let feasible = record.library.apply(candidate, genome, outcome);
    if let Outcome::Valid { cell, .. } = outcome {
        return Placed {
            feasible,
            infeasible: None,
            cell: Some(*cell),
        };
    }
    if mode == ConstraintHandling::Reject || outcome.shortfall().is_none() {
        return Placed {
            feasible,
            infeasible: None,
            cell: None,
        };
    }
    let cell = cell_of(ctx, genome);
    Placed {
        feasible,
        infeasible: record.infeasible.apply(candidate, genome, outcome, cell),
        cell: Some(cell),
    }
}

/// The library cell of a design (its features need the body plan: masses).
pub fn cell_of(ctx: &EvalContext, genome: &Genome) -> CellIndex {
    let plan = BodyPlan::new(&genome.morphology, ctx.brief.payload);
    ctx.grid
        .cell_of(&Features::of(&genome.morphology, &plan))
        .expect("features of a valid genome are finite")
}
