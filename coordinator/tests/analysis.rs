//! The analysis against independent numbers: hand-computed Mann-Whitney tests, and the
//! rule miner on synthetic designs.

use rand::Rng;
use strider_common::rng::{CandidateSeed, Purpose};
use strider_coordinator::results::analysis::mann_whitney::{erfc, mann_whitney, Method};
use strider_coordinator::results::analysis::rules::mine_rules;

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs()
}

#[test]
fn erfc_matches_reference_values() {
    // Reference values from the C library's erfc.
    for (x, want) in [
        (0.1, 0.887_537_083_981_715_2),
        (0.5, 0.479_500_122_186_953_5),
        (1.0, 0.157_299_207_050_285_13),
        (2.0, 0.004_677_734_981_047_265),
        (3.0, 2.209_049_699_858_543_8e-5),
        (-1.0, 2.0 - 0.157_299_207_050_285_13),
    ] {
        assert!(
            close(erfc(x), want, 2e-7),
            "erfc({x}) = {}, want {want}",
            erfc(x)
        );
    }
}

#[test]
fn complete_separation_exact() {
    // x below every y: U1 = 0. Of the C(6,3) = 20 equally likely arrangements only one has
    // U = 0, so P(U <= 0) = 1/20 and the two-sided p = 2/20 = 0.1.
    let r = mann_whitney(&[1.0, 2.0, 3.0], &[4.0, 5.0, 6.0]).unwrap();
    assert_eq!((r.u1, r.u2, r.method), (0.0, 9.0, Method::Exact));
    assert!(close(r.p, 0.1, 1e-12), "{}", r.p);
    // 4 against 5: one arrangement in C(9,4) = 126: p = 2/126.
    let r = mann_whitney(&[1.0, 2.0, 3.0, 4.0], &[5.0, 6.0, 7.0, 8.0, 9.0]).unwrap();
    assert!(close(r.p, 2.0 / 126.0, 1e-12), "{}", r.p);
    assert!(r.significant(0.05));
}

#[test]
fn small_overlap_exact() {
    // x = {1, 2, 4}, y = {3, 5, 6}: pairs with x > y: (4 > 3) only, so U1 = 1. Arrangements
    // of 3 and 3 with U <= 1: U = 0 (x x x y y y) and U = 1 (x x y x y y): 2 of 20, so
    // P(U <= 1) = 0.1 and p = 0.2.
    let r = mann_whitney(&[1.0, 2.0, 4.0], &[3.0, 5.0, 6.0]).unwrap();
    assert_eq!(r.u1, 1.0);
    assert!(close(r.p, 0.2, 1e-12), "{}", r.p);
    assert!(!r.significant(0.05));
}

#[test]
fn ties_use_the_corrected_normal_approximation() {
    // x = {1, 2, 2, 3}, y = {2, 3, 4, 5}. Pooled ranks: 1 -> 1; the three 2s share
    // (2+3+4)/3 = 3; the two 3s share 5.5; 4 -> 7; 5 -> 8. R1 = 1 + 3 + 3 + 5.5 = 12.5,
    // U1 = 12.5 - 4*5/2 = 2.5, U2 = 16 - 2.5 = 13.5. Mean n1 n2 / 2 = 8. Tie groups of 3
    // and 2: sum(t^3 - t) = 24 + 6 = 30, so var = (16/12) (9 - 30/56) = 11.2857143.
    // z = (|2.5 - 8| - 0.5) / sqrt(11.2857143) = 1.48835139, p = erfc(z / sqrt 2) = 0.1366582.
    let r = mann_whitney(&[1.0, 2.0, 2.0, 3.0], &[2.0, 3.0, 4.0, 5.0]).unwrap();
    assert_eq!((r.u1, r.u2, r.method), (2.5, 13.5, Method::Normal));
    assert!(close(r.p, 0.136_658_247_7, 1e-6), "{}", r.p);
}

#[test]
fn identical_samples_are_not_different() {
    let r = mann_whitney(&[1.0, 1.0, 1.0], &[1.0, 1.0]).unwrap();
    assert_eq!(r.p, 1.0);
    assert!(mann_whitney(&[], &[1.0]).is_err());
    assert!(mann_whitney(&[f64::NAN], &[1.0]).is_err());
}

/// `n` designs with independent features: d1 in [2.0, 2.8], d2 in [50, 75], d3 in 2..=6,
/// d4 in [0.001, 0.01], d5 and d6 in [-0.2, 0.2].
fn uncorrelated(n: usize) -> Vec<[f64; 6]> {
    let mut rng = CandidateSeed::new(42, 0).rng(Purpose::RandomGenome);
    (0..n)
        .map(|_| {
            [
                rng.random_range(2.0..2.8),
                rng.random_range(50.0..75.0),
                f64::from(rng.random_range(2..=6)),
                rng.random_range(0.001..0.01),
                rng.random_range(-0.2..0.2),
                rng.random_range(-0.2..0.2),
            ]
        })
        .collect()
}

#[test]
fn a_planted_linear_relation_is_recovered() {
    // d1 = 2.4 + 20 (d4 - 0.0055) + noise of 1 mm.
    let mut rng = CandidateSeed::new(43, 0).rng(Purpose::RandomGenome);
    let designs: Vec<[f64; 6]> = uncorrelated(2000)
        .into_iter()
        .map(|mut g| {
            g[0] = 2.4 + 20.0 * (g[3] - 0.0055) + rng.random_range(-0.001..0.001);
            g
        })
        .collect();
    let rules = mine_rules(&designs, 0.2).unwrap();
    let first = &rules.kept[0];
    println!("{first}");
    assert_eq!(first.target, 0, "the thinnest rule predicts d1");
    assert_eq!(first.terms[0].0, 3, "its heaviest term is d4");
    assert!(
        close(first.terms[0].1, 20.0, 0.01),
        "coefficient {}",
        first.terms[0].1
    );
    for &(j, a) in &first.terms[1..] {
        // Other features contribute nothing: their effect over their whole range is
        // below the noise.
        let range = [0.8, 25.0, 4.0, 0.009, 0.4, 0.4][j];
        assert!((a * range).abs() < 0.005, "d{} coefficient {a}", j + 1);
    }
    assert!(first.mean_error < 0.001, "{}", first.mean_error);
    // As a plain linear model (the rules CSV): intercept about 2.4 - 20 x 0.0055 = 2.29,
    // and it predicts exactly what the rule does.
    let (intercept, coefficients) = first.linear();
    assert_eq!(coefficients[0], 0.0);
    assert!(close(coefficients[3], 20.0, 0.01), "{coefficients:?}");
    assert!((intercept - 2.29).abs() < 0.01, "{intercept}");
    for g in &designs[..50] {
        let linear = intercept + (0..6).map(|j| coefficients[j] * g[j]).sum::<f64>();
        assert!((linear - first.predict(g)).abs() < 1e-9);
    }
    // Named one way throughout: by feature name, never by d-number.
    let text = first.to_string();
    assert!(text.starts_with("total_leg_length = "), "{text}");
    assert!(text.contains("(wall_thickness - "), "{text}");
    assert!(!text.contains("(d"), "{text}");
}

#[test]
fn uncorrelated_designs_give_only_feature_equals_mean_rules() {
    let rules = mine_rules(&uncorrelated(2000), 0.2).unwrap();
    // d1 (2.0 to 2.8 m) and d2 (50 to 75 kg) spread little against their RMS, so the
    // method keeps "feature = its mean" for them (the paper's section 7); nothing else.
    let mut targets: Vec<usize> = rules.kept.iter().map(|r| r.target).collect();
    targets.sort();
    assert_eq!(targets, [0, 1], "{:#?}", rules.kept);
    for r in &rules.kept {
        // Near-zero weights on the others: over its whole range each moves the target by
        // under a fifth of the target's own range (sampling noise mixes the d1 and d2 axes
        // slightly: about 0.06 rad for 2000 designs).
        let range = [0.8, 25.0, 4.0, 0.009, 0.4, 0.4];
        for &(j, a) in &r.terms {
            assert!((a * range[j]).abs() < 0.2 * range[r.target], "{r}");
        }
        // Its error is about std / RMS (uniform: mean |dev| = range/4).
        let want = [0.2 / 2.4, 6.25 / 62.5][r.target];
        assert!(close(r.mean_error, want, 0.1), "{} vs {want}", r.mean_error);
    }
}

#[test]
fn features_centred_near_zero_or_widely_spread_give_no_rule() {
    // Without the offset features (d1, d2 spread as widely as their values), nothing is kept.
    let designs: Vec<[f64; 6]> = uncorrelated(2000)
        .into_iter()
        .map(|mut g| {
            g[0] = (g[0] - 2.0) * 5.0; // 0 to 4
            g[1] -= 50.0; // 0 to 25
            g
        })
        .collect();
    let rules = mine_rules(&designs, 0.2).unwrap();
    assert!(rules.kept.is_empty(), "{:#?}", rules.kept);
    assert_eq!(rules.dropped.len(), 6);
}

#[test]
fn a_feature_that_never_varies_is_named_constant_and_in_no_rule() {
    // Every design has 2 legs a side (as every feasible elite of a search at the paper's
    // brief does): before, the method kept "legs_per_side = 2 + 0 x ..." as a rule.
    let designs: Vec<[f64; 6]> = uncorrelated(2000)
        .into_iter()
        .map(|mut g| {
            g[2] = 2.0;
            g
        })
        .collect();
    let rules = mine_rules(&designs, 0.2).unwrap();
    assert_eq!(rules.constant, [(2, 2.0)]);
    for r in rules.kept.iter().chain(&rules.dropped) {
        assert_ne!(r.target, 2, "{r}");
        assert!(r.terms.iter().all(|&(j, _)| j != 2), "{r}");
        assert_eq!(r.terms.len(), 4, "{r}");
    }
    assert_eq!(rules.kept.len() + rules.dropped.len(), 5);
    // The other features give what they gave with it varying: d1 and d2 equal their means.
    let mut targets: Vec<usize> = rules.kept.iter().map(|r| r.target).collect();
    targets.sort();
    assert_eq!(targets, [0, 1], "{:#?}", rules.kept);
}

#[test]
fn too_few_designs_give_no_rules() {
    use strider_coordinator::results::analysis::rules::{RulesError, MIN_RULE_DESIGNS};
    let designs = uncorrelated(MIN_RULE_DESIGNS - 1);
    assert_eq!(
        mine_rules(&designs, 0.2),
        Err(RulesError::TooFew(MIN_RULE_DESIGNS - 1))
    );
    assert!(mine_rules(&uncorrelated(MIN_RULE_DESIGNS), 0.2).is_ok());
    // Designs that are all one design: every feature constant, no rule.
    let same = vec![designs[0]; MIN_RULE_DESIGNS];
    let rules = mine_rules(&same, 0.2).unwrap();
    assert!(rules.kept.is_empty() && rules.dropped.is_empty());
    assert_eq!(rules.constant.len(), 6);
}

#[test]
fn an_empty_library_has_no_best_fitness_and_one_repeat_no_spread() {
    use strider_common::Scheme;
    use strider_coordinator::qd::library::{GenerationStats, InfeasibleLibrary, Library};
    use strider_coordinator::results::analysis::summary::{summarise, RunResult};
    let (library, infeasible) = (Library::new(), InfeasibleLibrary::new());
    let run = RunResult {
        scheme: Scheme::Static,
        library: &library,
        infeasible: &infeasible,
        last: GenerationStats::default(),
    };
    let text = summarise(&[run], &[Scheme::Static], 10.0).to_string();
    assert!(
        text.contains(
            "static  1 repeat: best fitness none (no design meets the brief), coverage 0.000 %\n"
        ),
        "{text}"
    );
    // One repeat: no "± sd" on its lines.
    for line in text.lines().filter(|l| l.starts_with("  static")) {
        assert!(!line.contains('±'), "{line}");
    }
}
