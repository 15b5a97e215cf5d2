//! The database: the only state a coordinator has. SQLite through sqlx, migrations embedded
//! in the binary, WAL with full syncs; every change to a run (a batch of the initial
//! population, or a whole generation with its statistics) is one transaction, so a
//! coordinator killed at any instant loses at most the work in flight.

pub mod checksum;
mod group;
pub(crate) mod rows;

pub use group::PreparedGroup;

use crate::qd::library::{GenerationStats, InfeasibleLibrary, Library};
use checksum::{GenerationColumns, GENERATION_COLUMNS};
use sqlx::sqlite::{
    SqliteConnectOptions, SqliteJournalMode, SqlitePool, SqlitePoolOptions, SqliteSynchronous,
};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use strider_common::rng::CandidateNumber;
use strider_common::{CellIndex, Experiment, Genome, Outcome, Shortfall, Standing};

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

use crate::qd::changes::{RunRecord, StoredCandidate, StoredPending};
use rows::{
    EliteRow, EliteWithOutcomeRow, InfeasibleRow, InfeasibleWithOutcomeRow, PendingRow, RunRow,
};
use std::collections::HashMap;

/// Which elites a listing wants.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EliteFilter {
    /// Only this run.
    pub run: Option<i64>,
    /// Only this cell.
    pub cell: Option<i64>,
    /// Only at least this fit.
    pub min_fitness: Option<f64>,
}

/// An elite as stored, with the outcome that placed it.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredElite {
    pub run: i64,
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

/// The writer's lock on a database: an advisory lock on `NAME.lock` beside it, held while
/// this value lives (and released by the system when the process ends, however it ends).
/// Dropped at a clean exit, it removes its file: a stopped run leaves nothing beside its
/// database.
#[derive(Debug)]
struct WriterLock {
    /// Held open: the lock is the open file's.
    _file: std::fs::File,
    path: PathBuf,
}

impl Drop for WriterLock {
    fn drop(&mut self) {
        // Removed while still held: a process that opened the file before it went sees,
        // once it holds the lock, that the name no longer leads to it, and tries again.
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Whether `file` is still the file that `path` names (not removed or replaced).
fn names(path: &Path, file: &std::fs::File) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (std::fs::metadata(path), file.metadata()) {
            (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = (path, file);
        true
    }
}

/// Takes the exclusive lock that makes one coordinator the only writer of `path`, which
/// also says who holds it ([`WriterLock`]).
fn lock(path: &Path) -> Result<WriterLock, DbError> {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".lock");
    let lock_path = path.with_file_name(name);
    let err = |source| DbError::Lock {
        path: path.display().to_string(),
        lock: lock_path.display().to_string(),
        source,
    };
    let mut file = loop {
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&lock_path)
            .map_err(err)?;
        match file.try_lock() {
            // The holder before may have removed the file between our open and our lock.
            Ok(()) if names(&lock_path, &file) => break file,
            Ok(()) => continue,
            Err(std::fs::TryLockError::WouldBlock) => {
                let mut holder = String::new();
                let _ = std::io::Read::read_to_string(&mut file, &mut holder);
                let holder = holder.trim();
                return Err(DbError::Locked {
                    path: path.display().to_string(),
                    holder: if holder.is_empty() {
                        "holder unknown".into()
                    } else {
                        holder.to_string()
                    },
                });
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(err(e)),
        }
    };
    let me = format!(
        "pid {} on {}",
        std::process::id(),
        strider_proto::process::host_name()
    );
    file.set_len(0).map_err(err)?;
    std::io::Write::write_all(&mut file, me.as_bytes()).map_err(err)?;
    Ok(WriterLock {
        _file: file,
        path: lock_path,
    })
}

/// A shortfall's place in the order of outcomes, from its stored figure: speed for trials
/// that ran to the end, the time it ended for the others.
pub fn standing_of(shortfall: Shortfall, figure: f64) -> Standing {
    match shortfall {
        Shortfall::Speed | Shortfall::Backward => Standing::TooSlow { speed: figure },
        Shortfall::StepSensitive
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
    /// Opens a database to write it, as its only writer: refuses while another process
    /// holds it ([`DbError::Locked`], naming the holder), then opens (creating if asked)
    /// and migrates it.
    pub async fn open_exclusive(path: &Path, create: bool) -> Result<Self, DbError> {
        // The one-writer rule is for the file, whatever names it: a symbolic link opens its
        // target (the lock, the log and its index go beside the file, not the link), and a
        // file with several names (hard links) is refused, for SQLite's log follows the
        // name.
        let real = std::fs::canonicalize(path);
        let path = real.as_deref().unwrap_or(path);
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            if let Ok(links @ 2..) = std::fs::metadata(path).map(|m| m.nlink()) {
                return Err(DbError::HardLinked {
                    path: path.display().to_string(),
                    links,
                });
            }
        }
        let lock = lock(path)?;
        let mut db = Self::open(path, create).await?;
        db._lock = Some(std::sync::Arc::new(lock));
        Ok(db)
    }

    /// Opens (creating if asked) a database file and brings its schema up to date.
    pub async fn open(path: &Path, create: bool) -> Result<Self, DbError> {
        // A missing or empty main file beside a log with frames in it is a lost
        // database, not a new one: SQLite would start it afresh and then delete the log.
        let size = |p: &Path| std::fs::metadata(p).map(|m| m.len()).ok();
        let mut wal = path.as_os_str().to_owned();
        wal.push("-wal");
        if let (None | Some(0), Some(log_bytes @ 1..)) = (size(path), size(Path::new(&wal))) {
            return Err(DbError::LogWithoutDatabase {
                path: path.display().to_string(),
                log_bytes,
            });
        }
        let options = SqliteConnectOptions::from_str(&format!("sqlite://{}", path.display()))
            .map_err(|e| DbError::Open {
                path: path.display().to_string(),
                source: e,
            })?
            .create_if_missing(create)
            // Candidate rows are about 2 KB: 4 KB pages held one each and wasted the rest.
            // (Takes effect when the file is created.)
            .page_size(16384)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Full)
            .foreign_keys(true)
            // A group commit touches many pages: a cache that holds them all spares
            // SQLite spilling and rereading them mid-transaction; statement journals
            // (multi-row upserts) need no file.
            .pragma("cache_size", "-65536")
            .pragma("temp_store", "MEMORY")
            // Checkpoints run beside the writer (`Db::checkpoint`, the writer task's
            // checkpointer), not inside its commits, where they took a fifth of its time.
            .pragma("wal_autocheckpoint", "0");
        // One writer (the writer task, or `run`'s loop) and a few readers (client calls):
        // WAL lets them read while it writes.
        let pool = SqlitePoolOptions::new()
            .max_connections(4)
            .connect_with(options)
            .await
            .map_err(|e| DbError::Open {
                path: path.display().to_string(),
                source: e,
            })?;
        sqlx::migrate!("./migrations").run(&pool).await?;
        // An experiment stored before its row had a checksum gets one now.
        let mut tx = pool.begin().await?;
        seal_experiment(&mut tx).await?;
        tx.commit().await?;
        Ok(Self { pool, _lock: None })
    }

    /// Opens an existing database to read it, writing nothing to it or beside it: with no
    /// write-ahead log beside it (a clean stop, a backup, a read-only mount) its main file
    /// is whole and is read as immutable (SQLite then creates no log or index either);
    /// with one (a coordinator running, or killed), read-only through the log. An older
    /// schema is brought up to date first, and only under the writer's lock
    /// ([`Db::open_exclusive`]: refused while a coordinator holds it).
    pub async fn open_for_reading(path: &Path) -> Result<Self, DbError> {
        let mut wal = path.as_os_str().to_owned();
        wal.push("-wal");
        let reader = Self::open_reader(path, !Path::new(&wal).exists()).await?;
        if reader.schema_current().await? {
            return Ok(reader);
        }
        reader.pool.close().await;
        let writer = Self::open_exclusive(path, false).await.map_err(|e| {
            DbError::Corrupt(format!(
                "{} has an older schema, brought up to date only by its writer: {e}",
                path.display()
            ))
        })?;
        writer.pool.close().await;
        drop(writer);
        Self::open_reader(path, true).await
    }

    /// A read-only connection pool on `path`, nothing set that writes; `immutable`:
    /// SQLite reads only the main file and creates nothing beside it (a clean stop's
    /// file, a backup, a read-only mount), else it reads through the log.
    async fn open_reader(path: &Path, immutable: bool) -> Result<Self, DbError> {
        let open_error = |e| DbError::Open {
            path: path.display().to_string(),
            source: e,
        };
        let options = SqliteConnectOptions::from_str(&format!("sqlite://{}", path.display()))
            .map_err(open_error)?
            .read_only(true)
            .immutable(immutable);
        let pool = SqlitePoolOptions::new()
            .max_connections(4)
            .connect_with(options)
            .await
            .map_err(open_error)?;
        // A read that needs the log's index fails here, not at the first query.
        sqlx::query("SELECT COUNT(*) FROM sqlite_master")
            .fetch_one(&pool)
            .await
            .map_err(open_error)?;
        Ok(Self { pool, _lock: None })
    }

    /// Whether every migration this build knows is applied.
    async fn schema_current(&self) -> Result<bool, DbError> {
        let applied: i64 =
            sqlx::query_scalar("SELECT COUNT(*) FROM _sqlx_migrations WHERE success")
                .fetch_one(&self.pool)
                .await?;
        Ok(applied >= sqlx::migrate!("./migrations").iter().count() as i64)
    }

    /// The stored experiment, if any, checked against its row's checksum (a row stored
    /// before checksums has none).
    pub async fn experiment(&self) -> Result<Option<(Experiment, String)>, DbError> {
        let row = sqlx::query(
            "SELECT name, definition, build, created_at, checksum FROM experiment WHERE id = 1",
        )
        .fetch_optional(&self.pool)
        .await?;
        row.map(|r| {
            let stored: Option<i64> = rows::column(&r, "experiment", "row 1", "checksum")?;
            let sum = experiment_row_checksum(&r)?;
            if stored.is_some_and(|s| s != sum) {
                return Err(DbError::Corrupt(
                    "table experiment, row 1: the row does not match its checksum, so its name, definition, build or created_at was changed after it was written".into(),
                ));
            }
            let text: String = rows::column(&r, "experiment", "row 1", "definition")?;
            let e = Experiment::from_toml(&text).map_err(|e| {
                DbError::Corrupt(format!("table experiment, row 1, column definition: {e}"))
            })?;
            Ok((e, rows::column(&r, "experiment", "row 1", "build")?))
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
        seal_experiment(&mut tx).await?;
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
                id: r.id,
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
            let sum = checksum::pending_checksum(
                r.run_id,
                r.number,
                r.generation,
                &r.status,
                r.attempts,
                r.worker,
                r.outcome.as_deref(),
                r.seconds,
            );
            if r.checksum.is_some_and(|c| c != sum) {
                return Err(DbError::Corrupt(format!(
                    "table pending, run {} candidate {}: the row does not match its checksum, so it was changed after it was written",
                    r.run_id, r.number
                )));
            }
        }
        rows.into_iter().map(StoredPending::try_from).collect()
    }

    /// What is inconsistent in the stored state, by cheap queries run on every resume
    /// (`verify` replays everything): the runs against the experiment, each run's next
    /// candidate against the highest stored, each library cell against its candidate row.
    /// Empty when all agree.
    pub async fn inconsistencies(&self, experiment: &Experiment) -> Result<Vec<String>, DbError> {
        let mut out = Vec::new();
        let specs = experiment.runs();
        let rows = sqlx::query(
            "SELECT id, scheme, repeat, seed, next_candidate, \
             (SELECT MAX(number) FROM candidates WHERE run_id = runs.id) AS highest \
             FROM runs ORDER BY id",
        )
        .fetch_all(&self.pool)
        .await?;
        if rows.len() != specs.len() {
            out.push(format!(
                "the experiment has {} runs, the database {}",
                specs.len(),
                rows.len()
            ));
        }
        for (r, spec) in rows.iter().zip(&specs) {
            let id: i64 = rows::column(r, "runs", "a row", "id")?;
            let key = format!("run {id}");
            let scheme: String = rows::column(r, "runs", &key, "scheme")?;
            let seed = rows::column::<i64>(r, "runs", &key, "seed")? as u64;
            let repeat = rows::column::<i64>(r, "runs", &key, "repeat")? as u32;
            if scheme != spec.scheme.to_string() || repeat != spec.repeat || seed != spec.seed.0 {
                out.push(format!(
                    "run {id}: stored as {scheme} repeat {repeat} seed {seed}, the experiment makes it {} repeat {} seed {}",
                    spec.scheme, spec.repeat, spec.seed.0
                ));
            }
            let next: i64 = rows::column(r, "runs", &key, "next_candidate")?;
            let highest: Option<i64> = rows::column(r, "candidates", &key, "highest")?;
            if next != highest.map_or(0, |h| h + 1) {
                out.push(format!(
                    "run {id}: its next candidate is {next}, but the highest stored is {}",
                    highest.map_or("none".to_string(), |h| h.to_string())
                ));
            }
        }
        let bad_cells: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM cells l LEFT JOIN candidates c \
             ON c.run_id = l.run_id AND c.number = l.candidate \
             WHERE c.number IS NULL OR c.kind <> 'valid' OR c.cell <> l.cell OR c.fitness <> l.fitness",
        )
        .fetch_one(&self.pool)
        .await?;
        if bad_cells > 0 {
            out.push(format!(
                "{bad_cells} library cells name no candidate that is valid, in that cell, with that fitness"
            ));
        }
        let bad_infeasible: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM infeasible_cells l LEFT JOIN candidates c \
             ON c.run_id = l.run_id AND c.number = l.candidate \
             WHERE c.number IS NULL OR c.kind = 'valid' OR c.standing <> l.standing",
        )
        .fetch_one(&self.pool)
        .await?;
        if bad_infeasible > 0 {
            out.push(format!(
                "{bad_infeasible} infeasible library cells name no candidate that missed the brief with that standing"
            ));
        }
        // Every design that met the brief was placed in its cell, so each such cell has a
        // holder (a deleted cell row would leave the search a hole).
        let empty_cells: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM (SELECT DISTINCT run_id, cell FROM candidates WHERE kind = 'valid') v \
             WHERE NOT EXISTS (SELECT 1 FROM cells l WHERE l.run_id = v.run_id AND l.cell = v.cell)",
        )
        .fetch_one(&self.pool)
        .await?;
        if empty_cells > 0 {
            out.push(format!(
                "{empty_cells} cells hold no elite though a stored candidate that meets the brief lies in each"
            ));
        }
        out.extend(damaged_rows(&self.checksum_mismatches(true).await?));
        out.extend(damaged_generations(
            &self.generation_checksum_mismatches().await?,
        ));
        Ok(out)
    }

    /// SQLite's `PRAGMA integrity_check`: `["ok"]`, or what it found (pages, indexes,
    /// constraints), at most 100 lines.
    pub async fn integrity_check(&self) -> Result<Vec<String>, DbError> {
        let lines = sqlx::query("PRAGMA integrity_check(100)")
            .fetch_all(&self.pool)
            .await?;
        lines
            .iter()
            .map(|r| rows::column::<String>(r, "integrity_check", "its result", "integrity_check"))
            .collect()
    }

    /// Refuses a library holder whose genome or outcome is not JSON, naming its row and
    /// column: the views that export, analyse and report read parse both in SQLite, which
    /// would fail saying only "malformed JSON". Holders only (at most one per cell), so
    /// it is cheap on any database.
    pub async fn check_library_json(&self) -> Result<(), DbError> {
        let bad = sqlx::query(
            "SELECT c.run_id, c.number, json_valid(c.genome) AS genome_ok \
             FROM cells l JOIN candidates c ON c.run_id = l.run_id AND c.number = l.candidate \
             WHERE NOT (json_valid(c.genome) AND json_valid(c.outcome)) \
             UNION ALL \
             SELECT c.run_id, c.number, json_valid(c.genome) AS genome_ok \
             FROM infeasible_cells l JOIN candidates c ON c.run_id = l.run_id AND c.number = l.candidate \
             WHERE NOT (json_valid(c.genome) AND json_valid(c.outcome)) LIMIT 1",
        )
        .fetch_optional(&self.pool)
        .await?;
        let Some(r) = bad else { return Ok(()) };
        let t = "candidates";
        let run: i64 = rows::column(&r, t, "a library holder", "run_id")?;
        let number: i64 = rows::column(&r, t, format!("run {run}"), "number")?;
        let genome_ok: i64 =
            rows::column(&r, t, format!("run {run} candidate {number}"), "genome_ok")?;
        let column = if genome_ok == 0 { "genome" } else { "outcome" };
        Err(DbError::Corrupt(format!(
            "table candidates, run {run} candidate {number} (a library holder), column {column}: not JSON (damaged)"
        )))
    }

    /// The candidate rows whose checksum ([`checksum`]) does not match their columns:
    /// of the rows the libraries hold (what the search reads again on resume) when
    /// `libraries_only`, else of every row. Rows written before checksums are skipped.
    pub async fn checksum_mismatches(
        &self,
        libraries_only: bool,
    ) -> Result<Vec<(i64, i64)>, DbError> {
        // From the cells to their rows, by the candidates' key: the other way round (each
        // candidate looking for a cell it holds) scanned the cells once per candidate and
        // took minutes on a resume of the throughput benchmark.
        let cols = checksum::selected("c");
        let sql = if libraries_only {
            format!(
                "SELECT {cols} FROM cells l JOIN candidates c \
                 ON c.run_id = l.run_id AND c.number = l.candidate WHERE c.checksum IS NOT NULL \
                 UNION ALL \
                 SELECT {cols} FROM infeasible_cells l JOIN candidates c \
                 ON c.run_id = l.run_id AND c.number = l.candidate WHERE c.checksum IS NOT NULL"
            )
        } else {
            format!("SELECT {cols} FROM candidates c WHERE c.checksum IS NOT NULL")
        };
        let rows = sqlx::query(&sql).fetch_all(&self.pool).await?;
        let mut bad: Vec<(i64, i64)> = Vec::new();
        for r in &rows {
            match checksum::CandidateColumns::from_row(r) {
                Ok((columns, stored)) if stored == Some(columns.checksum()) => {}
                Ok((columns, _)) => bad.push((columns.run, columns.number)),
                // Content that cannot even be decoded is damage too, in the row it names;
                // only a row that cannot be named is an error.
                Err(e) => {
                    let run: i64 = rows::column(r, "candidates", "a row", "run_id")?;
                    let number = rows::column(r, "candidates", format!("run {run}"), "number");
                    bad.push((run, number.map_err(|_| e)?));
                }
            }
        }
        bad.sort_unstable();
        Ok(bad)
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
                    run,
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
    pub async fn next_worker_id(&self) -> Result<u64, DbError> {
        let max: Option<i64> = sqlx::query_scalar("SELECT MAX(id) FROM workers")
            .fetch_one(&self.pool)
            .await?;
        Ok(max.map_or(1, |m| m as u64 + 1))
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
        .bind(filter.run)
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
    pub async fn list_infeasible(&self, run_id: i64) -> Result<Vec<StoredInfeasible>, DbError> {
        let found = sqlx::query(
            "SELECT e.run_id, e.cell, e.candidate, e.shortfall, e.standing, e.genome, c.outcome FROM infeasible_elites e \
             JOIN candidates c ON c.run_id = e.run_id AND c.number = e.candidate \
             WHERE e.run_id = ? ORDER BY e.cell",
        )
        .bind(run_id)
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
        run_id: i64,
    ) -> Result<Vec<(u32, u64, GenerationStats)>, DbError> {
        let rows = sqlx::query(&format!(
            "SELECT {GENERATION_COLUMNS} FROM generations WHERE run_id = ? ORDER BY generation"
        ))
        .bind(run_id)
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

    /// The generations rows (run, generation) that do not match their checksum or cannot
    /// be decoded, in order. Rows written before checksums are skipped.
    pub async fn generation_checksum_mismatches(&self) -> Result<Vec<(i64, i64)>, DbError> {
        let rows = sqlx::query(&format!(
            "SELECT {GENERATION_COLUMNS} FROM generations WHERE checksum IS NOT NULL"
        ))
        .fetch_all(&self.pool)
        .await?;
        let mut bad = Vec::new();
        for r in &rows {
            match GenerationColumns::from_row(r) {
                Ok((columns, stored)) if stored == Some(columns.checksum()) => {}
                Ok((columns, _)) => bad.push((columns.run, columns.generation)),
                Err(e) => {
                    let t = "generations";
                    let run: i64 = rows::column(r, t, "a row", "run_id")?;
                    let generation = rows::column(r, t, format!("run {run}"), "generation");
                    bad.push((run, generation.map_err(|_| e)?));
                }
            }
        }
        bad.sort_unstable();
        Ok(bad)
    }

    /// Copies committed pages from the write-ahead log into the database file without
    /// waiting for the writer (`truncate`: wait for it and empty the log, for a clean
    /// shutdown). Returns the pages still to copy, or None when the log is busy.
    pub async fn checkpoint(&self, truncate: bool) -> Result<Option<i64>, DbError> {
        let row = sqlx::query(if truncate {
            "PRAGMA wal_checkpoint(TRUNCATE)"
        } else {
            "PRAGMA wal_checkpoint(PASSIVE)"
        })
        .fetch_one(&self.pool)
        .await?;
        let col = |name| rows::column::<i64>(&row, "wal_checkpoint", "its result", name);
        let (busy, log, copied) = (col("busy")?, col("log")?, col("checkpointed")?);
        Ok((busy == 0).then_some(log - copied))
    }

    /// Writes a consistent copy of the database to `to`: `VACUUM INTO` a temporary file
    /// beside it (a snapshot; the writer goes on meanwhile), synced, then renamed over
    /// `to`. So `to` is always one whole database, never half a copy: the safe place for a
    /// copy on a network file system while the live file stays on local disk.
    pub async fn backup_to(&self, to: &Path) -> Result<(), DbError> {
        let err = |source| DbError::Backup {
            path: to.display().to_string(),
            source,
        };
        let mut name = to.file_name().unwrap_or_default().to_os_string();
        name.push(".partial");
        let partial = to.with_file_name(name);
        match std::fs::remove_file(&partial) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(err(e)),
            _ => {}
        }
        let target = partial
            .to_str()
            .ok_or_else(|| err(std::io::Error::other("the path is not UTF-8")))?;
        if let Err(e) = sqlx::query("VACUUM INTO ?")
            .bind(target)
            .execute(&self.pool)
            .await
        {
            // No half copy left behind.
            let _ = std::fs::remove_file(&partial);
            return Err(err(std::io::Error::other(e.to_string())));
        }
        std::fs::File::open(&partial)
            .and_then(|f| f.sync_all())
            .map_err(err)?;
        // A journal left beside an older copy would be replayed onto this one.
        for suffix in ["-wal", "-shm"] {
            let mut name = to.file_name().unwrap_or_default().to_os_string();
            name.push(suffix);
            match std::fs::remove_file(to.with_file_name(name)) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(err(e)),
                _ => {}
            }
        }
        std::fs::rename(&partial, to).map_err(err)?;
        if let Some(dir) = to.parent().filter(|d| !d.as_os_str().is_empty()) {
            // The rename is durable once the directory is.
            let _ = std::fs::File::open(dir).and_then(|d| d.sync_all());
        }
        Ok(())
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

/// Problems naming damaged generations rows (the first five, and how many in all).
pub fn damaged_generations(bad: &[(i64, i64)]) -> Option<String> {
    if bad.is_empty() {
        return None;
    }
    let named: Vec<String> = bad
        .iter()
        .take(5)
        .map(|(run, g)| format!("run {run} generation {g}"))
        .collect();
    Some(format!(
        "{} generations rows do not match their checksums, so their figures were changed after they were written ({}{})",
        bad.len(),
        named.join(", "),
        if bad.len() > 5 { ", ..." } else { "" }
    ))
}

/// The checksum of a read `experiment` row, from its name, definition, build and
/// created_at columns.
fn experiment_row_checksum(r: &sqlx::sqlite::SqliteRow) -> Result<i64, DbError> {
    let col = |name| rows::column::<String>(r, "experiment", "row 1", name);
    Ok(checksum::experiment_checksum(
        &col("name")?,
        &col("definition")?,
        &col("build")?,
        &col("created_at")?,
    ))
}

/// Gives the experiment row its checksum if it has none (just stored, or stored before
/// checksums). A migration that rewrites the row must set its checksum to NULL, so that
/// the next writer seals the new text.
async fn seal_experiment(tx: &mut sqlx::Transaction<'_, sqlx::Sqlite>) -> Result<(), DbError> {
    let row = sqlx::query(
        "SELECT name, definition, build, created_at FROM experiment WHERE id = 1 AND checksum IS NULL",
    )
    .fetch_optional(&mut **tx)
    .await?;
    if let Some(r) = row {
        sqlx::query("UPDATE experiment SET checksum = ? WHERE id = 1")
            .bind(experiment_row_checksum(&r)?)
            .execute(&mut **tx)
            .await?;
    }
    Ok(())
}

/// Problems naming damaged candidate rows (the first five, and how many in all).
pub fn damaged_rows(bad: &[(i64, i64)]) -> Option<String> {
    if bad.is_empty() {
        return None;
    }
    let named: Vec<String> = bad
        .iter()
        .take(5)
        .map(|(run, n)| format!("run {run} candidate {n}"))
        .collect();
    Some(format!(
        "{} candidate rows do not match their checksums, so they were changed after they were written ({}{})",
        bad.len(),
        named.join(", "),
        if bad.len() > 5 { ", ..." } else { "" }
    ))
}
