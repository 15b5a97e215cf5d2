//! The database: the only state a coordinator has. SQLite through sqlx, migrations embedded
//! in the binary, WAL with full syncs; every change to a run (a batch of the initial
//! population, or a whole generation with its statistics) is one transaction, so a
//! coordinator killed at any instant loses at most the work in flight.

mod checks;
pub mod checksum;
mod experiment;
mod group;
mod open;
pub(crate) mod rows;

pub use checks::{damaged_generations, damaged_rows};
pub use experiment::{canonical_toml, extends, first_difference};
use open::WriterLock;

pub use group::PreparedGroup;

use crate::qd::library::{GenerationStats, InfeasibleLibrary, Library};
use checksum::{GenerationColumns, GENERATION_COLUMNS};
use sqlx::sqlite::{
    SqliteConnectOptions, SqliteJournalMode, SqlitePool, SqlitePoolOptions, SqliteSynchronous,
};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use strider_common::ids::CandidateNumber;
use strider_common::{
    CellIndex, Experiment, Genome, Outcome, RunId, Shortfall, Standing, WorkerId,
};

/// A database problem, with what was being done.
#[derive(Debug, thiserror::Error)]
pub enum DbError {
    #[error("database {path}: {source}")]
    Open { path: String, source: sqlx::Error },
    #[error("database migration failed: {0}")]
    Migrate(#[from] sqlx::migrate::MigrateError),
    #[error("database query failed: {0}")]
    Query(#[from] sqlx::Error),
    #[error("database holds invalid data: {0}")]
    Corrupt(String),
    #[error("copying the database to {path}: {source}")]
    Backup {
        path: String,
        source: std::io::Error,
    },
    #[error("database {path} is in use by another coordinator ({holder}): stop it first, or use another --db")]
    Locked { path: String, holder: String },
    #[error("database {path} is missing or empty but its write-ahead log {path}-wal holds {log_bytes} bytes: the database file was deleted, truncated or replaced, and the log alone cannot rebuild it (opening it would start the experiment over and delete the log); restore {path} from a backup, or move the log away to start again")]
    LogWithoutDatabase { path: String, log_bytes: u64 },
    #[error("database {path} has {links} names (hard links): SQLite keeps its write-ahead log beside the name a file is opened by, so two names mean two logs, and two coordinators or a resume under the other name would damage it; remove the other links (`find / -xdev -samefile {path}` lists them) and open it by one name")]
    HardLinked { path: String, links: u64 },
    #[error("locking database {path} through {lock}: {source}")]
    Lock {
        path: String,
        lock: String,
        source: std::io::Error,
    },
}

pub use strider_common::build_id;

use crate::qd::changes::{StoredCandidate, StoredPending};
use crate::qd::run::RunRecord;
use rows::{
    EliteRow, EliteWithOutcomeRow, InfeasibleRow, InfeasibleWithOutcomeRow, PendingRow, RunRow,
};
use std::collections::HashMap;

/// A run's id as a row stores it.
pub(crate) fn run_column(run: RunId) -> i64 {
    i64::from(run.0)
}

/// A run id as `table` stores it, checked.
pub(crate) fn run_of(column: i64, table: &str) -> Result<RunId, DbError> {
    u32::try_from(column)
        .map(RunId)
        .map_err(|_| DbError::Corrupt(format!("table {table}: run id {column} out of range")))
}

/// A worker id as a row stores it.
pub(crate) fn worker_column(worker: WorkerId) -> i64 {
    worker.0 as i64
}

/// Which elites a listing wants.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EliteFilter {
    /// Only this run.
    pub run: Option<RunId>,
    /// Only this cell.
    pub cell: Option<i64>,
    /// Only at least this fit.
    pub min_fitness: Option<f64>,
}

/// An elite as stored, with the outcome that placed it.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredElite {
    pub run: RunId,
    pub cell: CellIndex,
    pub candidate: CandidateNumber,
    pub fitness: f64,
    /// Its genome, with the controller that earned the fitness.
    pub genome: Genome,
    pub outcome: Outcome,
}

/// An infeasible elite as stored, with the outcome that placed it.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredInfeasible {
    pub cell: CellIndex,
    pub candidate: CandidateNumber,
    /// What keeps it from the brief.
    pub shortfall: Shortfall,
    /// Its figure in the order of outcomes (speed, or when its trial ended).
    pub standing: f64,
    /// Its genome, with the controller it was evaluated with.
    pub genome: Genome,
    pub outcome: Outcome,
}

/// The database.
#[derive(Clone)]
pub struct Db {
    pool: SqlitePool,
    /// The writer's exclusive lock, held as long as any clone lives (`open_exclusive`).
    _lock: Option<std::sync::Arc<WriterLock>>,
}

/// A shortfall's place in the order of outcomes, from its stored figure: speed for trials
/// that ran to the end, the time it ended for the others.
pub fn standing_of(shortfall: Shortfall, figure: f64) -> Standing {
    match shortfall {
        Shortfall::Speed | Shortfall::Backward => Standing::TooSlow { speed: figure },
        Shortfall::StepSensitive
        | Shortfall::FrictionSensitive
        | Shortfall::Skating
        | Shortfall::Fell
        | Shortfall::SelfContact
        | Shortfall::Unstable => Standing::EndedEarly { at_time: figure },
    }
}

/// The figure stored beside a shortfall (the inverse of [`standing_of`]).
pub fn standing_figure(s: Standing) -> Option<f64> {
    match s {
        Standing::TooSlow { speed } => Some(speed),
        Standing::EndedEarly { at_time } => Some(at_time),
        Standing::Feasible { .. } | Standing::NotSimulated => None,
    }
}

impl Db {
    /// How many runs have generations left to do.
    pub async fn unfinished_runs(&self) -> Result<i64, DbError> {
        Ok(
            sqlx::query_scalar("SELECT COUNT(*) FROM runs WHERE finished = 0")
                .fetch_one(&self.pool)
                .await?,
        )
    }

    /// Every run with its library, rebuilt from the elites table.
    pub async fn runs(&self) -> Result<Vec<RunRecord>, DbError> {
        // Three queries whatever the number of runs: runs, elites, infeasible elites.
        let found = sqlx::query("SELECT id, scheme, repeat, seed, generation, initial_passed, next_candidate, finished FROM runs ORDER BY id")
            .fetch_all(&self.pool)
            .await?;
        let runs: Vec<RunRow> = rows::decode_all(&found, "runs", &["id"])?;
        let mut out = Vec::with_capacity(runs.len());
        let mut index = HashMap::with_capacity(runs.len());
        for r in runs {
            index.insert(r.id, out.len());
            out.push(RunRecord {
                id: run_of(r.id, "runs")?,
                spec: r.spec()?,
                generation: r.generation as u32,
                initial_passed: r.initial_passed as u32,
                next_candidate: r.next_candidate as u64,
                finished: r.finished != 0,
                library: Library::new(),
                infeasible: InfeasibleLibrary::default(),
            });
        }
        let run_of = |id: i64| {
            index.get(&id).copied().ok_or_else(|| {
                DbError::Corrupt(format!(
                    "table cells or infeasible_cells: an elite of run {id}, which table runs does not hold"
                ))
            })
        };
        let found = sqlx::query(
            "SELECT run_id, cell, candidate, fitness, genome FROM elites ORDER BY run_id, cell",
        )
        .fetch_all(&self.pool)
        .await?;
        let elites: Vec<EliteRow> = rows::decode_all(&found, "cells", &["run_id", "cell"])?;
        for e in elites {
            let run = run_of(e.run_id)?;
            let (cell, elite) = e.elite()?;
            out[run].library.restore(cell, elite);
        }
        let found = sqlx::query("SELECT run_id, cell, candidate, shortfall, standing, genome FROM infeasible_elites ORDER BY run_id, cell")
            .fetch_all(&self.pool)
            .await?;
        let infeasible: Vec<InfeasibleRow> =
            rows::decode_all(&found, "infeasible_cells", &["run_id", "cell"])?;
        for e in infeasible {
            let run = run_of(e.run_id)?;
            let (cell, elite) = e.elite()?;
            out[run].infeasible.restore(cell, elite);
        }
        Ok(out)
    }

    /// Every stored candidate of the runs' current steps.
    pub async fn pending(&self) -> Result<Vec<StoredPending>, DbError> {
        let found = sqlx::query(
            "SELECT run_id, number, generation, status, attempts, worker, outcome, seconds, checksum FROM pending ORDER BY run_id, number",
        )
        .fetch_all(&self.pool)
        .await?;
        let rows: Vec<PendingRow> = rows::decode_all(&found, "pending", &["run_id", "number"])?;
        // Each row against its checksum (rows written before checksums have none).
        for r in &rows {
            if r.checksum.is_some_and(|c| c != r.computed_checksum()) {
                return Err(DbError::Corrupt(format!(
                    "table pending, run {} candidate {}: the row does not match its checksum, so it was changed after it was written",
                    r.run_id, r.number
                )));
            }
        }
        rows.into_iter().map(StoredPending::try_from).collect()
    }

    /// Every applied candidate of every run, in run and number order.
    pub async fn candidates(&self) -> Result<Vec<StoredCandidate>, DbError> {
        let rows = sqlx::query(
            "SELECT run_id, number, generation, genome, outcome, kind, fitness, cell FROM candidates ORDER BY run_id, number",
        )
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| {
                let t = "candidates";
                let run: i64 = rows::column(r, t, "a row", "run_id")?;
                let number = rows::column::<i64>(r, t, format!("run {run}"), "number")? as u64;
                let key = format!("run {run} candidate {number}");
                let corrupt = |what: &str, e: serde_json::Error| {
                    DbError::Corrupt(format!("run {run} candidate {number}: {what}: {e}"))
                };
                Ok(StoredCandidate {
                    run: run_of(run, t)?,
                    number: CandidateNumber(number),
                    generation: rows::column::<i64>(r, t, &key, "generation")? as u32,
                    genome: serde_json::from_str(rows::column::<&str>(r, t, &key, "genome")?)
                        .map_err(|e| corrupt("genome", e))?,
                    outcome: serde_json::from_str(rows::column::<&str>(r, t, &key, "outcome")?)
                        .map_err(|e| corrupt("outcome", e))?,
                    columns: (
                        rows::column(r, t, &key, "kind")?,
                        rows::column(r, t, &key, "fitness")?,
                        rows::column(r, t, &key, "cell")?,
                    ),
                })
            })
            .collect()
    }

    /// Closes the worker sessions still open, ending them now for `reason`: at a start,
    /// those a coordinator that was killed (or lost its node) left open; at a clean stop,
    /// those whose workers had not left yet. Returns how many.
    pub async fn close_sessions_left_open(&self, reason: &str) -> Result<u64, DbError> {
        let done = sqlx::query(
            "UPDATE workers SET disconnected_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now'), \
             left_because = ? WHERE disconnected_at IS NULL",
        )
        .bind(reason)
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected())
    }

    /// The id the next worker session gets (ids are never reused, across restarts too).
    pub async fn next_worker_id(&self) -> Result<WorkerId, DbError> {
        let max: Option<i64> = sqlx::query_scalar("SELECT MAX(id) FROM workers")
            .fetch_one(&self.pool)
            .await?;
        Ok(WorkerId(max.map_or(1, |m| m as u64 + 1)))
    }

    /// Elites, best first, filtered, one page: `(run, cell, candidate, fitness, outcome)`.
    pub async fn list_elites(
        &self,
        filter: &EliteFilter,
        offset: u64,
        limit: u32,
    ) -> Result<Vec<StoredElite>, DbError> {
        let found = sqlx::query(
            "SELECT e.run_id, e.cell, e.candidate, e.fitness, e.genome, c.outcome FROM elites e \
             JOIN candidates c ON c.run_id = e.run_id AND c.number = e.candidate \
             WHERE (?1 IS NULL OR e.run_id = ?1) AND (?2 IS NULL OR e.cell = ?2) AND (?3 IS NULL OR e.fitness >= ?3) \
             ORDER BY e.fitness DESC, e.run_id, e.cell LIMIT ?4 OFFSET ?5",
        )
        .bind(filter.run.map(run_column))
        .bind(filter.cell)
        .bind(filter.min_fitness)
        .bind(i64::from(limit))
        .bind(offset as i64)
        .fetch_all(&self.pool)
        .await?;
        let rows: Vec<EliteWithOutcomeRow> =
            rows::decode_all(&found, "cells", &["run_id", "cell"])?;
        rows.into_iter().map(StoredElite::try_from).collect()
    }

    /// A run's infeasible library in cell order, with each elite's outcome.
    pub async fn list_infeasible(&self, run: RunId) -> Result<Vec<StoredInfeasible>, DbError> {
        let found = sqlx::query(
            "SELECT e.run_id, e.cell, e.candidate, e.shortfall, e.standing, e.genome, c.outcome FROM infeasible_elites e \
             JOIN candidates c ON c.run_id = e.run_id AND c.number = e.candidate \
             WHERE e.run_id = ? ORDER BY e.cell",
        )
        .bind(run_column(run))
        .fetch_all(&self.pool)
        .await?;
        let rows: Vec<InfeasibleWithOutcomeRow> =
            rows::decode_all(&found, "infeasible_cells", &["run_id", "cell"])?;
        rows.into_iter().map(StoredInfeasible::try_from).collect()
    }

    /// Per-generation statistics of a run, in order. A row that does not match its
    /// checksum, or cannot be decoded, is an error naming it.
    pub async fn generations(
        &self,
        run: RunId,
    ) -> Result<Vec<(u32, u64, GenerationStats)>, DbError> {
        let rows = sqlx::query(&format!(
            "SELECT {GENERATION_COLUMNS} FROM generations WHERE run_id = ? ORDER BY generation"
        ))
        .bind(run_column(run))
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| {
                let (columns, stored) = GenerationColumns::from_row(r)?;
                if stored.is_some_and(|s| s != columns.checksum()) {
                    return Err(DbError::Corrupt(format!(
                        "table generations, run {} generation {}: the row does not match its checksum, so it was changed after it was written",
                        columns.run, columns.generation
                    )));
                }
                columns.try_into()
            })
            .collect()
    }
}
