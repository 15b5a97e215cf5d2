//! A checksum per candidate row and per generations row, written with the row and
//! checked against it: damage SQLite cannot see (a flipped byte inside a genome's text,
//! an edited fitness, a changed mean fitness) is caught on resume for the rows the search
//! reads again (the libraries' holders, every generations row) and by `verify` for every
//! row.
//!
//! FNV-1a (64 bits) over the row's columns in a fixed order, each written as text (REALs
//! by their bits) and ended by a separator byte: portable, with no dependency, and a
//! row's checksum never changes with the build. It detects damage, not tampering: whoever
//! edits a row on purpose can write its checksum too.

use super::rows::column;
use super::DbError;
use crate::qd::library::GenerationStats;
use sqlx::sqlite::SqliteRow;
use strider_common::fnv::Fnv1a;

/// The columns of a candidate row the checksum covers, as stored.
#[derive(Clone, Copy, Debug)]
pub struct CandidateColumns<'a> {
    /// `run_id`.
    pub run: i64,
    pub number: i64,
    pub generation: i64,
    /// `genome` (JSON).
    pub genome: &'a str,
    /// `outcome` (JSON).
    pub outcome: &'a str,
    pub kind: &'a str,
    pub fitness: Option<f64>,
    pub cell: Option<i64>,
    pub placement: &'a str,
    pub shortfall: Option<&'a str>,
    pub standing: Option<f64>,
    pub infeasible_placement: Option<&'a str>,
}

/// The columns a checksum check selects ([`CandidateColumns::from_row`] reads them by name).
pub const SELECTED: [&str; 13] = [
    "run_id",
    "number",
    "generation",
    "genome",
    "outcome",
    "kind",
    "fitness",
    "cell",
    "placement",
    "shortfall",
    "standing",
    "infeasible_placement",
    "checksum",
];

/// [`SELECTED`] for a query naming the candidates table `alias`.
pub fn selected(alias: &str) -> String {
    SELECTED
        .iter()
        .map(|c| format!("{alias}.{c}"))
        .collect::<Vec<_>>()
        .join(", ")
}

impl<'a> CandidateColumns<'a> {
    /// The columns of `row` (selected as [`SELECTED`]), and its stored checksum (`None`
    /// for a row written before checksums). A column whose content cannot be decoded (text
    /// that is not UTF-8, a value of the wrong type) is an error naming it.
    pub fn from_row(row: &'a SqliteRow) -> Result<(Self, Option<i64>), DbError> {
        let t = "candidates";
        let run: i64 = column(row, t, "a row", "run_id")?;
        let number: i64 = column(row, t, format!("run {run}"), "number")?;
        let key = format!("run {run} candidate {number}");
        Ok((
            CandidateColumns {
                run,
                number,
                generation: column(row, t, &key, "generation")?,
                genome: column(row, t, &key, "genome")?,
                outcome: column(row, t, &key, "outcome")?,
                kind: column(row, t, &key, "kind")?,
                fitness: column(row, t, &key, "fitness")?,
                cell: column(row, t, &key, "cell")?,
                placement: column(row, t, &key, "placement")?,
                shortfall: column(row, t, &key, "shortfall")?,
                standing: column(row, t, &key, "standing")?,
                infeasible_placement: column(row, t, &key, "infeasible_placement")?,
            },
            column(row, t, &key, "checksum")?,
        ))
    }

    /// The row's checksum, stored as SQLite's 64-bit integer (the bits of the u64).
    pub fn checksum(&self) -> i64 {
        let mut h = Fnv1a::default();
        h.field(self.run.to_string().as_bytes());
        h.field(self.number.to_string().as_bytes());
        h.field(self.generation.to_string().as_bytes());
        h.field(self.genome.as_bytes());
        h.field(self.outcome.as_bytes());
        h.field(self.kind.as_bytes());
        h.field(real(self.fitness).as_bytes());
        h.field(
            self.cell
                .map(|c| c.to_string())
                .unwrap_or_default()
                .as_bytes(),
        );
        h.field(self.placement.as_bytes());
        h.field(self.shortfall.unwrap_or("").as_bytes());
        h.field(real(self.standing).as_bytes());
        h.field(self.infeasible_placement.unwrap_or("").as_bytes());
        h.value() as i64
    }
}

/// The columns of a `generations` row, as stored: the one type both its writer and its
/// readers use, so the checksum covers what is written and read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GenerationColumns {
    /// `run_id`.
    pub run: i64,
    pub generation: i64,
    pub evaluations: i64,
    pub coverage: f64,
    pub elites: i64,
    pub max_fitness: f64,
    pub mean_fitness: f64,
    pub min_fitness: f64,
    pub qd_score: f64,
    pub new: i64,
    pub improved: i64,
    pub discarded: i64,
    pub rejected: i64,
    pub invalid: i64,
    pub infeasible_elites: i64,
    pub infeasible_only: i64,
    pub infeasible_new: i64,
    pub infeasible_improved: i64,
}

/// The columns of a `generations` row, checksum last, in the table's order.
pub const GENERATION_COLUMNS: &str = "run_id, generation, evaluations, coverage, elites, max_fitness, mean_fitness, min_fitness, qd_score, new, improved, discarded, rejected, invalid, infeasible_elites, infeasible_only, infeasible_new, infeasible_improved, checksum";

impl GenerationColumns {
    /// The columns of `row` (selected as [`GENERATION_COLUMNS`]) and its stored checksum
    /// (`None` for a row written before generations had checksums); a column that cannot
    /// be decoded is an error naming the row and column.
    pub fn from_row(row: &SqliteRow) -> Result<(Self, Option<i64>), DbError> {
        let t = "generations";
        let run: i64 = column(row, t, "a row", "run_id")?;
        let generation: i64 = column(row, t, format!("run {run}"), "generation")?;
        let key = format!("run {run} generation {generation}");
        let c = |name: &str| column::<i64>(row, t, &key, name);
        let r = |name: &str| column::<f64>(row, t, &key, name);
        Ok((
            GenerationColumns {
                run,
                generation,
                evaluations: c("evaluations")?,
                coverage: r("coverage")?,
                elites: c("elites")?,
                max_fitness: r("max_fitness")?,
                mean_fitness: r("mean_fitness")?,
                min_fitness: r("min_fitness")?,
                qd_score: r("qd_score")?,
                new: c("new")?,
                improved: c("improved")?,
                discarded: c("discarded")?,
                rejected: c("rejected")?,
                invalid: c("invalid")?,
                infeasible_elites: c("infeasible_elites")?,
                infeasible_only: c("infeasible_only")?,
                infeasible_new: c("infeasible_new")?,
                infeasible_improved: c("infeasible_improved")?,
            },
            column(row, t, &key, "checksum")?,
        ))
    }

    /// The row's checksum, as [`CandidateColumns::checksum`]: every column in the table's
    /// order, integers as decimal text and REALs by their bits.
    pub fn checksum(&self) -> i64 {
        let mut h = Fnv1a::default();
        for v in [self.run, self.generation, self.evaluations] {
            h.field(v.to_string().as_bytes());
        }
        h.field(real(Some(self.coverage)).as_bytes());
        h.field(self.elites.to_string().as_bytes());
        for v in [
            self.max_fitness,
            self.mean_fitness,
            self.min_fitness,
            self.qd_score,
        ] {
            h.field(real(Some(v)).as_bytes());
        }
        for v in [
            self.new,
            self.improved,
            self.discarded,
            self.rejected,
            self.invalid,
            self.infeasible_elites,
            self.infeasible_only,
            self.infeasible_new,
            self.infeasible_improved,
        ] {
            h.field(v.to_string().as_bytes());
        }
        h.value() as i64
    }
}

/// The checksum of the `experiment` row: its columns in the table's order.
pub fn experiment_checksum(name: &str, definition: &str, build: &str, created_at: &str) -> i64 {
    let mut h = Fnv1a::default();
    for v in [name, definition, build, created_at] {
        h.field(v.as_bytes());
    }
    h.value() as i64
}

/// The checksum of a `pending` row: its columns in the table's order, as
/// [`CandidateColumns::checksum`] writes them (NULL as `-`).
#[allow(clippy::too_many_arguments)]
pub fn pending_checksum(
    run: i64,
    number: i64,
    generation: i64,
    status: &str,
    attempts: i64,
    worker: Option<i64>,
    outcome: Option<&str>,
    seconds: Option<f64>,
) -> i64 {
    let mut h = Fnv1a::default();
    for v in [run, number, generation] {
        h.field(v.to_string().as_bytes());
    }
    h.field(status.as_bytes());
    h.field(attempts.to_string().as_bytes());
    h.field(
        worker
            .map_or_else(|| "-".to_string(), |w| w.to_string())
            .as_bytes(),
    );
    h.field(outcome.unwrap_or("-").as_bytes());
    h.field(real(seconds).as_bytes());
    h.value() as i64
}

impl TryFrom<GenerationColumns> for (u32, u64, GenerationStats) {
    type Error = DbError;

    /// A generations row as the run's statistics; a count out of its type's range (a
    /// damaged row written before checksums) is an error naming the row and column.
    fn try_from(r: GenerationColumns) -> Result<Self, DbError> {
        let key = format!("run {} generation {}", r.run, r.generation);
        let out_of_range = |name: &str, v: i64| {
            DbError::Corrupt(format!(
                "table generations, {key}, column {name}: {v} is out of range"
            ))
        };
        let n = |name: &str, v: i64| usize::try_from(v).map_err(|_| out_of_range(name, v));
        Ok((
            u32::try_from(r.generation).map_err(|_| out_of_range("generation", r.generation))?,
            u64::try_from(r.evaluations).map_err(|_| out_of_range("evaluations", r.evaluations))?,
            GenerationStats {
                coverage: r.coverage,
                elites: n("elites", r.elites)?,
                max_fitness: r.max_fitness,
                mean_fitness: r.mean_fitness,
                min_fitness: r.min_fitness,
                qd_score: r.qd_score,
                new: n("new", r.new)?,
                improved: n("improved", r.improved)?,
                discarded: n("discarded", r.discarded)?,
                rejected: n("rejected", r.rejected)?,
                invalid: n("invalid", r.invalid)?,
                infeasible_elites: n("infeasible_elites", r.infeasible_elites)?,
                infeasible_only: n("infeasible_only", r.infeasible_only)?,
                infeasible_new: n("infeasible_new", r.infeasible_new)?,
                infeasible_improved: n("infeasible_improved", r.infeasible_improved)?,
            },
        ))
    }
}

/// A REAL by its bits (`-` for NULL), so that no rounding of a printed figure hides a change.
fn real(v: Option<f64>) -> String {
    v.map_or_else(|| "-".to_string(), |v| format!("{:016x}", v.to_bits()))
}

/// The pending row's checksum: the writer stores it, the reader checks it.
impl super::rows::PendingRow {
    /// The checksum of its columns, as the writer stores it and the reader checks it.
    pub fn computed_checksum(&self) -> i64 {
        pending_checksum(
            self.run_id,
            self.number,
            self.generation,
            &self.status,
            self.attempts,
            self.worker,
            self.outcome.as_deref(),
            self.seconds,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row() -> CandidateColumns<'static> {
        CandidateColumns {
            run: 0,
            number: 7,
            generation: 1,
            genome: r#"{"a":1}"#,
            outcome: r#"{"valid":{}}"#,
            kind: "valid",
            fitness: Some(2.5),
            cell: Some(42),
            placement: "new",
            shortfall: None,
            standing: None,
            infeasible_placement: None,
        }
    }

    fn generation() -> GenerationColumns {
        GenerationColumns {
            run: 0,
            generation: 3,
            evaluations: 60,
            coverage: 0.01,
            elites: 12,
            max_fitness: 2.0,
            mean_fitness: 1.5,
            min_fitness: 1.0,
            qd_score: 18.0,
            new: 1,
            improved: 2,
            discarded: 3,
            rejected: 4,
            invalid: 5,
            infeasible_elites: 6,
            infeasible_only: 7,
            infeasible_new: 8,
            infeasible_improved: 9,
        }
    }

    #[test]
    fn any_change_of_a_generations_column_changes_its_checksum() {
        let base = generation().checksum();
        assert_eq!(base, generation().checksum());
        // Each column in turn, by one unit or one ulp.
        let changes: [fn(&mut GenerationColumns); 18] = [
            |g| g.run += 1,
            |g| g.generation += 1,
            |g| g.evaluations += 1,
            |g| g.coverage = f64::from_bits(g.coverage.to_bits() + 1),
            |g| g.elites += 1,
            |g| g.max_fitness = f64::from_bits(g.max_fitness.to_bits() + 1),
            |g| g.mean_fitness = f64::from_bits(g.mean_fitness.to_bits() + 1),
            |g| g.min_fitness = f64::from_bits(g.min_fitness.to_bits() + 1),
            |g| g.qd_score = f64::from_bits(g.qd_score.to_bits() + 1),
            |g| g.new += 1,
            |g| g.improved += 1,
            |g| g.discarded += 1,
            |g| g.rejected += 1,
            |g| g.invalid += 1,
            |g| g.infeasible_elites += 1,
            |g| g.infeasible_only += 1,
            |g| g.infeasible_new += 1,
            |g| g.infeasible_improved += 1,
        ];
        for (i, change) in changes.iter().enumerate() {
            let mut g = generation();
            change(&mut g);
            assert_ne!(g.checksum(), base, "change of column {i} went unseen");
        }
    }

    #[test]
    fn any_change_of_an_experiment_column_changes_its_checksum() {
        let base = experiment_checksum("e", "seed = 1\n", "strider 0.1.0", "2026-11-25T18:00:00Z");
        for other in [
            experiment_checksum("f", "seed = 1\n", "strider 0.1.0", "2026-11-25T18:00:00Z"),
            experiment_checksum("e", "seed = 3\n", "strider 0.1.0", "2026-11-25T18:00:00Z"),
            experiment_checksum("e", "seed = 1\n", "strider 0.1.1", "2026-11-25T18:00:00Z"),
            experiment_checksum("e", "seed = 1\n", "strider 0.1.0", "2026-11-25T18:00:01Z"),
            // A byte moved from one column to the next.
            experiment_checksum("es", "eed = 1\n", "strider 0.1.0", "2026-11-25T18:00:00Z"),
        ] {
            assert_ne!(other, base);
        }
    }

    #[test]
    fn any_change_of_a_pending_column_changes_its_checksum() {
        let base = pending_checksum(0, 5, 1, "done", 0, Some(3), Some("{}"), Some(0.5));
        assert_eq!(
            base,
            pending_checksum(0, 5, 1, "done", 0, Some(3), Some("{}"), Some(0.5))
        );
        for other in [
            pending_checksum(1, 5, 1, "done", 0, Some(3), Some("{}"), Some(0.5)),
            pending_checksum(0, 6, 1, "done", 0, Some(3), Some("{}"), Some(0.5)),
            pending_checksum(0, 5, 2, "done", 0, Some(3), Some("{}"), Some(0.5)),
            pending_checksum(0, 5, 1, "failed", 0, Some(3), Some("{}"), Some(0.5)),
            pending_checksum(0, 5, 1, "done", 1, Some(3), Some("{}"), Some(0.5)),
            pending_checksum(0, 5, 1, "done", 0, None, Some("{}"), Some(0.5)),
            pending_checksum(0, 5, 1, "done", 0, Some(3), Some("{ }"), Some(0.5)),
            pending_checksum(0, 5, 1, "done", 0, Some(3), None, Some(0.5)),
            pending_checksum(0, 5, 1, "done", 0, Some(3), Some("{}"), Some(0.25)),
        ] {
            assert_ne!(other, base);
        }
    }

    #[test]
    fn any_change_of_a_covered_column_changes_the_checksum() {
        let base = row().checksum();
        assert_eq!(base, row().checksum(), "the same row, the same checksum");
        let changed = [
            CandidateColumns { run: 1, ..row() },
            CandidateColumns { number: 8, ..row() },
            CandidateColumns {
                generation: 2,
                ..row()
            },
            CandidateColumns {
                genome: r#"{"a":2}"#,
                ..row()
            },
            CandidateColumns {
                outcome: r#"{"valid":{ }}"#,
                ..row()
            },
            CandidateColumns {
                kind: "invalid",
                ..row()
            },
            CandidateColumns {
                fitness: Some(2.500_000_000_000_001),
                ..row()
            },
            CandidateColumns {
                fitness: None,
                ..row()
            },
            CandidateColumns {
                cell: Some(43),
                ..row()
            },
            CandidateColumns {
                placement: "improved",
                ..row()
            },
            CandidateColumns {
                shortfall: Some("speed"),
                ..row()
            },
            CandidateColumns {
                standing: Some(0.0),
                ..row()
            },
            CandidateColumns {
                infeasible_placement: Some("new"),
                ..row()
            },
            // A byte moved from one field to the next.
            CandidateColumns {
                genome: r#"{"a":1}{"#,
                outcome: r#""valid":{}}"#,
                ..row()
            },
        ];
        for (i, c) in changed.iter().enumerate() {
            assert_ne!(c.checksum(), base, "change {i} went unseen");
        }
    }
}
