//! Rows as the tables hold them, decoded by column name (a query's column order can change
//! without a silent mix-up), and their conversion to the model's types, which refuses text
//! that names nothing.

use super::{standing_of, DbError, StoredElite, StoredInfeasible};
use crate::qd::changes::StoredPending;
use crate::qd::library::{Elite, InfeasibleElite};
use sqlx::sqlite::{Sqlite, SqliteRow};
use sqlx::Row;
use std::fmt::Display;
use strider_common::experiment::RunSpec;
use strider_common::ids::CandidateNumber;
use strider_common::rng::RunSeed;
use strider_common::{CellIndex, Genome, Outcome, Scheme, Shortfall};

/// Column `column` of `row`, a row of `table` that `key` names ("run 0 candidate 12"):
/// damaged content (text that is not UTF-8, a value of the wrong type) is an error naming
/// all three, never a panic.
pub(crate) fn column<'r, T>(
    row: &'r SqliteRow,
    table: &str,
    key: impl Display,
    column: &str,
) -> Result<T, DbError>
where
    T: sqlx::Decode<'r, Sqlite> + sqlx::Type<Sqlite>,
{
    row.try_get(column)
        .map_err(|e| DbError::Corrupt(format!("table {table}, {key}, column {column}: {e}")))
}

/// Every row of a query decoded as `T` by column name: a column that cannot be decoded
/// (text that is not UTF-8, a value of the wrong type) is an error naming the table, the
/// row by its `key` columns, and the column, never a bare decode error.
pub(super) fn decode_all<T>(
    rows: &[SqliteRow],
    table: &str,
    key: &[&str],
) -> Result<Vec<T>, DbError>
where
    T: for<'r> sqlx::FromRow<'r, SqliteRow>,
{
    rows.iter()
        .map(|r| {
            T::from_row(r).map_err(|e| {
                let named: Vec<String> = key
                    .iter()
                    .map(|k| match r.try_get::<i64, _>(*k) {
                        Ok(v) => format!("{k} {v}"),
                        Err(_) => format!("{k} (unreadable)"),
                    })
                    .collect();
                DbError::Corrupt(format!("table {table}, {}: {e}", named.join(" ")))
            })
        })
        .collect()
}

/// A `runs` row.
#[derive(sqlx::FromRow)]
pub(super) struct RunRow {
    pub id: i64,
    pub scheme: String,
    pub repeat: i64,
    pub seed: i64,
    pub generation: i64,
    pub initial_passed: i64,
    pub next_candidate: i64,
    pub finished: i64,
}

impl RunRow {
    /// Its scheme, repeat and seed.
    pub fn spec(&self) -> Result<RunSpec, DbError> {
        Ok(RunSpec {
            scheme: self.scheme.parse::<Scheme>().map_err(|e| {
                DbError::Corrupt(format!("table runs, run {}, column scheme: {e}", self.id))
            })?,
            repeat: self.repeat as u32,
            seed: RunSeed(self.seed as u64),
        })
    }
}

/// An `elites` row.
#[derive(sqlx::FromRow)]
pub(super) struct EliteRow {
    pub run_id: i64,
    pub cell: i64,
    pub candidate: i64,
    pub fitness: f64,
    pub genome: String,
}

impl EliteRow {
    /// Its cell and elite.
    pub fn elite(self) -> Result<(CellIndex, Elite), DbError> {
        let genome: Genome = serde_json::from_str(&self.genome).map_err(|x| {
            DbError::Corrupt(format!(
                "table elites, run {} cell {} (candidate {}), column genome: {x}",
                self.run_id, self.cell, self.candidate
            ))
        })?;
        Ok((
            CellIndex(self.cell as u32),
            Elite {
                candidate: CandidateNumber(self.candidate as u64),
                genome,
                fitness: self.fitness,
            },
        ))
    }
}

/// An `infeasible_elites` row.
#[derive(sqlx::FromRow)]
pub(super) struct InfeasibleRow {
    pub run_id: i64,
    pub cell: i64,
    pub candidate: i64,
    pub shortfall: String,
    pub standing: f64,
    pub genome: String,
}

impl InfeasibleRow {
    /// Its cell and elite.
    pub fn elite(self) -> Result<(CellIndex, InfeasibleElite), DbError> {
        let (run, cell, candidate) = (self.run_id, self.cell, self.candidate);
        let corrupt = |what: String| {
            DbError::Corrupt(format!(
                "table infeasible_elites, run {run} cell {cell} (candidate {candidate}): {what}"
            ))
        };
        let shortfall =
            shortfall(&self.shortfall).map_err(|x| corrupt(format!("column shortfall: {x}")))?;
        Ok((
            CellIndex(self.cell as u32),
            InfeasibleElite {
                candidate: CandidateNumber(self.candidate as u64),
                genome: serde_json::from_str(&self.genome)
                    .map_err(|x| corrupt(format!("column genome: {x}")))?,
                standing: standing_of(shortfall, self.standing),
                shortfall,
            },
        ))
    }
}

/// The shortfall a stored name names.
pub(super) fn shortfall(name: &str) -> Result<Shortfall, String> {
    Shortfall::named(name).ok_or_else(|| format!("unknown shortfall `{name}`"))
}

/// A `pending` row, every column (the checksum covers them all), as written and as read.
#[derive(sqlx::FromRow)]
pub(super) struct PendingRow {
    pub run_id: i64,
    pub number: i64,
    pub generation: i64,
    pub status: String,
    pub attempts: i64,
    pub worker: Option<i64>,
    pub outcome: Option<String>,
    pub seconds: Option<f64>,
    pub checksum: Option<i64>,
}

impl TryFrom<PendingRow> for StoredPending {
    type Error = DbError;

    /// The row as the scheduler reads it (its checksum is checked by the reader, in
    /// `Db::pending`).
    fn try_from(r: PendingRow) -> Result<Self, DbError> {
        let (run, number) = (r.run_id, r.number);
        Ok(StoredPending {
            run: super::run_of(r.run_id, "pending")?,
            number: CandidateNumber(r.number as u64),
            attempts: r.attempts as u32,
            generation: r.generation as u32,
            outcome: r
                .outcome
                .map(|o| serde_json::from_str::<Outcome>(&o))
                .transpose()
                .map_err(|e| {
                    DbError::Corrupt(format!(
                        "table pending, run {run} candidate {number}, column outcome: {e}"
                    ))
                })?,
        })
    }
}

/// An `elites` row joined with its candidate's outcome.
#[derive(sqlx::FromRow)]
pub(super) struct EliteWithOutcomeRow {
    #[sqlx(flatten)]
    pub elite: EliteRow,
    pub outcome: String,
}

impl TryFrom<EliteWithOutcomeRow> for StoredElite {
    type Error = DbError;

    fn try_from(r: EliteWithOutcomeRow) -> Result<Self, DbError> {
        let run = r.elite.run_id;
        let (cell, elite) = r.elite.elite()?;
        let candidate = elite.candidate.0;
        Ok(StoredElite {
            run: super::run_of(run, "cells")?,
            cell,
            candidate: elite.candidate,
            fitness: elite.fitness,
            genome: elite.genome,
            outcome: serde_json::from_str(&r.outcome).map_err(|e| {
                DbError::Corrupt(format!(
                    "table candidates, run {run} candidate {candidate} (the elite of cell {}), column outcome: {e}",
                    cell.0
                ))
            })?,
        })
    }
}

/// An `infeasible_elites` row joined with its candidate's outcome.
#[derive(sqlx::FromRow)]
pub(super) struct InfeasibleWithOutcomeRow {
    #[sqlx(flatten)]
    pub elite: InfeasibleRow,
    pub outcome: String,
}

impl TryFrom<InfeasibleWithOutcomeRow> for StoredInfeasible {
    type Error = DbError;

    fn try_from(r: InfeasibleWithOutcomeRow) -> Result<Self, DbError> {
        let figure = r.elite.standing;
        let (cell, elite) = r.elite.elite()?;
        Ok(StoredInfeasible {
            cell,
            candidate: elite.candidate,
            shortfall: elite.shortfall,
            standing: figure,
            genome: elite.genome,
            outcome: serde_json::from_str(&r.outcome).map_err(|e| {
                DbError::Corrupt(format!(
                    "table candidates, candidate {} (the infeasible elite of cell {}), column outcome: {e}",
                    elite.candidate.0, cell.0
                ))
            })?,
        })
    }
}
