//! `fidelity`: the same designs at several physics steps (and stay-up windows, floors,
//! shoves): the steps each compared with the one before, the other settings with the run's:
//! does the verdict depend on the step?

use super::{context, emit};
use crate::fidelity::{Setting, Study};
use anyhow::Context;
use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};
use strider_common::experiment::{FRICTION_RANGE, PUSH_SPEED_RANGE};
use strider_common::precheck::check_before_trial;
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::{BodyPlan, Controller, Genome, Scheme, StartPose};
use strider_process::default_threads;

/// Arguments of `fidelity`.
#[derive(clap::Args)]
pub struct FidelityArgs {
    /// Designs from a file: `export --format json` output (every run's elites, and with
    /// `--infeasible` the infeasible library's too), one genome (`export --elite ...
    /// --genome` output, `designs/max.json`), a JSON array of genomes, or one genome per
    /// line.
    #[arg(long)]
    genomes: Option<PathBuf>,
    /// Take the infeasible elites of an export too.
    #[arg(long)]
    infeasible: bool,
    /// Random designs that pass mass, height and start pose (so are simulated), the first
    /// N that a run with `--seed` draws, besides or instead of `--genomes`.
    #[arg(long, default_value_t = 0)]
    random: u64,
    /// Run seed of the random designs.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Controller scheme: static (midpoint gait) or genome (each design's own gait).
    #[arg(long, default_value = "static")]
    scheme: Scheme,
    /// Physics steps per control step to compare, coarsest first.
    #[arg(long, value_delimiter = ',', default_value = "4,8,16")]
    substeps: Vec<u32>,
    /// Also evaluate at the first substeps with these stay-up windows after the trial, s.
    #[arg(long, value_delimiter = ',')]
    stay_up: Vec<f64>,
    /// Also evaluate at the first substeps with these friction coefficients between the
    /// robot and the ground (the run's is `[run] friction`, 0.8 by default): how much grip
    /// a design's walk depends on.
    #[arg(long, value_delimiter = ',')]
    friction: Vec<f64>,
    /// Also evaluate at the first substeps with a shove at the trial's end: the whole
    /// robot's sideways velocity changed by each of these, m/s, before the window it must
    /// stay up through (a design fast enough for the brief only: the others' verdicts do
    /// not change): whether its gait recovers.
    #[arg(long, value_delimiter = ',')]
    push: Vec<f64>,
    /// Threads (all cores by default).
    #[arg(long, value_parser = strider_process::at_least_one)]
    threads: Option<NonZeroUsize>,
    /// Take settings, brief and features from this experiment file (paper defaults
    /// otherwise). Every setting is judged with its `[trial] speed_margin` (0.05 by default),
    /// as a run's own trial is; a run's confirming trials (the floors, and the finer step where
    /// set) ask the brief as written: give a file with `speed_margin = 0` to see their verdict.
    #[arg(long)]
    experiment: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Also write one CSV row per design and setting.
    #[arg(long)]
    csv: Option<PathBuf>,
}

/// Genomes from an export, one genome, an array or JSON lines.
fn load_genomes(path: &Path, infeasible: bool) -> anyhow::Result<Vec<Genome>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let parse = |v: &serde_json::Value, what: &str| -> anyhow::Result<Genome> {
        serde_json::from_value(v.clone())
            .with_context(|| format!("{}: {what} is not a genome", path.display()))
    };
    let mut out = Vec::new();
    match serde_json::from_str::<serde_json::Value>(&text) {
        Ok(genome) if genome.get("morphology").is_some() => {
            out.push(parse(&genome, "the file")?);
        }
        Ok(serde_json::Value::Object(export)) => {
            let runs = export
                .get("runs")
                .and_then(|r| r.as_array())
                .with_context(|| {
                    format!(
                        "{}: neither an export (no \"runs\") nor a genome (no \"morphology\")",
                        path.display()
                    )
                })?;
            for (r, run) in runs.iter().enumerate() {
                let mut tables = vec!["elites"];
                if infeasible {
                    tables.push("infeasible");
                }
                for table in tables {
                    for (i, e) in run[table].as_array().into_iter().flatten().enumerate() {
                        out.push(parse(
                            &e["genome"],
                            &format!("runs[{r}].{table}[{i}].genome"),
                        )?);
                    }
                }
            }
        }
        Ok(serde_json::Value::Array(items)) => {
            for (i, v) in items.iter().enumerate() {
                out.push(parse(v, &format!("item {i}"))?);
            }
        }
        _ => {
            for (i, line) in text
                .lines()
                .enumerate()
                .filter(|(_, l)| !l.trim().is_empty())
            {
                let v: serde_json::Value = serde_json::from_str(line)
                    .with_context(|| format!("{} line {}", path.display(), i + 1))?;
                out.push(parse(&v, &format!("line {}", i + 1))?);
            }
        }
    }
    Ok(out)
}

/// Runs the study and prints (and writes) it.
pub fn execute(args: FidelityArgs) -> anyhow::Result<()> {
    let ctx = context(args.experiment.as_deref())?;
    let mut genomes = match &args.genomes {
        Some(path) => load_genomes(path, args.infeasible)?,
        None => Vec::new(),
    };
    let mut drawn = 0;
    for i in 0.. {
        if drawn == args.random {
            break;
        }
        let s = CandidateSeed::new(args.seed, i);
        let g = Genome::random(args.scheme, &mut s.rng(Purpose::RandomGenome));
        let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
        // ES starts from STATIC's controller.
        let controller = match args.scheme {
            Scheme::Genome => g.controller,
            Scheme::Static | Scheme::Es => Controller::static_default(),
        };
        let pose = StartPose::new(&plan, &controller);
        if check_before_trial(&ctx, &plan, &pose, &controller).is_none() {
            genomes.push(g);
            drawn += 1;
        }
    }
    anyhow::ensure!(
        !genomes.is_empty(),
        "no designs: give --genomes or --random"
    );
    anyhow::ensure!(!args.substeps.is_empty(), "--substeps names no setting");
    for &f in &args.friction {
        anyhow::ensure!(
            FRICTION_RANGE.contains(&f),
            "--friction {f}: a friction coefficient is from {} to {}",
            FRICTION_RANGE.start(),
            FRICTION_RANGE.end()
        );
    }
    for &p in &args.push {
        anyhow::ensure!(
            PUSH_SPEED_RANGE.contains(&p),
            "--push {p}: a shove is from {} to {} m/s",
            PUSH_SPEED_RANGE.start(),
            PUSH_SPEED_RANGE.end()
        );
    }
    let run_setting = Setting {
        physics_substeps: args.substeps[0],
        upright_after_seconds: ctx.limits.upright_after_seconds,
        upright_after_feasible_seconds: ctx.limits.upright_after_feasible_seconds,
        friction: ctx.settings.friction,
        push_speed: ctx.limits.push_speed,
    };
    let mut settings: Vec<Setting> = args
        .substeps
        .iter()
        .map(|&s| Setting {
            physics_substeps: s,
            ..run_setting
        })
        .collect();
    for &w in &args.stay_up {
        settings.push(Setting {
            upright_after_seconds: w,
            ..run_setting
        });
    }
    for &f in &args.friction {
        settings.push(Setting {
            friction: f,
            ..run_setting
        });
    }
    for &p in &args.push {
        settings.push(Setting {
            push_speed: p,
            ..run_setting
        });
    }
    let total = genomes.len() * settings.len();
    let last = std::sync::Mutex::new(std::time::Instant::now());
    let progress = |done: usize| {
        let Ok(mut last) = last.try_lock() else {
            return;
        };
        if last.elapsed() >= std::time::Duration::from_secs(10) {
            *last = std::time::Instant::now();
            eprintln!("fidelity: {done} of {total} trials");
        }
    };
    let threads = args.threads.unwrap_or_else(default_threads);
    let study = Study::run(&ctx, &genomes, args.scheme, &settings, threads, &progress);
    if let Some(path) = &args.csv {
        let file =
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let mut out = std::io::BufWriter::new(file);
        study
            .write_csv(&mut out)
            .and_then(|()| std::io::Write::flush(&mut out))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    emit(&study, args.json)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(name: &str, text: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("strider-fidelity-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn one_genome_file_is_one_design_and_other_objects_are_refused_by_what_they_lack() {
        let max = serde_json::to_string(&strider_common::reference::max()).unwrap();
        let one = load_genomes(&file("one.json", &max), false).unwrap();
        assert_eq!(one, vec![strider_common::reference::max()]);
        let array = load_genomes(&file("array.json", &format!("[{max},{max}]")), false).unwrap();
        assert_eq!(array.len(), 2);
        let err = load_genomes(&file("other.json", "{\"name\": 1}"), false)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("neither an export (no \"runs\") nor a genome (no \"morphology\")"),
            "{err}"
        );
    }
}
