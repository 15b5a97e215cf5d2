//! Opening a database for a command: to run or serve it (created when new, refused when it
//! holds another experiment or is inconsistent), or to read it (read-only if need be).

use crate::db::{extends, first_difference, Db};
use crate::qd::run::RunRecord;
use crate::service::reference::{computes_otherwise, this_machine_identity};
use anyhow::{bail, Context};
use std::path::Path;
use strider_common::Experiment;
use strider_common::RunId;

/// Opens the database, creating it with the given experiment (or, for `run`, the built-in
/// quick one) when new; refuses an experiment that differs from the stored one.
pub(super) async fn open_or_create(
    file: Option<&Path>,
    path: &Path,
    quick_by_default: bool,
) -> anyhow::Result<(Db, Experiment)> {
    let given = match file {
        Some(f) => Some(Experiment::load(f)?),
        None => None,
    };
    if !path.exists() && given.is_none() && !quick_by_default {
        bail!(
            "no database at {}: pass --experiment FILE to start one",
            path.display()
        );
    }
    let db = Db::open_exclusive(path, true).await?;
    let experiment = match db.experiment().await? {
        Some((mut stored, build)) => {
            if let Some(given) = &given {
                let longer = extends(&stored, given)
                    .map_err(|why| anyhow::anyhow!("{}: {why}", path.display()))?;
                if longer {
                    // Checked against the stored experiment first: the extension is written
                    // only to a database that would be resumed as it is.
                    let problems = db.inconsistencies(&stored).await?;
                    if problems.is_empty() {
                        db.extend_experiment(given).await?;
                        eprintln!(
                            "extending experiment `{}` from {} to {} generations",
                            stored.name, stored.run.generations, given.run.generations
                        );
                        stored = given.clone();
                    }
                } else if let Some(d) = first_difference(&stored, given) {
                    bail!(
                        "{} holds a different experiment ({d}); use another --db or the same file",
                        path.display()
                    );
                }
            }
            let problems = db.inconsistencies(&stored).await?;
            if !problems.is_empty() {
                bail!(
                    "{} is inconsistent, so it is not resumed from: {}. `strider-coordinator verify --db {}` says more; resume from a backup, or start again",
                    path.display(),
                    problems.join("; "),
                    path.display()
                );
            }
            let here = this_machine_identity();
            if computes_otherwise(&build, &here) {
                eprintln!("warning: {} was started by {build}; this is {here}: trials are bit-identical only within one build on one kind of node (the reference trial's digest tells kinds apart where the C library differs)", path.display());
            }
            eprintln!(
                "resuming experiment `{}` from {}",
                stored.name,
                path.display()
            );
            stored
        }
        None => {
            let e = match given {
                Some(e) => e,
                None if quick_by_default => Experiment::quick(),
                None => bail!(
                    "{} holds no experiment: pass --experiment FILE to start one",
                    path.display()
                ),
            };
            db.create_experiment(&e, &this_machine_identity()).await?;
            eprintln!("starting experiment `{}` in {}", e.name, path.display());
            e
        }
    };
    Ok((db, experiment))
}

/// Opens an existing database and its experiment, for reading.
pub(super) async fn open_existing(path: &Path) -> anyhow::Result<(Db, Experiment)> {
    if !path.exists() {
        bail!("no database at {}", path.display());
    }
    // Read-only: nothing written to the file or its backups (an older schema is migrated
    // under the writer's lock first).
    let db = Db::open_for_reading(path).await?;
    let (experiment, _) = db
        .experiment()
        .await?
        .context("the database holds no experiment")?;
    db.check_library_json().await?;
    Ok((db, experiment))
}

/// Every run of the database, or only `only` (which must exist).
pub(super) async fn selected_runs(db: &Db, only: Option<RunId>) -> anyhow::Result<Vec<RunRecord>> {
    let runs: Vec<_> = db
        .runs()
        .await?
        .into_iter()
        .filter(|r| only.is_none_or(|id| r.id == id))
        .collect();
    if let Some(id) = only {
        if runs.is_empty() {
            bail!("the database has no run {id}");
        }
    }
    Ok(runs)
}
