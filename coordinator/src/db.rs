//! The database: the only state a coordinator has. SQLite through sqlx, migrations embedded
//! in the binary, WAL with full syncs; every change to a run (a batch of the initial
//! population, or a whole generation with its statistics) is one transaction, so a
//! coordinator killed at any instant loses at most the work in flight.

use crate::library::{Elite, GenerationStats, Library, Placement};
use sqlx::sqlite::{
    SqliteConnectOptions, SqliteJournalMode, SqlitePool, SqlitePoolOptions, SqliteSynchronous,
};
use sqlx::Row;
use std::path::Path;
use std::str::FromStr;
use strider_common::experiment::RunSpec;
use strider_common::rng::{CandidateNumber, RunSeed};
use strider_common::{CellIndex, Experiment, Genome, Outcome, Scheme};

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
}

/// The Strider build, recorded with the experiment: trials are bit-identical only within
/// one build (see ../shared/notes/rapier.md).
pub fn build_id() -> String {
    format!(
        "strider {} ({}, {})",
        env!("CARGO_PKG_VERSION"),
        std::env::consts::ARCH,
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        }
    )
}

/// One run's persistent state.
#[derive(Clone, Debug)]
pub struct RunRecord {
    /// Row id (0-based, in experiment order).
    pub id: i64,
    /// Scheme, repeat and seed.
    pub spec: RunSpec,
    /// Last committed generation (0: the initial population, complete or not).
    pub generation: u32,
    /// Valid candidates in the initial population so far.
    pub initial_passed: u32,
    /// First candidate number not yet committed.
    pub next_candidate: u64,
    /// Whether the run has done all its generations.
    pub finished: bool,
    /// Its library.
    pub library: Library,
}

/// One evaluated candidate, ready to store.
pub struct CandidateRow<'a> {
    /// Its number.
    pub number: CandidateNumber,
    /// Its generation (0 = initial population).
    pub generation: u32,
    /// Its genome.
    pub genome: &'a Genome,
    /// Its outcome.
    pub outcome: &'a Outcome,
    /// What it did to the library.
    pub placement: Placement,
}

/// The database.
#[derive(Clone)]
pub struct Db {
    pool: SqlitePool,
}

fn placement_name(p: Placement) -> &'static str {
    match p {
        Placement::New => "new",
        Placement::Improved => "improved",
        Placement::Discarded => "discarded",
        Placement::Rejected => "rejected",
        Placement::Invalid => "invalid",
    }
}

impl Db {
    /// Opens (creating if asked) a database file and brings its schema up to date.
    pub async fn open(path: &Path, create: bool) -> Result<Self, DbError> {
        let options = SqliteConnectOptions::from_str(&format!("sqlite://{}", path.display()))
            .map_err(|e| DbError::Open {
                path: path.display().to_string(),
                source: e,
            })?
            .create_if_missing(create)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Full)
            .foreign_keys(true);
        // One connection: one writer, and reads see its commits.
        let pool = SqlitePoolOptions::new()
            .max_connections(1)
            .connect_with(options)
            .await
            .map_err(|e| DbError::Open {
                path: path.display().to_string(),
                source: e,
            })?;
        sqlx::migrate!("./migrations").run(&pool).await?;
        Ok(Self { pool })
    }

    /// The stored experiment, if any.
    pub async fn experiment(&self) -> Result<Option<(Experiment, String)>, DbError> {
        let row = sqlx::query("SELECT definition, build FROM experiment WHERE id = 1")
            .fetch_optional(&self.pool)
            .await?;
        row.map(|r| {
            let text: String = r.get(0);
            let e = Experiment::from_toml(&text)
                .map_err(|e| DbError::Corrupt(format!("stored experiment: {e}")))?;
            Ok((e, r.get(1)))
        })
        .transpose()
    }

    /// Stores a new experiment and its runs.
    pub async fn create_experiment(&self, e: &Experiment) -> Result<(), DbError> {
        let mut tx = self.pool.begin().await?;
        sqlx::query("INSERT INTO experiment (id, name, definition, build, created_at) VALUES (1, ?, ?, ?, strftime('%Y-%m-%dT%H:%M:%SZ', 'now'))")
            .bind(&e.name)
            .bind(canonical_toml(e))
            .bind(build_id())
            .execute(&mut *tx)
            .await?;
        for (id, run) in e.runs().iter().enumerate() {
            sqlx::query("INSERT INTO runs (id, scheme, repeat, seed, generation, initial_passed, next_candidate) VALUES (?, ?, ?, ?, 0, 0, 0)")
                .bind(id as i64)
                .bind(run.scheme.name())
                .bind(i64::from(run.repeat))
                .bind(run.seed.0 as i64)
                .execute(&mut *tx)
                .await?;
        }
        tx.commit().await?;
        Ok(())
    }

    /// Every run with its library, rebuilt from the elites table.
    pub async fn runs(&self) -> Result<Vec<RunRecord>, DbError> {
        let rows = sqlx::query("SELECT id, scheme, repeat, seed, generation, initial_passed, next_candidate, finished FROM runs ORDER BY id")
            .fetch_all(&self.pool)
            .await?;
        let mut out = Vec::with_capacity(rows.len());
        for r in rows {
            let id: i64 = r.get(0);
            let scheme: String = r.get(1);
            let mut library = Library::new();
            for e in sqlx::query("SELECT cell, candidate, fitness, genome FROM elites WHERE run_id = ? ORDER BY cell")
                .bind(id)
                .fetch_all(&self.pool)
                .await?
            {
                let genome: String = e.get(3);
                let genome: Genome = serde_json::from_str(&genome).map_err(|x| DbError::Corrupt(format!("elite genome of run {id}: {x}")))?;
                library.restore(
                    CellIndex(e.get::<i64, _>(0) as u32),
                    Elite { candidate: CandidateNumber(e.get::<i64, _>(1) as u64), genome, fitness: e.get(2) },
                );
            }
            out.push(RunRecord {
                id,
                spec: RunSpec {
                    scheme: Scheme::from_str(&scheme).map_err(DbError::Corrupt)?,
                    repeat: r.get::<i64, _>(2) as u32,
                    seed: RunSeed(r.get::<i64, _>(3) as u64),
                },
                generation: r.get::<i64, _>(4) as u32,
                initial_passed: r.get::<i64, _>(5) as u32,
                next_candidate: r.get::<i64, _>(6) as u64,
                finished: r.get::<i64, _>(7) != 0,
                library,
            });
        }
        Ok(out)
    }

    /// Commits one step of a run in one transaction: its evaluated candidates, the elites
    /// they changed, the run's new position, and, when a generation completes, its
    /// statistics (for the initial population, counted from all its stored candidates).
    pub async fn commit(
        &self,
        run: &RunRecord,
        candidates: &[CandidateRow<'_>],
        completed_generation: Option<(u32, GenerationStats)>,
    ) -> Result<(), DbError> {
        let mut tx = self.pool.begin().await?;
        for c in candidates {
            let (fitness, cell) = match c.outcome {
                Outcome::Valid { fitness, cell, .. } => (Some(*fitness), Some(i64::from(cell.0))),
                _ => (None, None),
            };
            sqlx::query("INSERT INTO candidates (run_id, number, generation, genome, outcome, kind, fitness, cell, placement) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)")
                .bind(run.id)
                .bind(c.number.0 as i64)
                .bind(i64::from(c.generation))
                .bind(serde_json::to_string(c.genome).expect("genomes serialise"))
                .bind(serde_json::to_string(c.outcome).expect("outcomes serialise"))
                .bind(c.outcome.kind())
                .bind(fitness)
                .bind(cell)
                .bind(placement_name(c.placement))
                .execute(&mut *tx)
                .await?;
            if matches!(c.placement, Placement::New | Placement::Improved) {
                let cell = match c.outcome {
                    Outcome::Valid { cell, .. } => *cell,
                    _ => unreachable!("only valid outcomes enter the library"),
                };
                let elite = run
                    .library
                    .get(cell)
                    .expect("a placed candidate's cell is occupied");
                sqlx::query("INSERT INTO elites (run_id, cell, candidate, fitness, genome) VALUES (?, ?, ?, ?, ?) ON CONFLICT (run_id, cell) DO UPDATE SET candidate = excluded.candidate, fitness = excluded.fitness, genome = excluded.genome")
                    .bind(run.id)
                    .bind(i64::from(cell.0))
                    .bind(elite.candidate.0 as i64)
                    .bind(elite.fitness)
                    .bind(serde_json::to_string(&elite.genome).expect("genomes serialise"))
                    .execute(&mut *tx)
                    .await?;
            }
        }
        if let Some((generation, mut stats)) = completed_generation {
            if generation == 0 {
                for r in sqlx::query("SELECT placement, COUNT(*) FROM candidates WHERE run_id = ? AND generation = 0 GROUP BY placement")
                    .bind(run.id)
                    .fetch_all(&mut *tx)
                    .await?
                {
                    let n = r.get::<i64, _>(1) as usize;
                    match r.get::<String, _>(0).as_str() {
                        "new" => stats.new = n,
                        "improved" => stats.improved = n,
                        "discarded" => stats.discarded = n,
                        "rejected" => stats.rejected = n,
                        _ => stats.invalid = n,
                    }
                }
            }
            let evaluations =
                stats.new + stats.improved + stats.discarded + stats.rejected + stats.invalid;
            sqlx::query("INSERT INTO generations (run_id, generation, evaluations, coverage, elites, max_fitness, mean_fitness, min_fitness, qd_score, new, improved, discarded, rejected, invalid) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)")
                .bind(run.id)
                .bind(i64::from(generation))
                .bind(evaluations as i64)
                .bind(stats.coverage)
                .bind(stats.elites as i64)
                .bind(stats.max_fitness)
                .bind(stats.mean_fitness)
                .bind(stats.min_fitness)
                .bind(stats.qd_score)
                .bind(stats.new as i64)
                .bind(stats.improved as i64)
                .bind(stats.discarded as i64)
                .bind(stats.rejected as i64)
                .bind(stats.invalid as i64)
                .execute(&mut *tx)
                .await?;
        }
        sqlx::query("UPDATE runs SET generation = ?, initial_passed = ?, next_candidate = ?, finished = ? WHERE id = ?")
            .bind(i64::from(run.generation))
            .bind(i64::from(run.initial_passed))
            .bind(run.next_candidate as i64)
            .bind(i64::from(run.finished))
            .bind(run.id)
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(())
    }

    /// Per-generation statistics of a run, in order.
    pub async fn generations(
        &self,
        run_id: i64,
    ) -> Result<Vec<(u32, u64, GenerationStats)>, DbError> {
        let rows = sqlx::query("SELECT generation, evaluations, coverage, elites, max_fitness, mean_fitness, min_fitness, qd_score, new, improved, discarded, rejected, invalid FROM generations WHERE run_id = ? ORDER BY generation")
            .bind(run_id)
            .fetch_all(&self.pool)
            .await?;
        Ok(rows
            .iter()
            .map(|r| {
                let n = |i: usize| r.get::<i64, _>(i) as usize;
                (
                    r.get::<i64, _>(0) as u32,
                    r.get::<i64, _>(1) as u64,
                    GenerationStats {
                        coverage: r.get(2),
                        elites: n(3),
                        max_fitness: r.get(4),
                        mean_fitness: r.get(5),
                        min_fitness: r.get(6),
                        qd_score: r.get(7),
                        new: n(8),
                        improved: n(9),
                        discarded: n(10),
                        rejected: n(11),
                        invalid: n(12),
                    },
                )
            })
            .collect())
    }

    /// `PRAGMA integrity_check`: "ok" for a sound file.
    pub async fn integrity_check(&self) -> Result<String, DbError> {
        Ok(sqlx::query("PRAGMA integrity_check")
            .fetch_one(&self.pool)
            .await?
            .get(0))
    }
}

/// The experiment as canonical TOML (what the database stores and compares).
pub fn canonical_toml(e: &Experiment) -> String {
    toml::to_string(e).expect("experiments serialise")
}

/// The first setting in which two experiments differ, as `path: stored vs given`.
pub fn first_difference(stored: &Experiment, given: &Experiment) -> Option<String> {
    let a: toml::Value = toml::from_str(&canonical_toml(stored)).expect("canonical TOML parses");
    let b: toml::Value = toml::from_str(&canonical_toml(given)).expect("canonical TOML parses");
    diff(&a, &b, String::new())
}

fn diff(a: &toml::Value, b: &toml::Value, path: String) -> Option<String> {
    match (a, b) {
        (toml::Value::Table(ta), toml::Value::Table(tb)) => {
            let mut keys: Vec<&String> = ta.keys().chain(tb.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter().find_map(|k| {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                match (ta.get(k), tb.get(k)) {
                    (Some(x), Some(y)) => diff(x, y, p),
                    (x, y) => Some(format!(
                        "{p}: {} in the database, {} given",
                        show(x),
                        show(y)
                    )),
                }
            })
        }
        _ if a == b => None,
        _ => Some(format!("{path}: {a} in the database, {b} given")),
    }
}

fn show(v: Option<&toml::Value>) -> String {
    v.map_or_else(|| "absent".into(), |v| v.to_string())
}
