//! The report's workbench: every design of the drawn run (its feasible library and its
//! infeasible one) as data embedded in the page, a file set per design (genome, URDF and
//! start pose, drawing, and for the best few an animated replay), and the section that
//! holds the table, the speed against cost of transport scatter and the design card. The
//! page's script (`workbench.js`) draws them from the data; the maps open the same cards.

use super::{Inputs, Page, RunData, SECTIONS};
use crate::results::export::urdf_robot_name;
use serde_json::{json, Value};
use std::collections::HashMap;
use std::fmt::Write;
use strider_common::drawing::design_svg;
use strider_common::features::{FEATURE_NAMES, FEATURE_UNITS};
use strider_common::motor_sizing::JointLoad;
use strider_common::{BodyPlan, CellIndex, Experiment, Genome, Outcome, StartPose};

/// Which library of the run a design is from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Library {
    /// Meets the brief.
    Feasible,
    /// Misses it (a near miss, kept by feasible-infeasible search).
    Infeasible,
}

/// A design as the report knows it beyond the library: its stored trial, and what a replay
/// of that trial measured (the report's command replays when it has the simulator).
#[derive(Clone, Debug, Default)]
pub struct DesignTrial {
    /// The outcome stored with the candidate.
    pub outcome: Option<Outcome>,
    /// Per joint load over the replayed trial.
    pub motors: Option<Vec<JointLoad>>,
    /// The replay as an animated side view (SVG), for the designs chosen for one.
    pub replay: Option<String>,
}

/// What the report has about the drawn run's designs, by library and cell.
#[derive(Clone, Debug, Default)]
pub struct DesignTrials {
    pub designs: HashMap<(Library, CellIndex), DesignTrial>,
    /// How many designs of each library got an animated replay (the fittest, the nearest).
    pub replays: usize,
    /// Why there are no replays or motor tables, when there are none.
    pub missing: Option<String>,
}

/// A file of a design, relative to the report's folder.
pub struct DesignFile {
    pub path: String,
    pub bytes: Vec<u8>,
}

/// The folder the design files go into.
pub const FOLDER: &str = "designs";

/// A design's file stem: `run0_cell123`, `run0_cell123_near_miss`.
pub fn stem(run: &RunData, library: Library, cell: CellIndex) -> String {
    match library {
        Library::Feasible => format!("run{}_cell{}", run.id, cell.0),
        Library::Infeasible => format!("run{}_cell{}_near_miss", run.id, cell.0),
    }
}

/// The workbench section, its data and the design files.
pub(super) fn workbench(out: &mut Page, inp: &Inputs<'_>, chosen: Option<&RunData>) {
    let _ = writeln!(out.html, "<h2>{}</h2>", SECTIONS[8]);
    let Some(run) = chosen else {
        out.html
            .push_str("<p>No run has started: there are no designs to browse.</p>\n");
        return;
    };
    let e = inp.experiment;
    let empty = DesignTrials::default();
    let trials = inp.trials.unwrap_or(&empty);
    let replay_note = match &trials.missing {
        Some(why) => why.clone(),
        None => format!(
            "The {n} fittest feasible designs and the {n} nearest near misses have an animated replay of their trial; for any other, its card gives the command that makes one (<code>strider-worker eval</code> on its genome file with <code>designs/experiment.toml</code>, the experiment as the database holds it).",
            n = trials.replays
        ),
    };
    let _ = writeln!(
        out.html,
        r#"<p>Every design of run {run} ({scheme}, repeat {repeat}): hover a cell of a map above for its figures, click it, a row of the table or a point of the scatter for its design card (drawings, replay, figures, motor sizing, genome and downloads). {replay_note}</p>
<div id="workbench">
<p class="library-toggle">Designs from: <label><input type="radio" name="library" value="feasible" checked> the feasible library ({feasible})</label> <label><input type="radio" name="library" value="infeasible"> the infeasible library: near misses ({infeasible})</label></p>
<p class="filters">Legs per side <select id="filter-legs"><option value="">any</option></select> · mass with payload at most <input id="filter-mass" type="number" step="1" size="5"> kg · <span id="shown"></span></p>
<div id="scatter"></div>
<div class="table-box"><table id="designs"><thead></thead><tbody></tbody></table></div>
</div>
<div id="tooltip" hidden></div>
<aside id="card" hidden></aside>"#,
        run = run.id,
        scheme = run.scheme.name(),
        repeat = run.repeat,
        feasible = run.library.len(),
        infeasible = run.infeasible.len(),
    );
    let mut designs = Vec::new();
    let feasible = run
        .library
        .elites()
        .map(|(c, el)| (Library::Feasible, c, &el.genome, Some(el.fitness), None));
    let infeasible = run.infeasible.elites().map(|(c, el)| {
        (
            Library::Infeasible,
            c,
            &el.genome,
            None,
            Some((el.shortfall, el.standing)),
        )
    });
    for (library, cell, genome, fitness, missed) in feasible.chain(infeasible) {
        let trial = trials.designs.get(&(library, cell));
        let files = design_files(e, run, library, cell, genome, trial);
        let outcome = trial.and_then(|t| t.outcome.as_ref());
        let misses =
            missed.map(|(shortfall, standing)| what_it_misses(e, shortfall, standing, outcome));
        designs.push(design_json(
            e, library, cell, genome, fitness, misses, trial, &files,
        ));
        out.files.extend(files);
    }
    let data = json!({
        "run": run.id.0,
        "payload": e.brief.payload,
        "min_speed": e.brief.min_speed,
        "brief": format!(
            "at most {} kg without the {} kg payload, at least {} m tall at the start pose, at least {} m/s over the trial (the search asks {:.3} m/s: a {} % margin for the physics step)",
            e.brief.max_mass, e.brief.payload, e.brief.min_height, e.brief.min_speed,
            e.brief.required_speed(e.trial.speed_margin), 100.0 * e.trial.speed_margin
        ),
        "whole": (0..FEATURE_NAMES.len()).map(|i| strider_common::features::whole_values(i).is_some()).collect::<Vec<_>>(),
        "stays_up_seconds": e.trial.upright_after_feasible_seconds,
        "feature_names": FEATURE_NAMES,
        "feature_units": FEATURE_UNITS,
        "designs": designs,
    });
    // "</" inside the data would end the script element early.
    let text = data.to_string().replace("</", "<\\/");
    let _ = writeln!(
        out.html,
        "<script type=\"application/json\" id=\"design-data\">{text}</script>"
    );
}

/// The files of one design: genome (as `export --elite --genome` writes it), URDF and start
/// pose (as `export --elite --urdf` writes them), drawing, and replay if made.
fn design_files(
    e: &Experiment,
    run: &RunData,
    library: Library,
    cell: CellIndex,
    genome: &Genome,
    trial: Option<&DesignTrial>,
) -> Vec<DesignFile> {
    let stem = stem(run, library, cell);
    let plan = BodyPlan::new(&genome.morphology, e.brief.payload);
    let pose = StartPose::new(&plan, &genome.controller);
    let urdf = std::path::PathBuf::from(format!("{FOLDER}/{stem}.urdf"));
    let [(urdf_path, urdf_text), (pose_path, pose_text)] = strider_common::urdf::files(
        &urdf_robot_name(&e.name, run.id, cell),
        &plan,
        &genome.controller,
        &urdf,
    );
    let title = format!("run {} cell {}", run.id, cell.0);
    let mut files = vec![
        DesignFile {
            path: format!("{FOLDER}/{stem}.genome.json"),
            bytes: (genome.to_json_pretty() + "\n").into_bytes(),
        },
        DesignFile {
            path: urdf_path.to_string_lossy().into_owned(),
            bytes: urdf_text.into_bytes(),
        },
        DesignFile {
            path: pose_path.to_string_lossy().into_owned(),
            bytes: pose_text.into_bytes(),
        },
        DesignFile {
            path: format!("{FOLDER}/{stem}.svg"),
            bytes: design_svg(&plan, &pose, &title).into_bytes(),
        },
    ];
    if let Some(svg) = trial.and_then(|t| t.replay.as_ref()) {
        files.push(DesignFile {
            path: format!("{FOLDER}/{stem}.replay.svg"),
            bytes: svg.clone().into_bytes(),
        });
    }
    files
}

/// One design's data for the page's script.
#[allow(clippy::too_many_arguments)]
fn design_json(
    e: &Experiment,
    library: Library,
    cell: CellIndex,
    genome: &Genome,
    fitness: Option<f64>,
    misses: Option<String>,
    trial: Option<&DesignTrial>,
    files: &[DesignFile],
) -> Value {
    let plan = BodyPlan::new(&genome.morphology, e.brief.payload);
    let pose = StartPose::new(&plan, &genome.controller);
    let outcome = trial.and_then(|t| t.outcome.as_ref());
    let stats = outcome.and_then(Outcome::stats).map(|s| {
        json!({
            "distance": s.distance, "speed": s.speed, "energy": s.energy,
            "cot": s.cost_of_transport, "duration": s.duration,
            "peak_torque_ratio": s.gait.peak_torque_ratio, "foot_slip": s.gait.foot_slip,
            "low_forward_share": s.gait.low_forward_share, "duty_factor": s.gait.duty_factor,
        })
    });
    // Motor figures to 0.001 (Nm, rad/s, W): the card shows one decimal; full precision
    // tripled the page.
    let motors = trial.and_then(|t| t.motors.as_ref()).map(|loads| {
        loads
            .iter()
            .map(|m| {
                json!({
                    "joint": m.joint, "peak_torque": milli(m.peak_torque),
                    "rms_torque": milli(m.rms_torque), "torque_limit": milli(m.torque_limit),
                    "peak_speed": milli(m.peak_speed), "speed_limit": milli(m.speed_limit),
                    "peak_power": milli(m.peak_power), "rms_power": milli(m.rms_power),
                })
            })
            .collect::<Vec<_>>()
    });
    // As stored for a feasible design; from the genome (the same function) for a near
    // miss, whose outcome holds none.
    let features = match outcome {
        Some(Outcome::Valid { features, .. }) => features.0,
        _ => strider_common::Features::of(&genome.morphology, &plan).0,
    };
    let file = |suffix: &str| {
        files
            .iter()
            .find(|f| f.path.ends_with(suffix))
            .map(|f| f.path.clone())
    };
    json!({
        "key": format!("{}{}", if library == Library::Feasible { "f" } else { "i" }, cell.0),
        "cell": cell.0,
        "feasible": library == Library::Feasible,
        "fitness": fitness,
        "misses": misses,
        "legs": plan.legs.len(),
        "legs_per_side": plan.legs_per_side(),
        "mass": plan.total_mass(),
        "mass_without_payload": plan.mass_without_payload(),
        "height": pose.height,
        "stats": stats,
        "features": features.to_vec(),
        "bins": e.features.bins_of_cell(cell).0.to_vec(),
        "motors": motors,
        "genome": genome,
        "files": {
            "genome": file(".genome.json"), "urdf": file(".urdf"),
            "pose": file(".start_pose.json"), "drawing": file(&format!("{}.svg", stem_tail(library, cell))),
            "replay": file(".replay.svg"),
        },
    })
}

/// What a near miss misses the brief by, in words: the speed it made against the speed
/// the search asks (the brief's with its margin), or why and when its trial ended.
fn what_it_misses(
    e: &Experiment,
    shortfall: strider_common::Shortfall,
    standing: strider_common::Standing,
    outcome: Option<&Outcome>,
) -> String {
    use strider_common::{Shortfall, Standing};
    match (shortfall, standing, outcome) {
        (Shortfall::Backward, Standing::TooSlow { speed }, _) => {
            format!("walked backward: {speed:.3} m/s")
        }
        (_, Standing::TooSlow { speed }, _) => format!(
            "too slow: {speed:.3} m/s against the {:.3} m/s the search asks (the brief's {} m/s and its {} % margin)",
            e.brief.required_speed(e.trial.speed_margin),
            e.brief.min_speed,
            100.0 * e.trial.speed_margin
        ),
        // The trial's own account says by how much (a fall's height against its limit).
        (_, _, Some(Outcome::Invalid { reason, at_time, .. })) => {
            format!("{reason} at t = {at_time:.2} s")
        }
        (_, Standing::EndedEarly { at_time }, _) => {
            format!("{} at t = {at_time:.2} s", shortfall.label())
        }
        _ => shortfall.label().to_string(),
    }
}

/// `v` rounded to 0.001.
fn milli(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

/// The end of a design's drawing file name (to tell it from its replay).
fn stem_tail(library: Library, cell: CellIndex) -> String {
    match library {
        Library::Feasible => format!("_cell{}", cell.0),
        Library::Infeasible => format!("_cell{}_near_miss", cell.0),
    }
}
