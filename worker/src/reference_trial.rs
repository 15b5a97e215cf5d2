//! The reference trial: MAX walking for one second under STATIC at the paper's settings,
//! its outcome reduced to 64 bits. Trials are the same bits only on machines that do the
//! same arithmetic, and the build identity names only what can be seen of it (the commit,
//! the CPU's fused multiply-add, the instruction sets compiled for); the C library's `sin`
//! and `cos`, or anything else a node does differently, can be seen only by stepping the
//! robot. Each worker sends this digest with its Hello, and the coordinator refuses one
//! whose digest differs from its session's first worker's (docs/rapier.md, "The same
//! binary on another CPU").

use crate::evaluate::evaluate;
use std::sync::OnceLock;
use strider_common::rng::CandidateSeed;
use strider_common::{reference, EvalContext, Scheme};

/// Simulated seconds of the reference trial: long enough for every part of a step (the
/// gait's `sin` and `cos`, contacts, the drives' limits and retakes, the fall checks) to
/// run many times, short enough to cost a worker's start little (about 240 physics steps).
pub const SECONDS: f64 = 1.0;

/// The reference trial's digest on this machine, computed once per process: never 0 (which
/// on the wire means none was sent).
pub fn digest() -> u64 {
    static DIGEST: OnceLock<u64> = OnceLock::new();
    *DIGEST.get_or_init(compute)
}

fn compute() -> u64 {
    let mut ctx = EvalContext::paper();
    ctx.settings.trial_seconds = SECONDS;
    let outcome = evaluate(
        &ctx,
        &reference::max(),
        Scheme::Static,
        CandidateSeed::new(0, 0),
    );
    // serde_json writes each f64 in the shortest form that reads back to the same bits,
    // so the text differs exactly when some figure of the outcome does.
    let text = serde_json::to_string(&outcome).expect("an outcome serialises");
    fnv1a(text.as_bytes()).max(1)
}

/// FNV-1a, 64 bits: stable across builds and platforms, which `std`'s hasher is not.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_its_published_values() {
        // The FNV reference values (draft-eastlake-fnv): "" and "a".
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
    }

    #[test]
    fn the_digest_is_of_a_trial_that_ran() {
        let mut ctx = EvalContext::paper();
        ctx.settings.trial_seconds = SECONDS;
        let outcome = evaluate(
            &ctx,
            &reference::max(),
            Scheme::Static,
            CandidateSeed::new(0, 0),
        );
        // A trial that ran has stats (an outcome settled before the trial would digest the
        // same on every machine and catch nothing).
        let stats = outcome.stats().expect("MAX's reference trial runs");
        assert!(stats.distance > 0.1, "MAX walks in its second: {stats:?}");
        assert_eq!(digest(), compute(), "the same machine, the same digest");
        assert_ne!(digest(), 0);
    }
}
