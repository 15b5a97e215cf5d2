//! The one task that writes to the database while the service runs: it takes the
//! scheduler's changes in order and commits whatever has queued up in one transaction, so
//! commits stay durable (full sync) and cheap per result however fast results arrive.

use crate::db::{Db, DbError, Write};
use tokio::sync::{mpsc, oneshot};

/// Most writes in one transaction (bounds a group's latency).
const MAX_GROUP: usize = 50_000;

/// What the writer is sent.
pub enum WriterMessage {
    /// Changes to store, in order.
    Writes(Vec<Write>),
    /// Answer once everything sent before is committed.
    Flush(oneshot::Sender<()>),
}

/// Runs until every sender is dropped; fails on the first database error (the service
/// stops: the database is the only state, so it must not run on without it).
pub async fn run_writer(
    db: Db,
    mut rx: mpsc::UnboundedReceiver<WriterMessage>,
) -> Result<(), DbError> {
    let mut group: Vec<Write> = Vec::new();
    let mut flushes = Vec::new();
    while let Some(first) = rx.recv().await {
        let mut next = Some(first);
        while let Some(m) = next {
            match m {
                WriterMessage::Writes(w) => group.extend(w),
                WriterMessage::Flush(done) => flushes.push(done),
            }
            next = if group.len() < MAX_GROUP {
                rx.try_recv().ok()
            } else {
                None
            };
        }
        if !group.is_empty() {
            db.write(&group).await?;
            group.clear();
        }
        for done in flushes.drain(..) {
            let _ = done.send(());
        }
    }
    Ok(())
}
