//! Random genomes and mutation (docs/model.md section 12).
//!
//! Real parameters mutate by a normal step with standard deviation 10 % of their range,
//! clamped; integers by +-1, clamped. Each morphology parameter mutates with its group's
//! probability; the controller, when it evolves (GENOME) or is tuned (ES), mutates every
//! parameter every time.

use crate::genome::{Controller, Genome, Morphology, ParamVector};
use crate::params::{MutationGroup, ParamKind, ParamSpec};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Standard deviation of a real mutation, as a fraction of the parameter's range.
pub const MUTATION_SIGMA_FRACTION: f64 = 0.1;

/// Per-parameter mutation probability of each morphology group (paper Table 3).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MutationRates {
    /// Body extents and payload position.
    pub body: f64,
    pub leg_count: f64,
    /// Leg attachment.
    pub leg_offset: f64,
    /// Wall thickness and the quadratic multipliers.
    pub leg: f64,
    /// Link lengths, widths and hinge axes.
    pub link: f64,
    /// Motors.
    pub motor: f64,
}

impl Default for MutationRates {
    fn default() -> Self {
        Self {
            body: 0.25,
            leg_count: 0.25,
            leg_offset: 0.25,
            leg: 0.25,
            link: 0.4,
            motor: 0.25,
        }
    }
}

impl MutationRates {
    /// Every group at the same probability.
    pub fn uniform(rate: f64) -> Self {
        Self {
            body: rate,
            leg_count: rate,
            leg_offset: rate,
            leg: rate,
            link: rate,
            motor: rate,
        }
    }

    /// The probability that one parameter of `group` mutates.
    pub fn rate(&self, group: MutationGroup) -> f64 {
        match group {
            MutationGroup::Body => self.body,
            MutationGroup::LegCount => self.leg_count,
            MutationGroup::LegOffset => self.leg_offset,
            MutationGroup::Leg => self.leg,
            MutationGroup::Link => self.link,
            MutationGroup::Motor => self.motor,
            MutationGroup::Controller => 1.0,
        }
    }
}

fn random_value<R: Rng + ?Sized>(spec: &ParamSpec, rng: &mut R) -> f64 {
    match spec.kind {
        ParamKind::Real => rng.random_range(spec.min..=spec.max),
        ParamKind::Integer => rng.random_range(spec.min as i64..=spec.max as i64) as f64,
    }
}

fn mutate_value<R: Rng + ?Sized>(spec: &ParamSpec, v: f64, rng: &mut R) -> f64 {
    let moved = match spec.kind {
        ParamKind::Real => {
            let z: f64 = StandardNormal.sample(rng);
            v + z * MUTATION_SIGMA_FRACTION * spec.span()
        }
        ParamKind::Integer => {
            if rng.random_bool(0.5) {
                v + 1.0
            } else {
                v - 1.0
            }
        }
    };
    spec.clamp(moved)
}

fn fill_random<R: Rng + ?Sized>(table: &[ParamSpec], values: &mut [f64], rng: &mut R) {
    for (v, spec) in values.iter_mut().zip(table) {
        *v = random_value(spec, rng);
    }
}

impl Morphology {
    /// A morphology drawn uniformly from every range.
    pub fn random<R: Rng + ?Sized>(rng: &mut R) -> Self {
        let mut m = Morphology::midpoints();
        fill_random(Self::TABLE, m.raw_mut(), rng);
        m
    }

    /// Mutates each parameter with its group's probability. Returns how many changed.
    pub fn mutate<R: Rng + ?Sized>(&mut self, rates: &MutationRates, rng: &mut R) -> usize {
        let mut changed = 0;
        for (v, spec) in self.raw_mut().iter_mut().zip(Self::TABLE) {
            // One uniform draw per parameter, always, so the draw sequence does not
            // depend on earlier outcomes.
            if rng.random::<f64>() < rates.rate(spec.group) {
                let new = mutate_value(spec, *v, rng);
                changed += usize::from(new != *v);
                *v = new;
            }
        }
        changed
    }
}

impl Controller {
    /// A controller drawn uniformly from every range (the GENOME scheme's start).
    pub fn random<R: Rng + ?Sized>(rng: &mut R) -> Self {
        let mut c = Controller::midpoints();
        fill_random(Self::TABLE, c.raw_mut(), rng);
        c
    }

    /// Mutates every parameter (GENOME reproduction and each ES iteration).
    pub fn mutate_all<R: Rng + ?Sized>(&mut self, rng: &mut R) {
        for (v, spec) in self.raw_mut().iter_mut().zip(Self::TABLE) {
            *v = mutate_value(spec, *v, rng);
        }
    }
}

/// How a run's controllers are produced (docs/model.md section 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scheme {
    /// The controller is fixed at the midpoints of its ranges.
    Static,
    /// The controller is part of the genome and evolves with it.
    Genome,
    /// Each morphology's controller is tuned by a 1+1 evolution strategy.
    Es,
}

impl Scheme {
    /// All schemes, in the paper's order.
    pub const ALL: [Scheme; 3] = [Scheme::Static, Scheme::Genome, Scheme::Es];

    /// The scheme's name in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Scheme::Static => "static",
            Scheme::Genome => "genome",
            Scheme::Es => "es",
        }
    }
}

impl std::fmt::Display for Scheme {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.name())
    }
}

impl std::str::FromStr for Scheme {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Scheme::ALL
            .into_iter()
            .find(|x| x.name() == s)
            .ok_or_else(|| format!("unknown scheme `{s}` (expected static, genome or es)"))
    }
}

impl Genome {
    /// A random genome for `scheme`: random morphology; a random controller under GENOME,
    /// the STATIC one otherwise.
    pub fn random<R: Rng + ?Sized>(scheme: Scheme, rng: &mut R) -> Self {
        let morphology = Morphology::random(rng);
        let controller = match scheme {
            Scheme::Genome => Controller::random(rng),
            Scheme::Static | Scheme::Es => Controller::static_default(),
        };
        Genome {
            morphology,
            controller,
        }
    }

    /// The offspring of `self` under `scheme`: the morphology mutates by group rates; under
    /// GENOME the controller mutates too (every parameter).
    pub fn offspring<R: Rng + ?Sized>(
        &self,
        scheme: Scheme,
        rates: &MutationRates,
        rng: &mut R,
    ) -> Self {
        let mut child = *self;
        child.morphology.mutate(rates, rng);
        if scheme == Scheme::Genome {
            child.controller.mutate_all(rng);
        }
        child
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{CONTROLLER_PARAMS, M, MORPHOLOGY_PARAMS};
    use crate::rng::{CandidateSeed, Purpose};
    use proptest::prelude::*;

    fn assert_valid(g: &Genome) {
        Morphology::from_values(g.morphology.values()).expect("morphology in range");
        Controller::from_values(g.controller.values()).expect("controller in range");
    }

    proptest! {
        #[test]
        fn random_genomes_are_in_range(run in any::<u64>(), cand in any::<u64>()) {
            for scheme in Scheme::ALL {
                let mut rng = CandidateSeed::new(run, cand).rng(Purpose::RandomGenome);
                assert_valid(&Genome::random(scheme, &mut rng));
            }
        }

        #[test]
        fn mutation_stays_in_range(run in any::<u64>(), cand in any::<u64>(), rounds in 1usize..40) {
            let mut rng = CandidateSeed::new(run, cand).rng(Purpose::Reproduction);
            let mut g = Genome::random(Scheme::Genome, &mut rng);
            // Heavy rates push values against the clamps often.
            let rates = MutationRates::uniform(1.0);
            for _ in 0..rounds {
                g = g.offspring(Scheme::Genome, &rates, &mut rng);
                assert_valid(&g);
            }
        }

        #[test]
        fn integer_mutation_moves_by_one(run in any::<u64>()) {
            let mut rng = CandidateSeed::new(run, 0).rng(Purpose::Reproduction);
            let mut m = Morphology::random(&mut rng);
            let before = m.get(M::LegsPerSide);
            let rates = MutationRates { leg_count: 1.0, ..MutationRates::default() };
            m.mutate(&rates, &mut rng);
            let step = (m.get(M::LegsPerSide) - before).abs();
            prop_assert!(step == 1.0 || (step == 0.0 && (before == 2.0 || before == 6.0)));
        }
    }

    #[test]
    fn same_seed_same_genome_different_candidate_different_genome() {
        let a = Genome::random(
            Scheme::Genome,
            &mut CandidateSeed::new(11, 5).rng(Purpose::RandomGenome),
        );
        let b = Genome::random(
            Scheme::Genome,
            &mut CandidateSeed::new(11, 5).rng(Purpose::RandomGenome),
        );
        let c = Genome::random(
            Scheme::Genome,
            &mut CandidateSeed::new(11, 6).rng(Purpose::RandomGenome),
        );
        assert_eq!(a, b);
        assert_ne!(a, c);
        // Different streams differ in every real parameter.
        let differing = a
            .morphology
            .values()
            .iter()
            .zip(c.morphology.values())
            .filter(|(x, y)| x != y)
            .count();
        assert!(
            differing
                >= MORPHOLOGY_PARAMS
                    .iter()
                    .filter(|p| p.kind == ParamKind::Real)
                    .count()
        );
    }

    #[test]
    fn zero_rates_leave_the_morphology_alone() {
        let mut rng = CandidateSeed::new(1, 1).rng(Purpose::Reproduction);
        let parent = Genome::random(Scheme::Static, &mut rng);
        let rates = MutationRates::uniform(0.0);
        let child = parent.offspring(Scheme::Static, &rates, &mut rng);
        assert_eq!(parent, child);
        // GENOME still mutates every controller parameter.
        let child = parent.offspring(Scheme::Genome, &rates, &mut rng);
        assert_eq!(parent.morphology, child.morphology);
        for (i, (a, b)) in parent
            .controller
            .values()
            .iter()
            .zip(child.controller.values())
            .enumerate()
        {
            assert_ne!(a, b, "{} did not mutate", CONTROLLER_PARAMS[i].name);
        }
    }

    #[test]
    fn mutation_rate_is_honoured_statistically() {
        // 4000 mutations of one body parameter at rate 0.25: the count of changes is
        // binomial(4000, 0.25): mean 1000, sd 27; +-150 is over 5 sd.
        let mut rng = CandidateSeed::new(3, 0).rng(Purpose::Reproduction);
        let rates = MutationRates::default();
        let mut changed = 0;
        let base = Morphology::midpoints();
        for _ in 0..4000 {
            let mut m = base;
            m.mutate(&rates, &mut rng);
            changed += usize::from(m.get(M::BodyHalfX) != base.get(M::BodyHalfX));
        }
        assert!((850..=1150).contains(&changed), "{changed}");
    }

    #[test]
    fn real_step_has_the_specified_spread() {
        // Mutating the midpoint of body_half_x (range 0.6) by sigma 0.06, far from clamps:
        // the sample standard deviation of 4000 steps lies within 5 % of 0.06.
        let mut rng = CandidateSeed::new(4, 0).rng(Purpose::Reproduction);
        let spec = M::BodyHalfX.spec();
        let n = 4000;
        let steps: Vec<f64> = (0..n)
            .map(|_| mutate_value(spec, spec.midpoint(), &mut rng) - spec.midpoint())
            .collect();
        let mean = steps.iter().sum::<f64>() / n as f64;
        let sd = (steps.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
        // Clamping at +-5 sigma is negligible.
        assert!((sd - 0.06).abs() < 0.003, "{sd}");
        assert!(mean.abs() < 0.005, "{mean}");
    }
}
