//! A trial trace as CSV: one row per control step (at its end) with the body pose and
//! every joint's angle, torque and the target it was driven toward over the step, for plots
//! and replays (a second engine replays the targets: tests/python/pybullet_replay.py).
//! Every column name ends in its unit (`_s`, `_m`, `_rad`, `_Nm`, `_J`; the quaternion
//! has none); the world is y-up, x forward (the walking direction), z to the robot's right
//! (docs/model.md section 1).

use crate::sim::trial::{Observer, Sample};
use std::io::{self, Write};
use strider_common::body_plan::{BodyPlan, Side};

/// Writes a trace row per control step.
pub struct CsvTrace<W: Write> {
    out: W,
    error: Option<io::Error>,
}

impl<W: Write> CsvTrace<W> {
    /// Starts a trace of `plan`, writing the header.
    pub fn new(mut out: W, plan: &BodyPlan) -> io::Result<Self> {
        let mut header = String::from("time_s,x_forward_m,y_up_m,z_right_m,qw,qx,qy,qz,energy_J");
        for leg in &plan.legs {
            let side = if leg.side == Side::Right { "r" } else { "l" };
            for k in 0..leg.links.len() {
                header.push_str(&format!(",{side}{}_q{k}_rad", leg.index));
            }
        }
        for leg in &plan.legs {
            let side = if leg.side == Side::Right { "r" } else { "l" };
            for k in 0..leg.links.len() {
                header.push_str(&format!(",{side}{}_tau{k}_Nm", leg.index));
            }
        }
        for leg in &plan.legs {
            let side = if leg.side == Side::Right { "r" } else { "l" };
            for k in 0..leg.links.len() {
                header.push_str(&format!(",{side}{}_target{k}_rad", leg.index));
            }
        }
        writeln!(out, "{header}")?;
        Ok(Self { out, error: None })
    }

    /// Finishes the trace, reporting the first write error.
    pub fn finish(self) -> io::Result<()> {
        self.into_inner().map(drop)
    }

    /// Finishes the trace and returns what it wrote into, or the first write error.
    pub fn into_inner(mut self) -> io::Result<W> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

impl<W: Write> Observer for CsvTrace<W> {
    fn control_step(&mut self, s: &Sample<'_>) {
        if self.error.is_some() {
            return;
        }
        let t = s.body.translation.vector;
        let r = s.body.rotation;
        let mut row = format!(
            "{:.4},{:.5},{:.5},{:.5},{:.6},{:.6},{:.6},{:.6},{:.4}",
            s.time, t.x, t.y, t.z, r.w, r.i, r.j, r.k, s.energy
        );
        for v in s.angles.iter().chain(s.torques) {
            row.push_str(&format!(",{v:.5}"));
        }
        for v in s.targets {
            row.push_str(&format!(",{v:.7}"));
        }
        if let Err(e) = writeln!(self.out, "{row}") {
            self.error = Some(e);
        }
    }
}
