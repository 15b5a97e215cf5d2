//! The mass model against a hand calculation, on a fixed hexapod genome
//! (`fixtures/hand_calc.json`, an early draft of MAX kept so that MAX can be tuned freely).

use strider_common::params::M;
use strider_common::{BodyPlan, Genome};

fn hand_calc_genome() -> Genome {
    Genome::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hand_calc.json"),
    )
    .unwrap()
}

fn assert_close(what: &str, got: f64, want: f64) {
    assert!((got - want).abs() < 1e-9, "{what}: got {got}, want {want}");
}

#[test]
fn masses_match_the_hand_calculation() {
    let plan = BodyPlan::new(&hand_calc_genome().morphology, 10.0);

    // Body: 1.8 x 0.2 x 0.4 m = 0.144 m^3 of 170 kg/m^3 foam = 24.48 kg,
    // plus 7.5 kg avionics and 10 kg payload = 41.98 kg.
    assert_close("body", plan.body_mass.mass, 41.98);

    // Hip link: 0.3 m of 0.06 m tube with 0.0025 m wall: (0.06^2 - 0.055^2) = 0.000575 m^2,
    // x 0.3 m x 1600 kg/m^3 = 0.276 kg. Motor: 150 Nm x 1.2 rad/s = 180 W,
    // 0.2 + sqrt(180 / 13000) = 0.2 + 0.117670 = 0.317670 kg.
    let hip = 0.276 + 0.2 + (180.0f64 / 13000.0).sqrt();
    // Upper leg: 0.000575 x 1.05 x 1600 = 0.966 kg; motor 200 x 0.3 = 60 W: 0.267937 kg.
    let upper = 0.966 + 0.2 + (60.0f64 / 13000.0).sqrt();
    // Lower leg: (0.05^2 - 0.045^2) = 0.000475 m^2 x 1.45 x 1600 = 1.102 kg; motor 60 W.
    let lower = 1.102 + 0.2 + (60.0f64 / 13000.0).sqrt();
    for leg in &plan.legs {
        assert_close("hip link", leg.links[0].mass.mass, hip);
        assert_close("upper link", leg.links[1].mass.mass, upper);
        assert_close("lower link", leg.links[2].mass.mass, lower);
    }
    // Tubes 0.276 + 0.966 + 1.102 = 2.344 kg, motors 0.317670 + 2 x 0.267937 = 0.853543 kg:
    // 3.197543 kg a leg, six legs 19.185258 kg.
    let legs = 6.0 * (hip + upper + lower);
    assert!((legs - 19.185_258).abs() < 1e-6, "{legs}");
    assert_close("total", plan.total_mass(), 41.98 + legs);
    assert_close("without payload", plan.mass_without_payload(), 31.98 + legs);
}

#[test]
fn quadratic_multipliers_change_the_end_legs_only() {
    let mut g = hand_calc_genome();
    g.morphology.set_clamped(M::StrengthMult, 5.0);
    g.morphology.set_clamped(M::LengthMult, 0.2);
    let plan = BodyPlan::new(&g.morphology, 10.0);
    // Front leg (u = 1): lengths x 1.2, torque x 1.5. Upper link 1.26 m of 0.000575 m^2
    // tube = 1.1592 kg; motor 300 Nm x 0.3 rad/s = 90 W: 0.2 + sqrt(90 / 13000) kg.
    let front = &plan.legs[0];
    assert_close("front upper length", front.links[1].length, 1.26);
    assert_close("front upper torque", front.links[1].drive.max_torque, 300.0);
    assert_close(
        "front upper mass",
        front.links[1].mass.mass,
        1.1592 + 0.2 + (90.0f64 / 13000.0).sqrt(),
    );
    // Middle leg (u = 0): unchanged.
    let middle = &plan.legs[1];
    assert_eq!(middle.u, 0.0);
    assert_close(
        "middle upper mass",
        middle.links[1].mass.mass,
        0.966 + 0.2 + (60.0f64 / 13000.0).sqrt(),
    );
}

#[test]
fn link_centre_of_mass_sits_between_tube_centre_and_motor() {
    let plan = BodyPlan::new(&hand_calc_genome().morphology, 10.0);
    let link = &plan.legs[0].links[1];
    // Tube 0.966 kg at 0.525 m, motor 0.267937 kg at 1.05 m.
    let motor = 0.2 + (60.0f64 / 13000.0).sqrt();
    let want = (0.966 * 0.525 + motor * 1.05) / (0.966 + motor);
    assert_close("link com", link.mass.com.z, want);
    assert_close("link com x", link.mass.com.x, 0.0);
}
