//! The experiment file (TOML): which runs to make and their settings, with the paper's
//! values as defaults. Validated on load; every error names the field and what it allows.

use crate::brief::DesignBrief;
use crate::features::{FeatureGrid, FeatureRange, FEATURE_NAMES};
use crate::initial_designs::InitialDesigns;
use crate::rng::RunSeed;
use crate::variation::{MutationRates, Scheme};
use serde::{Deserialize, Serialize};

mod files;

/// The friction coefficient between a robot and the ground by default: a rubber foot on a
/// firm surface.
pub const DEFAULT_FRICTION: f64 = 0.8;

/// The friction coefficients a run (or `fidelity --friction`) may ask for.
pub const FRICTION_RANGE: std::ops::RangeInclusive<f64> = 0.01..=2.0;

/// Settings every run of an experiment shares.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunSettings {
    /// Candidates that must pass the brief before generations start.
    pub initial_population: u32,
    pub offspring_per_generation: u32,
    /// Generations after the initial population.
    pub generations: u32,
    /// Trial length, s.
    pub trial_seconds: f64,
    /// Controller update rate, Hz.
    pub control_hz: f64,
    /// Physics steps per control step (the physics step is `1 / (control_hz * substeps)`).
    pub physics_substeps: u32,
    /// Iterations of the ES scheme's 1+1 evolution strategy.
    pub es_iterations: u32,
    /// Coulomb friction coefficient between the robot and the ground (every part; the
    /// ground has the same). The setting to check a design on a slipperier or grippier
    /// floor, as `physics_substeps` checks it at a finer step (docs/model.md section 6).
    pub friction: f64,
}

impl Default for RunSettings {
    fn default() -> Self {
        Self {
            initial_population: 400,
            offspring_per_generation: 60,
            generations: 4000,
            trial_seconds: 5.0,
            control_hz: 30.0,
            physics_substeps: 8,
            es_iterations: 20,
            friction: DEFAULT_FRICTION,
        }
    }
}

impl RunSettings {
    /// Candidates a run has counted toward its budget by the end of generation
    /// `generation`: its initial population, then `offspring_per_generation` a generation
    /// (initial draws refused before simulating do not count). The one formula for a
    /// run's budget, its progress and the report's evaluations axis.
    pub fn candidates_by(&self, generation: u32) -> u64 {
        u64::from(self.initial_population)
            + u64::from(generation) * u64::from(self.offspring_per_generation)
    }

    /// A run's whole budget in candidates (an ES candidate counts once).
    pub fn candidates_per_run(&self) -> u64 {
        self.candidates_by(self.generations)
    }

    /// Control steps in one trial.
    pub fn control_steps(&self) -> u32 {
        (self.trial_seconds * self.control_hz).round() as u32
    }

    /// The physics step, s.
    pub fn physics_dt(&self) -> f64 {
        1.0 / (self.control_hz * f64::from(self.physics_substeps))
    }
}

/// When a trial ends because the robot fell (docs/model.md section 6): `[trial]` in the
/// experiment file.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrialLimits {
    /// Largest tilt of the body from upright, degrees.
    pub max_tilt_degrees: f64,
    /// Lowest body-centre height, as a fraction of its height in the start pose.
    pub min_height_fraction: f64,
    /// Whether a part other than a lower leg touching the ground ends the trial.
    pub only_feet_on_ground: bool,
    /// How long the robot must stay up after the trial, the gait going on, s: a robot that
    /// falls then was falling at the end (distance and energy count over the trial only).
    pub upright_after_seconds: f64,
    /// Largest tilt of the body while it must stay up after the trial, degrees (the
    /// smaller of this and `max_tilt_degrees` applies): a robot past it is falling, not
    /// walking on, though it may not pass `max_tilt_degrees` before the window ends.
    pub upright_after_max_tilt_degrees: f64,
    /// How long a robot fast enough to meet the brief (its speed at the trial's end at
    /// least `min_speed` with the margin) must stay up after the trial, s: a gait that
    /// keeps walking (docs/model.md section 6). The longer of this and
    /// `upright_after_seconds` applies to it.
    pub upright_after_feasible_seconds: f64,
    /// Largest distance a foot may slide on the ground over the trial (mean over the feet)
    /// per metre walked: past it the feet skate (docs/model.md section 6).
    pub max_foot_slip_ratio: f64,
    /// Largest share of the feet's forward travel made within the ground clearance
    /// (3 cm): past it the feet shuffle along the ground instead of stepping.
    pub max_low_forward_share: f64,
    /// Fraction by which a design's average speed must beat the brief's `min_speed` in
    /// the run's own trial to count as feasible: a safety factor for the physics step's
    /// error, so that a design in the library still meets the brief at any finer step
    /// (docs/model.md section 6, "A verdict that holds at a finer step"). The confirming
    /// trials (`confirm_substeps_factor`, `friction_margin`) ask the brief as written:
    /// they are the check of that error, not a second trial to pass with the margin.
    pub speed_margin: f64,
    /// With more than 1 (2 by default), a design feasible at the run's physics step (and on
    /// the floors of `friction_margin`, tried first) is simulated again at a step this many
    /// times finer (`physics_substeps` times this) and is feasible only if it is feasible
    /// there too; otherwise it is invalid, `step_sensitive`. 1 turns the confirmation off.
    /// Why on: without it, 13 of the 226 feasible elites of the 1000-generation
    /// STATIC run lose their verdict at 480 Hz (94.2 % keep it, the bar is 95 %), ten of
    /// them falling in the window; with it, all keep it, for about a quarter more of a
    /// full-size run's wall time (docs/model.md section 6, "The issue's checks on its own
    /// sample").
    pub confirm_substeps_factor: u32,
    /// How long a design must stay up after its trial at the finer step of
    /// `confirm_substeps_factor`, s (the longer of this and `upright_after_seconds`
    /// applies). 1 by default: the run's own trial and both floors' have already held it
    /// `upright_after_feasible_seconds` (15 s); in the full-size run with a 15-s window
    /// there too, the 480-Hz trial took 18.6 % of the simulation, three quarters of it in
    /// that window (a 480-Hz second costs two at 240 Hz), and its window refused 168 of
    /// the 8,500 designs that reached it. On the issue's
    /// 1000-generation sample with 1 s, the 40 fittest feasible elites all stay feasible
    /// at 480 and 960 Hz with the 15-s window, all 40 walk in PyBullet at 4000 Hz, and 111
    /// of the 113 keep their verdict at 480 Hz with it (docs/model.md section 6, "The
    /// finer step's window"). Set it to `upright_after_feasible_seconds` for the full
    /// check at the finer step.
    pub confirm_substeps_upright_seconds: f64,
    /// A shove at the trial's end for a design fast enough to meet the brief: the whole
    /// robot's sideways velocity changes by this much, m/s (0: none), before the long
    /// window it must stay up through. A gait that keeps walking takes a shove
    /// (docs/model.md section 6); distance and energy count over the trial only, so only
    /// the verdict can change.
    pub push_speed: f64,
    /// A design feasible at the run's step is simulated again (before the finer step of
    /// `confirm_substeps_factor`) on floors with this fraction less and more grip (`[run] friction` times 1 -
    /// this and 1 + this), and is feasible only if it is feasible on both; otherwise it
    /// is invalid, `friction_sensitive`. 0 turns it off. Why: a walk that holds on one
    /// floor only is one a second engine's contacts, or a real floor, tip over
    /// (docs/model.md section 6).
    pub friction_margin: f64,
}

impl Default for TrialLimits {
    fn default() -> Self {
        Self {
            max_tilt_degrees: 45.0,
            min_height_fraction: 0.5,
            only_feet_on_ground: true,
            upright_after_seconds: 1.0,
            upright_after_max_tilt_degrees: 20.0,
            upright_after_feasible_seconds: 15.0,
            max_foot_slip_ratio: 0.5,
            max_low_forward_share: 0.4,
            speed_margin: 0.05,
            confirm_substeps_factor: 2,
            confirm_substeps_upright_seconds: 1.0,
            push_speed: 0.3,
            friction_margin: 0.25,
        }
    }
}

impl TrialLimits {
    /// The floors of the confirming trials (`[trial] friction_margin`): the run's
    /// `friction` times 1 - margin and 1 + margin, rounded to 1e-6, or `None` with the
    /// margin off. Rounded because it is the value a user types to try that floor
    /// (`fidelity --friction 0.6`), not 0.8 x 0.75 = 0.6000000000000001, one float step
    /// away, which on a gait near the tipping edge can be another verdict.
    pub fn confirming_floors(&self, friction: f64) -> Option<[f64; 2]> {
        let m = self.friction_margin;
        let rounded = |f: f64| (f * 1e6).round() / 1e6;
        (m > 0.0).then(|| [rounded(friction * (1.0 - m)), rounded(friction * (1.0 + m))])
    }
}

/// The shoves a trial may give, m/s (`[trial] push_speed`, `fidelity --push`): up to a
/// brisk walk's speed.
pub const PUSH_SPEED_RANGE: std::ops::RangeInclusive<f64> = 0.0..=2.0;

/// How a run treats designs that fail the brief (docs/model.md section 11).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ConstraintHandling {
    /// Constrained MAP-Elites (after FI-2Pop, Kimbrough et al. 2008, and Khalifa et al.,
    /// GECCO 2018): a feasible library ranked by fitness and an infeasible library ranked by
    /// closeness to the brief over the same cells, parents drawn from both; the initial
    /// population is random designs that pass the checks before simulating.
    FeasibleInfeasible,
    /// The paper's method: a design that fails the brief never enters the library, and the
    /// initial population is drawn until that many designs pass every check.
    Reject,
}

impl ConstraintHandling {
    /// The name in experiment files.
    pub fn name(self) -> &'static str {
        match self {
            ConstraintHandling::FeasibleInfeasible => "feasible-infeasible",
            ConstraintHandling::Reject => "reject",
        }
    }
}

/// The default infeasible tournament size (docs/model.md section 16 measures it).
pub const DEFAULT_INFEASIBLE_TOURNAMENT: u32 = 4;

/// How the search handles the brief: `[search]` in the experiment file.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SearchSettings {
    /// Feasible-infeasible libraries (the default) or the paper's rejection.
    pub constraints: ConstraintHandling,
    /// Under feasible-infeasible, the chance that an offspring's parent comes from the
    /// feasible library (1 while the infeasible one is empty, 0 while the feasible one is).
    pub feasible_parent_share: f64,
    /// Under feasible-infeasible, an infeasible parent is the nearest the brief of this
    /// many infeasible elites drawn uniformly (1: uniform, no pressure toward the brief).
    pub infeasible_tournament: u32,
}

impl Default for SearchSettings {
    fn default() -> Self {
        Self {
            constraints: ConstraintHandling::FeasibleInfeasible,
            feasible_parent_share: 0.5,
            infeasible_tournament: DEFAULT_INFEASIBLE_TOURNAMENT,
        }
    }
}

/// An experiment: schemes x repeats runs, each with its own seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiment {
    /// A name for humans and reports.
    pub name: String,
    /// Schemes to compare.
    pub schemes: Vec<Scheme>,
    /// Runs per scheme.
    pub repeats: u32,
    /// Base seed: repeat `r` of every scheme uses seed `seed + r` unless `seeds` is given
    /// (so schemes are compared on common random numbers).
    pub seed: u64,
    /// Explicit per-repeat seeds, one per repeat.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seeds: Option<Vec<u64>>,
    /// Shared run settings.
    #[serde(default)]
    pub run: RunSettings,
    /// When a robot counts as fallen.
    #[serde(default)]
    pub trial: TrialLimits,
    /// How the search handles the brief.
    #[serde(default)]
    pub search: SearchSettings,
    /// The design brief.
    #[serde(default)]
    pub brief: DesignBrief,
    /// Feature binning.
    #[serde(default)]
    pub features: FeatureGrid,
    /// Mutation rates per group.
    #[serde(default)]
    pub mutation: MutationRates,
    /// Designs drawn first in every run's initial population (a JSON file of genomes in
    /// an experiment file; the genomes themselves once loaded).
    #[serde(default, skip_serializing_if = "InitialDesigns::is_none")]
    pub initial_designs: InitialDesigns,
}

/// One run of an experiment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RunSpec {
    pub scheme: Scheme,
    /// Repeat number, from 0.
    pub repeat: u32,
    pub seed: RunSeed,
}

/// Why an experiment file was refused.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    #[error("cannot read experiment file {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("invalid experiment file {path}: {message}")]
    Parse { path: String, message: String },
    #[error("invalid experiment: `{field}` {problem}")]
    Invalid { field: String, problem: String },
}

fn invalid(field: impl Into<String>, problem: impl Into<String>) -> ExperimentError {
    ExperimentError::Invalid {
        field: field.into(),
        problem: problem.into(),
    }
}

fn check_int(field: &str, v: u32, min: u32, max: u32) -> Result<(), ExperimentError> {
    if v < min || v > max {
        return Err(invalid(field, format!("is {v}; allowed: {min} to {max}")));
    }
    Ok(())
}

fn check_real(field: &str, v: f64, min: f64, max: f64) -> Result<(), ExperimentError> {
    if !v.is_finite() {
        return Err(invalid(
            field,
            format!("is {v}; it must be a finite number"),
        ));
    }
    if v < min || v > max {
        return Err(invalid(field, format!("is {v}; allowed: {min} to {max}")));
    }
    Ok(())
}

impl Experiment {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ExperimentError> {
        if self.name.trim().is_empty() {
            return Err(invalid("name", "is empty"));
        }
        if self.schemes.is_empty() {
            return Err(invalid(
                "schemes",
                "is empty; list one or more of static, genome, es",
            ));
        }
        for (i, s) in self.schemes.iter().enumerate() {
            if self.schemes[..i].contains(s) {
                return Err(invalid("schemes", format!("lists `{s}` twice")));
            }
        }
        check_int("repeats", self.repeats, 1, 1000)?;
        if let Some(seeds) = &self.seeds {
            if seeds.len() != self.repeats as usize {
                return Err(invalid(
                    "seeds",
                    format!(
                        "has {} entries; it needs one per repeat ({})",
                        seeds.len(),
                        self.repeats
                    ),
                ));
            }
        }
        let r = &self.run;
        check_int("run.initial_population", r.initial_population, 1, 1_000_000)?;
        if let InitialDesigns::File(name) = &self.initial_designs {
            return Err(invalid(
                "initial_designs",
                format!("names {name}, which was not read: load the experiment from its file"),
            ));
        }
        let designs = self.initial_designs.designs().len();
        if designs > r.initial_population as usize {
            return Err(invalid(
                "initial_designs",
                format!(
                    "has {designs} designs, more than run.initial_population ({})",
                    r.initial_population
                ),
            ));
        }
        check_int(
            "run.offspring_per_generation",
            r.offspring_per_generation,
            1,
            1_000_000,
        )?;
        check_int("run.generations", r.generations, 0, 10_000_000)?;
        check_real("run.trial_seconds", r.trial_seconds, 0.1, 600.0)?;
        check_real("run.control_hz", r.control_hz, 1.0, 1000.0)?;
        check_int("run.physics_substeps", r.physics_substeps, 1, 64)?;
        // The drive's splitting (explicit stiffness, implicit damping) is stable for any
        // step up to twice the servo's derivative time (docs/model.md section 6).
        let longest = 2.0 * crate::body_plan::SERVO_DERIVATIVE_TIME;
        if r.physics_dt() > longest * (1.0 + 1e-12) {
            return Err(invalid(
                "run.physics_substeps",
                format!(
                    "gives a physics step of {:.4} s (control_hz {} x physics_substeps {}); the joint drives need one of at most {longest:.4} s: raise physics_substeps",
                    r.physics_dt(),
                    r.control_hz,
                    r.physics_substeps
                ),
            ));
        }
        check_int("run.es_iterations", r.es_iterations, 1, 10_000)?;
        check_real(
            "run.friction",
            r.friction,
            *FRICTION_RANGE.start(),
            *FRICTION_RANGE.end(),
        )?;
        check_real(
            "trial.max_tilt_degrees",
            self.trial.max_tilt_degrees,
            1.0,
            180.0,
        )?;
        check_real(
            "trial.min_height_fraction",
            self.trial.min_height_fraction,
            0.0,
            1.0,
        )?;
        check_real(
            "trial.upright_after_seconds",
            self.trial.upright_after_seconds,
            0.0,
            60.0,
        )?;
        check_real(
            "trial.upright_after_max_tilt_degrees",
            self.trial.upright_after_max_tilt_degrees,
            1.0,
            180.0,
        )?;
        check_real(
            "trial.max_foot_slip_ratio",
            self.trial.max_foot_slip_ratio,
            0.0,
            1000.0,
        )?;
        check_real(
            "trial.max_low_forward_share",
            self.trial.max_low_forward_share,
            0.0,
            1.0,
        )?;
        check_real(
            "trial.upright_after_feasible_seconds",
            self.trial.upright_after_feasible_seconds,
            0.0,
            600.0,
        )?;
        check_real(
            "trial.confirm_substeps_upright_seconds",
            self.trial.confirm_substeps_upright_seconds,
            0.0,
            600.0,
        )?;
        check_real("trial.speed_margin", self.trial.speed_margin, 0.0, 1.0)?;
        check_real(
            "trial.friction_margin",
            self.trial.friction_margin,
            0.0,
            0.9,
        )?;
        for f in self
            .trial
            .confirming_floors(self.run.friction)
            .into_iter()
            .flatten()
        {
            if !FRICTION_RANGE.contains(&f) {
                return Err(invalid(
                    "trial.friction_margin",
                    format!(
                        "is {}: it takes `run.friction` {} to {f}, outside {} to {} \
                         (set a smaller `trial.friction_margin`, or 0 for no floors but the run's)",
                        self.trial.friction_margin,
                        self.run.friction,
                        FRICTION_RANGE.start(),
                        FRICTION_RANGE.end()
                    ),
                ));
            }
        }
        check_real(
            "trial.push_speed",
            self.trial.push_speed,
            *PUSH_SPEED_RANGE.start(),
            *PUSH_SPEED_RANGE.end(),
        )?;
        check_int(
            "trial.confirm_substeps_factor",
            self.trial.confirm_substeps_factor,
            1,
            8,
        )?;
        check_real(
            "search.feasible_parent_share",
            self.search.feasible_parent_share,
            0.0,
            1.0,
        )?;
        check_int(
            "search.infeasible_tournament",
            self.search.infeasible_tournament,
            1,
            64,
        )?;
        let b = &self.brief;
        check_real("brief.max_mass", b.max_mass, 0.0, 10_000.0)?;
        check_real("brief.min_height", b.min_height, 0.0, 100.0)?;
        check_real("brief.min_speed", b.min_speed, 0.0, 100.0)?;
        check_real("brief.payload", b.payload, 0.0, 10_000.0)?;
        check_int("features.bins", self.features.bins, 1, 16)?;
        for (name, range) in FEATURE_NAMES.iter().zip(self.features.ranges()) {
            check_feature_range(name, range)?;
        }
        let m = &self.mutation;
        for (name, v) in [
            ("body", m.body),
            ("leg_count", m.leg_count),
            ("leg_offset", m.leg_offset),
            ("leg", m.leg),
            ("link", m.link),
            ("motor", m.motor),
        ] {
            check_real(&format!("mutation.{name}"), v, 0.0, 1.0)?;
        }
        Ok(())
    }

    /// Every run, scheme-major, repeats in order.
    pub fn runs(&self) -> Vec<RunSpec> {
        self.schemes
            .iter()
            .flat_map(|&scheme| {
                (0..self.repeats).map(move |repeat| RunSpec {
                    scheme,
                    repeat,
                    seed: RunSeed(match &self.seeds {
                        Some(s) => s[repeat as usize],
                        None => self.seed.wrapping_add(u64::from(repeat)),
                    }),
                })
            })
            .collect()
    }

    /// Candidates one run evaluates for its generations (the initial population needs
    /// more: it draws until `initial_population` pass its checks).
    pub fn offspring_per_run(&self) -> u64 {
        self.run.candidates_per_run() - u64::from(self.run.initial_population)
    }
}

fn check_feature_range(name: &str, r: FeatureRange) -> Result<(), ExperimentError> {
    if !(r.min.is_finite() && r.max.is_finite()) {
        return Err(invalid(
            format!("features.{name}"),
            "must have finite min and max",
        ));
    }
    if r.min >= r.max {
        return Err(invalid(
            format!("features.{name}"),
            format!("has min {} >= max {}; min must be below max", r.min, r.max),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = "name = \"t\"\nschemes = [\"static\"]\nrepeats = 2\nseed = 5\n";

    fn err(text: &str) -> String {
        Experiment::from_toml(text).unwrap_err().to_string()
    }

    /// Every experiment file shipped in `experiments/` (the ones the README and
    /// BENCHMARKS.md tell users to run) loads and validates, its initial designs too.
    #[test]
    fn every_shipped_experiment_loads() {
        let folder = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../experiments");
        let mut names = Vec::new();
        for entry in std::fs::read_dir(&folder).expect("experiments/ is readable") {
            let path = entry.expect("a directory entry").path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            // Dot files are editors' locks and backups, not experiments.
            if name.ends_with(".toml") && !name.starts_with('.') {
                if let Err(e) = Experiment::load(&path) {
                    panic!("{}: {e}", path.display());
                }
                names.push(name);
            }
        }
        names.sort();
        for shipped in [
            "paper-compare.toml",
            "paper-reject.toml",
            "paper-static.toml",
            "paper.toml",
            "quick.toml",
        ] {
            assert!(
                names.iter().any(|n| n == shipped),
                "{shipped} missing from {names:?}"
            );
        }
    }

    #[test]
    fn paper_defaults() {
        let e = Experiment::paper();
        assert_eq!(e.runs().len(), 60);
        assert_eq!(e.run, RunSettings::default());
        assert_eq!(e.run.control_steps(), 150);
        assert_eq!(e.offspring_per_run(), 240_000);
        assert_eq!(e.brief, DesignBrief::default());
        assert_eq!(e.trial, TrialLimits::default());
        assert_eq!(e.search, SearchSettings::default());
        assert_eq!(e.features, FeatureGrid::default());
        assert_eq!(e.mutation, MutationRates::default());
    }

    #[test]
    fn minimal_file_gets_paper_defaults_and_seeds() {
        let e = Experiment::from_toml(MINIMAL).unwrap();
        assert_eq!(e.run.generations, 4000);
        let seeds: Vec<u64> = e.runs().iter().map(|r| r.seed.0).collect();
        assert_eq!(seeds, [5, 6]);
    }

    #[test]
    fn a_physics_step_the_drives_cannot_take_is_refused_naming_the_fix() {
        let e = err(&format!(
            "{MINIMAL}[run]\ncontrol_hz = 10.0\nphysics_substeps = 1\n"
        ));
        assert!(
            e.contains("`run.physics_substeps`") && e.contains("raise physics_substeps"),
            "{e}"
        );
        // 15 Hz is the slowest the drives take.
        assert!(Experiment::from_toml(&format!(
            "{MINIMAL}[run]\ncontrol_hz = 15.0\nphysics_substeps = 1\n"
        ))
        .is_ok());
    }

    #[test]
    fn friction_is_a_setting_with_a_range() {
        let e = Experiment::from_toml(MINIMAL).unwrap();
        assert_eq!(e.run.friction, DEFAULT_FRICTION);
        let e = Experiment::from_toml(&format!("{MINIMAL}[run]\nfriction = 0.6\n")).unwrap();
        assert_eq!(e.run.friction, 0.6);
        let e = err(&format!("{MINIMAL}[run]\nfriction = 0.0\n"));
        assert!(e.contains("`run.friction` is 0; allowed: 0.01 to 2"), "{e}");
    }

    #[test]
    fn a_shove_is_on_by_default_can_be_turned_off_and_has_a_range() {
        let e = Experiment::from_toml(MINIMAL).unwrap();
        assert_eq!(e.trial.push_speed, 0.3);
        let e = Experiment::from_toml(&format!("{MINIMAL}[trial]\npush_speed = 0.0\n")).unwrap();
        assert_eq!(e.trial.push_speed, 0.0);
        let e = err(&format!("{MINIMAL}[trial]\npush_speed = 2.5\n"));
        assert!(
            e.contains("`trial.push_speed` is 2.5; allowed: 0 to 2"),
            "{e}"
        );
    }

    #[test]
    fn the_friction_margin_is_on_by_default_can_be_turned_off_and_keeps_both_floors_in_range() {
        let e = Experiment::from_toml(MINIMAL).unwrap();
        assert_eq!(e.trial.friction_margin, 0.25);
        // The floors a user types (0.6, not 0.8 x 0.75 = 0.6000000000000001).
        assert_eq!(e.trial.confirming_floors(e.run.friction), Some([0.6, 1.0]));
        let e =
            Experiment::from_toml(&format!("{MINIMAL}[trial]\nfriction_margin = 0.0\n")).unwrap();
        assert_eq!(e.trial.friction_margin, 0.0);
        assert_eq!(e.trial.confirming_floors(0.8), None);
        let e = err(&format!("{MINIMAL}[trial]\nfriction_margin = 0.95\n"));
        assert!(
            e.contains("`trial.friction_margin` is 0.95; allowed: 0 to 0.9"),
            "{e}"
        );
        // The default margin too names the setting to change.
        let e = err(&format!("{MINIMAL}[run]\nfriction = 1.8\n"));
        assert!(
            e.contains("`trial.friction_margin` is 0.25: it takes `run.friction` 1.8 to 2.25, outside 0.01 to 2 (set a smaller `trial.friction_margin`, or 0"),
            "{e}"
        );
        assert!(Experiment::from_toml(&format!(
            "{MINIMAL}[run]\nfriction = 1.8\n[trial]\nfriction_margin = 0.0\n"
        ))
        .is_ok());
    }

    #[test]
    fn missing_field_is_named() {
        let e = err("name = \"t\"\nschemes = [\"static\"]\nseed = 5\n");
        assert!(e.contains("missing field `repeats`"), "{e}");
    }

    #[test]
    fn out_of_range_is_named_with_the_range() {
        let e = err(&format!("{MINIMAL}[run]\nphysics_substeps = 0\n"));
        assert!(
            e.contains("`run.physics_substeps` is 0; allowed: 1 to 64"),
            "{e}"
        );
        let e = err(&format!("{MINIMAL}[mutation]\nlink = 1.5\n"));
        assert!(e.contains("`mutation.link` is 1.5; allowed: 0 to 1"), "{e}");
        let e = err(&format!(
            "{MINIMAL}[features.total_mass]\nmin = 80.0\nmax = 75.0\n"
        ));
        assert!(
            e.contains("`features.total_mass` has min 80 >= max 75"),
            "{e}"
        );
    }

    #[test]
    fn wrong_type_is_named() {
        let e = err(&format!("{MINIMAL}[run]\ngenerations = \"many\"\n"));
        assert!(
            e.contains("generations") && e.contains("invalid type"),
            "{e}"
        );
        let e = err("name = \"t\"\nschemes = [\"walk\"]\nrepeats = 1\nseed = 1\n");
        assert!(e.contains("walk") && e.contains("schemes"), "{e}");
    }

    #[test]
    fn nan_is_named() {
        let e = err(&format!("{MINIMAL}[brief]\nmin_height = nan\n"));
        assert!(
            e.contains("`brief.min_height` is NaN; it must be a finite number"),
            "{e}"
        );
    }

    #[test]
    fn unknown_field_is_named() {
        let e = err(&format!("{MINIMAL}[run]\ngenerationz = 3\n"));
        assert!(e.contains("unknown field `generationz`"), "{e}");
    }

    #[test]
    fn constraint_handling_is_named_and_checked() {
        let e = Experiment::from_toml(&format!("{MINIMAL}[search]\nconstraints = \"reject\"\n"))
            .unwrap();
        assert_eq!(e.search.constraints, ConstraintHandling::Reject);
        let e = err(&format!("{MINIMAL}[search]\nconstraints = \"maybe\"\n"));
        assert!(
            e.contains("maybe") && e.contains("feasible-infeasible"),
            "{e}"
        );
        let e = err(&format!("{MINIMAL}[search]\nfeasible_parent_share = 1.5\n"));
        assert!(
            e.contains("`search.feasible_parent_share` is 1.5; allowed: 0 to 1"),
            "{e}"
        );
    }

    #[test]
    fn seeds_must_match_repeats() {
        let e = err(&format!("{MINIMAL}seeds = [1]\n"));
        assert!(
            e.contains("`seeds` has 1 entries; it needs one per repeat (2)"),
            "{e}"
        );
    }

    /// MAX's genome file, as JSON text.
    fn max_json() -> String {
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../designs/max.json"))
            .unwrap()
    }

    #[test]
    fn initial_designs_are_read_from_the_experiment_files_folder_and_stored_as_genomes() {
        let max: crate::Genome = serde_json::from_str(&max_json()).unwrap();
        let folder = std::env::temp_dir().join(format!("strider-initial-{}", std::process::id()));
        std::fs::create_dir_all(&folder).unwrap();
        std::fs::write(folder.join("seeds.json"), format!("[{0}, {0}]", max_json())).unwrap();
        let file = folder.join("e.toml");
        let text = MINIMAL.replace("seed = 5\n", "seed = 5\ninitial_designs = \"seeds.json\"\n");
        std::fs::write(&file, &text).unwrap();
        let e = Experiment::load(&file).unwrap();
        assert_eq!(e.initial_designs.designs(), [max, max]);
        // What the database stores holds the genomes: read back with no file to read.
        let stored = toml::to_string(&e).unwrap();
        let again = Experiment::from_toml_reading(&stored, |name| Err(format!("read {name}")));
        assert_eq!(again.unwrap(), e);
        // Read from the current directory when the experiment is text: here, not there.
        let here = Experiment::from_toml(&text).unwrap_err().to_string();
        assert!(
            here.contains("`initial_designs` cannot read seeds.json"),
            "{here}"
        );
        std::fs::remove_dir_all(&folder).unwrap();
    }

    #[test]
    fn bad_initial_designs_are_refused_naming_the_file_and_the_problem() {
        let with = |designs: String| {
            let text =
                format!("initial_designs = \"d.json\"\n{MINIMAL}[run]\ninitial_population = 2\n");
            Experiment::from_toml_reading(&text, |_| Ok(designs))
                .unwrap_err()
                .to_string()
        };
        let e = with(format!("[{0}, {0}, {0}]", max_json()));
        assert!(
            e.contains("`initial_designs` has 3 designs, more than run.initial_population (2)"),
            "{e}"
        );
        let e = with(max_json().replace("\"legs_per_side\": 3", "\"legs_per_side\": 9"));
        assert!(
            e.contains("file d.json") && e.contains("expected a sequence"),
            "{e}"
        );
        let e = with(format!(
            "[{}]",
            max_json().replace("\"legs_per_side\": 3", "\"legs_per_side\": 9")
        ));
        assert!(
            e.contains("file d.json") && e.contains("legs_per_side"),
            "{e}"
        );
        let e = err(&format!("initial_designs = \"\"\n{MINIMAL}"));
        assert!(e.contains("names no file"), "{e}");
        let e = with("[]".into());
        assert!(e.contains("file d.json holds no design"), "{e}");
        let e = err(&format!("initial_designs = []\n{MINIMAL}"));
        assert!(e.contains("is an empty list"), "{e}");
        // An experiment made in code with a file it never read is refused, not run from
        // random designs.
        let mut unread = Experiment::from_toml(MINIMAL).unwrap();
        unread.initial_designs = InitialDesigns::File("d.json".into());
        let e = unread.validate().unwrap_err().to_string();
        assert!(e.contains("names d.json, which was not read"), "{e}");
    }

    #[test]
    fn the_quick_experiment_starts_from_its_built_in_designs() {
        let e = Experiment::quick();
        assert_eq!(e.initial_designs.designs().len(), 10);
    }
}
