//! The reference trial: MAX walking for one second under STATIC at the paper's settings,
//! and the C library's mathematical functions that the worker calls (those the gait, the
//! engine and the ES's draws use), on fixed arguments, all reduced to 64 bits. Trials are
//! the same bits only on machines that do the same arithmetic, and the build identity
//! names only what can be seen of it (the commit, the CPU's fused multiply-add, the
//! instruction sets compiled for); another C library's `sin` or `exp` can be seen only by
//! calling it. Each worker sends this digest with its Hello, and the coordinator refuses
//! one whose digest is not its own (docs/rapier.md, "The same binary on another CPU").

use crate::evaluate::evaluate;
use std::sync::OnceLock;
use strider_common::fnv::Fnv1a;
use strider_common::rng::CandidateSeed;
use strider_common::{reference, EvalContext, Outcome, Scheme};

/// Simulated seconds of the reference trial: long enough for every part of a step (the
/// gait's `sin` and `cos`, contacts, the drives' limits and retakes, the fall checks) to
/// run many times, short enough to cost a worker's start little (with its 1-s window
/// after the trial, about 480 physics steps).
pub const SECONDS: f64 = 1.0;

/// The reference trial's digest on this machine, computed once per process: never 0 (which
/// on the wire means none was sent).
pub fn digest() -> u64 {
    static DIGEST: OnceLock<u64> = OnceLock::new();
    *DIGEST.get_or_init(compute)
}

fn compute() -> u64 {
    // serde_json writes each f64 in the shortest form that reads back to the same bits,
    // so the text differs exactly when some figure of the outcome does.
    let text = serde_json::to_string(&reference_outcome()).expect("an outcome serialises");
    let mut h = Fnv1a::default();
    h.bytes(text.as_bytes());
    for v in libm_probe() {
        h.bytes(&v.to_le_bytes());
    }
    h.value().max(1)
}

/// MAX's reference trial.
fn reference_outcome() -> Outcome {
    let mut ctx = EvalContext::paper();
    ctx.settings.trial_seconds = SECONDS;
    evaluate(
        &ctx,
        &reference::max(),
        Scheme::Static,
        CandidateSeed::new(0, 0),
    )
}

/// The bits of every C-library function the worker imports (`nm -D strider-worker`: the
/// trigonometry of the gait and the engine's rotations, `exp` and `log` of the ES's normal
/// draws, the rest of rapier's and parry's), each on 64 arguments across its domain. A
/// trial calls some of them rarely (the ES not at all), so they are asked directly; with
/// f32 results widened exactly.
fn libm_probe() -> Vec<u64> {
    use std::hint::black_box;
    let mut out = Vec::new();
    for i in 0..64 {
        // black_box: arguments the compiler cannot see, or it would fold the calls.
        let x = black_box(-8.0 + 0.25 * f64::from(i) + 0.0123);
        let (s, c) = x.sin_cos();
        let unit = x / 8.5;
        let positive = x.abs() + 0.1;
        let xf = x as f32;
        let (sf, cf) = xf.sin_cos();
        let (unit_f, positive_f) = (unit as f32, positive as f32);
        out.extend(
            [
                x.sin(),
                x.cos(),
                s,
                c,
                (x / 2.0).exp(),
                positive.ln(),
                unit.acos(),
                unit.asin(),
                x.atan2(1.7),
                positive.powf(1.3),
            ]
            .map(f64::to_bits),
        );
        out.extend(
            [
                xf.sin(),
                xf.cos(),
                sf,
                cf,
                (xf / 2.0).exp(),
                positive_f.log2(),
                unit_f.acos(),
                unit_f.asin(),
                xf.atan2(1.7),
                positive_f.powf(1.3),
            ]
            .map(|v| f64::from(v).to_bits()),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_digest_is_of_a_trial_that_ran() {
        let outcome = reference_outcome();
        // A trial that ran has stats (an outcome settled before the trial would digest the
        // same on every machine and catch nothing).
        let stats = outcome.stats().expect("MAX's reference trial runs");
        assert!(stats.distance > 0.1, "MAX walks in its second: {stats:?}");
        assert_eq!(digest(), compute(), "the same machine, the same digest");
        assert_ne!(digest(), 0);
    }

    #[test]
    fn the_probe_asks_each_function_for_finite_values() {
        let probe = libm_probe();
        assert_eq!(probe.len(), 64 * 20);
        // Arguments inside each function's domain: a NaN would hash the same whatever the
        // library computed.
        assert!(probe.iter().all(|&b| f64::from_bits(b).is_finite()));
    }
}
