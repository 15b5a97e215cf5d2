//! The coordinator settles designs that fail the brief's static checks or start with parts
//! touching without a trial (`precheck`); that must give exactly what a worker's
//! `evaluate` would.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use strider_common::precheck::precheck;
use strider_common::rng::CandidateSeed;
use strider_common::EvalContext;
use strider_common::{Genome, InvalidReason, Outcome, Scheme};
use strider_worker::evaluate::evaluate;

#[test]
fn precheck_agrees_with_evaluate_whenever_it_decides() {
    let ctx = EvalContext::paper();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for scheme in [Scheme::Static, Scheme::Genome, Scheme::Es] {
        let mut decided = 0;
        for n in 0..400 {
            let genome = Genome::random(scheme, &mut rng);
            if let Some(quick) = precheck(&ctx, &genome, scheme) {
                decided += 1;
                assert!(matches!(
                    quick,
                    Outcome::Rejected { stats: None, .. }
                        | Outcome::Invalid {
                            reason: InvalidReason::StartPoseContact { .. },
                            ..
                        }
                ));
                let full = evaluate(&ctx, &genome, scheme, CandidateSeed::new(5, n));
                assert_eq!(quick, full, "{scheme} candidate {n}");
            }
        }
        // Most random designs fail mass or height (docs/model.md, section 15).
        assert!(decided > 100, "{scheme}: only {decided} of 400 decided");
    }
}
