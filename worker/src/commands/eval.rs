//! `eval`: one genome simulated under a scheme, its outcome printed, and on request its
//! trace, drawing, replay and filmstrip written.

use super::context;
use crate::evaluate::evaluate;
use crate::replay::Replay;
use crate::trace::CsvTrace;
use crate::trial_outcome::evaluate_controller;
use anyhow::Context;
use std::path::PathBuf;
use strider_common::drawing::{design_svg, filmstrip_svg, replay_svg};
use strider_common::rng::CandidateSeed;
use strider_common::{BodyPlan, Controller, EvalContext, Genome, Outcome, Scheme, StartPose};
use strider_process::files::Outputs;
use strider_process::outln;

/// Arguments of `eval`.
#[derive(clap::Args)]
pub struct EvalArgs {
    /// Genome file (.json or .toml).
    genome: PathBuf,
    /// Controller scheme: static (midpoint gait), genome (the file's gait) or es (tuned).
    #[arg(long, default_value = "static")]
    scheme: Scheme,
    /// Run seed (ES draws its mutations from it).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Take settings, brief and features from this experiment file (paper defaults otherwise).
    #[arg(long)]
    experiment: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Write a CSV trace (body pose, joint angles, torques and targets per control step;
    /// each column name ends in its unit; the world is y-up, x forward, z to the right).
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Write a drawing of the design (side, front and top views of its start pose, to
    /// scale, with a 1 m bar) as SVG.
    #[arg(long)]
    svg: Option<PathBuf>,
    /// Write a replay of the trial: an animated side view (SVG; opens in a browser).
    #[arg(long)]
    replay: Option<PathBuf>,
    /// Write the trial as a still picture (SVG): side, front and top views every half
    /// second and at the end.
    #[arg(long)]
    filmstrip: Option<PathBuf>,
}

/// Simulates the genome and prints (and writes) what was asked.
pub fn execute(args: EvalArgs) -> anyhow::Result<()> {
    let EvalArgs {
        genome,
        scheme,
        seed,
        experiment,
        json,
        trace,
        svg,
        replay,
        filmstrip,
    } = args;
    // Pictures are SVG whatever their name: one named `.png` would not open as one.
    for (flag, path) in [
        ("--svg", &svg),
        ("--replay", &replay),
        ("--filmstrip", &filmstrip),
    ] {
        if let Some(path) = path {
            let is_svg = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
            anyhow::ensure!(
                is_svg,
                "{flag} writes SVG: name the file .svg ({} given)",
                path.display()
            );
        }
    }
    let g = Genome::load(&genome)?;
    let ctx = context(experiment.as_deref())?;
    let cand = CandidateSeed::new(seed, 0);
    let outcome = evaluate(&ctx, &g, scheme, cand);
    // The files asked for are written together at the end: all, or none.
    let mut outputs = Outputs::new();
    if let Some(path) = trace {
        // Replay the reported controller with a trace attached (the trial is
        // deterministic, so this is the same trial).
        outputs.add(path, trace_csv(&ctx, &g, outcome.controller())?);
    }
    let title = format!(
        "{} ({} scheme): {}",
        genome.file_name().unwrap_or_default().to_string_lossy(),
        scheme.name(),
        outcome_summary(&outcome)
    );
    if let Some(path) = svg {
        let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
        let pose = StartPose::new(&plan, outcome.controller());
        outputs.add(path, design_svg(&plan, &pose, &title));
    }
    if replay.is_some() || filmstrip.is_some() {
        let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
        let mut frames = Replay::default();
        evaluate_controller(&ctx, &g, &plan, outcome.controller(), &mut frames);
        if let Some(path) = replay {
            outputs.add(path, replay_svg(&plan, &frames.frames, &title));
        }
        if let Some(path) = filmstrip {
            let stills = frames.every(0.5);
            outputs.add(path, filmstrip_svg(&plan, &stills, &title));
        }
    }
    let written = outputs.paths();
    outputs.commit()?;
    if !written.is_empty() {
        let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
        eprintln!("wrote {}", names.join(", "));
    }
    if json {
        outln!(
            "{}",
            serde_json::to_string_pretty(&outcome).context("serialising the outcome")?
        );
    } else {
        print_outcome(&outcome, &ctx)?;
    }
    Ok(())
}

/// The trial's trace as CSV.
fn trace_csv(ctx: &EvalContext, g: &Genome, controller: &Controller) -> anyhow::Result<Vec<u8>> {
    let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
    let mut trace = CsvTrace::new(Vec::new(), &plan)?;
    evaluate_controller(ctx, g, &plan, controller, &mut trace);
    Ok(trace.into_inner()?)
}

/// One line about an outcome, for drawing titles.
fn outcome_summary(o: &Outcome) -> String {
    match (o.fitness(), o.stats()) {
        (Some(f), Some(s)) => format!("fitness {f:.3}, {:.1} kg, {:.2} m/s", s.mass, s.speed),
        (None, Some(s)) => format!("{}, {:.1} kg, {:.2} m/s", o.kind(), s.mass, s.speed),
        _ => o.kind().to_string(),
    }
}

fn print_outcome(o: &Outcome, ctx: &EvalContext) -> anyhow::Result<()> {
    outln!("outcome            {}", o.kind());
    if let Some(s) = o.stats() {
        outln!("distance           {:.3} m", s.distance);
        outln!("speed              {:.3} m/s", s.speed);
        outln!("energy             {:.1} J", s.energy);
        outln!("cost of transport  {:.4}", s.cost_of_transport);
        outln!("mass with payload  {:.2} kg", s.mass);
    }
    match o {
        Outcome::Valid {
            fitness,
            features,
            cell,
            ..
        } => {
            outln!("fitness            {fitness:.4}");
            outln!("features           {:?}", features.0);
            outln!("cell               {}", cell.0);
            outln!("checked            {}", checks_passed(ctx));
        }
        Outcome::Rejected { violations, .. } => {
            for v in violations {
                outln!("rejected           {v}");
            }
        }
        Outcome::Invalid {
            reason, at_time, ..
        } => {
            outln!("invalid            {reason} at t = {at_time:.3} s");
        }
    }
    let c = o.controller();
    outln!(
        "controller         {}",
        serde_json::to_string(c).expect("controller serialises")
    );
    Ok(())
}

/// What a feasible design passed besides its trial: the long window and the confirming
/// trials of the run's settings (docs/model.md section 6).
fn checks_passed(ctx: &EvalContext) -> String {
    let l = &ctx.limits;
    let mut said = vec![format!(
        "stayed up {} s after the trial",
        l.upright_after_feasible_seconds
            .max(l.upright_after_seconds)
    )];
    let mut again = Vec::new();
    if let Some([less, more]) = l.confirming_floors(ctx.settings.friction) {
        again.push(format!("on floors of friction {less} and {more}"));
    }
    if l.confirm_substeps_factor > 1 {
        again.push(format!(
            "at {} Hz (staying up {} s after it)",
            ctx.settings.control_hz
                * f64::from(ctx.settings.physics_substeps * l.confirm_substeps_factor),
            l.confirm_substeps_upright_seconds
                .max(l.upright_after_seconds)
        ));
    }
    if !again.is_empty() {
        said.push(format!(
            "met the brief as written again {}",
            again.join(" and ")
        ));
    }
    said.join("; ")
}
