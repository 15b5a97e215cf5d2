//! The experiment a database holds: storing it once, sealed by its checksum, reading it
//! back, and saying where another experiment file differs from it.

use super::*;

/// The experiment as canonical TOML (what the database stores and compares).
pub fn canonical_toml(e: &Experiment) -> String {
    toml::to_string(e).expect("experiments serialise")
}

/// The first setting in which two experiments differ, as `path: stored vs given`.
pub fn first_difference(stored: &Experiment, given: &Experiment) -> Option<String> {
    let a: toml::Value = toml::from_str(&canonical_toml(stored)).expect("canonical TOML parses");
    let b: toml::Value = toml::from_str(&canonical_toml(given)).expect("canonical TOML parses");
    diff(&a, &b, String::new())
}

fn diff(a: &toml::Value, b: &toml::Value, path: String) -> Option<String> {
    match (a, b) {
        (toml::Value::Table(ta), toml::Value::Table(tb)) => {
            let mut keys: Vec<&String> = ta.keys().chain(tb.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter().find_map(|k| {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                match (ta.get(k), tb.get(k)) {
                    (Some(x), Some(y)) => diff(x, y, p),
                    (x, y) => Some(format!(
                        "{p}: {} in the database, {} given",
                        show(x),
                        show(y)
                    )),
                }
            })
        }
        // Arrays of tables (the initial designs) are told entry by entry: whole, they
        // would fill a screen.
        (toml::Value::Array(xa), toml::Value::Array(xb)) if is_tables(xa) || is_tables(xb) => {
            if xa.len() != xb.len() {
                return Some(format!(
                    "{path}: {} entries in the database, {} given",
                    xa.len(),
                    xb.len()
                ));
            }
            xa.iter()
                .zip(xb)
                .enumerate()
                .find_map(|(i, (x, y))| diff(x, y, format!("{path}[{i}]")))
        }
        _ if a == b => None,
        _ => Some(format!("{path}: {a} in the database, {b} given")),
    }
}

/// Whether an array holds tables (TOML's `[[name]]`).
fn is_tables(values: &[toml::Value]) -> bool {
    values.first().is_some_and(toml::Value::is_table)
}

/// Whether `given` is `stored` with more generations and nothing else changed: an
/// extension of a run that may have finished. `Err` says why not when only the number of
/// generations differs but `given` has fewer.
pub fn extends(stored: &Experiment, given: &Experiment) -> Result<bool, String> {
    let mut same = given.clone();
    same.run.generations = stored.run.generations;
    if first_difference(stored, &same).is_some() {
        return Ok(false);
    }
    match given.run.generations.cmp(&stored.run.generations) {
        std::cmp::Ordering::Greater => Ok(true),
        std::cmp::Ordering::Equal => Ok(false),
        std::cmp::Ordering::Less => Err(format!(
            "run.generations: {} in the database, {} given: a run cannot be shortened (its later generations are stored); give {} or more to extend it",
            stored.run.generations, given.run.generations, stored.run.generations
        )),
    }
}

fn show(v: Option<&toml::Value>) -> String {
    match v {
        None => "absent".into(),
        Some(toml::Value::Array(a)) if is_tables(a) => format!("{} entries", a.len()),
        Some(v) => v.to_string(),
    }
}

/// The checksum of a read `experiment` row, from its name, definition, build and
/// created_at columns.
pub(super) fn experiment_row_checksum(r: &sqlx::sqlite::SqliteRow) -> Result<i64, DbError> {
    let col = |name| rows::column::<String>(r, "experiment", "row 1", name);
    Ok(checksum::experiment_checksum(
        &col("name")?,
        &col("definition")?,
        &col("build")?,
        &col("created_at")?,
    ))
}

/// Gives the experiment row its checksum if it has none (just stored, or stored before
/// checksums). A migration that rewrites the row must set its checksum to NULL, so that
/// the next writer seals the new text.
pub(super) async fn seal_experiment(
    tx: &mut sqlx::Transaction<'_, sqlx::Sqlite>,
) -> Result<(), DbError> {
    let row = sqlx::query(
        "SELECT name, definition, build, created_at FROM experiment WHERE id = 1 AND checksum IS NULL",
    )
    .fetch_optional(&mut **tx)
    .await?;
    if let Some(r) = row {
        sqlx::query("UPDATE experiment SET checksum = ? WHERE id = 1")
            .bind(experiment_row_checksum(&r)?)
            .execute(&mut **tx)
            .await?;
    }
    Ok(())
}

impl Db {
    /// The stored experiment, if any, checked against its row's checksum (a row stored
    /// before checksums has none).
    pub async fn experiment(&self) -> Result<Option<(Experiment, String)>, DbError> {
        let row = sqlx::query(
            "SELECT name, definition, build, created_at, checksum FROM experiment WHERE id = 1",
        )
        .fetch_optional(&self.pool)
        .await?;
        row.map(|r| {
            let stored: Option<i64> = rows::column(&r, "experiment", "row 1", "checksum")?;
            let sum = experiment_row_checksum(&r)?;
            if stored.is_some_and(|s| s != sum) {
                return Err(DbError::Corrupt(
                    "table experiment, row 1: the row does not match its checksum, so its name, definition, build or created_at was changed after it was written".into(),
                ));
            }
            let text: String = rows::column(&r, "experiment", "row 1", "definition")?;
            let e = Experiment::from_toml(&text).map_err(|e| {
                DbError::Corrupt(format!("table experiment, row 1, column definition: {e}"))
            })?;
            Ok((e, rows::column(&r, "experiment", "row 1", "build")?))
        })
        .transpose()
    }

    /// Replaces the stored experiment with `longer` (the same with more generations, see
    /// [`extends`]) and marks every run unfinished that has not done them all: one
    /// transaction, the row sealed anew.
    pub async fn extend_experiment(&self, longer: &Experiment) -> Result<(), DbError> {
        let mut tx = self.pool.begin().await?;
        sqlx::query("UPDATE experiment SET definition = ?, checksum = NULL WHERE id = 1")
            .bind(canonical_toml(longer))
            .execute(&mut *tx)
            .await?;
        seal_experiment(&mut tx).await?;
        sqlx::query("UPDATE runs SET finished = 0 WHERE generation < ?")
            .bind(i64::from(longer.run.generations))
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(())
    }

    /// Stores a new experiment and its runs, `made_by` the identity of what runs it (the
    /// build, and the machine's reference-trial digest where known).
    pub async fn create_experiment(&self, e: &Experiment, made_by: &str) -> Result<(), DbError> {
        let mut tx = self.pool.begin().await?;
        sqlx::query("INSERT INTO experiment (id, name, definition, build, created_at) VALUES (1, ?, ?, ?, strftime('%Y-%m-%dT%H:%M:%SZ', 'now'))")
            .bind(&e.name)
            .bind(canonical_toml(e))
            .bind(made_by)
            .execute(&mut *tx)
            .await?;
        seal_experiment(&mut tx).await?;
        for (id, run) in e.runs().iter().enumerate() {
            sqlx::query("INSERT INTO runs (id, scheme, repeat, seed, generation, initial_passed, next_candidate) VALUES (?, ?, ?, ?, 0, 0, 0)")
                .bind(id as i64)
                .bind(run.scheme.name())
                .bind(i64::from(run.repeat))
                .bind(run.seed.0 as i64)
                .execute(&mut *tx)
                .await?;
        }
        tx.commit().await?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strider_common::initial_designs::InitialDesigns;

    #[test]
    fn differing_initial_designs_are_told_by_entry_not_whole() {
        let max: strider_common::Genome = serde_json::from_str(
            &std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../designs/max.json"))
                .unwrap(),
        )
        .unwrap();
        let plain =
            Experiment::from_toml("name = \"d\"\nschemes = [\"static\"]\nrepeats = 1\nseed = 1\n")
                .unwrap();
        let with = |designs: Vec<strider_common::Genome>| Experiment {
            initial_designs: InitialDesigns::Designs(designs),
            ..plain.clone()
        };
        let mut other = serde_json::to_value(max).unwrap();
        other["morphology"]["legs_per_side"] = serde_json::json!(2);
        let other: strider_common::Genome = serde_json::from_value(other).unwrap();
        let a = with(vec![max, max]);
        assert_eq!(first_difference(&a, &a), None);
        let d = first_difference(&a, &with(vec![max, other])).unwrap();
        assert_eq!(
            d,
            "initial_designs[1].morphology.legs_per_side: 3 in the database, 2 given"
        );
        let d = first_difference(&a, &with(vec![max])).unwrap();
        assert_eq!(d, "initial_designs: 2 entries in the database, 1 given");
        let d = first_difference(&plain, &a).unwrap();
        assert_eq!(
            d,
            "initial_designs: absent in the database, 2 entries given"
        );
    }
}
