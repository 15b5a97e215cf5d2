//! Which workers step the robot as this coordinator does. Every worker runs a short
//! reference trial when it starts and sends its digest with its Hello
//! (`strider_worker::reference_trial`: MAX for a second, and the C library's functions on
//! fixed arguments). A coordinator built with the simulator runs it too, and its own
//! digest is the reference, as its own CPU is for the build identity's arithmetic: the same
//! on every start on the same kind of node, so a run resumed there keeps its bits. Built
//! without it, the session's first worker sets the digest the others must match. The build
//! identity names the commit and what can be seen of the CPU; this catches what cannot,
//! another C library's `sin` or `exp`. A worker refused here would have given results that
//! a run on the reference's nodes would not: the run would no longer be the same bits
//! whatever the workers.

use std::sync::Mutex;

/// What a database records as having made it, and what a resume or `verify` compares:
/// the build identity and, where this coordinator has the simulator, its reference
/// trial's digest, so that a run resumed on a node whose C library computes otherwise
/// (which the build identity cannot name) says so.
pub fn this_machine_identity() -> String {
    #[cfg(feature = "simulator")]
    let digest = Some(strider_worker::reference_trial::digest());
    #[cfg(not(feature = "simulator"))]
    let digest: Option<u64> = None;
    let build = strider_common::build_id();
    match digest {
        Some(d) => format!("{build}{DIGEST_AFTER}{d:016x}"),
        None => build,
    }
}

/// Between the build identity and the digest in [`this_machine_identity`].
const DIGEST_AFTER: &str = ", reference trial ";

/// Whether a database made by `stored` (a [`this_machine_identity`], or an older row's bare
/// build identity) would be stepped otherwise by `here`: another build, or both digests
/// known and different. A coordinator without the simulator records and has no digest,
/// so against it only the builds compare (a head node's `serve` and a compute node's
/// `verify` of one build agree).
pub fn computes_otherwise(stored: &str, here: &str) -> bool {
    let (build, digest) = build_and_digest(stored);
    let (our_build, our_digest) = build_and_digest(here);
    build != our_build || matches!((digest, our_digest), (Some(a), Some(b)) if a != b)
}

fn build_and_digest(identity: &str) -> (&str, Option<&str>) {
    identity
        .split_once(DIGEST_AFTER)
        .map_or((identity, None), |(build, digest)| (build, Some(digest)))
}

/// The digest workers must match, once known.
pub struct ReferenceTrial(Mutex<Option<Reference>>);

struct Reference {
    digest: u64,
    /// Whose digest it is, for the refusal: "this coordinator's" or the first worker's.
    whose: String,
}

impl ReferenceTrial {
    /// This coordinator's reference: its own reference trial's digest where it has the
    /// simulator (about 480 physics steps, run here once), else none until a worker's.
    pub fn of_this_coordinator() -> Self {
        #[cfg(feature = "simulator")]
        let own = Some(strider_worker::reference_trial::digest());
        #[cfg(not(feature = "simulator"))]
        let own = None;
        Self::new(own)
    }

    /// A reference set to `own` (`None`: the first worker admitted sets it).
    pub fn new(own: Option<u64>) -> Self {
        Self(Mutex::new(own.map(|digest| Reference {
            digest,
            whose: "this coordinator's".into(),
        })))
    }

    /// Admits a worker named `worker` whose reference trial gave `digest` (0: it sent
    /// none), or says why not.
    pub fn admit(&self, digest: u64, worker: &str) -> Result<(), String> {
        if digest == 0 {
            return Err(
                "reference_trial: 0, none sent; a worker sends the digest of its reference trial (strider_worker::reference_trial)"
                    .into(),
            );
        }
        let mut reference = self.0.lock().expect("no panic while admitting");
        match &*reference {
            None => {
                *reference = Some(Reference {
                    digest,
                    whose: format!("the session's first worker's ({worker:?})"),
                });
                Ok(())
            }
            Some(r) if r.digest == digest => Ok(()),
            Some(r) => Err(format!(
                "reference trial mismatch: this worker's reference trial (MAX walking for a second, and the C library's functions on fixed arguments) gives digest {digest:016x}, {} {:016x}: the same build computes differently on the two nodes (another C library, or a CPU whose arithmetic the build identity does not tell apart), so this worker's trials would not be the run's bits; run the coordinator and the workers on nodes of one kind, or from one container image (docs/rapier.md, \"The same binary on another CPU\")",
                r.whose, r.digest
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identities_differ_by_build_or_by_two_known_digests() {
        let with = |d: &str| format!("strider 0.1.0 (commit a), reference trial {d}");
        let bare = "strider 0.1.0 (commit a)";
        assert!(!computes_otherwise(&with("01"), &with("01")));
        assert!(computes_otherwise(&with("01"), &with("02")));
        // Without the simulator on one side: the builds alone.
        assert!(!computes_otherwise(bare, &with("01")));
        assert!(!computes_otherwise(&with("01"), bare));
        assert!(!computes_otherwise(bare, bare));
        assert!(computes_otherwise("strider 0.1.0 (commit b)", &with("01")));
        assert!(computes_otherwise(
            "strider 0.1.0 (commit b), reference trial 01",
            bare
        ));
    }

    #[test]
    fn without_its_own_the_first_digest_sets_the_reference() {
        let r = ReferenceTrial::new(None);
        assert!(r.admit(0, "silent").unwrap_err().contains("none sent"));
        r.admit(0xabc, "node-a").unwrap();
        r.admit(0xabc, "node-b").unwrap();
        let e = r.admit(0xdef, "node-c").unwrap_err();
        assert!(
            e.contains("0000000000000def")
                && e.contains("0000000000000abc")
                && e.contains("first worker's (\"node-a\")"),
            "{e}"
        );
        // A refused worker changes nothing: the first worker's digest still admits.
        r.admit(0xabc, "node-d").unwrap();
    }

    #[test]
    fn with_its_own_only_that_digest_is_admitted() {
        let r = ReferenceTrial::new(Some(0xabc));
        let e = r.admit(0xdef, "node-a").unwrap_err();
        assert!(e.contains("this coordinator's 0000000000000abc"), "{e}");
        r.admit(0xabc, "node-b").unwrap();
        assert!(r.admit(0, "silent").is_err());
    }

    #[cfg(feature = "simulator")]
    #[test]
    fn a_coordinator_with_the_simulator_admits_its_own_build_on_this_machine() {
        let r = ReferenceTrial::of_this_coordinator();
        r.admit(strider_worker::reference_trial::digest(), "local")
            .unwrap();
        assert!(r
            .admit(strider_worker::reference_trial::digest() ^ 1, "other")
            .is_err());
    }
}
