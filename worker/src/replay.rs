//! A trial's replay: the body pose and joint angles sampled at a steady frame rate while
//! the trial runs, drawn as an animated side view (`strider_common::drawing`).

use crate::sim::trial::{Observer, Sample};
use strider_common::drawing::Frame3;
use strider_common::params::LINKS_PER_LEG;

/// Frames per simulated second in replays: smooth enough to read the gait, small files.
pub const FRAMES_PER_SECOND: f64 = 20.0;

/// Collects frames of a trial.
#[derive(Default)]
pub struct Replay {
    /// The frames so far, in time order.
    pub frames: Vec<Frame3>,
}

impl Replay {
    /// The first frame, one frame every `seconds` after it, and the last frame.
    pub fn every(&self, seconds: f64) -> Vec<Frame3> {
        let mut out: Vec<Frame3> = Vec::new();
        for f in &self.frames {
            if out.last().is_none_or(|l| f.time - l.time >= seconds - 1e-9) {
                out.push(f.clone());
            }
        }
        if let (Some(last), Some(kept)) = (self.frames.last(), out.last()) {
            if last.time > kept.time {
                out.push(last.clone());
            }
        }
        out
    }
}

impl Observer for Replay {
    fn control_step(&mut self, s: &Sample<'_>) {
        let due = self
            .frames
            .last()
            .is_none_or(|f| s.time - f.time >= 1.0 / FRAMES_PER_SECOND - 1e-9);
        if due {
            self.frames.push(Frame3 {
                time: s.time,
                body: s.body,
                angles: s
                    .angles
                    .chunks_exact(LINKS_PER_LEG)
                    .map(|c| [c[0], c[1], c[2]])
                    .collect(),
            });
        }
    }
}

/// What replaying a design's trial measured: each joint's load, and the frames of an
/// animated replay when they were asked for.
pub struct Measured {
    pub motors: Vec<strider_common::motor_sizing::JointLoad>,
    pub frames: Option<Vec<Frame3>>,
}

/// Replays `genome`'s trial with the controller it holds (the one it was evaluated with),
/// measuring its motors' loads, and keeping frames every `frame_seconds` if given.
pub fn measure(
    ctx: &strider_common::EvalContext,
    genome: &strider_common::Genome,
    frame_seconds: Option<f64>,
) -> Measured {
    use crate::trial_outcome::evaluate_controller;
    use strider_common::motor_sizing::MotorSizing;
    let plan = strider_common::BodyPlan::new(&genome.morphology, ctx.brief.payload);
    let mut watch = (MotorSizing::default(), Replay::default());
    evaluate_controller(ctx, genome, &plan, &genome.controller, &mut watch);
    Measured {
        motors: watch.0.loads(&plan),
        frames: frame_seconds.map(|s| watch.1.every(s)),
    }
}
