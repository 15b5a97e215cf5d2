//! Every elite of a real experiment, replayed from its exported genome: the trial gives
//! the stored outcome bit for bit, and every design that meets the brief stays upright
//! through the whole replay (tilt, height and ground contact read off the trace with the
//! model's own geometry, not the trial's checks).

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use std::path::Path;
use strider_common::body_plan::BodyPlan;
use strider_common::contact::{part_boxes, Part};
use strider_common::experiment::Experiment;
use strider_common::params::LINKS_PER_LEG;
use strider_common::{Genome, StartPose};
use strider_tests::{export, run_ok, temp_dir, workspace_root};

const EXPERIMENT: &str = "tests/fixtures/replay.toml";

/// A part other than a lower leg this far below the ground on a trace row counts as
/// touching it (the trace rounds to 0.01 mm; the trial sees a contact one step late).
const GROUND_TOLERANCE: f64 = 0.01;

/// Replays `genome` with its own controller; returns the outcome JSON and the trace.
fn replay(dir: &Path, name: &str, genome: &serde_json::Value) -> (serde_json::Value, String) {
    let g = dir.join(format!("{name}.json"));
    let trace = dir.join(format!("{name}.csv"));
    std::fs::write(&g, genome.to_string()).unwrap();
    let out = run_ok(
        "strider-worker",
        &[
            "eval",
            g.to_str().unwrap(),
            "--scheme",
            "genome",
            "--experiment",
            EXPERIMENT,
            "--json",
            "--trace",
            trace.to_str().unwrap(),
        ],
    );
    (
        serde_json::from_slice(&out.stdout).expect("eval --json writes an outcome"),
        std::fs::read_to_string(&trace).unwrap(),
    )
}

/// Panics unless every row of `trace` shows the robot of `genome` upright: tilt and body
/// height within the experiment's limits, no part but a lower leg on the ground.
fn assert_upright(e: &Experiment, genome: &Genome, trace: &str, what: &str) {
    let plan = BodyPlan::new(&genome.morphology, e.brief.payload);
    let start = StartPose::new(&plan, &genome.controller);
    let mut rows = trace.lines();
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let first_q = col("r0_q0_rad");
    let mut n = 0;
    for row in rows {
        let v: Vec<f64> = row.split(',').map(|x| x.parse().unwrap()).collect();
        let t = v[col("time_s")];
        let body = Isometry3::from_parts(
            Translation3::new(v[col("x_forward_m")], v[col("y_up_m")], v[col("z_right_m")]),
            UnitQuaternion::new_normalize(Quaternion::new(
                v[col("qw")],
                v[col("qx")],
                v[col("qy")],
                v[col("qz")],
            )),
        );
        let tilt = (body.rotation * nalgebra::Vector3::y())
            .y
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        assert!(
            tilt <= e.trial.max_tilt_degrees,
            "{what}: tilted {tilt:.1} degrees at {t} s"
        );
        let floor = e.trial.min_height_fraction * start.body_height;
        assert!(
            body.translation.y >= floor,
            "{what}: body at {:.3} m at {t} s",
            body.translation.y
        );
        let links: Vec<[Isometry3<f64>; LINKS_PER_LEG]> = plan
            .legs
            .iter()
            .enumerate()
            .map(|(i, leg)| {
                let q = &v[first_q + LINKS_PER_LEG * i..][..LINKS_PER_LEG];
                leg.link_poses([q[0], q[1], q[2]]).map(|p| body * p)
            })
            .collect();
        for (part, b) in part_boxes(&plan, &body, &links) {
            if part != Part::Body && part.may_touch_ground() {
                continue;
            }
            assert!(
                b.lowest_y() > -GROUND_TOLERANCE,
                "{what}: {} at {:.3} m at {t} s",
                part.name(&plan),
                b.lowest_y()
            );
        }
        n += 1;
    }
    // The trial and the second after it, at the control rate.
    let expected =
        ((e.run.trial_seconds + e.trial.upright_after_seconds) * e.run.control_hz).round() as usize;
    assert_eq!(n, expected, "{what}: the replay stopped early");
}

#[test]
fn every_elite_replays_to_its_stored_outcome_and_the_feasible_ones_stay_upright() {
    let dir = temp_dir("replay");
    let db = dir.join("replay.db");
    run_ok(
        "strider-coordinator",
        &["run", EXPERIMENT, "--db", db.to_str().unwrap()],
    );
    let e = Experiment::load(&workspace_root().join(EXPERIMENT)).unwrap();
    let library = export(&db);
    let (mut feasible, mut infeasible) = (0, 0);
    for run in library["runs"].as_array().unwrap() {
        let id = run["run"].as_i64().unwrap();
        for elite in run["elites"].as_array().unwrap() {
            let what = format!("run {id} cell {}", elite["cell"]);
            let (outcome, trace) =
                replay(&dir, &format!("f{id}-{}", elite["cell"]), &elite["genome"]);
            assert_eq!(outcome["outcome"], "valid", "{what}: {outcome}");
            assert_eq!(outcome["fitness"], elite["fitness"], "{what}");
            assert_eq!(outcome["stats"], elite["stats"], "{what}");
            let genome: Genome = serde_json::from_value(elite["genome"].clone()).unwrap();
            assert_upright(&e, &genome, &trace, &what);
            feasible += 1;
        }
        for elite in run["infeasible"].as_array().unwrap() {
            let what = format!("run {id} infeasible cell {}", elite["cell"]);
            let (outcome, _) = replay(&dir, &format!("i{id}-{}", elite["cell"]), &elite["genome"]);
            assert_ne!(outcome["outcome"], "valid", "{what}");
            match outcome["outcome"].as_str().unwrap() {
                // Ran to the end, too slowly: the same figures.
                "rejected" => assert_eq!(outcome["stats"], elite["stats"], "{what}"),
                // Ended early, or went backward: the same moment, the same reason.
                _ => {
                    assert_eq!(outcome["at_time"], elite["ended"]["at_time"], "{what}");
                    assert_eq!(outcome["reason"], elite["ended"]["reason"], "{what}");
                }
            }
            infeasible += 1;
        }
    }
    println!("replayed {feasible} feasible and {infeasible} infeasible elites");
    assert!(
        feasible > 0,
        "the experiment must hold designs that meet its brief"
    );
    assert!(infeasible > 0, "and designs that miss it");
    std::fs::remove_dir_all(&dir).unwrap();
}
