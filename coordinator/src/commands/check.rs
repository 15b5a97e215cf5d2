//! `check`: an experiment file validated, its runs listed, and what it would cost on this
//! machine (measured with the `simulator` feature, else estimated).

use super::Exit;
use std::num::NonZeroUsize;
use std::path::PathBuf;
use strider_common::Experiment;
use strider_process::default_threads;
use strider_process::outln;

/// Arguments of `check`.
#[derive(clap::Args)]
pub struct CheckArgs {
    /// Experiment file (TOML).
    experiment: PathBuf,
    /// Skip the second of full-length trials that measures this machine's speed (the
    /// cost is then estimated from a figure measured on the development machine).
    #[arg(long)]
    no_calibration: bool,
}

/// A duration in hours, as a person reads it.
fn hours_text(h: f64) -> String {
    if h >= 1.0 {
        format!("{h:.1} h")
    } else {
        format!("{:.0} min", (h * 60.0).ceil())
    }
}

/// Prints what the experiment file defines and what it would cost here.
pub fn execute(args: CheckArgs) -> anyhow::Result<Exit> {
    let (path, calibrate) = (args.experiment.as_path(), !args.no_calibration);
    let e = Experiment::load(path)?;
    let runs = e.runs();
    outln!(
        "experiment `{}`: {} runs; each {} initial designs, then {} generations of {} ({} offspring)",
        e.name,
        runs.len(),
        e.run.initial_population,
        e.run.generations,
        e.run.offspring_per_generation,
        e.offspring_per_run()
    );
    outln!(
        "trial {} s at {} Hz control, physics step {:.5} s; brief: mass <= {} kg, height >= {} m, speed >= {} m/s (the trial asks {:.0} % more), payload {} kg",
        e.run.trial_seconds,
        e.run.control_hz,
        e.run.physics_dt(),
        e.brief.max_mass,
        e.brief.min_height,
        e.brief.min_speed,
        100.0 * e.trial.speed_margin,
        e.brief.payload
    );
    outln!(
        "search: {}{}; a trial ends when the robot falls: tilt > {} degrees, body centre below {} of its start height{}",
        e.search.constraints.name(),
        match e.search.constraints {
            strider_common::experiment::ConstraintHandling::FeasibleInfeasible => format!(
                " (feasible and infeasible libraries, {} of parents from the feasible one, infeasible parents by tournament of {})",
                e.search.feasible_parent_share, e.search.infeasible_tournament
            ),
            strider_common::experiment::ConstraintHandling::Reject => {
                " (designs that miss the brief are dropped; the initial population is drawn until that many pass)".into()
            }
        },
        e.trial.max_tilt_degrees,
        e.trial.min_height_fraction,
        if e.trial.only_feet_on_ground {
            ", or a part other than a lower leg on the ground"
        } else {
            ""
        }
    );
    let feasible_window = e
        .trial
        .upright_after_feasible_seconds
        .max(e.trial.upright_after_seconds);
    if feasible_window > 0.0 {
        let shove = if e.trial.push_speed > 0.0 {
            format!(
                ", shoved sideways by {} m/s at its start",
                e.trial.push_speed
            )
        } else {
            String::new()
        };
        outln!(
            "after the trial the robot must stay up {} s more ({} s when it is fast enough for the brief{shove}), its body within {} degrees of level",
            e.trial.upright_after_seconds,
            feasible_window,
            e.trial
                .max_tilt_degrees
                .min(e.trial.upright_after_max_tilt_degrees)
        );
    }
    // A design that meets the brief costs more than a trial: its long window, and its
    // confirming trials, the floors' with that window, the finer step's with its own
    // (`confirm_substeps_upright_seconds`). Said, with what it comes to, since no bound can
    // be put on how many designs meet the brief.
    // In the order they are tried (the worker's `Confirmation::all`).
    let factor = e.trial.confirm_substeps_factor;
    let floors = e.trial.confirming_floors(e.run.friction);
    let finer_window = e
        .trial
        .confirm_substeps_upright_seconds
        .max(e.trial.upright_after_seconds);
    let longer = feasible_window > e.trial.upright_after_seconds;
    let mut confirming = Vec::new();
    if let Some([less, more]) = floors {
        let window = if longer {
            ", each with that window"
        } else {
            ""
        };
        confirming.push(format!(
            "on floors of friction {more} and {less} (2 trials{window})"
        ));
    }
    if factor > 1 {
        let then = if confirming.is_empty() { "" } else { "then " };
        let window = if !longer {
            String::new()
        } else if finer_window == feasible_window {
            ", with that window".into()
        } else {
            format!(", with a {finer_window}-s window")
        };
        confirming.push(format!(
            "{then}at {factor}x the physics steps ({factor} trials' time{window})"
        ));
    }
    // In seconds at the run's step: a trial that misses the brief, one that meets it, and
    // one that meets it with its confirming trials.
    let plain_trial = e.run.trial_seconds + e.trial.upright_after_seconds;
    let meeting_trial = e.run.trial_seconds + feasible_window;
    let meeting_seconds = meeting_trial * if floors.is_some() { 3.0 } else { 1.0 }
        + if factor > 1 {
            f64::from(factor) * (e.run.trial_seconds + finer_window)
        } else {
            0.0
        };
    let meeting_cost = meeting_seconds / plain_trial;
    if meeting_cost > 1.0 {
        let walks = if longer {
            format!(" walks its {feasible_window}-s window")
        } else {
            String::new()
        };
        let again = if confirming.is_empty() {
            String::new()
        } else {
            format!(
                "{} is simulated again before it counts: {}",
                if longer { " and" } else { "" },
                confirming.join(", ")
            )
        };
        let who = if e.schemes.contains(&strider_common::Scheme::Es) {
            "such a trial (under ES, every child that meets the brief and beats its parent)"
        } else {
            "such a candidate"
        };
        outln!(
            "a design that meets the brief and is fitter than its cell's elite{walks}{again}: {meeting_seconds} s of simulation at the run's step against {plain_trial} s for one that misses the brief, up to {meeting_cost:.1} trials' time in all for {who}, not in the figures below (for scale, BENCHMARKS.md: in the full-size STATIC run at the paper's brief and the defaults, 1.6 % of the first 1000 generations' candidates met the brief and were fitter, and took 18 % of the simulation; late in it, 5.7 % and 49 %)"
        );
    }
    // What it costs: every trial (an ES candidate is many) at the cost of one that walks
    // to its end, measured now on this machine, or else from MAX's measured trial on the
    // development machine (`check` there, 2026-11-27: 118.6 to 120.2 ms of one core for
    // MAX's 6 s at 240 Hz, 0.083 ms a physics step).
    let per_run = e.run.candidates_per_run();
    // Trials per candidate: an ES candidate tunes its gait in es_iterations more.
    let trials_per_candidate = |scheme| match scheme {
        strider_common::Scheme::Es => u64::from(e.run.es_iterations) + 1,
        _ => 1,
    };
    // Each scheme: its runs and their trials (at most: an ES candidate refused before its
    // first trial runs none).
    let by_scheme: Vec<(strider_common::Scheme, u64, u64)> = e
        .schemes
        .iter()
        .map(|&scheme| {
            let n = runs.iter().filter(|r| r.scheme == scheme).count() as u64;
            (scheme, n, n * per_run * trials_per_candidate(scheme))
        })
        .collect();
    let trials: u64 = by_scheme.iter().map(|s| s.2).sum();
    outln!(
        "cost: {} candidates, {} trials{}{}; an initial random design refused before its trial (mass, height, start pose) is drawn again, stored but not counted here",
        per_run * runs.len() as u64,
        trials,
        if e.schemes.contains(&strider_common::Scheme::Es) {
            format!(
                " (an ES candidate is up to {} trials)",
                e.run.es_iterations + 1
            )
        } else {
            String::new()
        },
        match e.search.constraints {
            strider_common::experiment::ConstraintHandling::Reject =>
                ", plus the initial draws until enough meet the whole brief (unbounded)",
            _ => "",
        },
    );
    let cores = default_threads();
    let (thread_seconds, all_walked, source) = match calibrate.then(|| measure(&e, cores, trials)) {
        Some(Some(measured)) => measured,
        not_measured => {
            // MAX's physics step, s of one core on the development machine at 84f7368
            // (calibrations of 53.6 to 54.8 ms for its 1,440 steps, BENCHMARKS.md), the
            // figure the run-to-estimate ratios below were measured against.
            let per_trial = plain_trial / e.run.physics_dt() * 0.038e-3;
            let why = match not_measured {
                None => "--no-calibration",
                _ => "this build has no simulator",
            };
            (
                per_trial,
                trials as f64 * per_trial / cores.get() as f64,
                format!("from MAX's trial on the development machine; {why}"),
            )
        }
    };
    outln!(
        "time on this machine's {} cores: {} if every trial walks to its end and none meets the brief ({:.1} ms of one core a trial, {source}); an estimate, not a bound: many trials end sooner in a fall or are settled without one (about half of a STATIC run's first 1000 generations, few late in a run), and a design that meets the brief costs more (above); runs at the current trial and defaults in BENCHMARKS.md took 0.4x (the three-scheme comparison, where this figure counts each candidate of the evolution strategy as 21 whole trials), 1.1x (the full-size STATIC run) and 1.6x to 1.8x (the quick experiment, started from designs that meet it) of this figure",
        cores,
        hours_text(all_walked / 3600.0),
        thread_seconds * 1e3,
    );
    for (scheme, n, scheme_trials) in &by_scheme {
        outln!(
            "  {:<7} {n} run{} x {per_run} candidates x {} trial{} = {scheme_trials} trials, {} at that figure",
            scheme.name(),
            if *n == 1 { "" } else { "s" },
            trials_per_candidate(*scheme),
            if trials_per_candidate(*scheme) == 1 { "" } else { "s" },
            hours_text(*scheme_trials as f64 * thread_seconds / cores.get() as f64 / 3600.0)
        );
    }
    for r in runs {
        outln!(
            "  {:<7} repeat {:>3}  seed {}",
            r.scheme,
            r.repeat,
            r.seed.0
        );
    }
    Ok(Exit::Success)
}

/// A second of full-length MAX trials on every core: the thread-seconds a trial takes, the
/// whole experiment if every trial walks to its end, and where the figure comes from.
#[cfg(feature = "simulator")]
fn measure(e: &Experiment, cores: NonZeroUsize, trials: u64) -> Option<(f64, f64, String)> {
    let c = strider_worker::calibrate::calibrate(
        &e.run,
        &e.trial,
        &e.brief,
        cores,
        std::time::Duration::from_secs(1),
    );
    Some((
        c.thread_seconds_per_trial(),
        c.wall_seconds_for(trials),
        format!(
            "measured now: the fastest of {} trials of MAX to their end in {:.1} s, in CPU time, which load does not stretch",
            c.trials, c.wall_seconds
        ),
    ))
}

/// Without the simulator nothing can be measured.
#[cfg(not(feature = "simulator"))]
fn measure(_: &Experiment, _: NonZeroUsize, _: u64) -> Option<(f64, f64, String)> {
    None
}
