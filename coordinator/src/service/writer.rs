//! The one task that writes to the database while the service runs: it takes the
//! scheduler's changes in order and commits whatever has queued up in one transaction, so
//! commits stay durable (full sync) and cheap per result however fast results arrive.
//!
//! A group stays open for [`GROUP_WINDOW`] after its first change (or until it is full,
//! someone waits for a flush, or the backlog reaches [`super::MAX_BACKLOG`]): a result arriving in that window is work in flight, which a
//! crash may lose and a worker then redoes; a committed one is never lost. Without the
//! window a slow stream of results paid one fsync each (about 150 commits/s in a local
//! run, each waking the writer, SQLite's thread and the kernel beside the simulations).

use super::Backlog;
use crate::db::{Db, DbError, PreparedGroup};
use crate::qd::changes::Write;
use std::sync::Arc;
use tokio::sync::{mpsc, oneshot};

/// Most writes in one transaction (bounds a group's latency).
const MAX_GROUP: usize = 50_000;

/// How long a group collects changes before it is committed.
pub const GROUP_WINDOW: std::time::Duration = std::time::Duration::from_millis(50);

/// What the writer is sent.
pub enum WriterMessage {
    /// Changes to store, in order.
    Writes(Vec<Write>),
    /// Answer once everything sent before is committed.
    Flush(oneshot::Sender<()>),
    /// Commit everything sent before, then end: what is sent after is dropped, as a crash
    /// at this point would lose it (a session that outlives the service's stop may still
    /// hold a sender, and must not hold the exit).
    Close,
}

/// Runs until it is sent [`WriterMessage::Close`] or every sender is dropped; fails on the
/// first database error (the service stops: the database is the only state, so it must
/// not run on without it).
pub async fn run_writer(
    db: Db,
    mut rx: mpsc::UnboundedReceiver<WriterMessage>,
    backlog: Arc<Backlog>,
) -> Result<(), DbError> {
    let (stop_checkpoints, stopped) = oneshot::channel();
    let checkpointer = tokio::spawn(checkpoint_continually(db.clone(), stopped));
    let result = write_groups(&db, &mut rx, &backlog).await;
    // Stopped between checkpoints, not aborted: a task aborted while it acquires a
    // connection leaves SQLite's half-opened connection to close on its own thread, which
    // the process's exit may cut short, leaving the -wal and -shm files it made (seen as
    // an empty -wal after a clean local run, one run in three under load).
    let _ = stop_checkpoints.send(());
    let _ = checkpointer.await;
    result?;
    // Leave a tidy file: everything in the database, an empty log.
    db.checkpoint(true).await?;
    Ok(())
}

/// Pause between checkpoints.
const CHECKPOINT_EVERY: std::time::Duration = std::time::Duration::from_millis(100);

/// Keeps the write-ahead log short: copies committed pages into the database file while
/// the writer goes on (the connection's own checkpoints are off: they ran inside commits).
/// Ends when `stop` is sent (or dropped), after the checkpoint in progress.
async fn checkpoint_continually(db: Db, mut stop: oneshot::Receiver<()>) {
    loop {
        if let Err(e) = db.checkpoint(false).await {
            tracing::warn!("checkpoint failed: {e}");
        }
        tokio::select! {
            _ = tokio::time::sleep(CHECKPOINT_EVERY) => {}
            _ = &mut stop => return,
        }
    }
}

/// A prepared group on its way to the committer, with the flushes waiting for it.
struct Ready {
    group: Option<PreparedGroup>,
    /// Changes it holds, as counted in the backlog.
    changes: usize,
    flushes: Vec<oneshot::Sender<()>>,
}

/// Groups smaller than this are prepared on the writer task itself (a thread hand-off
/// costs more than preparing a few rows).
const PREPARE_INLINE: usize = 64;

/// Two stages: one collects and prepares groups (JSON and all, on a blocking thread), the
/// other commits them (on SQLite's thread), so group n + 1 is prepared while n commits.
async fn write_groups(
    db: &Db,
    rx: &mut mpsc::UnboundedReceiver<WriterMessage>,
    backlog: &Backlog,
) -> Result<(), DbError> {
    let (ready_tx, mut ready_rx) = mpsc::channel::<Ready>(1);
    let commit = async {
        while let Some(Ready {
            group,
            changes,
            flushes,
        }) = ready_rx.recv().await
        {
            if let Some(group) = group {
                let started = std::time::Instant::now();
                let writes = group.writes();
                db.commit(group).await?;
                tracing::debug!(
                    writes,
                    ms = started.elapsed().as_secs_f64() * 1e3,
                    "group committed"
                );
            }
            backlog.committed(changes);
            for done in flushes {
                let _ = done.send(());
            }
        }
        Ok::<(), DbError>(())
    };
    let prepare = async move {
        while let Some(Group {
            writes,
            flushes,
            last,
        }) = collect_group(rx, backlog).await
        {
            let changes = writes.len();
            let group = match writes.len() {
                0 => None,
                n if n < PREPARE_INLINE => Some(PreparedGroup::new(&writes)),
                _ => Some(
                    tokio::task::spawn_blocking(move || PreparedGroup::new(&writes))
                        .await
                        .expect("preparing a group does not panic"),
                ),
            };
            if ready_tx
                .send(Ready {
                    group,
                    changes,
                    flushes,
                })
                .await
                .is_err()
            {
                // The committer failed; its error is the one reported.
                break;
            }
            if last {
                break;
            }
        }
        // Dropping `ready_tx` lets the committer finish what it has and end.
        Ok(())
    };
    // A commit error ends both at once (the collector may be waiting for writes).
    tokio::try_join!(commit, prepare).map(|_| ())
}

/// Changes collected for one transaction.
struct Group {
    writes: Vec<Write>,
    flushes: Vec<oneshot::Sender<()>>,
    /// A [`WriterMessage::Close`] ended it: nothing follows.
    last: bool,
}

/// The next group: everything queued, then whatever comes within [`GROUP_WINDOW`] of its
/// first change, up to [`MAX_GROUP`] writes, the first flush or close, or a full backlog
/// (the sessions then wait for this commit: waiting out the window would stall them).
/// `None` once every sender is gone and nothing is left.
async fn collect_group(
    rx: &mut mpsc::UnboundedReceiver<WriterMessage>,
    backlog: &Backlog,
) -> Option<Group> {
    let first = rx.recv().await?;
    let close_at = tokio::time::Instant::now() + GROUP_WINDOW;
    let (mut group, mut flushes, mut last) = (Vec::new(), Vec::new(), false);
    let mut next = Some(first);
    while let Some(m) = next {
        match m {
            WriterMessage::Writes(w) => group.extend(w),
            WriterMessage::Flush(done) => flushes.push(done),
            WriterMessage::Close => last = true,
        }
        next = if last || group.len() >= MAX_GROUP || !flushes.is_empty() || backlog.full() {
            None
        } else if let Ok(m) = rx.try_recv() {
            Some(m)
        } else {
            // Nothing queued: wait for more until the window closes (or every sender is
            // gone, when the group is committed at once).
            tokio::time::timeout_at(close_at, rx.recv())
                .await
                .ok()
                .flatten()
        };
    }
    Some(Group {
        writes: group,
        flushes,
        last,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use strider_common::WorkerId;

    fn joined(id: u64) -> Write {
        Write::WorkerJoined {
            id: WorkerId(id),
            name: format!("w{id}"),
            build: "test".into(),
            slots: 1,
        }
    }

    #[tokio::test]
    async fn close_commits_what_came_before_and_ends_while_a_sender_lives() {
        let dir = std::env::temp_dir().join(format!("strider-writer-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let db = Db::open(&dir.join("w.db"), true).await.unwrap();
        let backlog = Arc::new(Backlog::default());
        let (tx, rx) = mpsc::unbounded_channel();
        let writer = tokio::spawn(run_writer(db.clone(), rx, backlog.clone()));
        for m in [joined(1), joined(2)] {
            backlog.queued(1);
            tx.send(WriterMessage::Writes(vec![m])).unwrap();
        }
        tx.send(WriterMessage::Close).unwrap();
        // Sent after the close (as by a session that outlived the stop): dropped.
        let _ = tx.send(WriterMessage::Writes(vec![joined(3)]));
        // `tx` is still alive here: the writer ends on the close alone (bounded, so that a
        // writer that waits for the senders fails the test instead of hanging it).
        tokio::time::timeout(std::time::Duration::from_secs(60), writer)
            .await
            .expect("the writer ends on Close")
            .unwrap()
            .unwrap();
        assert_eq!(db.next_worker_id().await.unwrap(), WorkerId(3));
        assert!(backlog.is_empty());
        drop(tx);
        db.close().await;
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
