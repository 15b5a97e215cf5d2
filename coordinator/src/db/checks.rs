//! What `open` and `verify` check of a database: SQLite's integrity, the libraries'
//! JSON, the rows' checksums, and whether the tables agree with each other.

use super::*;

/// Problems naming damaged generations rows (the first five, and how many in all).
pub fn damaged_generations(bad: &[(i64, i64)]) -> Option<String> {
    if bad.is_empty() {
        return None;
    }
    let named: Vec<String> = bad
        .iter()
        .take(5)
        .map(|(run, g)| format!("run {run} generation {g}"))
        .collect();
    Some(format!(
        "{} generations rows do not match their checksums, so their figures were changed after they were written ({}{})",
        bad.len(),
        named.join(", "),
        if bad.len() > 5 { ", ..." } else { "" }
    ))
}

/// Problems naming damaged candidate rows (the first five, and how many in all).
pub fn damaged_rows(bad: &[(i64, i64)]) -> Option<String> {
    if bad.is_empty() {
        return None;
    }
    let named: Vec<String> = bad
        .iter()
        .take(5)
        .map(|(run, n)| format!("run {run} candidate {n}"))
        .collect();
    Some(format!(
        "{} candidate rows do not match their checksums, so they were changed after they were written ({}{})",
        bad.len(),
        named.join(", "),
        if bad.len() > 5 { ", ..." } else { "" }
    ))
}

impl Db {
    /// What is inconsistent in the stored state, by cheap queries run on every resume
    /// (`verify` replays everything): the runs against the experiment, each run's next
    /// candidate against the highest stored, each library cell against its candidate row.
    /// Empty when all agree.
    pub async fn inconsistencies(&self, experiment: &Experiment) -> Result<Vec<String>, DbError> {
        let mut out = Vec::new();
        let specs = experiment.runs();
        let rows = sqlx::query(
            "SELECT id, scheme, repeat, seed, next_candidate, \
             (SELECT MAX(number) FROM candidates WHERE run_id = runs.id) AS highest \
             FROM runs ORDER BY id",
        )
        .fetch_all(&self.pool)
        .await?;
        if rows.len() != specs.len() {
            out.push(format!(
                "the experiment has {} runs, the database {}",
                specs.len(),
                rows.len()
            ));
        }
        for (r, spec) in rows.iter().zip(&specs) {
            let id: i64 = rows::column(r, "runs", "a row", "id")?;
            let key = format!("run {id}");
            let scheme: String = rows::column(r, "runs", &key, "scheme")?;
            let seed = rows::column::<i64>(r, "runs", &key, "seed")? as u64;
            let repeat = rows::column::<i64>(r, "runs", &key, "repeat")? as u32;
            if scheme != spec.scheme.to_string() || repeat != spec.repeat || seed != spec.seed.0 {
                out.push(format!(
                    "run {id}: stored as {scheme} repeat {repeat} seed {seed}, the experiment makes it {} repeat {} seed {}",
                    spec.scheme, spec.repeat, spec.seed.0
                ));
            }
            let next: i64 = rows::column(r, "runs", &key, "next_candidate")?;
            let highest: Option<i64> = rows::column(r, "candidates", &key, "highest")?;
            if next != highest.map_or(0, |h| h + 1) {
                out.push(format!(
                    "run {id}: its next candidate is {next}, but the highest stored is {}",
                    highest.map_or("none".to_string(), |h| h.to_string())
                ));
            }
        }
        let bad_cells: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM cells l LEFT JOIN candidates c \
             ON c.run_id = l.run_id AND c.number = l.candidate \
             WHERE c.number IS NULL OR c.kind <> 'valid' OR c.cell <> l.cell OR c.fitness <> l.fitness",
        )
        .fetch_one(&self.pool)
        .await?;
        if bad_cells > 0 {
            out.push(format!(
                "{bad_cells} library cells name no candidate that is valid, in that cell, with that fitness"
            ));
        }
        let bad_infeasible: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM infeasible_cells l LEFT JOIN candidates c \
             ON c.run_id = l.run_id AND c.number = l.candidate \
             WHERE c.number IS NULL OR c.kind = 'valid' OR c.standing <> l.standing",
        )
        .fetch_one(&self.pool)
        .await?;
        if bad_infeasible > 0 {
            out.push(format!(
                "{bad_infeasible} infeasible library cells name no candidate that missed the brief with that standing"
            ));
        }
        // Every design that met the brief was placed in its cell, so each such cell has a
        // holder (a deleted cell row would leave the search a hole).
        let empty_cells: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM (SELECT DISTINCT run_id, cell FROM candidates WHERE kind = 'valid') v \
             WHERE NOT EXISTS (SELECT 1 FROM cells l WHERE l.run_id = v.run_id AND l.cell = v.cell)",
        )
        .fetch_one(&self.pool)
        .await?;
        if empty_cells > 0 {
            out.push(format!(
                "{empty_cells} cells hold no elite though a stored candidate that meets the brief lies in each"
            ));
        }
        out.extend(damaged_rows(&self.checksum_mismatches(true).await?));
        out.extend(damaged_generations(
            &self.generation_checksum_mismatches().await?,
        ));
        Ok(out)
    }

    /// SQLite's `PRAGMA integrity_check`: `["ok"]`, or what it found (pages, indexes,
    /// constraints), at most 100 lines.
    pub async fn integrity_check(&self) -> Result<Vec<String>, DbError> {
        let lines = sqlx::query("PRAGMA integrity_check(100)")
            .fetch_all(&self.pool)
            .await?;
        lines
            .iter()
            .map(|r| rows::column::<String>(r, "integrity_check", "its result", "integrity_check"))
            .collect()
    }

    /// Refuses a library holder whose genome or outcome is not JSON, naming its row and
    /// column: the views that export, analyse and report read parse both in SQLite, which
    /// would fail saying only "malformed JSON". Holders only (at most one per cell), so
    /// it is cheap on any database.
    pub async fn check_library_json(&self) -> Result<(), DbError> {
        let bad = sqlx::query(
            "SELECT c.run_id, c.number, json_valid(c.genome) AS genome_ok \
             FROM cells l JOIN candidates c ON c.run_id = l.run_id AND c.number = l.candidate \
             WHERE NOT (json_valid(c.genome) AND json_valid(c.outcome)) \
             UNION ALL \
             SELECT c.run_id, c.number, json_valid(c.genome) AS genome_ok \
             FROM infeasible_cells l JOIN candidates c ON c.run_id = l.run_id AND c.number = l.candidate \
             WHERE NOT (json_valid(c.genome) AND json_valid(c.outcome)) LIMIT 1",
        )
        .fetch_optional(&self.pool)
        .await?;
        let Some(r) = bad else { return Ok(()) };
        let t = "candidates";
        let run: i64 = rows::column(&r, t, "a library holder", "run_id")?;
        let number: i64 = rows::column(&r, t, format!("run {run}"), "number")?;
        let genome_ok: i64 =
            rows::column(&r, t, format!("run {run} candidate {number}"), "genome_ok")?;
        let column = if genome_ok == 0 { "genome" } else { "outcome" };
        Err(DbError::Corrupt(format!(
            "table candidates, run {run} candidate {number} (a library holder), column {column}: not JSON (damaged)"
        )))
    }

    /// The candidate rows whose checksum ([`checksum`]) does not match their columns:
    /// of the rows the libraries hold (what the search reads again on resume) when
    /// `libraries_only`, else of every row. Rows written before checksums are skipped.
    pub async fn checksum_mismatches(
        &self,
        libraries_only: bool,
    ) -> Result<Vec<(i64, i64)>, DbError> {
        // From the cells to their rows, by the candidates' key: the other way round (each
        // candidate looking for a cell it holds) scanned the cells once per candidate and
        // took minutes on a resume of the throughput benchmark.
        let cols = checksum::selected("c");
        let sql = if libraries_only {
            format!(
                "SELECT {cols} FROM cells l JOIN candidates c \
                 ON c.run_id = l.run_id AND c.number = l.candidate WHERE c.checksum IS NOT NULL \
                 UNION ALL \
                 SELECT {cols} FROM infeasible_cells l JOIN candidates c \
                 ON c.run_id = l.run_id AND c.number = l.candidate WHERE c.checksum IS NOT NULL"
            )
        } else {
            format!("SELECT {cols} FROM candidates c WHERE c.checksum IS NOT NULL")
        };
        let rows = sqlx::query(&sql).fetch_all(&self.pool).await?;
        let mut bad: Vec<(i64, i64)> = Vec::new();
        for r in &rows {
            match checksum::CandidateColumns::from_row(r) {
                Ok((columns, stored)) if stored == Some(columns.checksum()) => {}
                Ok((columns, _)) => bad.push((columns.run, columns.number)),
                // Content that cannot even be decoded is damage too, in the row it names;
                // only a row that cannot be named is an error.
                Err(e) => {
                    let run: i64 = rows::column(r, "candidates", "a row", "run_id")?;
                    let number = rows::column(r, "candidates", format!("run {run}"), "number");
                    bad.push((run, number.map_err(|_| e)?));
                }
            }
        }
        bad.sort_unstable();
        Ok(bad)
    }

    /// The generations rows (run, generation) that do not match their checksum or cannot
    /// be decoded, in order. Rows written before checksums are skipped.
    pub async fn generation_checksum_mismatches(&self) -> Result<Vec<(i64, i64)>, DbError> {
        let rows = sqlx::query(&format!(
            "SELECT {GENERATION_COLUMNS} FROM generations WHERE checksum IS NOT NULL"
        ))
        .fetch_all(&self.pool)
        .await?;
        let mut bad = Vec::new();
        for r in &rows {
            match GenerationColumns::from_row(r) {
                Ok((columns, stored)) if stored == Some(columns.checksum()) => {}
                Ok((columns, _)) => bad.push((columns.run, columns.generation)),
                Err(e) => {
                    let t = "generations";
                    let run: i64 = rows::column(r, t, "a row", "run_id")?;
                    let generation = rows::column(r, t, format!("run {run}"), "generation");
                    bad.push((run, generation.map_err(|_| e)?));
                }
            }
        }
        bad.sort_unstable();
        Ok(bad)
    }
}
