//! Opening and closing a database: the writer's lock file, opening to write (with
//! migrations) or to read, checkpoints and backups.

use super::experiment::seal_experiment;
use super::*;
use sqlx::ConnectOptions;

/// The writer's lock on a database: an advisory lock on `NAME.lock` beside it, held while
/// this value lives (and released by the system when the process ends, however it ends).
/// Dropped at a clean exit, it removes its file: a stopped run leaves nothing beside its
/// database.
#[derive(Debug)]
pub(super) struct WriterLock {
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
        strider_process::host_name()
    );
    file.set_len(0).map_err(err)?;
    std::io::Write::write_all(&mut file, me.as_bytes()).map_err(err)?;
    Ok(WriterLock {
        _file: file,
        path: lock_path,
    })
}

/// When sqlx warns of a slow statement (its default, 1 s, warned at every resume of the
/// full-size run: its consistency checks read every candidate row, about 2 s of its 400 MB
/// when cold). Expected work is not a warning; a statement stuck for this long is.
const SLOW_STATEMENT: (log::LevelFilter, std::time::Duration) =
    (log::LevelFilter::Warn, std::time::Duration::from_secs(30));

/// How long [`Db::close`] waits for connections still in use to come back.
const CLOSE_WAIT: std::time::Duration = std::time::Duration::from_secs(5);

/// How often [`Db::close`] looks whether they have (sqlx gives no event for it).
const CLOSE_POLL: std::time::Duration = std::time::Duration::from_millis(5);

impl Db {
    /// Closes every connection of this database (and its clones), waiting (at most
    /// [`CLOSE_WAIT`]) for those still in use. SQLite removes the write-ahead log and
    /// shared-memory files when the last connection closes, so a clean exit leaves the
    /// `.db` alone beside its lock.
    pub async fn close(&self) {
        // sqlx's close does not wait for a connection still on its way back: a query's
        // connection is handed back by a task spawned when it drops, and closing the idle
        // ones releases permits they never took, so close's wait for every permit ends at
        // once. Measured: the pool at size 1 after close, with nothing idle, in 3 of 24
        // local runs six at a time; the exit then cut that connection's close short and
        // left the emptied -wal and the -shm. Handed back to a closed pool, it is closed:
        // wait for that.
        let deadline = tokio::time::Instant::now() + CLOSE_WAIT;
        loop {
            self.pool.close().await;
            if self.pool.size() == 0 {
                return;
            }
            if tokio::time::Instant::now() >= deadline {
                break;
            }
            tokio::time::sleep(CLOSE_POLL).await;
        }
        tracing::warn!(
            "{} database connections still open {} s after closing: the -wal file may stay until the next start",
            self.pool.size(),
            CLOSE_WAIT.as_secs()
        );
    }

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
            .pragma("wal_autocheckpoint", "0")
            .log_slow_statements(SLOW_STATEMENT.0, SLOW_STATEMENT.1);
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
            .immutable(immutable)
            .log_slow_statements(SLOW_STATEMENT.0, SLOW_STATEMENT.1);
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
