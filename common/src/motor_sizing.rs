//! Motor sizing: per joint, the peak and RMS torque, speed and mechanical power a trial
//! asked of its motor, beside the motor's ratings. What an engineer sizes motors from
//! (the report's design cards show it). Plain data, fed one physics step at a time.

use crate::body_plan::{BodyPlan, Side};
use serde::{Deserialize, Serialize};

/// One joint's load over a trial, against its motor's limits.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointLoad {
    /// Which joint: "right leg 0 motor 1 (leg0_upper_joint)": motor 0 at the hip, 2 at
    /// the foot end, and in brackets the joint's name in the exported URDF.
    pub joint: String,
    /// Largest |torque| applied, Nm.
    pub peak_torque: f64,
    /// Root mean square torque, Nm (what heats a motor).
    pub rms_torque: f64,
    /// The motor's torque limit, Nm.
    pub torque_limit: f64,
    /// Largest |joint speed|, rad/s.
    pub peak_speed: f64,
    /// The motor's speed rating, rad/s (`motor*_max_speed`: it sets the gait's amplitude).
    pub speed_limit: f64,
    /// Largest |torque x speed|, W.
    pub peak_power: f64,
    /// Root mean square of torque x speed, W.
    pub rms_power: f64,
}

/// Accumulates the joints' loads step by step.
#[derive(Clone, Debug, Default)]
pub struct MotorSizing {
    steps: u64,
    peak_torque: Vec<f64>,
    torque_squares: Vec<f64>,
    peak_speed: Vec<f64>,
    peak_power: Vec<f64>,
    power_squares: Vec<f64>,
}

impl MotorSizing {
    /// Adds one physics step: each joint's applied torque (Nm) and speed (rad/s), in the
    /// plan's joint order (three per leg).
    pub fn add(&mut self, torques: &[f64], speeds: &[f64]) {
        let n = torques.len();
        if self.peak_torque.len() != n {
            *self = Self {
                steps: 0,
                peak_torque: vec![0.0; n],
                torque_squares: vec![0.0; n],
                peak_speed: vec![0.0; n],
                peak_power: vec![0.0; n],
                power_squares: vec![0.0; n],
            };
        }
        self.steps += 1;
        for (i, (&tau, &w)) in torques.iter().zip(speeds).enumerate() {
            let p = tau * w;
            self.peak_torque[i] = self.peak_torque[i].max(tau.abs());
            self.torque_squares[i] += tau * tau;
            self.peak_speed[i] = self.peak_speed[i].max(w.abs());
            self.peak_power[i] = self.peak_power[i].max(p.abs());
            self.power_squares[i] += p * p;
        }
    }

    /// Each joint's load, in the plan's joint order (empty before the first step).
    pub fn loads(&self, plan: &BodyPlan) -> Vec<JointLoad> {
        let steps = self.steps.max(1) as f64;
        let joints = plan.legs.iter().enumerate().flat_map(|(l, leg)| {
            leg.links.iter().enumerate().map(move |(k, link)| {
                let side = if leg.side == Side::Right {
                    "right"
                } else {
                    "left"
                };
                let urdf = crate::urdf::joint_name(l, k);
                (
                    format!("{side} leg {} motor {k} ({urdf})", leg.index),
                    link.drive,
                )
            })
        });
        joints
            .zip(0..self.peak_torque.len())
            .map(|((joint, drive), i)| JointLoad {
                joint,
                peak_torque: self.peak_torque[i],
                rms_torque: (self.torque_squares[i] / steps).sqrt(),
                torque_limit: drive.max_torque,
                peak_speed: self.peak_speed[i],
                speed_limit: drive.max_speed,
                peak_power: self.peak_power[i],
                rms_power: (self.power_squares[i] / steps).sqrt(),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peaks_and_root_mean_squares_per_joint() {
        let plan = BodyPlan::new(&crate::reference::max().morphology, 10.0);
        let n = plan.legs.len() * 3;
        let mut s = MotorSizing::default();
        let mut torques = vec![0.0; n];
        let mut speeds = vec![0.0; n];
        torques[0] = 3.0;
        speeds[0] = -2.0;
        s.add(&torques, &speeds);
        torques[0] = -4.0;
        speeds[0] = 1.0;
        s.add(&torques, &speeds);
        let loads = s.loads(&plan);
        assert_eq!(loads.len(), n);
        let l = &loads[0];
        assert_eq!(l.peak_torque, 4.0);
        assert!((l.rms_torque - (12.5f64).sqrt()).abs() < 1e-12);
        assert_eq!(l.peak_speed, 2.0);
        assert_eq!(l.peak_power, 6.0);
        assert!((l.rms_power - (26.0f64).sqrt()).abs() < 1e-12);
        assert_eq!(l.torque_limit, plan.legs[0].links[0].drive.max_torque);
        assert!(
            l.joint.ends_with("leg 0 motor 0 (leg0_hip_joint)"),
            "{}",
            l.joint
        );
        assert_eq!(loads[1].peak_torque, 0.0);
    }
}
