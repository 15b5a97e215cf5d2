//! One trial (docs/model.md section 6): the robot walks for the trial's duration under its
//! controller; the energy, distance and cost of transport are measured, and the trial stops
//! early on a self-contact, a fall (tilt, sinking, a part other than a lower leg on the
//! ground), a non-finite value or a blow-up. After the trial the robot must stay up a
//! while longer (`upright_after_seconds`), its gait going on; distance and energy count
//! over the trial only.
//!
//! Torque accounting. Each joint is driven by its servo law (`super::drive`); after each
//! step the torque it actually received is computed from its speed after the step and
//! integrated: `E += |tau * v_{n+1}| dt`, the exact work of that torque under rapier's
//! position update `q_{n+1} = q_n + dt v_{n+1}`.

use super::drive::DrivenStepper;
use super::falls::{contacts, FallCheck};
use super::feet::FootTracker;
use super::world::{RobotWorld, HINGE_DOF_AXIS};
use ::nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use rapier3d::prelude::*;
use strider_common::body_plan::BodyPlan;
use strider_common::experiment::{RunSettings, TrialLimits};
use strider_common::gait::leg_targets;
use strider_common::outcome::{GaitStats, InvalidReason, Skate, TrialStats};
use strider_common::params::LINKS_PER_LEG;
use strider_common::{Controller, Standing, StartPose};

/// The body frame's up axis (the model's y): its angle from the world's vertical is the
/// body's tilt.
pub fn up_axis() -> Vector3<f64> {
    Vector3::y()
}

/// Standard gravity, m/s^2.
pub const GRAVITY: f64 = 9.81;
/// A generalized velocity beyond this (m/s or rad/s) means the simulation blew up.
pub use strider_common::body_plan::BLOW_UP_SPEED;

/// How a trial ended.
#[derive(Clone, Debug, PartialEq)]
pub enum TrialEnd {
    /// It ran its full duration.
    Completed(TrialStats),
    /// It ranked no higher than the bar it was run against at the trial's end
    /// ([`run_trial_to_beat`]): it met the speed that holds it to the long stay-up window
    /// and was no fitter than [`Bar::fitness`], or it was slower and stood no higher than
    /// [`Bar::standing`]. Ended there, its window (and shove) not run, since it could not
    /// count whatever they said. Its figures are the trial's, those it would have had had
    /// it stayed up.
    Outranked(TrialStats),
    /// It was stopped.
    Stopped {
        /// Why.
        reason: InvalidReason,
        /// When, s.
        at_time: f64,
    },
    /// Its observer gave it up ([`Observer::abandoned`]): a confirming trial run beside
    /// the others (crate::help) whose verdict no longer counts, one before it having
    /// refused the design or its holder having panicked.
    Abandoned {
        /// When, s.
        at_time: f64,
    },
}

/// The state reported to an observer after each control step.
pub struct Sample<'a> {
    /// Simulated time, s.
    pub time: f64,
    /// The body frame's world pose.
    pub body: Isometry3<f64>,
    /// Joint angles, three per leg in the plan's leg order, rad.
    pub angles: &'a [f64],
    /// Torques applied during the last physics step, same order, Nm.
    pub torques: &'a [f64],
    /// The targets the joints were driven toward over this control step, same order, rad.
    pub targets: &'a [f64],
    /// Energy spent so far, J.
    pub energy: f64,
    /// The robot's centre of mass in the world, m.
    pub com: Vector3<f64>,
}

/// Watches a trial (for traces); the unit type watches nothing.
pub trait Observer {
    /// Whether to build samples at all (the plain trial skips the work).
    const WANTS_SAMPLES: bool = true;
    /// Called after every control step.
    fn control_step(&mut self, sample: &Sample<'_>);
    /// Called after every physics step of the trial (not of the stay-up window after it)
    /// with each joint's applied torque (Nm) and speed (rad/s).
    fn physics_step(&mut self, _torques: &[f64], _speeds: &[f64]) {}
    /// Asked before every control step: whether the trial's verdict no longer matters, so
    /// it ends there, [`TrialEnd::Abandoned`]. Never for a trial whose answer is used.
    fn abandoned(&self) -> bool {
        false
    }
}

impl<A: Observer, B: Observer> Observer for (A, B) {
    const WANTS_SAMPLES: bool = A::WANTS_SAMPLES || B::WANTS_SAMPLES;
    fn control_step(&mut self, sample: &Sample<'_>) {
        self.0.control_step(sample);
        self.1.control_step(sample);
    }
    fn physics_step(&mut self, torques: &[f64], speeds: &[f64]) {
        self.0.physics_step(torques, speeds);
        self.1.physics_step(torques, speeds);
    }
    fn abandoned(&self) -> bool {
        self.0.abandoned() || self.1.abandoned()
    }
}

impl Observer for strider_common::motor_sizing::MotorSizing {
    fn control_step(&mut self, _: &Sample<'_>) {}
    fn physics_step(&mut self, torques: &[f64], speeds: &[f64]) {
        self.add(torques, speeds);
    }
}

impl Observer for () {
    const WANTS_SAMPLES: bool = false;
    #[inline]
    fn control_step(&mut self, _: &Sample<'_>) {}
}

/// Runs the trial of `plan` under `controller`'s gait.
pub fn run_trial<O: Observer>(
    plan: &BodyPlan,
    controller: &Controller,
    settings: &RunSettings,
    limits: &TrialLimits,
    observer: &mut O,
) -> TrialEnd {
    let start = StartPose::new(plan, controller);
    run_trial_from(
        plan,
        &start,
        controller,
        settings,
        limits,
        f64::INFINITY,
        observer,
    )
}

/// [`run_trial`] from a start pose already computed (`StartPose::new(plan, controller)`),
/// a design whose speed at the trial's end is at least `feasible_speed` (the brief's,
/// with the speed margin in the run's own trial, without it in a confirming trial) being
/// held to the longer stay-up window.
pub fn run_trial_from<O: Observer>(
    plan: &BodyPlan,
    start: &StartPose,
    controller: &Controller,
    settings: &RunSettings,
    limits: &TrialLimits,
    feasible_speed: f64,
    observer: &mut O,
) -> TrialEnd {
    run_trial_to_beat(
        plan,
        start,
        controller,
        settings,
        limits,
        feasible_speed,
        Bar::NONE,
        observer,
    )
}

/// What a trial must pass to count, judged at the trial's end ([`run_trial_to_beat`]).
/// The window after it can only keep a trial's standing or lower it (a fall, which ranks
/// below every trial that ran to its end), so a trial at or under its bar there counts
/// for nothing whatever the window says.
#[derive(Clone, Copy, Debug)]
pub struct Bar {
    /// For a trial fast enough for the long window: the fitness (1 / cost of transport
    /// over the trial) it must pass.
    pub fitness: Option<f64>,
    /// For a slower trial: the standing it must pass (its own is
    /// [`Standing::TooSlow`] at its average speed).
    pub standing: Option<Standing>,
}

impl Bar {
    /// No bar: every trial runs its window.
    pub const NONE: Bar = Bar {
        fitness: None,
        standing: None,
    };

    /// The bar of a design that counts only if it ranks above `standing` (the ES's
    /// parent): a fast trial must be fitter than a feasible one; a slower trial must stand
    /// above it.
    pub fn above(standing: Standing) -> Bar {
        Bar {
            fitness: match standing {
                Standing::Feasible { fitness } => Some(fitness),
                _ => None,
            },
            standing: Some(standing),
        }
    }
}

/// [`run_trial_from`] for a design that matters only if it passes `to_beat`: one that at
/// the trial's end is fast enough for the long window and no fitter than
/// [`Bar::fitness`], or slower and standing no higher than [`Bar::standing`], ends there,
/// [`TrialEnd::Outranked`]. The window could only keep its standing or make it fall, and
/// neither makes it count. [`Bar::NONE`] runs the whole trial.
#[allow(clippy::too_many_arguments)]
pub fn run_trial_to_beat<O: Observer>(
    plan: &BodyPlan,
    start: &StartPose,
    controller: &Controller,
    settings: &RunSettings,
    limits: &TrialLimits,
    feasible_speed: f64,
    to_beat: Bar,
    observer: &mut O,
) -> TrialEnd {
    trial(
        plan,
        start,
        settings,
        limits,
        (feasible_speed, to_beat),
        |leg, t| leg_targets(controller, &plan.legs[leg], t),
        observer,
    )
}

/// Runs a trial from `start` with any joint targets: `targets(leg index, t)` gives a leg's
/// three target angles at control time `t` (the gait in a real trial; tests script others).
/// A robot whose average speed at the trial's end is at least `feasible_speed` must stay up
/// `upright_after_feasible_seconds` after it, the others `upright_after_seconds`
/// (`f64::INFINITY`: the shorter window for all).
pub fn run_trial_with<O: Observer>(
    plan: &BodyPlan,
    start: &StartPose,
    settings: &RunSettings,
    limits: &TrialLimits,
    feasible_speed: f64,
    targets_at: impl Fn(usize, f64) -> [f64; LINKS_PER_LEG],
    observer: &mut O,
) -> TrialEnd {
    trial(
        plan,
        start,
        settings,
        limits,
        (feasible_speed, Bar::NONE),
        targets_at,
        observer,
    )
}

/// The trial: [`run_trial_with`] with the bar of [`run_trial_to_beat`].
fn trial<O: Observer>(
    plan: &BodyPlan,
    start: &StartPose,
    settings: &RunSettings,
    limits: &TrialLimits,
    (feasible_speed, to_beat): (f64, Bar),
    targets_at: impl Fn(usize, f64) -> [f64; LINKS_PER_LEG],
    observer: &mut O,
) -> TrialEnd {
    let dt = settings.physics_dt();
    let mut rw = RobotWorld::with_friction(plan, start, dt, settings.friction);
    let substeps = settings.physics_substeps as usize;
    let steps = settings.control_steps() as usize * substeps;
    // Past the trial the robot must stay up a while, its gait going on: one that falls
    // then was falling at the end, and would otherwise be credited with the distance it
    // fell forward (seen in the best designs of a search). Distance and energy stop at
    // `steps`.
    // A design fast enough to meet the brief must keep walking longer: a 1-s window let
    // through designs that fell within 15 s, half of a search's feasible elites
    // (docs/model.md section 6, "Gaits that keep walking"). The others only need to be
    // walking at the end, and the longer window would cost every slow trial 3 times over.
    let window = |seconds: f64| (seconds * settings.control_hz).round() as usize * substeps;
    let mut after = window(limits.upright_after_seconds);
    let long_after = window(
        limits
            .upright_after_feasible_seconds
            .max(limits.upright_after_seconds),
    );
    // The trial's figures, once it has run its length.
    let mut at_end: Option<TrialStats> = None;
    let total_mass = plan.total_mass();
    let com_start = centre_of_mass(&rw);
    let falls = FallCheck::new(limits, start);

    let n = rw.joints.len();
    let mut targets = vec![0.0; n];
    let mut angles = vec![0.0; n];
    let mut stepper = DrivenStepper::new(n);
    let mut energy = 0.0;
    let mut peak_torque_ratio: f64 = 0.0;
    let mut feet = FootTracker::new(plan, &rw);
    let mut down = vec![false; plan.legs.len()];

    let mut step = 0;
    let stats = loop {
        // The trial's end is judged before the loop's exit test, so a trial with no window
        // after it is judged here too, and a design fast enough for the brief gets its long
        // window even when the others get none (`upright_after_seconds = 0`; before d65b9ab
        // such a trial ended with no window at all).
        if step == steps {
            // What the trial measured is judged at its end: a design that skates is
            // refused here, before any window (which changes none of its figures).
            let end = TrialFigures {
                com_start,
                com_end: centre_of_mass(&rw),
                energy,
                duration: steps as f64 * dt,
                trial_seconds: settings.trial_seconds,
                mass: total_mass,
                gait: GaitStats {
                    peak_torque_ratio,
                    ..feet.stats()
                },
            }
            .judge(limits);
            let TrialEnd::Completed(stats) = end else {
                return end;
            };
            at_end = Some(stats);
            if stats.speed >= feasible_speed {
                // `NaN <= bar` is false: such a trial runs on to its own verdict.
                if to_beat
                    .fitness
                    .is_some_and(|bar| 1.0 / stats.cost_of_transport <= bar)
                {
                    return TrialEnd::Outranked(stats);
                }
                after = long_after;
                // Shoved only when held to the long window: a slower design's verdict
                // stays what its walk alone earns it.
                if limits.push_speed > 0.0 {
                    shove(&mut rw, limits.push_speed);
                }
            } else if to_beat.standing.is_some_and(|bar| {
                // Too slow for the brief (or not forward at all), it stands by its speed.
                !Standing::TooSlow { speed: stats.speed }.beats(&bar)
            }) {
                return TrialEnd::Outranked(stats);
            }
        }
        if step >= steps + after {
            break at_end.expect("the trial's end is judged before its window ends");
        }
        let t = step as f64 * dt;
        if step % substeps == 0 {
            if observer.abandoned() {
                return TrialEnd::Abandoned { at_time: t };
            }
            let control_time = (step / substeps) as f64 / settings.control_hz;
            for leg_index in 0..plan.legs.len() {
                let q = targets_at(leg_index, control_time);
                targets[leg_index * LINKS_PER_LEG..][..LINKS_PER_LEG].copy_from_slice(&q);
            }
        }
        stepper.step(&mut rw, dt, &targets);
        let time = t + dt;

        // Applied torques and the work they did.
        let mb = rw.robot();
        let mut fastest: f64 = 0.0;
        for &v in mb.generalized_velocity().iter() {
            // Checked one by one: f64::max would silently skip a NaN.
            if !v.is_finite() {
                return stopped(
                    InvalidReason::NonFinite {
                        what: "velocity".into(),
                    },
                    time,
                );
            }
            fastest = fastest.max(f64::from(v.abs()));
        }
        if fastest > BLOW_UP_SPEED {
            return stopped(InvalidReason::BlowUp { speed: fastest }, time);
        }
        for (i, slot) in rw.joints.iter().enumerate() {
            let (tau, v1) = (stepper.torques[i], stepper.speeds[i]);
            energy += (tau * v1).abs() * dt;
            if step < steps {
                peak_torque_ratio = peak_torque_ratio.max(tau.abs() / slot.drive.max_torque);
            }
        }
        if !energy.is_finite() {
            return stopped(
                InvalidReason::NonFinite {
                    what: "energy".into(),
                },
                time,
            );
        }
        if O::WANTS_SAMPLES && step < steps {
            observer.physics_step(&stepper.torques, &stepper.speeds);
        }
        // The observer sees the step that ends a trial too (a replay shows the fall).
        if O::WANTS_SAMPLES && (step + 1) % substeps == 0 {
            let mb = rw.robot();
            for (i, slot) in rw.joints.iter().enumerate() {
                angles[i] = f64::from(
                    mb.link(slot.link_id).expect("joint link").joint.coords()[HINGE_DOF_AXIS],
                );
            }
            observer.control_step(&Sample {
                time,
                body: body_pose(&rw),
                angles: &angles,
                torques: &stepper.torques,
                targets: &targets,
                energy,
                com: centre_of_mass(&rw),
            });
        }
        // After the trial only falls count: a self-contact then changes no figure.
        if let Some(reason) = contacts(
            &rw,
            limits.only_feet_on_ground,
            step < steps,
            plan,
            &mut down,
        ) {
            return stopped(reason, time);
        }
        if step < steps {
            feet.step(&rw, &down);
        }
        if let Some(fall) = falls.check(&rw, step >= steps) {
            return stopped(InvalidReason::Fell { fall }, time);
        }
        step += 1;
    };
    TrialEnd::Completed(stats)
}

/// What a trial measured by its end (the stay-up window after it changes none of it).
struct TrialFigures {
    com_start: Vector3<f64>,
    com_end: Vector3<f64>,
    energy: f64,
    /// The trial's length, s: its steps times the step.
    duration: f64,
    /// The trial's length as set, s: when a non-finite position stopped it.
    trial_seconds: f64,
    /// The robot's whole mass, kg.
    mass: f64,
    gait: GaitStats,
}

impl TrialFigures {
    /// The trial's verdict from its figures alone: a non-finite position, skating, or its
    /// stats.
    fn judge(self, limits: &TrialLimits) -> TrialEnd {
        let Self {
            com_start,
            com_end,
            energy,
            duration,
            trial_seconds,
            mass,
            gait,
        } = self;
        if !com_end.iter().all(|c| c.is_finite()) {
            return stopped(
                InvalidReason::NonFinite {
                    what: "position".into(),
                },
                trial_seconds,
            );
        }
        let distance = com_end.x - com_start.x;
        if let Some(skate) = skating(&gait, distance, limits) {
            return stopped(InvalidReason::Skating { skate }, duration);
        }
        TrialEnd::Completed(TrialStats {
            distance,
            energy,
            speed: distance / duration,
            mass,
            cost_of_transport: energy / (mass * GRAVITY * distance),
            duration,
            gait,
        })
    }
}

/// Changes the whole robot's sideways velocity (+z, to its right) by `speed`, m/s: the
/// root's linear velocity is the first three of a free multibody's generalized velocities,
/// and every link's velocity is relative to it.
fn shove(rw: &mut RobotWorld, speed: f64) {
    let mut v = rw.robot_mut().generalized_velocity_mut();
    v[2] += speed as Real;
}

/// A trial is judged for skating only when the robot walked at least this far, m (about a
/// stride of these robots): over a shorter walk, a few centimetres of settling make any
/// share or ratio of the feet's travel large, and say nothing of how they step.
pub const SKATING_MIN_DISTANCE: f64 = 1.0;

/// How the feet skated over a trial that walked `distance`, if past the limits.
fn skating(gait: &GaitStats, distance: f64, limits: &TrialLimits) -> Option<Skate> {
    if distance < SKATING_MIN_DISTANCE {
        return None;
    }
    let ratio = gait.foot_slip / distance;
    if ratio > limits.max_foot_slip_ratio {
        return Some(Skate::Slid {
            ratio,
            limit: limits.max_foot_slip_ratio,
        });
    }
    if gait.low_forward_share > limits.max_low_forward_share {
        return Some(Skate::Shuffled {
            share: gait.low_forward_share,
            limit: limits.max_low_forward_share,
        });
    }
    None
}

fn stopped(reason: InvalidReason, at_time: f64) -> TrialEnd {
    TrialEnd::Stopped { reason, at_time }
}

fn body_pose(rw: &RobotWorld) -> Isometry3<f64> {
    let p = rw.world.bodies[rw.parts[0].0].position();
    let (t, r) = (p.translation, p.rotation);
    Isometry3::from_parts(
        Translation3::new(f64::from(t.x), f64::from(t.y), f64::from(t.z)),
        UnitQuaternion::new_normalize(Quaternion::new(
            f64::from(r.w),
            f64::from(r.x),
            f64::from(r.y),
            f64::from(r.z),
        )),
    )
}

/// The robot's centre of mass in the world, from each part's pose and local centre.
fn centre_of_mass(rw: &RobotWorld) -> Vector3<f64> {
    let mut sum = Vector3::zeros();
    let mut mass = 0.0;
    for (handle, local_com, m) in &rw.parts {
        let p = rw.world.bodies[*handle].position();
        let c = p.transform_point(Vector::new(
            local_com.x as f32,
            local_com.y as f32,
            local_com.z as f32,
        ));
        sum += Vector3::new(f64::from(c.x), f64::from(c.y), f64::from(c.z)) * *m;
        mass += m;
    }
    sum / mass
}
