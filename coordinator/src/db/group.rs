//! A group of writes made ready to commit, and committing it. Preparing decides which
//! rows outlive the group and turns every genome and outcome into JSON: plain CPU work,
//! done before the transaction so that the writer task can prepare the next group while
//! SQLite commits this one (the two used to run one after the other, and the writer was
//! the service's bottleneck).

use super::checksum::{CandidateColumns, GenerationColumns, GENERATION_COLUMNS};
use super::rows::{column, PendingRow};
use super::{run_column, standing_figure, worker_column, Db, DbError};
use crate::qd::changes::{StepCommit, Write};
use crate::qd::library::{CellChange, GenerationStats, Placement};
use crate::qd::run::RunPosition;
use std::collections::HashMap;
use strider_common::{InvalidReason, Outcome, RunId};

/// Rows per multi-row statement (9 parameters each; SQLite allows 32,766).
const ROWS_PER_STATEMENT: usize = 1000;

/// Writes ready to commit in one transaction, in order.
pub struct PreparedGroup {
    items: Vec<Item>,
    writes: usize,
}

enum Item {
    /// Consecutive pending rows (results and lost leases), at most a statement's worth.
    Pending(Vec<PendingRow>),
    Step(StepRows),
    Worker(Write),
}

struct StepRows {
    run: i64,
    candidates: Vec<CandidateRow>,
    elites: Vec<CellRow>,
    infeasible: Vec<InfeasibleCellRow>,
    completed: Option<(u32, GenerationStats)>,
    position: RunPosition,
    initial_population_done: bool,
}

struct CandidateRow {
    number: i64,
    generation: i64,
    genome: String,
    outcome: String,
    kind: &'static str,
    fitness: Option<f64>,
    cell: Option<i64>,
    placement: &'static str,
    shortfall: Option<&'static str>,
    standing: Option<f64>,
    infeasible_placement: Option<&'static str>,
    /// Of the columns above ([`super::checksum`]).
    checksum: i64,
}

impl CandidateRow {
    fn columns(&self, run: i64) -> CandidateColumns<'_> {
        CandidateColumns {
            run,
            number: self.number,
            generation: self.generation,
            genome: &self.genome,
            outcome: &self.outcome,
            kind: self.kind,
            fitness: self.fitness,
            cell: self.cell,
            placement: self.placement,
            shortfall: self.shortfall,
            standing: self.standing,
            infeasible_placement: self.infeasible_placement,
        }
    }
}

/// An `infeasible_cells` row: an infeasible cell's new holder.
struct InfeasibleCellRow {
    cell: i64,
    candidate: i64,
    shortfall: &'static str,
    standing: f64,
}

/// A `cells` row: a cell's new holder (the genome is in its candidate row).
struct CellRow {
    cell: i64,
    candidate: i64,
    fitness: f64,
}

fn json(o: &impl serde::Serialize) -> String {
    serde_json::to_string(o).expect("genomes and outcomes serialise")
}

/// The pending row of a result or a lost lease; `None` for other writes.
fn pending_row(w: &Write) -> Option<PendingRow> {
    match w {
        Write::Resolved {
            run,
            number,
            generation,
            attempts,
            outcome,
            worker,
            seconds,
        } => {
            let failed = matches!(
                outcome,
                Outcome::Invalid {
                    reason: InvalidReason::EvaluationFailed { .. },
                    ..
                }
            );
            Some(PendingRow {
                run_id: run_column(*run),
                number: number.0 as i64,
                generation: i64::from(*generation),
                status: if failed { "failed" } else { "done" }.to_string(),
                attempts: i64::from(*attempts),
                worker: worker.map(worker_column),
                outcome: Some(json(outcome)),
                seconds: Some(*seconds),
                checksum: None,
            })
        }
        Write::LeaseLost {
            run,
            number,
            generation,
            attempts,
            worker,
        } => Some(PendingRow {
            run_id: run_column(*run),
            number: number.0 as i64,
            generation: i64::from(*generation),
            status: "waiting".to_string(),
            attempts: i64::from(*attempts),
            worker: Some(worker_column(*worker)),
            outcome: None,
            seconds: None,
            checksum: None,
        }),
        _ => None,
    }
}

fn step_rows(step: &StepCommit) -> StepRows {
    StepRows {
        run: run_column(step.run),
        candidates: step
            .candidates
            .iter()
            .map(|c| {
                let (fitness, cell) = match &c.outcome {
                    Outcome::Valid { fitness, cell, .. } => {
                        (Some(*fitness), Some(i64::from(cell.0)))
                    }
                    _ => (None, None),
                };
                let mut row = CandidateRow {
                    number: c.number.0 as i64,
                    generation: i64::from(c.generation),
                    genome: json(&c.genome),
                    outcome: json(&c.outcome),
                    kind: c.outcome.kind(),
                    fitness,
                    cell,
                    placement: c.placement.name(),
                    shortfall: c.outcome.shortfall().map(|s| s.name()),
                    standing: c
                        .outcome
                        .shortfall()
                        .and_then(|_| standing_figure(c.outcome.standing())),
                    infeasible_placement: c.infeasible.map(|p| p.name()),
                    checksum: 0,
                };
                row.checksum = row.columns(run_column(step.run)).checksum();
                row
            })
            .collect(),
        infeasible: step
            .infeasible
            .iter()
            .map(|(cell, e)| InfeasibleCellRow {
                cell: i64::from(cell.0),
                candidate: e.candidate.0 as i64,
                shortfall: e.shortfall.name(),
                standing: standing_figure(e.standing)
                    .expect("an infeasible elite was simulated and missed the brief"),
            })
            .collect(),
        elites: step
            .elites
            .iter()
            .map(|(cell, elite)| CellRow {
                cell: i64::from(cell.0),
                candidate: elite.candidate.0 as i64,
                fitness: elite.fitness,
            })
            .collect(),
        completed: step.completed,
        position: step.position,
        initial_population_done: step.initial_population_done(),
    }
}

impl PreparedGroup {
    /// Prepares `writes` (in order) for one transaction.
    pub fn new(writes: &[Write]) -> Self {
        // A pending row that a later step of the same group deletes again need not be
        // written: the transaction ends the same. When the writer is behind, most are.
        let needed = rows_outliving_the_group(writes);
        let mut items = Vec::new();
        for (w, needed) in writes.iter().zip(needed) {
            match w {
                Write::Step(step) => items.push(Item::Step(step_rows(step))),
                Write::WorkerJoined { .. } | Write::WorkerLeft { .. } => {
                    items.push(Item::Worker(w.clone()))
                }
                // Skipped before its outcome is turned into JSON.
                _ if !needed => {}
                _ => {
                    let row = pending_row(w).expect("the other writes are pending rows");
                    // Consecutive pending rows go in one statement (a statement costs far
                    // more than a row).
                    match items.last_mut() {
                        Some(Item::Pending(rows)) if rows.len() < ROWS_PER_STATEMENT => {
                            rows.push(row)
                        }
                        _ => items.push(Item::Pending(vec![row])),
                    }
                }
            }
        }
        Self {
            items,
            writes: writes.len(),
        }
    }

    /// How many writes it holds.
    pub fn writes(&self) -> usize {
        self.writes
    }
}

impl Db {
    /// Commits a prepared group in one transaction (the writer task's group commit).
    pub async fn commit(&self, group: PreparedGroup) -> Result<(), DbError> {
        let mut tx = self.pool.begin().await?;
        for item in &group.items {
            match item {
                Item::Pending(rows) => write_pending_rows(&mut tx, rows).await?,
                Item::Step(step) => write_step(&mut tx, step).await?,
                Item::Worker(w) => write_worker(&mut tx, w).await?,
            }
        }
        tx.commit().await?;
        Ok(())
    }
}

/// For each write, whether it must be written: false for a pending row that a later step
/// of its run in the same group removes from `pending` again.
fn rows_outliving_the_group(writes: &[Write]) -> Vec<bool> {
    // A run's steps only ever widen what they clear, so its last step in the group
    // decides for every row before it.
    let mut last_step: HashMap<RunId, &StepCommit> = HashMap::new();
    let mut needed = vec![true; writes.len()];
    for (i, w) in writes.iter().enumerate().rev() {
        match w {
            Write::Step(step) => {
                last_step.entry(step.run).or_insert(step);
            }
            Write::Resolved {
                run,
                number,
                generation,
                ..
            }
            | Write::LeaseLost {
                run,
                number,
                generation,
                ..
            } => {
                if let Some(step) = last_step.get(run) {
                    needed[i] = !step.clears(*number, *generation);
                }
            }
            _ => {}
        }
    }
    needed
}

/// Upserts pending rows (results and lost leases) in one statement.
async fn write_pending_rows(
    tx: &mut sqlx::Transaction<'_, sqlx::Sqlite>,
    rows: &[PendingRow],
) -> Result<(), DbError> {
    let mut q = sqlx::QueryBuilder::new(
        "INSERT INTO pending (run_id, number, generation, status, attempts, worker, outcome, seconds, checksum) ",
    );
    q.push_values(rows, |mut b, r| {
        b.push_bind(r.run_id)
            .push_bind(r.number)
            .push_bind(r.generation)
            .push_bind(r.status.as_str())
            .push_bind(r.attempts)
            .push_bind(r.worker)
            .push_bind(r.outcome.as_deref())
            .push_bind(r.seconds)
            .push_bind(r.computed_checksum());
    });
    q.push(
        " ON CONFLICT (run_id, number) DO UPDATE SET generation = excluded.generation, \
         status = excluded.status, attempts = excluded.attempts, worker = excluded.worker, \
         outcome = excluded.outcome, seconds = excluded.seconds, checksum = excluded.checksum",
    );
    q.build().execute(&mut **tx).await?;
    Ok(())
}

/// A worker's arrival or departure.
async fn write_worker(
    tx: &mut sqlx::Transaction<'_, sqlx::Sqlite>,
    w: &Write,
) -> Result<(), DbError> {
    match w {
        Write::WorkerJoined {
            id,
            name,
            build,
            slots,
        } => {
            sqlx::query("INSERT INTO workers (id, name, build, slots, connected_at) VALUES (?, ?, ?, ?, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))")
                .bind(worker_column(*id))
                .bind(name)
                .bind(build)
                .bind(i64::from(*slots))
                .execute(&mut **tx)
                .await?;
        }
        Write::WorkerLeft {
            id,
            results,
            reason,
        } => {
            sqlx::query("UPDATE workers SET disconnected_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now'), results = ?, left_because = ? WHERE id = ?")
                .bind(*results as i64)
                .bind(reason)
                .bind(worker_column(*id))
                .execute(&mut **tx)
                .await?;
        }
        _ => unreachable!("only worker writes are written one by one"),
    }
    Ok(())
}

/// A step: its candidates, the cells it changed, its statistics, the run's new position.
/// A stored placement that names none: the database was written by something else.
fn unknown_placement(run: i64, name: &str) -> DbError {
    DbError::Corrupt(format!(
        "run {run}: a candidate's placement is `{name}`, which names no placement"
    ))
}

/// Generation 0's candidates of `run` counted by one placement column (`placement` or
/// `infeasible_placement`): each placement's name and how many had it. Generation 0's
/// placement counts come from every stored draw of it, which span many steps.
async fn generation_zero_counts(
    tx: &mut sqlx::Transaction<'_, sqlx::Sqlite>,
    run: i64,
    column_name: &'static str,
) -> Result<Vec<(String, usize)>, DbError> {
    let sql = format!(
        "SELECT {column_name} AS placement, COUNT(*) AS n FROM candidates \
         WHERE run_id = ? AND generation = 0 AND {column_name} IS NOT NULL GROUP BY {column_name}"
    );
    let key = format!("run {run} generation 0");
    let rows = sqlx::query(&sql).bind(run).fetch_all(&mut **tx).await?;
    rows.iter()
        .map(|r| {
            let n = column::<i64>(r, "candidates", &key, "n")? as usize;
            Ok((column(r, "candidates", &key, "placement")?, n))
        })
        .collect()
}

async fn write_step(
    tx: &mut sqlx::Transaction<'_, sqlx::Sqlite>,
    step: &StepRows,
) -> Result<(), DbError> {
    let run = step.run;
    for chunk in step.candidates.chunks(ROWS_PER_STATEMENT) {
        let mut q = sqlx::QueryBuilder::new(
            "INSERT INTO candidates (run_id, number, generation, genome, outcome, kind, fitness, cell, placement, shortfall, standing, infeasible_placement, checksum) ",
        );
        q.push_values(chunk, |mut b, c| {
            b.push_bind(run)
                .push_bind(c.number)
                .push_bind(c.generation)
                .push_bind(c.genome.as_str())
                .push_bind(c.outcome.as_str())
                .push_bind(c.kind)
                .push_bind(c.fitness)
                .push_bind(c.cell)
                .push_bind(c.placement)
                .push_bind(c.shortfall)
                .push_bind(c.standing)
                .push_bind(c.infeasible_placement)
                .push_bind(c.checksum);
        });
        q.build().execute(&mut **tx).await?;
    }
    for chunk in step.elites.chunks(ROWS_PER_STATEMENT) {
        let mut q =
            sqlx::QueryBuilder::new("INSERT INTO cells (run_id, cell, candidate, fitness) ");
        q.push_values(chunk, |mut b, e| {
            b.push_bind(run)
                .push_bind(e.cell)
                .push_bind(e.candidate)
                .push_bind(e.fitness);
        });
        q.push(" ON CONFLICT (run_id, cell) DO UPDATE SET candidate = excluded.candidate, fitness = excluded.fitness");
        q.build().execute(&mut **tx).await?;
    }
    for chunk in step.infeasible.chunks(ROWS_PER_STATEMENT) {
        let mut q = sqlx::QueryBuilder::new(
            "INSERT INTO infeasible_cells (run_id, cell, candidate, shortfall, standing) ",
        );
        q.push_values(chunk, |mut b, e| {
            b.push_bind(run)
                .push_bind(e.cell)
                .push_bind(e.candidate)
                .push_bind(e.shortfall)
                .push_bind(e.standing);
        });
        q.push(" ON CONFLICT (run_id, cell) DO UPDATE SET candidate = excluded.candidate, shortfall = excluded.shortfall, standing = excluded.standing");
        q.build().execute(&mut **tx).await?;
    }
    if let Some((generation, mut stats)) = step.completed {
        if generation == 0 {
            for (name, n) in generation_zero_counts(tx, run, "infeasible_placement").await? {
                match CellChange::named(&name) {
                    Some(CellChange::New) => stats.infeasible_new = n,
                    Some(CellChange::Improved) => stats.infeasible_improved = n,
                    Some(CellChange::Discarded) => {}
                    None => return Err(unknown_placement(run, &name)),
                }
            }
            for (name, n) in generation_zero_counts(tx, run, "placement").await? {
                match Placement::named(&name) {
                    Some(Placement::New) => stats.new = n,
                    Some(Placement::Improved) => stats.improved = n,
                    Some(Placement::Discarded) => stats.discarded = n,
                    Some(Placement::Rejected) => stats.rejected = n,
                    Some(Placement::Invalid) => stats.invalid = n,
                    None => return Err(unknown_placement(run, &name)),
                }
            }
        }
        let evaluations =
            stats.new + stats.improved + stats.discarded + stats.rejected + stats.invalid;
        let row = GenerationColumns {
            run,
            generation: i64::from(generation),
            evaluations: evaluations as i64,
            coverage: stats.coverage,
            elites: stats.elites as i64,
            max_fitness: stats.max_fitness,
            mean_fitness: stats.mean_fitness,
            min_fitness: stats.min_fitness,
            qd_score: stats.qd_score,
            new: stats.new as i64,
            improved: stats.improved as i64,
            discarded: stats.discarded as i64,
            rejected: stats.rejected as i64,
            invalid: stats.invalid as i64,
            infeasible_elites: stats.infeasible_elites as i64,
            infeasible_only: stats.infeasible_only as i64,
            infeasible_new: stats.infeasible_new as i64,
            infeasible_improved: stats.infeasible_improved as i64,
        };
        sqlx::query(&format!(
            "INSERT INTO generations ({GENERATION_COLUMNS}) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)"
        ))
        .bind(row.run)
        .bind(row.generation)
        .bind(row.evaluations)
        .bind(row.coverage)
        .bind(row.elites)
        .bind(row.max_fitness)
        .bind(row.mean_fitness)
        .bind(row.min_fitness)
        .bind(row.qd_score)
        .bind(row.new)
        .bind(row.improved)
        .bind(row.discarded)
        .bind(row.rejected)
        .bind(row.invalid)
        .bind(row.infeasible_elites)
        .bind(row.infeasible_only)
        .bind(row.infeasible_new)
        .bind(row.infeasible_improved)
        .bind(row.checksum())
        .execute(&mut **tx)
        .await?;
    }
    let p = step.position;
    // What `StepCommit::clears` says.
    sqlx::query("DELETE FROM pending WHERE run_id = ? AND (number < ? OR (generation = 0 AND ?))")
        .bind(run)
        .bind(p.next_candidate as i64)
        .bind(step.initial_population_done)
        .execute(&mut **tx)
        .await?;
    sqlx::query("UPDATE runs SET generation = ?, initial_passed = ?, next_candidate = ?, finished = ? WHERE id = ?")
        .bind(i64::from(p.generation))
        .bind(i64::from(p.initial_passed))
        .bind(p.next_candidate as i64)
        .bind(i64::from(p.finished))
        .bind(run)
        .execute(&mut **tx)
        .await?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qd::changes::StepCommit;
    use crate::qd::run::RunPosition;
    use strider_common::ids::CandidateNumber;
    use strider_common::WorkerId;

    fn lost(run: u32, number: u64, generation: u32) -> Write {
        Write::LeaseLost {
            run: RunId(run),
            number: CandidateNumber(number),
            generation,
            attempts: 1,
            worker: WorkerId(7),
        }
    }

    fn step(run: u32, generation: u32, next_candidate: u64) -> Write {
        Write::Step(Box::new(StepCommit {
            run: RunId(run),
            position: RunPosition {
                generation,
                initial_passed: 400,
                next_candidate,
                finished: false,
            },
            candidates: Vec::new(),
            elites: Vec::new(),
            infeasible: Vec::new(),
            completed: None,
        }))
    }

    #[test]
    fn only_rows_a_later_step_of_their_run_clears_are_skipped() {
        let writes = [
            lost(0, 10, 3), // cleared by run 0's later step (next 20)
            lost(1, 10, 3), // run 1 has no step in the group
            lost(0, 25, 3), // beyond the step's next candidate
            lost(0, 2, 0),  // a spare initial draw: the initial population is done
            step(0, 3, 20),
            lost(0, 12, 3), // after the step: written (cannot happen, but must be kept)
            Write::WorkerLeft {
                id: WorkerId(7),
                results: 0,
                reason: String::new(),
            },
        ];
        assert_eq!(
            rows_outliving_the_group(&writes),
            [false, true, true, false, true, true, true]
        );
    }

    #[test]
    fn spare_initial_draws_stay_while_the_initial_population_is_open() {
        // Generation 0, not completed: a step clears only applied numbers.
        let writes = [lost(0, 30, 0), lost(0, 5, 0), step(0, 0, 10)];
        assert_eq!(rows_outliving_the_group(&writes), [true, false, true]);
    }
}
