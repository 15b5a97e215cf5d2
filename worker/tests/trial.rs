//! The trial and the evaluation: physics sanity, determinism, schemes, the batch evaluator.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::num::NonZeroUsize;
use strider_common::experiment::TrialLimits;
use strider_common::params::{M, MOTOR_MAX_SPEED};
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::EvalContext;
use strider_common::{
    BodyPlan, Controller, Fall, Genome, InvalidReason, Outcome, Scheme, Standing, StartPose,
};
use strider_worker::batch::{evaluate_batch, Job};
use strider_worker::evaluate::{evaluate, evaluate_to_enter};
use strider_worker::sim::trial::{
    run_trial, run_trial_to_beat, run_trial_with, Bar, Observer, Sample, TrialEnd, GRAVITY,
};
use strider_worker::sim::world::RobotWorld;
use strider_worker::trial_outcome::{evaluate_controller, evaluate_controller_against};

fn max() -> Genome {
    strider_common::reference::max()
}

fn ctx() -> EvalContext {
    EvalContext::paper()
}

/// The paper's context without the friction margin's floors and the shove (on by default
/// since docs/model.md section 6's gated run), confirmed at twice the physics steps (the
/// default, said here so that a change of default keeps it): the trial as runs made
/// before the gate judged.
fn ungated() -> EvalContext {
    let mut c = ctx();
    (c.limits.friction_margin, c.limits.push_speed) = (0.0, 0.0);
    c.limits.confirm_substeps_factor = 2;
    c
}

/// A design from `tests/fixtures`.
fn fixture(name: &str) -> Genome {
    Genome::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures")
            .join(name),
    )
    .unwrap()
}

/// A hash of every bit of an outcome (JSON floats round-trip exactly).
fn outcome_hash(o: &Outcome) -> u64 {
    let mut h = DefaultHasher::new();
    serde_json::to_string(o).unwrap().hash(&mut h);
    h.finish()
}

/// Records every sample.
#[derive(Default)]
struct Recorder {
    time: Vec<f64>,
    energy: Vec<f64>,
    com: Vec<[f64; 3]>,
    body_y: Vec<f64>,
}

impl Observer for Recorder {
    fn control_step(&mut self, s: &Sample<'_>) {
        self.time.push(s.time);
        self.energy.push(s.energy);
        self.com.push([s.com.x, s.com.y, s.com.z]);
        self.body_y.push(s.body.translation.y);
    }
}

#[test]
fn simulated_mass_equals_the_model() {
    for seed in 0..5 {
        let g = Genome::random(
            Scheme::Static,
            &mut CandidateSeed::new(seed, 0).rng(Purpose::RandomGenome),
        );
        let plan = BodyPlan::new(&g.morphology, 10.0);
        let pose = StartPose::new(&plan, &g.controller);
        let world = RobotWorld::new(&plan, &pose, 1.0 / 30.0);
        let (sim, model) = (world.mass(), plan.total_mass());
        // rapier stores masses in f32.
        assert!(
            (sim - model).abs() < 1e-5 * model,
            "seed {seed}: simulated {sim} kg, model {model} kg"
        );
    }
}

#[test]
fn zero_amplitude_robot_stands_still_and_spends_almost_nothing() {
    let mut g = max();
    for p in MOTOR_MAX_SPEED {
        g.morphology.set_clamped(p, 0.0);
    }
    let plan = BodyPlan::new(&g.morphology, 10.0);
    let mut rec = Recorder::default();
    let end = run_trial(
        &plan,
        &Controller::static_default(),
        &ctx().settings,
        &ctx().limits,
        &mut rec,
    );
    let TrialEnd::Completed(stats) = end else {
        panic!("trial stopped: {end:?}")
    };
    println!(
        "standing MAX: drift {:.4} m, energy {:.2} J",
        stats.distance, stats.energy
    );
    // Settling on its springs under 64 kg: the body sinks a few centimetres, but does not
    // wander, and the springs do almost no work (walking costs about 2 kJ).
    assert!(stats.distance.abs() < 0.02, "drifted {} m", stats.distance);
    assert!(stats.energy < 30.0, "spent {} J standing", stats.energy);
    let sink = rec.body_y[0] - rec.body_y.last().unwrap();
    assert!(sink.abs() < 0.1, "body moved {sink} m vertically");
    // Every foot carries it on every step (counted by overlap alone, 0.9975: rapier holds a
    // pressed foot a hair above the ground on some steps).
    assert_eq!(stats.gait.duty_factor, 1.0, "{:?}", stats.gait);
}

#[test]
fn lifting_the_robot_costs_at_least_m_g_h() {
    // MAX crouched (upper and lower legs at 0.3 rad, shins vertical) settles for 0.5 s, then
    // every leg straightens to 0.8 rad over 3 s and holds: the body rises about 0.29 m and
    // ends at rest. The joints must have supplied at least the potential energy gained.
    let g = max();
    let plan = BodyPlan::new(&g.morphology, 10.0);
    let (low, high) = (0.3, 0.8);
    let lift = |t: f64| {
        let s = ((t - 0.5) / 3.0).clamp(0.0, 1.0);
        low + (high - low) * (1.0 - (s * std::f64::consts::PI).cos()) / 2.0
    };
    let start = StartPose::with_angles(&plan, vec![[0.5, low, low]; plan.legs.len()]);
    let mut rec = Recorder::default();
    let end = run_trial_with(
        &plan,
        &start,
        &ctx().settings,
        &ctx().limits,
        f64::INFINITY,
        |_, t| [0.5, lift(t), lift(t)],
        &mut rec,
    );
    assert!(matches!(end, TrialEnd::Completed(_)), "{end:?}");
    let settled = rec.time.iter().position(|&t| t >= 0.5).unwrap();
    let last = rec.com.len() - 1;
    let rise = rec.com[last][1] - rec.com[settled][1];
    let work = rec.energy[last] - rec.energy[settled];
    let m_g_h = plan.total_mass() * GRAVITY * rise;
    println!("rise {rise:.3} m: m g h = {m_g_h:.1} J, joint energy {work:.1} J");
    assert!(
        rise > 0.25,
        "the body should rise about 0.29 m, rose {rise} m"
    );
    assert!(work >= m_g_h, "joints spent {work} J to lift {m_g_h} J");
}

#[test]
fn colliding_legs_are_invalid_with_the_self_contact_reason() {
    // Six legs a side crammed on the shortest body, swinging hard: neighbours must meet.
    let mut g = max();
    for (p, v) in [
        (M::LegsPerSide, 6.0),
        (M::BodyHalfX, 0.4),
        (M::SpreadLinFwd, 0.7),
        (M::Motor0MaxSpeed, 1.5),
    ] {
        g.morphology.set_clamped(p, v);
    }
    let o = evaluate(&ctx(), &g, Scheme::Static, CandidateSeed::new(0, 0));
    match o {
        Outcome::Invalid {
            reason: InvalidReason::SelfContact { first, second },
            at_time,
            ..
        } => {
            println!("self-contact between {first} and {second} at {at_time} s");
            assert!(first.contains("leg") && second.contains("leg"));
        }
        other => panic!("expected a self-contact, got {other:?}"),
    }
}

#[test]
fn max_walks_forward_under_static_and_es() {
    let g = max();
    let stat = evaluate(&ctx(), &g, Scheme::Static, CandidateSeed::new(0, 0));
    let es = evaluate(&ctx(), &g, Scheme::Es, CandidateSeed::new(0, 0));
    for (name, o) in [("STATIC", &stat), ("ES", &es)] {
        let s = o
            .stats()
            .unwrap_or_else(|| panic!("{name}: no completed trial: {o:?}"));
        println!(
            "MAX {name}: {} distance {:.3} m, speed {:.3} m/s, energy {:.1} J, COT {:.4}",
            o.kind(),
            s.distance,
            s.speed,
            s.energy,
            s.cost_of_transport
        );
        assert!(s.distance > 2.0, "{name}: MAX walked only {} m", s.distance);
    }
    // ES starts from STATIC and keeps the best: never slower (the ranking below valid).
    assert!(es.stats().unwrap().speed >= stat.stats().unwrap().speed);
}

#[test]
fn a_trial_is_bit_identical_when_repeated_and_across_threads() {
    let genomes: Vec<Genome> = std::iter::once(max())
        .chain((0..5).map(|i| {
            Genome::random(
                Scheme::Genome,
                &mut CandidateSeed::new(9, i).rng(Purpose::RandomGenome),
            )
        }))
        .collect();
    let jobs: Vec<Job> = genomes
        .iter()
        .enumerate()
        .flat_map(|(i, g)| {
            [Scheme::Static, Scheme::Genome].map(|scheme| Job {
                genome: *g,
                scheme,
                seed: CandidateSeed::new(9, i as u64),
                to_beat: None,
            })
        })
        .collect();
    let sequential: Vec<u64> = jobs
        .iter()
        .map(|j| outcome_hash(&evaluate(&ctx(), &j.genome, j.scheme, j.seed)))
        .collect();
    let again: Vec<u64> = jobs
        .iter()
        .map(|j| outcome_hash(&evaluate(&ctx(), &j.genome, j.scheme, j.seed)))
        .collect();
    assert_eq!(sequential, again, "repeated trials differ");
    // The same jobs four times over on three threads at once, in a different order.
    let mut many: Vec<Job> = jobs
        .iter()
        .rev()
        .cycle()
        .take(4 * jobs.len())
        .copied()
        .collect();
    many.rotate_left(3);
    let parallel = evaluate_batch(&ctx(), &many, NonZeroUsize::new(3).unwrap());
    for (job, o) in many.iter().zip(&parallel) {
        let i = jobs.iter().position(|j| j == job).unwrap();
        assert_eq!(outcome_hash(o), sequential[i], "job {i} differs on threads");
    }
}

#[test]
fn es_is_reproducible_from_its_seed() {
    let g = max();
    let a = evaluate(&ctx(), &g, Scheme::Es, CandidateSeed::new(5, 7));
    let b = evaluate(&ctx(), &g, Scheme::Es, CandidateSeed::new(5, 7));
    assert_eq!(outcome_hash(&a), outcome_hash(&b));
    // The tuned controller differs from STATIC (20 iterations always find something on MAX).
    assert_ne!(a.controller(), &Controller::static_default());
}

#[test]
fn batch_returns_outcomes_in_job_order() {
    let jobs: Vec<Job> = (0..12)
        .map(|i| {
            let seed = CandidateSeed::new(3, i);
            Job {
                genome: Genome::random(Scheme::Static, &mut seed.rng(Purpose::RandomGenome)),
                scheme: Scheme::Static,
                seed,
                to_beat: None,
            }
        })
        .collect();
    let batch = evaluate_batch(&ctx(), &jobs, NonZeroUsize::new(2).unwrap());
    assert_eq!(batch.len(), jobs.len());
    for (j, o) in jobs.iter().zip(&batch) {
        assert_eq!(o, &evaluate(&ctx(), &j.genome, j.scheme, j.seed));
    }
}

#[test]
fn static_checks_reject_without_simulating() {
    // A short-legged design cannot stand 2 m tall: rejected for height, no trial figures.
    let mut g = max();
    g.morphology.set_clamped(M::Link1Length, 0.4);
    g.morphology.set_clamped(M::Link2Length, 0.4);
    let plan = BodyPlan::new(&g.morphology, 10.0);
    let o = evaluate_controller(&ctx(), &g, &plan, &Controller::static_default(), &mut ());
    match o {
        Outcome::Rejected {
            violations, stats, ..
        } => {
            assert!(stats.is_none());
            assert_eq!(violations.len(), 1);
            assert_eq!(
                violations[0].constraint,
                strider_common::brief::Constraint::Height
            );
        }
        other => panic!("expected a height rejection, got {other:?}"),
    }
}

/// MAX from its stance, every leg driven toward `q(leg, t)`: how the trial ends under
/// `limits`.
fn scripted(
    limits: TrialLimits,
    q: impl Fn(&strider_common::body_plan::LegPlan, f64) -> [f64; 3],
) -> TrialEnd {
    let g = max();
    let plan = BodyPlan::new(&g.morphology, 10.0);
    let start = StartPose::with_angles(&plan, vec![[0.5; 3]; plan.legs.len()]);
    run_trial_with(
        &plan,
        &start,
        &ctx().settings,
        &limits,
        f64::INFINITY,
        |leg, t| q(&plan.legs[leg], t),
        &mut (),
    )
}

/// A ramp from 0 at t = 0.3 s to 1 at t = 1.3 s.
fn ramp(t: f64) -> f64 {
    ((t - 0.3) / 1.0).clamp(0.0, 1.0)
}

#[test]
fn a_robot_that_tips_over_has_fallen() {
    // The right legs fold up while the left legs push down: the body rolls onto its right
    // side. Only the tilt limit is left on, so that it is the one that fires.
    let limits = TrialLimits {
        min_height_fraction: 0.0,
        only_feet_on_ground: false,
        ..TrialLimits::default()
    };
    let end = scripted(limits, |leg, t| {
        if leg.side == strider_common::body_plan::Side::Right {
            [0.5, 0.5 - 1.5 * ramp(t), 0.5 - 1.5 * ramp(t)]
        } else {
            [0.5, 0.5 + 0.8 * ramp(t), 0.5]
        }
    });
    match end {
        TrialEnd::Stopped {
            reason:
                InvalidReason::Fell {
                    fall: Fall::Tilted { degrees, limit },
                },
            at_time,
        } => {
            println!("tilted {degrees:.1} degrees at {at_time:.2} s");
            assert!(degrees > 45.0 && limit == 45.0);
            assert!(at_time > 0.3 && at_time < 5.0);
        }
        other => panic!("expected a tilt, got {other:?}"),
    }
}

/// The body's largest tilt from upright after `from` s, degrees.
struct TiltAfter {
    from: f64,
    max: f64,
}

impl Observer for TiltAfter {
    fn control_step(&mut self, s: &Sample<'_>) {
        if s.time > self.from {
            let up = s.body.rotation * strider_worker::sim::trial::up_axis();
            self.max = self.max.max(up.y.clamp(-1.0, 1.0).acos().to_degrees());
        }
    }
}

#[test]
fn a_robot_tipping_after_the_trial_has_fallen_under_the_stricter_limit() {
    // Upright through the trial; from 5 s the right legs fold slowly: the body leans
    // further than 20 degrees but not 45 by the end of the second after the trial.
    let tip = |leg: &strider_common::body_plan::LegPlan, t: f64| {
        let lean = 0.7 * (t - 5.0).clamp(0.0, 1.0);
        if leg.side == strider_common::body_plan::Side::Right {
            [0.5, 0.5 - 1.5 * lean, 0.5 - 1.5 * lean]
        } else {
            [0.5, 0.5 + 0.8 * lean, 0.5]
        }
    };
    let run = |limits: TrialLimits, observer: &mut TiltAfter| {
        let g = max();
        let plan = BodyPlan::new(&g.morphology, 10.0);
        let start = StartPose::with_angles(&plan, vec![[0.5; 3]; plan.legs.len()]);
        run_trial_with(
            &plan,
            &start,
            &ctx().settings,
            &limits,
            f64::INFINITY,
            |leg, t| tip(&plan.legs[leg], t),
            observer,
        )
    };
    let lenient = TrialLimits {
        upright_after_max_tilt_degrees: 180.0,
        ..TrialLimits::default()
    };
    let mut seen = TiltAfter {
        from: 5.0,
        max: 0.0,
    };
    let end = run(lenient, &mut seen);
    println!("largest tilt after the trial: {:.1} degrees", seen.max);
    assert!(matches!(end, TrialEnd::Completed(_)), "{end:?}");
    assert!(seen.max > 20.0 && seen.max < 45.0, "{}", seen.max);

    let mut seen = TiltAfter {
        from: 5.0,
        max: 0.0,
    };
    match run(TrialLimits::default(), &mut seen) {
        TrialEnd::Stopped {
            reason:
                InvalidReason::Fell {
                    fall: Fall::Tilted { degrees, limit },
                },
            at_time,
        } => {
            assert!(degrees > 20.0 && limit == 20.0, "{degrees} {limit}");
            assert!(at_time > 5.0 && at_time <= 6.0 + 1e-9, "{at_time}");
        }
        other => panic!("expected a tilt after the trial, got {other:?}"),
    }
}

#[test]
fn a_robot_that_sinks_onto_its_body_has_fallen() {
    // Every upper leg rises above horizontal: the body comes down on its legs' hips.
    let limits = TrialLimits {
        max_tilt_degrees: 180.0,
        only_feet_on_ground: false,
        ..TrialLimits::default()
    };
    let end = scripted(limits, |_, t| {
        [0.5, 0.5 - 1.2 * ramp(t), 0.5 - 1.2 * ramp(t)]
    });
    let start_height =
        StartPose::with_angles(&BodyPlan::new(&max().morphology, 10.0), vec![[0.5; 3]; 6])
            .body_height;
    match end {
        TrialEnd::Stopped {
            reason:
                InvalidReason::Fell {
                    fall: Fall::Sank { height, limit },
                },
            ..
        } => {
            println!("sank to {height:.3} m (limit {limit:.3} m)");
            assert!((limit - 0.5 * start_height).abs() < 1e-3, "{limit}");
            assert!(height < limit);
        }
        other => panic!("expected sinking, got {other:?}"),
    }
}

#[test]
fn a_robot_that_drags_its_knees_has_fallen() {
    // Every knee opens until the lower legs point outward and up: the knees (the upper
    // legs' tips) come down onto the ground. The height limit is off so that the ground
    // contact is what ends it.
    let limits = TrialLimits {
        min_height_fraction: 0.0,
        ..TrialLimits::default()
    };
    let end = scripted(limits, |_, t| [0.5, 0.5, 0.5 + 2.0 * ramp(t)]);
    match end {
        TrialEnd::Stopped {
            reason:
                InvalidReason::Fell {
                    fall: Fall::Dragged { part },
                },
            at_time,
        } => {
            println!("{part} touched the ground at {at_time:.2} s");
            assert!(
                part.ends_with("link 1") || part.ends_with("link 0"),
                "{part}"
            );
        }
        other => panic!("expected a knee on the ground, got {other:?}"),
    }
}

#[test]
fn the_default_limits_end_a_collapse_and_leave_a_standing_robot_alone() {
    let end = scripted(TrialLimits::default(), |_, t| {
        [0.5, 0.5 - 1.2 * ramp(t), 0.5 - 1.2 * ramp(t)]
    });
    assert!(
        matches!(
            end,
            TrialEnd::Stopped {
                reason: InvalidReason::Fell { .. },
                ..
            }
        ),
        "{end:?}"
    );
    let end = scripted(TrialLimits::default(), |_, _| [0.5; 3]);
    assert!(matches!(end, TrialEnd::Completed(_)), "{end:?}");
}

#[test]
fn parts_touching_in_the_start_pose_are_rejected_before_simulating() {
    // Hips swung 1.5 rad forward: each leg lies along the body into the leg in front.
    let mut g = max();
    g.controller
        .set_clamped(strider_common::params::C::VerticalOffset0, 2.0);
    let o = evaluate(&ctx(), &g, Scheme::Genome, CandidateSeed::new(0, 0));
    match &o {
        Outcome::Invalid {
            reason: InvalidReason::StartPoseContact { first, second },
            at_time,
            ..
        } => {
            println!("{first} and {second} touch in the start pose");
            assert_eq!(*at_time, 0.0);
            assert!(first.contains("leg") || second.contains("leg"));
        }
        other => panic!("expected a start-pose contact, got {other:?}"),
    }
    // The coordinator's check before leasing says the same, without a trial.
    assert_eq!(
        strider_common::precheck::precheck(&ctx(), &g, Scheme::Genome),
        Some(o)
    );
    // MAX itself starts clear.
    assert_eq!(
        strider_common::precheck::precheck(&ctx(), &max(), Scheme::Static),
        None
    );
}

/// MAX's STATIC trial with `settings` and `limits` changed by `tune`.
fn max_static(
    tune: impl Fn(&mut strider_common::experiment::RunSettings, &mut TrialLimits),
    plan_tune: impl Fn(&mut BodyPlan),
) -> TrialEnd {
    let c = ctx();
    let (mut settings, mut limits) = (c.settings, c.limits);
    tune(&mut settings, &mut limits);
    let mut plan = BodyPlan::new(&max().morphology, c.brief.payload);
    plan_tune(&mut plan);
    run_trial(
        &plan,
        &Controller::static_default(),
        &settings,
        &limits,
        &mut (),
    )
}

/// MAX's STATIC trial from its start pose under `limits`, recorded: held to the long window
/// when its speed reaches `feasible_speed`, and ended at the trial's end when it is no
/// fitter than `to_beat` ([`run_trial_to_beat`]).
fn max_trial(
    limits: &TrialLimits,
    feasible_speed: f64,
    to_beat: Option<f64>,
) -> (TrialEnd, Recorder) {
    design_trial(&max(), limits, feasible_speed, to_beat)
}

/// `design`'s trial under the STATIC gait, held to the long window (and the shove) when it
/// walks at least `feasible_speed`, ended early when it cannot beat `to_beat`.
fn design_trial(
    design: &Genome,
    limits: &TrialLimits,
    feasible_speed: f64,
    to_beat: Option<f64>,
) -> (TrialEnd, Recorder) {
    let bar = Bar {
        fitness: to_beat,
        standing: None,
    };
    design_trial_against(design, limits, feasible_speed, bar)
}

/// [`design_trial`] against any bar.
fn design_trial_against(
    design: &Genome,
    limits: &TrialLimits,
    feasible_speed: f64,
    to_beat: Bar,
) -> (TrialEnd, Recorder) {
    let c = ctx();
    let plan = BodyPlan::new(&design.morphology, c.brief.payload);
    let controller = Controller::static_default();
    let start = StartPose::new(&plan, &controller);
    let mut rec = Recorder::default();
    let end = run_trial_to_beat(
        &plan,
        &start,
        &controller,
        &c.settings,
        limits,
        feasible_speed,
        to_beat,
        &mut rec,
    );
    (end, rec)
}

#[test]
fn no_joint_receives_more_than_its_motor_limit_on_any_step() {
    // MAX at full strength and with weaker motors: the weak ones spend much of the stride
    // at their limit (the peak reaches it), and on no physics step may any joint receive
    // more (a foot strike would push a joint driven by its law past the limit; that step is
    // taken again with the joint held at it). The peak is measured over completed trials.
    let mut completed = 0;
    let mut reached = false;
    for strength in [1.0, 0.8, 0.6, 0.45] {
        for substeps in [4, 8] {
            let end = max_static(
                |s, _| s.physics_substeps = substeps,
                |plan| {
                    for leg in &mut plan.legs {
                        for link in &mut leg.links {
                            link.drive.max_torque *= strength;
                        }
                    }
                },
            );
            let TrialEnd::Completed(stats) = end else {
                println!("{strength} x torque, {substeps} substeps: not completed: {end:?}");
                continue;
            };
            completed += 1;
            let peak = stats.gait.peak_torque_ratio;
            println!("{strength} x torque, {substeps} substeps: peak {peak:.6} of the limit");
            assert!(
                peak <= 1.0 + strider_worker::sim::drive::LIMIT_ROUNDING,
                "{strength} x torque, {substeps} substeps: a joint received {peak} x its limit"
            );
            reached |= strength < 1.0 && peak > 0.999;
        }
    }
    assert!(completed >= 4, "only {completed} trials completed");
    assert!(reached, "no weakened MAX reached its torque limit");
}

#[test]
fn the_drive_is_the_same_at_every_step_so_the_walk_converges() {
    // The servo's damping no longer comes from the integrator: halving the step moves
    // MAX's distance and energy by a few per cent (with rapier's spring damping, k dt,
    // the energy grew by 48 % from 30 to 240 Hz).
    let figures = |substeps| {
        let TrialEnd::Completed(s) = max_static(|s, _| s.physics_substeps = substeps, |_| {})
        else {
            panic!("MAX fell at {substeps} substeps")
        };
        (s.distance, s.energy)
    };
    let (d8, e8) = figures(8);
    let (d16, e16) = figures(16);
    println!("8 substeps: {d8:.3} m, {e8:.1} J; 16: {d16:.3} m, {e16:.1} J");
    assert!((d8 - d16).abs() < 0.05 * d16, "distance {d8} vs {d16}");
    assert!((e8 - e16).abs() < 0.05 * e16, "energy {e8} vs {e16}");
}

#[test]
fn feet_that_skate_past_the_limits_are_invalid_with_the_skating_reason() {
    // MAX lifts its feet: its figures are those of a walker, inside the defaults.
    let TrialEnd::Completed(s) = max_static(|_, _| {}, |_| {}) else {
        panic!("MAX fell")
    };
    let g = s.gait;
    println!("MAX: {g:?}");
    assert!(g.duty_factor > 0.2 && g.duty_factor < 0.8, "{g:?}");
    assert!(
        g.foot_slip > 0.0 && g.foot_slip < 0.25 * s.distance,
        "{g:?}"
    );
    assert!(
        g.low_forward_share > 0.0 && g.low_forward_share < 0.25,
        "{g:?}"
    );
    // Limits below its figures make the same walk a skater, saying how.
    let shuffled = max_static(
        |_, l| l.max_low_forward_share = 0.5 * g.low_forward_share,
        |_| {},
    );
    match shuffled {
        TrialEnd::Stopped {
            reason:
                InvalidReason::Skating {
                    skate: strider_common::Skate::Shuffled { share, limit },
                },
            at_time,
        } => {
            assert_eq!(share, g.low_forward_share);
            assert_eq!(limit, 0.5 * g.low_forward_share);
            assert_eq!(at_time, s.duration);
        }
        other => panic!("{other:?}"),
    }
    let slid = max_static(|_, l| l.max_foot_slip_ratio = 0.01, |_| {});
    assert!(
        matches!(
            slid,
            TrialEnd::Stopped {
                reason: InvalidReason::Skating {
                    skate: strider_common::Skate::Slid { .. }
                },
                ..
            }
        ),
        "{slid:?}"
    );
}

#[test]
fn a_foot_pressed_on_the_ground_is_on_it_though_rapier_holds_it_a_hair_above() {
    // An elite of the 1000-generation STATIC run whose feet shuffle, on the 0.6 floor that
    // refused it for skating. Rapier's predictive contacts hold a pressed foot up to half a
    // millimetre above the ground; counted by overlap alone its feet were down 24 % of the
    // trial and slid 0.37 m, where PyBullet has them down 59 % of it, sliding 1.75 m.
    // Counted by the push they get: down 62 %, 1.96 m slid.
    let c = ctx();
    let g = fixture("shuffling_feet.json");
    let plan = BodyPlan::new(&g.morphology, c.brief.payload);
    let mut settings = c.settings;
    settings.friction = 0.6;
    let mut limits = c.limits;
    limits.max_low_forward_share = 1.0;
    limits.max_foot_slip_ratio = f64::INFINITY;
    let end = run_trial(
        &plan,
        &Controller::static_default(),
        &settings,
        &limits,
        &mut (),
    );
    let TrialEnd::Completed(s) = end else {
        panic!("it walks: {end:?}")
    };
    println!("shuffler: {:?}, {} m", s.gait, s.distance);
    assert!(s.gait.duty_factor > 0.5, "{:?}", s.gait);
    assert!(s.gait.foot_slip > 1.5, "{:?}", s.gait);
}

#[test]
fn two_legs_pressed_together_touch_though_rapier_holds_them_a_hair_apart() {
    // An elite of a search late in a 1000-generation STATIC run whose left front and back
    // lower legs press together half a second into the trial. Rapier's predictive contacts
    // keep them a hair apart: by overlap alone it walked on and was feasible. PyBullet,
    // colliding the robot with itself, has the same two legs touch within 0.03 s of the
    // time here. Counted by the push between them, it is a self-contact.
    let c = ctx();
    let g = fixture("legs_pressed_together.json");
    let plan = BodyPlan::new(&g.morphology, c.brief.payload);
    let end = run_trial(
        &plan,
        &Controller::static_default(),
        &c.settings,
        &c.limits,
        &mut (),
    );
    match end {
        TrialEnd::Stopped {
            reason: InvalidReason::SelfContact { first, second },
            at_time,
        } => {
            assert_eq!(
                (first.as_str(), second.as_str()),
                ("left leg 0 link 2", "left leg 1 link 2")
            );
            assert!(at_time < 1.0, "{at_time}");
        }
        other => panic!("expected its lower legs to touch, got {other:?}"),
    }
}

#[test]
fn a_design_must_beat_the_brief_speed_by_the_margin() {
    // The finer step's confirmation alone: the floors and the shove (on by default) are
    // other tests'.
    // MAX's own speed under STATIC; a brief asking a little less than it.
    let base = evaluate(&ungated(), &max(), Scheme::Static, CandidateSeed::new(0, 0));
    let speed = base.stats().expect("MAX completes its trial").speed;
    let mut c = ungated();
    // The margin alone (at 480 Hz MAX walks 2.5 % slower, which the confirmation would see).
    c.limits.confirm_substeps_factor = 1;
    c.brief.min_speed = speed / 1.02;
    // Inside a 5 % margin: refused for speed, the limit being the speed asked for.
    c.limits.speed_margin = 0.05;
    match evaluate(&c, &max(), Scheme::Static, CandidateSeed::new(0, 0)) {
        Outcome::Rejected { violations, .. } => {
            assert_eq!(violations.len(), 1);
            assert_eq!(violations[0].value, speed);
            assert_eq!(violations[0].limit, c.brief.min_speed * 1.05);
        }
        other => panic!("expected a speed rejection, got {other:?}"),
    }
    // Without the margin the same walk meets the same brief.
    c.limits.speed_margin = 0.0;
    let o = evaluate(&c, &max(), Scheme::Static, CandidateSeed::new(0, 0));
    assert!(matches!(o, Outcome::Valid { .. }), "{o:?}");
}

#[test]
fn a_robot_fast_enough_for_the_brief_must_stay_up_the_longer_window() {
    // Upright through the trial and the second after it; from 8 s the right legs fold
    // and the body rolls over.
    let tip = |leg: &strider_common::body_plan::LegPlan, t: f64| {
        let lean = 1.0 * (t - 8.0).clamp(0.0, 1.0);
        if leg.side == strider_common::body_plan::Side::Right {
            [0.5, 0.5 - 1.5 * lean, 0.5 - 1.5 * lean]
        } else {
            [0.5, 0.5 + 0.8 * lean, 0.5]
        }
    };
    let run = |feasible_speed: f64| {
        let g = max();
        let plan = BodyPlan::new(&g.morphology, 10.0);
        let start = StartPose::with_angles(&plan, vec![[0.5; 3]; plan.legs.len()]);
        run_trial_with(
            &plan,
            &start,
            &ctx().settings,
            &TrialLimits::default(),
            feasible_speed,
            |leg, t| tip(&plan.legs[leg], t),
            &mut (),
        )
    };
    // Too slow for the brief: the 1-s window, which ends before the fall.
    let slow = run(f64::INFINITY);
    assert!(matches!(slow, TrialEnd::Completed(_)), "{slow:?}");
    // Fast enough (any speed is, here): the 15-s window sees the fall, and says when.
    match run(f64::NEG_INFINITY) {
        TrialEnd::Stopped {
            reason: InvalidReason::Fell { .. },
            at_time,
        } => assert!(at_time > 8.0 && at_time <= 20.0 + 1e-9, "{at_time}"),
        other => panic!("expected a fall in the longer window, got {other:?}"),
    }
}

#[test]
fn a_design_feasible_only_at_the_runs_step_is_step_sensitive() {
    // The finer step's confirmation alone: the floors and the shove (on by default) are
    // other tests'.
    // An elite of a 1000-generation STATIC run made without the confirmation: it walks the
    // trial and the 15 s after it at 240 Hz, and tips over at 480 Hz.
    let g = fixture("step_sensitive.json");
    let mut unconfirmed = ungated();
    unconfirmed.limits.confirm_substeps_factor = 1;
    let at_run_step = evaluate(&unconfirmed, &g, Scheme::Static, CandidateSeed::new(0, 0));
    assert!(
        matches!(at_run_step, Outcome::Valid { .. }),
        "{at_run_step:?}"
    );
    match evaluate(&ungated(), &g, Scheme::Static, CandidateSeed::new(0, 0)) {
        Outcome::Invalid {
            reason: InvalidReason::StepSensitive { substeps, verdict },
            at_time,
            ..
        } => {
            assert_eq!(substeps, 2 * ungated().settings.physics_substeps);
            assert!(verdict.starts_with("fell"), "{verdict}");
            assert!(at_time > 0.0 && at_time < 20.0, "{at_time}");
        }
        other => panic!("expected step_sensitive, got {other:?}"),
    }
    // A design of the same run that holds at the finer step keeps the run's step's
    // figures, bit for bit.
    let g = fixture("walks_at_both_steps.json");
    let confirmed = evaluate(&ungated(), &g, Scheme::Static, CandidateSeed::new(0, 0));
    assert!(matches!(confirmed, Outcome::Valid { .. }), "{confirmed:?}");
    let plain = evaluate(&unconfirmed, &g, Scheme::Static, CandidateSeed::new(0, 0));
    assert_eq!(outcome_hash(&confirmed), outcome_hash(&plain));
}

#[test]
fn an_es_child_that_cannot_beat_its_parent_is_not_confirmed() {
    // The finer step's confirmation alone: the floors and the shove (on by default) are
    // other tests'.
    // Feasible at the run's step, step-sensitive at the finer one. Against a parent it
    // does not beat, the confirmation could only lower it: skipped. Against one it beats,
    // it is confirmed, and found step-sensitive.
    let g = fixture("step_sensitive.json");
    let plan = BodyPlan::new(&g.morphology, ungated().brief.payload);
    let controller = Controller::static_default();
    let mut unconfirmed = ungated();
    unconfirmed.limits.confirm_substeps_factor = 1;
    let fitness = match evaluate_controller(&unconfirmed, &g, &plan, &controller, &mut ()) {
        Outcome::Valid { fitness, .. } => fitness,
        other => panic!("expected feasible at the run's step, got {other:?}"),
    };
    let against = |to_beat: Standing| {
        evaluate_controller_against(&ungated(), &g, &plan, &controller, &to_beat)
    };
    assert!(against(Standing::Feasible { fitness }).is_none());
    match against(Standing::EndedEarly { at_time: 0.0 }) {
        Some(Outcome::Invalid {
            reason: InvalidReason::StepSensitive { .. },
            ..
        }) => {}
        other => panic!("expected a confirmed step_sensitive, got {other:?}"),
    }
}

#[test]
fn the_es_with_its_shortcuts_ends_where_judging_every_child_in_full_does() {
    // MAX is too slow for the brief, so its strategy climbs by speed: a child slower than
    // its parent ends with its trial (its window not run), one no fitter than a feasible
    // parent too, and none that does not beat its parent is confirmed. The strategy's
    // result is that of judging every child in full, bit for bit, and at least one child
    // took the slow shortcut.
    let mut c = ctx();
    c.settings.es_iterations = 8;
    let g = max();
    let plan = BodyPlan::new(&g.morphology, c.brief.payload);
    let seed = CandidateSeed::new(0, 0);
    let mut rng = seed.rng(Purpose::EvolutionStrategy);
    let mut best = evaluate_controller(&c, &g, &plan, &Controller::static_default(), &mut ());
    let mut slower = 0;
    for _ in 0..c.settings.es_iterations {
        let mut child = *best.controller();
        child.mutate_all(&mut rng);
        let outcome = evaluate_controller(&c, &g, &plan, &child, &mut ());
        let beats = outcome.standing().beats(&best.standing());
        slower += usize::from(matches!(outcome.standing(), Standing::TooSlow { .. }) && !beats);
        if beats {
            best = outcome;
        }
    }
    let tuned = strider_worker::es::tune_controller(&c, &g, &plan, seed);
    assert_eq!(outcome_hash(&tuned), outcome_hash(&best), "{tuned:?}");
    assert!(slower > 0, "no child took the slow shortcut");
}

#[test]
fn motor_sizing_sees_the_trials_own_torques_and_work() {
    // The report's motor sizing replays a design's trial: its peak torques are the trial's
    // (the largest peak over limit is the outcome's peak torque ratio), no joint passes its
    // limit (to the f32 rounding the drive allows), and RMS figures stay under the peaks.
    let ctx = ctx();
    let g = max();
    let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
    let outcome = evaluate_controller(&ctx, &g, &plan, &g.controller, &mut ());
    let stats = outcome.stats().expect("MAX completes its trial");
    let m = strider_worker::replay::measure(&ctx, &g, Some(0.5));
    assert_eq!(m.motors.len(), plan.legs.len() * 3);
    let ratio = m
        .motors
        .iter()
        .map(|l| l.peak_torque / l.torque_limit)
        .fold(0.0, f64::max);
    assert_eq!(ratio, stats.gait.peak_torque_ratio);
    for l in &m.motors {
        let rounding = strider_worker::sim::drive::LIMIT_ROUNDING;
        assert!(l.peak_torque <= l.torque_limit * (1.0 + rounding), "{l:?}");
        assert!(
            l.rms_torque <= l.peak_torque && l.rms_power <= l.peak_power,
            "{l:?}"
        );
        assert!(l.peak_power > 0.0, "{l:?}");
    }
    // Frames every half second over the trial and the window after it.
    let frames = m.frames.expect("frames were asked for");
    assert!(
        frames.len() >= (stats.duration / 0.5) as usize,
        "{}",
        frames.len()
    );
}

#[test]
fn a_shove_at_the_trials_end_moves_the_robot_sideways_and_leaves_the_trials_figures() {
    // MAX, taken as fast enough for the brief (so held to the 15-s window), shoved to its
    // right at the trial's end: just after it, its centre of mass moves right at about the
    // shove's speed faster than without it (the gait sways it either way); distance and
    // energy (over the trial) are the unshoved ones. Too slow for the brief, it is not
    // shoved at all.
    let c = ctx();
    let run = |push: f64, feasible_speed: f64| {
        let mut limits = c.limits;
        limits.push_speed = push;
        max_trial(&limits, feasible_speed, None)
    };
    let trial = |push: f64| run(push, 0.0);
    let (slow, slow_rec) = run(0.5, f64::INFINITY);
    let (slow_calm, slow_calm_rec) = run(0.0, f64::INFINITY);
    assert_eq!(slow, slow_calm);
    assert_eq!(
        slow_rec.com, slow_calm_rec.com,
        "a slow design is not shoved"
    );
    let (calm, calm_rec) = trial(0.0);
    let (shoved, shoved_rec) = trial(0.5);
    let (TrialEnd::Completed(a), TrialEnd::Completed(b)) = (&calm, &shoved) else {
        panic!("MAX completes both: {calm:?} {shoved:?}");
    };
    assert_eq!(a, b, "the trial's figures do not see a shove after it");
    let end = (c.settings.trial_seconds * c.settings.control_hz).round() as usize;
    // Sideways speed over the control step after the shove (sample `end` is the first one
    // after the trial's end, when it is given).
    let speed =
        |r: &Recorder| (r.com[end][2] - r.com[end - 1][2]) / (r.time[end] - r.time[end - 1]);
    let (before, after) = (speed(&calm_rec), speed(&shoved_rec));
    println!("sideways {before} m/s calm, {after} m/s shoved");
    assert!(
        (after - before - 0.5).abs() < 0.15,
        "sideways speed {before} m/s calm, {after} m/s shoved by 0.5 m/s"
    );
}

#[test]
fn a_design_feasible_on_one_floor_only_is_friction_sensitive() {
    // The fittest elite of a 1000-generation STATIC run made without the friction margin:
    // it meets the brief at friction 0.8 (and at the finer step); at 1.0 its feet shuffle
    // (judged at the trial's end; it then tips over in the window after, where that was
    // its verdict before skating was judged first).
    // With a margin of 0.25 it is invalid, naming that floor; a design of the same run that
    // walks on both floors keeps its figures, bit for bit.
    let mut margin = ungated();
    margin.limits.friction_margin = 0.25;
    let g = fixture("friction_sensitive.json");
    let plain = evaluate(&ungated(), &g, Scheme::Static, CandidateSeed::new(0, 0));
    assert!(matches!(plain, Outcome::Valid { .. }), "{plain:?}");
    match evaluate(&margin, &g, Scheme::Static, CandidateSeed::new(0, 0)) {
        Outcome::Invalid {
            reason: InvalidReason::FrictionSensitive { friction, verdict },
            at_time,
            ..
        } => {
            assert!((friction - 1.0).abs() < 1e-12, "{friction}");
            assert!(verdict.starts_with("skated"), "{verdict}");
            assert!(
                (at_time - margin.settings.trial_seconds).abs() < 1e-9,
                "{at_time}"
            );
        }
        other => panic!("expected friction_sensitive, got {other:?}"),
    }
    let g = fixture("walks_on_every_floor.json");
    let kept = evaluate(&margin, &g, Scheme::Static, CandidateSeed::new(0, 0));
    assert!(matches!(kept, Outcome::Valid { .. }), "{kept:?}");
    let plain = evaluate(&ungated(), &g, Scheme::Static, CandidateSeed::new(0, 0));
    assert_eq!(outcome_hash(&kept), outcome_hash(&plain));
}

#[test]
fn a_confirming_trial_judges_the_brief_as_written_without_the_speed_margin() {
    // A candidate of the 1000-generation STATIC run with the friction margin and the shove
    // (docs/model.md section 6): 1.07 m/s at friction 0.8, and 1.02 m/s on the floor with a
    // quarter less grip, which meets the brief (1.0 m/s) but not the margin the run's own
    // trial asks (1.05 m/s). The confirming trial asks the brief: it is feasible, with the
    // run's trial's figures.
    // The defaults since that run.
    let robust = ctx();
    assert_eq!(
        (robust.limits.friction_margin, robust.limits.push_speed),
        (0.25, 0.3)
    );
    let g = fixture("meets_the_brief_on_the_slippery_floor.json");
    let kept = evaluate(&robust, &g, Scheme::Static, CandidateSeed::new(0, 0));
    assert!(matches!(kept, Outcome::Valid { .. }), "{kept:?}");
    let unconfirmed = ungated();
    let plain = evaluate(&unconfirmed, &g, Scheme::Static, CandidateSeed::new(0, 0));
    assert_eq!(outcome_hash(&kept), outcome_hash(&plain));
    // As the run's own trial, the slippery floor's trial is short of the margin.
    let mut slippery = unconfirmed;
    slippery.settings.friction = 0.6;
    match evaluate(&slippery, &g, Scheme::Static, CandidateSeed::new(0, 0)) {
        Outcome::Rejected {
            stats: Some(stats), ..
        } => assert!(
            stats.speed >= robust.brief.min_speed
                && stats.speed < robust.brief.required_speed(robust.limits.speed_margin),
            "{}",
            stats.speed
        ),
        other => panic!("expected a speed short of the margin only, got {other:?}"),
    }
    // Meeting the brief as written, the finer step's confirming trial holds the design to
    // its own window after it (`confirm_substeps_upright_seconds`), shove included: a
    // candidate of a quick run (refused on the slippery floor there) meets the brief at
    // 480 Hz and then tips past the window's 20 degrees at 11.4 s. With the long window
    // there it is refused; with the default 1 s it passes there (its run's trial held it
    // 15 s at 240 Hz). (The floors, tried first, refuse it on the slippery one, where it
    // tips too: the finer step's confirmation alone here.)
    let g = fixture("meets_the_brief_at_the_finer_step_then_falls.json");
    let mut finer_step_only = robust;
    finer_step_only.limits.friction_margin = 0.0;
    finer_step_only.limits.confirm_substeps_factor = 2;
    assert_eq!(finer_step_only.limits.confirm_substeps_upright_seconds, 1.0);
    let short = evaluate(
        &finer_step_only,
        &g,
        Scheme::Static,
        CandidateSeed::new(0, 0),
    );
    assert!(matches!(short, Outcome::Valid { .. }), "{short:?}");
    finer_step_only.limits.confirm_substeps_upright_seconds = 15.0;
    match evaluate(
        &finer_step_only,
        &g,
        Scheme::Static,
        CandidateSeed::new(0, 0),
    ) {
        Outcome::Invalid {
            reason: InvalidReason::StepSensitive { verdict, .. },
            at_time,
            ..
        } => {
            assert!(verdict.starts_with("fell"), "{verdict}");
            assert!(at_time > robust.settings.trial_seconds, "{at_time}");
        }
        other => panic!("expected a fall at the finer step, got {other:?}"),
    }
    // With the floors on (the defaults) they are tried first, the cheaper and likelier to
    // refuse: it is refused there, tipping in the window on the floor with less grip, the
    // finer step not run.
    match evaluate(&robust, &g, Scheme::Static, CandidateSeed::new(0, 0)) {
        Outcome::Invalid {
            reason: InvalidReason::FrictionSensitive { friction, verdict },
            at_time,
            ..
        } => {
            assert!((friction - 0.6).abs() < 1e-12, "{friction}");
            assert!(verdict.starts_with("fell"), "{verdict}");
            assert!(at_time > robust.settings.trial_seconds, "{at_time}");
        }
        other => panic!("expected a refusal on the slippery floor, got {other:?}"),
    }
}

#[test]
fn a_feasible_design_no_fitter_than_its_cells_elite_skips_its_confirming_trials() {
    // The elite that meets the brief at friction 0.8 (and at the finer step) and not at
    // 1.0: its confirming trials refuse it.
    let g = fixture("friction_sensitive.json");
    let seed = CandidateSeed::new(0, 0);
    let mut c = ctx();
    (c.limits.friction_margin, c.limits.push_speed) = (0.25, 0.0);
    let mut bare = c;
    (
        bare.limits.confirm_substeps_factor,
        bare.limits.friction_margin,
    ) = (1, 0.0);
    let at_step = evaluate(&bare, &g, Scheme::Static, seed);
    let Outcome::Valid { fitness, .. } = at_step else {
        panic!("feasible at the run's step: {at_step:?}")
    };
    // No fitter than its cell's elite: answered with the run's trial's figures, marked,
    // the confirming trials not run.
    let mut outranked = evaluate_to_enter(&c, &g, Scheme::Static, seed, Some(fitness));
    let Outcome::Valid { outranked: m, .. } = &mut outranked else {
        panic!("{outranked:?}")
    };
    assert!(*m);
    *m = false;
    assert_eq!(outranked, at_step);
    // A hair fitter, or no elite: its confirming trials are owed, and they refuse it.
    for to_beat in [Some(fitness * (1.0 - 1e-12)), None] {
        match evaluate_to_enter(&c, &g, Scheme::Static, seed, to_beat) {
            Outcome::Invalid {
                reason: InvalidReason::FrictionSensitive { .. },
                ..
            } => {}
            other => panic!("expected friction_sensitive with {to_beat:?}, got {other:?}"),
        }
    }
    assert_eq!(
        evaluate_to_enter(&c, &g, Scheme::Static, seed, None),
        evaluate(&c, &g, Scheme::Static, seed)
    );
    // With no confirming trial, its stay-up window alone is skipped: marked all the same.
    let mut windowless = evaluate_to_enter(&bare, &g, Scheme::Static, seed, Some(fitness));
    let Outcome::Valid { outranked: m, .. } = &mut windowless else {
        panic!("{windowless:?}")
    };
    assert!(*m);
    *m = false;
    assert_eq!(windowless, at_step);
}

#[test]
fn a_trial_no_fitter_than_its_bar_ends_at_the_trials_end_with_the_same_figures() {
    // A design that meets the brief on every floor, taken as fast enough for the brief
    // (any speed is, here), so held to the 15-s window. Against a bar it does not pass, it
    // ends when the trial does: the window and the shove are not run, and its figures are
    // the whole trial's, bit for bit. A hair below its fitness, or with no bar, the whole
    // trial runs. (MAX tips 20.1 degrees 7.9 s into the window after the shove.)
    let c = ctx();
    let walker = fixture("walks_on_every_floor.json");
    let run = |to_beat: Option<f64>| {
        let (end, rec) = design_trial(&walker, &c.limits, 0.0, to_beat);
        (end, rec.time.len())
    };
    let (whole, whole_steps) = run(None);
    let TrialEnd::Completed(stats) = &whole else {
        panic!("it stays up: {whole:?}")
    };
    let trial_steps = (c.settings.trial_seconds * c.settings.control_hz).round() as usize;
    let window = (c.limits.upright_after_feasible_seconds * c.settings.control_hz).round();
    assert_eq!(whole_steps, trial_steps + window as usize);
    let fitness = 1.0 / stats.cost_of_transport;
    let (at_bar, at_bar_steps) = run(Some(fitness));
    assert_eq!(at_bar, TrialEnd::Outranked(*stats));
    assert_eq!(at_bar_steps, trial_steps, "ended at the trial's end");
    assert_eq!(run(Some(fitness * (1.0 - 1e-12))).0, whole);
    // Too slow for the long window: the bar changes nothing.
    let slow = |to_beat| design_trial(&walker, &c.limits, f64::INFINITY, to_beat).0;
    assert_eq!(slow(Some(f64::INFINITY)), slow(None));
}

#[test]
fn a_slow_trial_standing_no_higher_than_its_bar_ends_at_the_trials_end() {
    // The same walker taken as too slow for the brief (held to the 1-s window): against a
    // standing it does not pass (its own speed, or a feasible design), it ends when the
    // trial does, with the whole trial's figures bit for bit; against a standing a hair
    // lower, or one a slow trial always passes (a trial that ended early), the window runs.
    let c = ctx();
    let walker = fixture("walks_on_every_floor.json");
    let run = |standing: Option<Standing>| {
        let bar = Bar {
            fitness: None,
            standing,
        };
        let (end, rec) = design_trial_against(&walker, &c.limits, f64::INFINITY, bar);
        (end, rec.time.len())
    };
    let (whole, whole_steps) = run(None);
    let TrialEnd::Completed(stats) = &whole else {
        panic!("it stays up: {whole:?}")
    };
    let trial_steps = (c.settings.trial_seconds * c.settings.control_hz).round() as usize;
    let window = (c.limits.upright_after_seconds * c.settings.control_hz).round() as usize;
    assert_eq!(whole_steps, trial_steps + window);
    let speed = stats.speed;
    for bar in [
        Standing::TooSlow { speed },
        Standing::Feasible { fitness: 0.0 },
    ] {
        let (end, steps) = run(Some(bar));
        assert_eq!(end, TrialEnd::Outranked(*stats), "against {bar:?}");
        assert_eq!(
            steps, trial_steps,
            "ended at the trial's end against {bar:?}"
        );
    }
    for bar in [
        Standing::TooSlow {
            speed: speed * (1.0 - 1e-12),
        },
        Standing::EndedEarly { at_time: 1e9 },
        Standing::NotSimulated,
    ] {
        assert_eq!(run(Some(bar)).0, whole, "against {bar:?}");
    }
    // `Bar::above` a parent: the fast path's bar only for a feasible one.
    assert_eq!(Bar::above(Standing::TooSlow { speed }).fitness, None);
    assert_eq!(
        Bar::above(Standing::Feasible { fitness: 2.0 }).fitness,
        Some(2.0)
    );
}

#[test]
fn with_no_window_for_slow_designs_a_fast_one_still_gets_its_long_window() {
    // `upright_after_seconds = 0`: a design that meets the brief on every floor, taken as
    // too slow for the brief, ends with its trial; taken as fast enough, it is held to the
    // 15-s window all the same; with both windows at 0 it is the paper's bare trial. The
    // trial's figures are the same in all three.
    let c = ctx();
    let walker = fixture("walks_on_every_floor.json");
    let run = |feasible_after: f64, feasible_speed: f64| {
        let mut limits = c.limits;
        limits.upright_after_seconds = 0.0;
        limits.upright_after_feasible_seconds = feasible_after;
        let (end, rec) = design_trial(&walker, &limits, feasible_speed, None);
        (end, rec.time.len())
    };
    let trial_steps = (c.settings.trial_seconds * c.settings.control_hz).round() as usize;
    let window = (c.limits.upright_after_feasible_seconds * c.settings.control_hz).round() as usize;
    let (slow, slow_steps) = run(c.limits.upright_after_feasible_seconds, f64::INFINITY);
    let (fast, fast_steps) = run(c.limits.upright_after_feasible_seconds, 0.0);
    let (bare, bare_steps) = run(0.0, 0.0);
    assert_eq!(slow_steps, trial_steps);
    assert_eq!(fast_steps, trial_steps + window);
    assert_eq!(bare_steps, trial_steps);
    assert!(matches!(slow, TrialEnd::Completed(_)), "{slow:?}");
    assert_eq!(slow, fast);
    assert_eq!(fast, bare);
}

#[test]
fn the_floor_with_more_grip_is_tried_before_the_one_with_less() {
    // A candidate of a small STATIC run at a brief of 0.05 m/s: feasible at the run's
    // floor (0.8), it tips past the window's 20 degrees on the floor with more grip (1.0)
    // and past 45 in its trial on the one with less (0.6). The grippier floor is tried
    // first, so that is the refusal it gets.
    let mut c = ctx();
    c.brief.min_speed = 0.05;
    let g = fixture("fails_on_both_floors.json");
    let seed = CandidateSeed::new(0, 0);
    let on = |friction: f64| {
        let mut floor = c;
        (
            floor.limits.friction_margin,
            floor.limits.confirm_substeps_factor,
        ) = (0.0, 1);
        floor.limits.speed_margin = 0.0;
        floor.settings.friction = friction;
        evaluate(&floor, &g, Scheme::Static, seed)
    };
    assert!(matches!(on(0.8), Outcome::Valid { .. }), "{:?}", on(0.8));
    for friction in [0.6, 1.0] {
        let there = on(friction);
        assert!(
            matches!(
                there,
                Outcome::Invalid {
                    reason: InvalidReason::Fell { .. },
                    ..
                }
            ),
            "at {friction}: {there:?}"
        );
    }
    match evaluate(&c, &g, Scheme::Static, seed) {
        Outcome::Invalid {
            reason: InvalidReason::FrictionSensitive { friction, .. },
            ..
        } => assert!((friction - 1.0).abs() < 1e-12, "{friction}"),
        other => panic!("expected a refusal on the floor with more grip, got {other:?}"),
    }
}
