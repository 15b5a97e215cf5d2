//! Natural frequency and damping ratio of every joint of a design (each joint alone, the
//! rest of the robot held): f = sqrt(k / I) / 2 pi, zeta = D / (2 sqrt(k I)), I the joint's
//! inertia in the start pose (rapier's dof inverse inertia, inverted).
use strider_common::body_plan::SERVO_DERIVATIVE_TIME;
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::{BodyPlan, Controller, Genome, Scheme, StartPose};
use strider_worker::sim::world::RobotWorld;
fn main() {
    let mut genomes = vec![("MAX".to_string(), strider_common::reference::max())];
    for i in 0..200u64 {
        let s = CandidateSeed::new(1, i);
        genomes.push((
            format!("random {i}"),
            Genome::random(Scheme::Static, &mut s.rng(Purpose::RandomGenome)),
        ));
    }
    let (mut zd, mut zs, mut fr) = (vec![], vec![], vec![]);
    for (name, g) in &genomes {
        let plan = BodyPlan::new(&g.morphology, 10.0);
        let start = StartPose::new(&plan, &Controller::static_default());
        let mut rw = RobotWorld::new(&plan, &start, 1.0 / 240.0);
        rw.world.step();
        let joints = rw.joints.clone();
        let inv = {
            let (mb, _) = rw.world.multibody_joints.get_mut(rw.multibody).unwrap();
            mb.dof_inverse_inertia(&rw.world.bodies)
        };
        for (j, slot) in joints.iter().enumerate() {
            let i = 1.0 / f64::from(inv[slot.dof]);
            let k = slot.drive.stiffness;
            let f = (k / i).sqrt() / (2.0 * std::f64::consts::PI);
            let z0 = slot.drive.damping / (2.0 * (k * i).sqrt());
            let z1 = (slot.drive.damping + k * SERVO_DERIVATIVE_TIME) / (2.0 * (k * i).sqrt());
            if name == "MAX" && j < 3 {
                println!("MAX joint {j}: I {i:.3} kg m2, k {k:.0}, d {:.1}: f {f:.1} Hz, zeta {z0:.3} (encoded d), {z1:.2} (servo)", slot.drive.damping);
            }
            if name != "MAX" {
                zd.push(z0);
                zs.push(z1);
                fr.push(f);
            }
        }
    }
    for v in [&mut zd, &mut zs, &mut fr] {
        v.sort_by(f64::total_cmp);
    }
    let q = |v: &Vec<f64>, p: f64| v[((v.len() - 1) as f64 * p) as usize];
    println!("200 random designs, {} joints: f {:.1} / {:.1} / {:.1} Hz (10/50/90 %), zeta with d alone {:.3} / {:.3} / {:.3}, with the servo {:.2} / {:.2} / {:.2}",
        fr.len(), q(&fr,0.1), q(&fr,0.5), q(&fr,0.9), q(&zd,0.1), q(&zd,0.5), q(&zd,0.9), q(&zs,0.1), q(&zs,0.5), q(&zs,0.9));
}
