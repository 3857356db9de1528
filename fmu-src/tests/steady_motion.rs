//! The cylinder at rest and in steady motion through the Model API: the start pressures
//! balance the load, and at a constant speed the hydraulic force balances friction and load
//! while the port flows balance displacement and leakage.

mod scenario;

use ehsv_actuator::model::Model;
use ehsv_actuator::variables::vr;
use scenario::{model, run};
use std::f64::consts::FRAC_PI_4;

const AREA_A: f64 = FRAC_PI_4 * 0.016 * 0.016;
const AREA_B: f64 = AREA_A - FRAC_PI_4 * 0.010 * 0.010;
const P_SUPPLY: f64 = 6.8948e6;
// Friction parameters (start values).
const F_COULOMB: f64 = 20.0;
const F_STATIC: f64 = 30.0;
const V_STRIBECK: f64 = 0.01;
const V_SMOOTH: f64 = 1e-4;
const B_VISCOUS: f64 = 2000.0;
const MASS: f64 = 5.0;

fn friction(v: f64) -> f64 {
    let dry = F_COULOMB + (F_STATIC - F_COULOMB) * (-(v / V_STRIBECK).powi(2)).exp();
    dry * (v / V_SMOOTH).tanh() + B_VISCOUS * v
}

/// A model moving at the steady speed a constant current gives, 0.25 s after the step
/// (the start transient, the oil spring against the mass, has decayed by ~1e-9 then).
fn steady(settings: &[(&str, f64)], i_ref: f64) -> Model {
    let mut m = model(settings);
    m.set(vr::I_REF, i_ref).unwrap();
    run(&mut m, 0.25, 1e-4, &[]);
    assert!(m.get(vr::X_PISTON).unwrap().abs() < 0.03, "clear of the stops");
    m
}

#[test]
fn start_pressures_hold_the_load_at_the_valve_null() {
    // A centred valve rests at p_A + p_B = p_S + p_T with p_A A_A - p_B A_B + F_ext = 0.
    for f_ext in [0.0, 400.0, -250.0] {
        let m = model(&[("F_ext", f_ext)]);
        let (p_a, p_b) = (m.get(vr::P_A).unwrap(), m.get(vr::P_B).unwrap());
        assert!((p_a + p_b - P_SUPPLY).abs() <= 1e-12 * P_SUPPLY, "F_ext {f_ext}: {p_a} + {p_b}");
        let force = p_a * AREA_A - p_b * AREA_B + f_ext;
        assert!(force.abs() <= 1e-12 * P_SUPPLY * AREA_A, "F_ext {f_ext}: net {force} N");
        assert_eq!(m.get(vr::X_PISTON), Some(0.0));
        assert_eq!(m.get(vr::V_PISTON), Some(0.0));
    }
}

#[test]
fn at_steady_speed_the_hydraulic_force_balances_friction_and_load() {
    // Speeds around the Stribeck velocity (10 mm/s), where every friction term counts, both
    // ways and with a load either way. The falling Stribeck curve (slope down to -860 N s/m)
    // would make the motion stick-slip here with the default viscous friction (200 N s/m),
    // so it is raised to 2000 N s/m. The rest of the start transient shows as m a, taken
    // out by a central difference of v (its error, h^2/6 times the third derivative of v,
    // is far below 1e-6 N).
    let h = 1e-4;
    for (i_ref, f_ext) in [(0.07e-3, 0.0), (-0.07e-3, 0.0), (0.1e-3, -300.0), (0.1e-3, 300.0)] {
        let mut m = steady(&[("F_ext", f_ext), ("cylinder.b_viscous", B_VISCOUS)], i_ref);
        let trace = run(&mut m, 2.0 * h, h, &[vr::V_PISTON, vr::F_HYDRAULIC]);
        let (v, f_h) = (trace[1].1[0], trace[1].1[1]);
        let inertia = MASS * (trace[2].1[0] - trace[0].1[0]) / (2.0 * h);
        let residual = f_h + f_ext - friction(v) - inertia;
        let stribeck = friction(v) - F_COULOMB * (v / V_SMOOTH).tanh() - B_VISCOUS * v;
        println!(
            "i_ref {i_ref}, F_ext {f_ext}: v {v:e} m/s, friction {:.4} N (Stribeck {stribeck:.4}), m a {inertia:e}, residual {residual:e} N",
            friction(v)
        );
        assert!(stribeck.abs() > 0.3, "the Stribeck term counts: {stribeck}");
        assert!(residual.abs() <= 1e-6, "{residual} N");
    }
}

#[test]
fn at_steady_speed_the_port_flows_feed_displacement_and_leakage() {
    // Internal leakage (here B -> A: extending without load, p_B > p_A) and external leakage
    // to the drain, each several percent of the flow.
    let (c_int, c_ext) = (1.5e-12, 5e-13);
    let m = steady(&[("cylinder.C_leak", c_int), ("cylinder.C_leak_external", c_ext)], 0.3e-3);
    let get = |r| m.get(r).unwrap();
    let (v, p_a, p_b) = (get(vr::V_PISTON), get(vr::P_A), get(vr::P_B));
    let internal = c_int * (p_a - p_b);
    let into_a = AREA_A * v + internal + c_ext * p_a;
    let out_of_b = AREA_B * v + internal - c_ext * p_b;
    println!(
        "Q_A {:e} vs {into_a:e}, Q_B {:e} vs {out_of_b:e} (leak {internal:e}, {:e})",
        get(vr::Q_A),
        get(vr::Q_B),
        c_ext * p_a
    );
    assert!(internal.abs().min(c_ext * p_a) > 0.03 * get(vr::Q_A), "the leaks matter");
    // What is left is the chambers' compression as the volumes change (1e-10, as without
    // leakage); 1e-8 of the flow allows for it.
    assert!((get(vr::Q_A) - into_a).abs() <= 1e-8 * into_a.abs());
    assert!((get(vr::Q_B) - out_of_b).abs() <= 1e-8 * out_of_b.abs());
}
