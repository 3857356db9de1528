//! The cylinder's end stops through the Model API: a rod driven slowly into either stop
//! comes to rest where the contact spring carries the hydraulic force, `k d = F_hydraulic`.

mod scenario;

use ehsv_actuator::model::Model;
use ehsv_actuator::variables::vr;
use scenario::{model, run};

const HALF_STROKE: f64 = 0.04;
const K_ENDSTOP: f64 = 1.0e8;
const P_SUPPLY: f64 = 6.8948e6;
const BORE: f64 = 0.016;
const ROD: f64 = 0.010;

/// Drives the rod at about 0.13 m/s (1 mA) into the stop on the side of `i_ref` and lets it
/// come to rest there.
fn resting_at_stop(i_ref: f64, settings: &[(&str, f64)]) -> Model {
    let mut m = model(settings);
    m.set(vr::I_REF, i_ref).unwrap();
    run(&mut m, 0.6, 1e-4, &[]);
    m
}

#[test]
fn rod_at_rest_in_a_stop_compresses_the_contact_spring_by_force_over_stiffness() {
    let area_a = std::f64::consts::FRAC_PI_4 * BORE * BORE;
    let area_b = area_a - std::f64::consts::FRAC_PI_4 * ROD * ROD;
    // Extending: p_A -> p_S, p_B -> tank, so the stop holds p_S A_A (1386 N: 13.9 um).
    // Retracting: the mirror, p_S A_B (541 N: 5.4 um).
    for (i_ref, side, force) in [(1e-3, 1.0, P_SUPPLY * area_a), (-1e-3, -1.0, P_SUPPLY * area_b)] {
        let m = resting_at_stop(i_ref, &[]);
        let get = |r| m.get(r).unwrap();
        let (x, v, f_h) = (get(vr::X_PISTON), get(vr::V_PISTON), get(vr::F_HYDRAULIC));
        let penetration = side * (x - side * HALF_STROKE);
        println!(
            "side {side}: penetration {:.4} um, v {v:e}, F_hydraulic {f_h:.3} N",
            penetration * 1e6
        );
        // At rest (|v| < 1e-9 m/s: damper c v and friction F_s v/v_smooth below 1e-3 N) the
        // contact force k d balances the hydraulic force; the pressures have reached supply
        // and tank (the open valve drives them there) to 1e-4.
        assert!(v.abs() < 1e-9, "at rest: {v}");
        assert!(
            (K_ENDSTOP * penetration - side * f_h).abs() <= 1e-6 * force,
            "k d {} vs F {f_h}",
            K_ENDSTOP * penetration
        );
        assert!((side * f_h / force - 1.0).abs() < 1e-4, "{f_h} vs {force}");
    }
}

#[test]
fn external_load_adds_to_the_contact_force() {
    // A 500 N push towards the stop: k d = F_hydraulic + F_ext.
    let m = resting_at_stop(1e-3, &[("F_ext", 500.0)]);
    let get = |r| m.get(r).unwrap();
    let penetration = get(vr::X_PISTON) - HALF_STROKE;
    let force = get(vr::F_HYDRAULIC) + 500.0;
    assert!(get(vr::V_PISTON).abs() < 1e-9);
    assert!(
        (K_ENDSTOP * penetration - force).abs() <= 1e-6 * force,
        "k d {} vs {force}",
        K_ENDSTOP * penetration
    );
}
