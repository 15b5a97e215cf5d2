//! Which workers step the robot as the session's first one did. Every worker runs a short
//! reference trial when it starts and sends its digest with its Hello
//! (`strider_worker::reference_trial`); the first worker of a session sets the digest the
//! others must match. The build identity already names the commit and what can be seen of
//! the CPU's arithmetic; this catches what cannot: another C library's `sin` and `cos`, or
//! any other difference a node makes to the bits (docs/rapier.md). A worker refused here
//! would have produced results a run on the first worker's nodes would not: the run would
//! no longer be the same bits whatever the workers.

use std::sync::Mutex;

/// The session's reference digest, once a worker has set it.
#[derive(Default)]
pub struct ReferenceTrial(Mutex<Option<First>>);

struct First {
    digest: u64,
    worker: String,
}

impl ReferenceTrial {
    /// Admits a worker named `worker` whose reference trial gave `digest` (0: it sent
    /// none), or says why not. The first one admitted sets the session's digest.
    pub fn admit(&self, digest: u64, worker: &str) -> Result<(), String> {
        if digest == 0 {
            return Err(
                "reference_trial: 0, none sent; a worker sends the digest of its reference trial (strider_worker::reference_trial)"
                    .into(),
            );
        }
        let mut first = self.0.lock().expect("no panic while admitting");
        match &*first {
            None => {
                *first = Some(First {
                    digest,
                    worker: worker.to_string(),
                });
                Ok(())
            }
            Some(f) if f.digest == digest => Ok(()),
            Some(f) => Err(format!(
                "reference trial mismatch: this worker's reference trial (MAX walking for one second) gives digest {digest:016x}, the session's first worker's ({:?}) {:016x}: the same build steps the robot differently on this node (another C library, or a CPU whose arithmetic the build identity does not tell apart), so its trials would not be the run's bits; run the workers on nodes of one kind, or from one container image (docs/rapier.md, \"The same binary on another CPU\")",
                f.worker, f.digest
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_digest_sets_the_sessions_and_others_must_match_it() {
        let r = ReferenceTrial::default();
        assert!(r.admit(0, "silent").unwrap_err().contains("none sent"));
        r.admit(0xabc, "node-a").unwrap();
        r.admit(0xabc, "node-b").unwrap();
        let e = r.admit(0xdef, "node-c").unwrap_err();
        assert!(
            e.contains("0000000000000def")
                && e.contains("0000000000000abc")
                && e.contains("node-a"),
            "{e}"
        );
        // A refused worker changes nothing: the first worker's digest still admits.
        r.admit(0xabc, "node-d").unwrap();
    }
}
