//! What `strider-coordinator export` writes: every elite, one row each, with its cell,
//! features, fitness, trial statistics and full genome (CSV or JSON), and how an elite is
//! named on the command line (`RUN:CELL` or `best`). Plain functions over plain data.

use crate::db::StoredInfeasible;
use crate::qd::library::Elite;
use crate::qd::run::RunRecord;
use std::collections::HashMap;
use std::fmt::Write;
use strider_common::features::FEATURE_NAMES;
use strider_common::genome::ParamVector;
use strider_common::params::{ParamKind, CONTROLLER_PARAMS, MORPHOLOGY_PARAMS};
use strider_common::{
    CellIndex, Features, Genome, Outcome, RunId, Shortfall, Standing, TrialStats,
};

/// One elite as exported.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportedElite {
    pub run: RunId,
    /// The run's scheme name.
    pub scheme: String,
    /// The run's repeat number.
    pub repeat: u32,
    pub cell: CellIndex,
    /// Its candidate number in the run.
    pub candidate: u64,
    /// 1 / cost of transport.
    pub fitness: f64,
    /// Features d1..d6 and the trial's figures (from its outcome).
    pub measured: Option<(Features, TrialStats)>,
    /// The whole genome, with the controller that earned the fitness.
    pub genome: Genome,
}

/// The rows of `run`'s library in cell order; `outcomes` maps a cell to its elite's
/// outcome (as stored with the candidate).
pub fn rows(run: &RunRecord, outcomes: &HashMap<CellIndex, Outcome>) -> Vec<ExportedElite> {
    run.library
        .elites()
        .map(|(cell, e)| ExportedElite {
            run: run.id,
            scheme: run.spec.scheme.name().to_string(),
            repeat: run.spec.repeat,
            cell,
            candidate: e.candidate.0,
            fitness: e.fitness,
            measured: match outcomes.get(&cell) {
                Some(Outcome::Valid {
                    features, stats, ..
                }) => Some((*features, *stats)),
                _ => None,
            },
            genome: e.genome,
        })
        .collect()
}

/// The robot name an exported design's URDF carries: `name_run_0_cell_12` for experiment
/// `name` (the report's downloads and `export --elite --urdf` give the same file).
pub fn urdf_robot_name(experiment: &str, run: RunId, cell: CellIndex) -> String {
    format!("{experiment} run {run} cell {}", cell.0)
}

/// Names of the trial statistics columns, in order.
pub const STAT_NAMES: [&str; 6] = [
    "distance",
    "energy",
    "speed",
    "mass",
    "cost_of_transport",
    "duration",
];

fn stat_values(s: &TrialStats) -> [f64; 6] {
    [
        s.distance,
        s.energy,
        s.speed,
        s.mass,
        s.cost_of_transport,
        s.duration,
    ]
}

/// The trial statistics in the CSV: all but `mass`, which is the feature
/// `feature_total_mass` again.
const CSV_STATS: [usize; 5] = [0, 1, 2, 4, 5];

/// The CSV header: identity, fitness, features (`feature_` and the feature's name: four
/// features are genome parameters too, and a column name must not repeat), statistics,
/// then every genome parameter, `genome_` and its table name. Every name is unique, so
/// pandas reads it as written.
pub fn csv_header() -> String {
    let mut h = String::from("run,scheme,repeat,cell,candidate,fitness");
    for name in FEATURE_NAMES {
        h.push_str(",feature_");
        h.push_str(name);
    }
    for i in CSV_STATS {
        h.push(',');
        h.push_str(STAT_NAMES[i]);
    }
    for p in MORPHOLOGY_PARAMS.iter().chain(CONTROLLER_PARAMS) {
        h.push_str(",genome_");
        h.push_str(p.name);
    }
    h
}

/// The per-generation CSV's header: the run, the generation, the candidates it evaluated
/// (the initial population's draws for generation 0, those refused before simulating
/// included) and all of the run's so far, then the library's statistics after it
/// ([`GenerationStats`](crate::qd::library::GenerationStats), coverage in per cent of the
/// cells, as the report, `analyse` and `status` give it); the fitness columns are
/// blank while the feasible library is empty.
pub const GENERATIONS_CSV_HEADER: &str = "run,scheme,repeat,generation,evaluations,\
cumulative_evaluations,coverage_percent,\
feasible_elites,max_fitness,mean_fitness,min_fitness,qd_score,new,improved,discarded,\
rejected,invalid,infeasible_elites,infeasible_only,infeasible_new,infeasible_improved";

/// A library's fitness figure for the CSV: blank while the library is empty (no design
/// has fitness 0).
fn blank_if_empty(s: &crate::qd::library::GenerationStats, figure: f64) -> String {
    if s.elites == 0 {
        String::new()
    } else {
        figure.to_string()
    }
}

/// Coverage as every figure a user reads gives it: per cent of the cells (the database
/// keeps the share, 0 to 1).
pub fn coverage_percent(share: f64) -> f64 {
    100.0 * share
}

/// One line of the per-generation CSV.
pub fn generations_csv_line(
    run: &RunRecord,
    generation: u32,
    (evaluations, cumulative): (u64, u64),
    s: &crate::qd::library::GenerationStats,
) -> String {
    format!(
        "{},{},{},{generation},{evaluations},{cumulative},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
        run.id,
        run.spec.scheme.name(),
        run.spec.repeat,
        coverage_percent(s.coverage),
        s.elites,
        blank_if_empty(s, s.max_fitness),
        blank_if_empty(s, s.mean_fitness),
        blank_if_empty(s, s.min_fitness),
        s.qd_score,
        s.new,
        s.improved,
        s.discarded,
        s.rejected,
        s.invalid,
        s.infeasible_elites,
        s.infeasible_only,
        s.infeasible_new,
        s.infeasible_improved
    )
}

/// One CSV line (features and statistics empty when the outcome is missing).
pub fn csv_line(r: &ExportedElite) -> String {
    let mut line = format!(
        "{},{},{},{},{},{}",
        r.run, r.scheme, r.repeat, r.cell.0, r.candidate, r.fitness
    );
    match &r.measured {
        Some((f, s)) => {
            let stats = stat_values(s);
            for v in f.0.iter().chain(CSV_STATS.iter().map(|&i| &stats[i])) {
                let _ = write!(line, ",{v}");
            }
        }
        None => line.push_str(&",".repeat(FEATURE_NAMES.len() + CSV_STATS.len())),
    }
    let values = r
        .genome
        .morphology
        .values()
        .iter()
        .zip(MORPHOLOGY_PARAMS)
        .chain(r.genome.controller.values().iter().zip(CONTROLLER_PARAMS));
    for (v, spec) in values {
        match spec.kind {
            ParamKind::Integer => {
                let _ = write!(line, ",{}", *v as i64);
            }
            ParamKind::Real => {
                let _ = write!(line, ",{v}");
            }
        }
    }
    line
}

/// One elite as a JSON object.
pub fn json(r: &ExportedElite) -> serde_json::Value {
    let (features, stats) = match &r.measured {
        Some((f, s)) => (
            serde_json::Value::Object(
                FEATURE_NAMES
                    .iter()
                    .zip(f.0)
                    .map(|(n, v)| (n.to_string(), v.into()))
                    .collect(),
            ),
            serde_json::to_value(s).unwrap_or(serde_json::Value::Null),
        ),
        None => (serde_json::Value::Null, serde_json::Value::Null),
    };
    serde_json::json!({
        "cell": r.cell.0,
        "candidate": r.candidate,
        "fitness": r.fitness,
        "features": features,
        "stats": stats,
        "genome": r.genome,
    })
}

/// One infeasible elite as a JSON object: where it is, what keeps it from the brief, its
/// figure in the order of outcomes, the trial's figures (or when and why it ended), and its
/// genome.
pub fn infeasible_json(e: &StoredInfeasible) -> serde_json::Value {
    let (stats, ended) = match &e.outcome {
        Outcome::Invalid {
            reason, at_time, ..
        } => (
            serde_json::Value::Null,
            serde_json::json!({
                "at_time": at_time,
                "reason": reason,
                "why": reason.to_string(),
            }),
        ),
        o => (
            o.stats()
                .and_then(|s| serde_json::to_value(s).ok())
                .unwrap_or(serde_json::Value::Null),
            serde_json::Value::Null,
        ),
    };
    serde_json::json!({
        "cell": e.cell.0,
        "candidate": e.candidate.0,
        "shortfall": e.shortfall.name(),
        "standing": e.standing,
        "stats": stats,
        "ended": ended,
        "genome": e.genome,
    })
}

/// An elite named on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EliteChoice {
    /// The fittest elite (of one run, or of the experiment).
    Best,
    /// Run and cell, written `RUN:CELL`.
    At { run: RunId, cell: u32 },
}

impl std::str::FromStr for EliteChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "best" {
            return Ok(EliteChoice::Best);
        }
        let bad = || format!("elite `{s}`: expected RUN:CELL (for example 0:1234) or `best`");
        let (run, cell) = s.split_once(':').ok_or_else(bad)?;
        Ok(EliteChoice::At {
            run: RunId(run.trim().parse().map_err(|_| bad())?),
            cell: cell.trim().parse().map_err(|_| bad())?,
        })
    }
}

/// An elite found by [`find`]: a feasible one, or the infeasible library's where its
/// cell holds no feasible design.
#[derive(Clone, Debug, PartialEq)]
pub struct Found {
    pub run: RunId,
    pub cell: CellIndex,
    pub genome: Genome,
    /// Its fitness when it meets the brief; otherwise what it misses the brief by.
    pub standing: FoundStanding,
}

/// Whether a [`Found`] elite meets the brief.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FoundStanding {
    /// A feasible elite, 1 / COT.
    Feasible { fitness: f64 },
    /// The infeasible library's elite: what keeps it from the brief and how near it came.
    Infeasible {
        shortfall: Shortfall,
        standing: Standing,
    },
}

impl std::fmt::Display for Found {
    /// `run R, cell C: fitness F`, or for an infeasible elite what it misses.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "run {}, cell {}: ", self.run, self.cell.0)?;
        match self.standing {
            FoundStanding::Feasible { fitness } => write!(f, "fitness {fitness:.4}"),
            FoundStanding::Infeasible {
                shortfall,
                standing,
            } => {
                write!(
                    f,
                    "no feasible design; the infeasible library's elite (short of the brief: {}",
                    shortfall.name()
                )?;
                match standing {
                    Standing::TooSlow { speed } => write!(f, ", {speed:.3} m/s)"),
                    Standing::EndedEarly { at_time } => write!(f, ", ended at {at_time:.2} s)"),
                    Standing::NotSimulated | Standing::Feasible { .. } => write!(f, ")"),
                }
            }
        }
    }
}

/// Finds the chosen elite among `runs`, whose cells number `cell_count`: for `RUN:CELL`
/// the cell's feasible elite, or its infeasible one where it has no feasible one.
pub fn find(runs: &[RunRecord], choice: EliteChoice, cell_count: u32) -> Result<Found, String> {
    let feasible = |run: RunId, cell: CellIndex, e: &Elite| Found {
        run,
        cell,
        genome: e.genome,
        standing: FoundStanding::Feasible { fitness: e.fitness },
    };
    match choice {
        EliteChoice::Best => runs
            .iter()
            .flat_map(|r| r.library.elites().map(move |(c, e)| (r.id, c, e)))
            .max_by(|a, b| a.2.fitness.total_cmp(&b.2.fitness))
            .map(|(run, c, e)| feasible(run, c, e))
            .ok_or_else(|| "the library is empty".to_string()),
        EliteChoice::At { run, cell } => {
            let r = runs
                .iter()
                .find(|r| r.id == run)
                .ok_or_else(|| format!("the database has no run {run}"))?;
            if cell >= cell_count {
                return Err(format!(
                    "cell {cell} is out of range: cells are numbered 0 to {}",
                    cell_count - 1
                ));
            }
            let c = CellIndex(cell);
            if let Some(e) = r.library.get(c) {
                return Ok(feasible(run, c, e));
            }
            r.infeasible
                .get(c)
                .map(|e| Found {
                    run,
                    cell: c,
                    genome: e.genome,
                    standing: FoundStanding::Infeasible {
                        shortfall: e.shortfall,
                        standing: e.standing,
                    },
                })
                .ok_or_else(|| format!("run {run} has no design in cell {cell}, feasible or not"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_librarys_fitness_columns_are_blank_not_zero() {
        use crate::qd::library::GenerationStats;
        use strider_common::experiment::RunSpec;
        use strider_common::rng::RunSeed;
        use strider_common::Scheme;
        let run = RunRecord::new(
            RunId(0),
            RunSpec {
                scheme: Scheme::Static,
                repeat: 0,
                seed: RunSeed(1),
            },
        );
        let header: Vec<&str> = GENERATIONS_CSV_HEADER.split(',').collect();
        let column = |line: &str, name: &str| {
            let at = header.iter().position(|h| *h == name).unwrap();
            line.split(',').nth(at).unwrap().to_string()
        };
        let empty = generations_csv_line(&run, 3, (60, 600), &GenerationStats::default());
        for name in ["max_fitness", "mean_fitness", "min_fitness"] {
            assert_eq!(column(&empty, name), "", "{name} in {empty}");
        }
        assert_eq!(column(&empty, "qd_score"), "0");
        let one = GenerationStats {
            elites: 1,
            max_fitness: 1.5,
            mean_fitness: 1.5,
            min_fitness: 1.5,
            qd_score: 1.5,
            ..GenerationStats::default()
        };
        let line = generations_csv_line(&run, 3, (60, 600), &one);
        assert_eq!(column(&line, "max_fitness"), "1.5");
    }

    #[test]
    fn elites_are_named_by_run_and_cell_or_best() {
        assert_eq!("best".parse(), Ok(EliteChoice::Best));
        assert_eq!(
            "2:1234".parse(),
            Ok(EliteChoice::At {
                run: RunId(2),
                cell: 1234
            })
        );
        let err = "1234".parse::<EliteChoice>().unwrap_err();
        assert!(err.contains("expected RUN:CELL"), "{err}");
        assert!("a:b".parse::<EliteChoice>().is_err());
    }

    #[test]
    fn the_csv_header_and_a_line_without_outcome_have_the_same_columns() {
        let header = csv_header();
        assert!(
            header.starts_with("run,scheme,repeat,cell,candidate,fitness,feature_total_leg_length")
        );
        let names: Vec<&str> = header.split(',').collect();
        let unique: std::collections::HashSet<&&str> = names.iter().collect();
        assert_eq!(unique.len(), names.len(), "a column name repeats: {header}");
        let genome = Genome::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../designs/max.json"),
        )
        .unwrap();
        let row = ExportedElite {
            run: RunId(0),
            scheme: "static".into(),
            repeat: 0,
            cell: CellIndex(7),
            candidate: 3,
            fitness: 1.5,
            measured: None,
            genome,
        };
        assert_eq!(csv_line(&row).split(',').count(), header.split(',').count());
    }
}
