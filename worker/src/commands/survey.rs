//! `survey`: random genomes evaluated, and how often each constraint of the brief fails.

use super::{context, emit};
use crate::survey::Survey;
use anyhow::Context;
use std::num::NonZeroUsize;
use std::path::PathBuf;
use strider_common::Scheme;
use strider_process::default_threads;
use strider_process::terminal::Bar;

/// Arguments of `survey`.
#[derive(clap::Args)]
pub struct SurveyArgs {
    /// Genomes to draw.
    #[arg(long, default_value_t = 1000)]
    count: usize,
    /// Controller scheme.
    #[arg(long, default_value = "static")]
    scheme: Scheme,
    /// Run seed the genomes are drawn from.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Threads (all cores by default).
    #[arg(long, value_parser = strider_process::at_least_one)]
    threads: Option<NonZeroUsize>,
    /// Take settings, brief and features from this experiment file (paper defaults otherwise).
    #[arg(long)]
    experiment: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Also write one CSV row per design: its outcome, the figures computed without
    /// physics, and the cause found for a failure.
    #[arg(long)]
    csv: Option<PathBuf>,
}

/// Runs the survey with progress on stderr and prints (and writes) its counts.
pub fn execute(args: SurveyArgs) -> anyhow::Result<()> {
    let SurveyArgs {
        count,
        scheme,
        seed,
        threads,
        experiment,
        json,
        csv,
    } = args;
    let ctx = context(experiment.as_deref())?;
    let threads = threads.unwrap_or_else(default_threads);
    // A bar on a terminal, else a line on stderr every 5 s (or so), with the rate
    // and what is left: a large survey runs for minutes.
    let started = std::time::Instant::now();
    let last = std::sync::Mutex::new(started);
    let bar = Bar::start(count as u64, "designs");
    let progress = |done: usize| {
        if let Some(bar) = &bar {
            bar.set_position(done as u64);
            let rate = done as f64 / started.elapsed().as_secs_f64().max(1e-9);
            if done > 0 {
                bar.set_message(format!(
                    "{rate:.0}/s, about {} left",
                    strider_process::duration_words((count - done) as f64 / rate.max(1e-9))
                ));
            }
            return;
        }
        let Ok(mut last) = last.try_lock() else {
            return;
        };
        if last.elapsed() < std::time::Duration::from_secs(5) {
            return;
        }
        *last = std::time::Instant::now();
        let seconds = started.elapsed().as_secs_f64();
        let rate = done as f64 / seconds;
        eprintln!(
            "survey: {done} of {count} designs ({:.0} %), {rate:.0}/s, about {} left",
            100.0 * done as f64 / count as f64,
            strider_process::duration_words((count - done) as f64 / rate.max(1e-9))
        );
    };
    let survey = Survey::run(&ctx, scheme, seed, count, threads, &progress);
    drop(bar);
    if let Some(path) = csv {
        let file =
            std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        let mut out = std::io::BufWriter::new(file);
        survey
            .write_csv(&mut out)
            .and_then(|()| std::io::Write::flush(&mut out))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    emit(&survey, json)
}
