//! The worker sessions alive now, by token (`Welcome.session`): a worker that connects
//! again names its last session (`Hello.replaces`), which ends at once. Without this the
//! old session's connection could look alive for up to half a minute after a network cut
//! (until keepalive gives up, or the worker's close gets through), counting the worker
//! twice and holding leases for trials the worker had already given up.

use std::collections::hash_map::RandomState;
use std::collections::HashMap;
use std::hash::BuildHasher;
use std::sync::Mutex;
use strider_common::WorkerId;
use tokio::sync::oneshot;

/// Live sessions and how to end each.
pub struct Sessions {
    /// This process's own: a token from another coordinator (restarted, or another
    /// experiment behind the same address file) names no session here.
    keys: RandomState,
    live: Mutex<HashMap<u64, oneshot::Sender<WorkerId>>>,
}

impl Default for Sessions {
    fn default() -> Self {
        Self {
            // std's hasher: keyed at random per process, and not invertible (no token
            // tells another session's), with no dependency.
            keys: RandomState::new(),
            live: Mutex::new(HashMap::new()),
        }
    }
}

impl Sessions {
    /// The token of worker session `id` (never 0, which means none on the wire).
    pub fn token(&self, id: WorkerId) -> u64 {
        self.keys.hash_one(id.0).max(1)
    }

    /// Registers a live session; the receiver completes with the id of the session that
    /// replaced it.
    pub fn open(&self, token: u64) -> oneshot::Receiver<WorkerId> {
        let (tx, rx) = oneshot::channel();
        self.live
            .lock()
            .expect("no panic while registering")
            .insert(token, tx);
        rx
    }

    /// Ends the live session `token` (0, ended or unknown: nothing) in favour of `by`;
    /// whether there was one.
    pub fn replace(&self, token: u64, by: WorkerId) -> bool {
        if token == 0 {
            return false;
        }
        let ended = self
            .live
            .lock()
            .expect("no panic while replacing")
            .remove(&token);
        ended.is_some_and(|tx| tx.send(by).is_ok())
    }

    /// A session ended: its token names nothing any more.
    pub fn close(&self, token: u64) {
        self.live
            .lock()
            .expect("no panic while closing")
            .remove(&token);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_session_replaced_is_told_by_whom_once_and_a_closed_or_foreign_one_is_not() {
        let s = Sessions::default();
        let (a, b) = (s.token(WorkerId(1)), s.token(WorkerId(2)));
        assert_ne!(a, b);
        assert_ne!(a, 0);
        let mut first = s.open(a);
        let _second = s.open(b);
        assert!(s.replace(a, WorkerId(3)));
        assert_eq!(first.try_recv(), Ok(WorkerId(3)));
        assert!(!s.replace(a, WorkerId(4)), "already replaced");
        s.close(b);
        assert!(!s.replace(b, WorkerId(5)), "closed");
        assert!(!s.replace(0, WorkerId(6)), "0 is no session");
        // Another coordinator's tokens for the same ids differ.
        let other = Sessions::default();
        assert_ne!(other.token(WorkerId(1)), a);
    }
}
