use super::*;
use crate::components::cylinder_jacobian::linearise;
use crate::components::cylinder_terms::{friction, port_flows};
use crate::components::metering_ports::AnyLap;
use crate::numerics::rosenbrock::tests::simulate;
use crate::numerics::rosenbrock::{RosenbrockMemory, STATE_SCALE};
use crate::params::CylinderLoadParams;

const P_RATED: f64 = 6.8948e6;
/// Spool opening for the rated 10 mA flow (2.5268e-4 m3/s, K3 times the spool opening).
const X_S_RATED: f64 = 2.5268e-4 / 0.664515;

fn jacobian(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
    f_ext: f64,
) -> nalgebra::Matrix4<f64> {
    let y = state.to_array();
    let f0 = derivatives::<AnyLap>(params, state, x_s, p_supply, f_ext);
    let mut jac = nalgebra::Matrix4::zeros();
    for j in 0..4 {
        let delta = 1e-7 * y[j].abs().max(STATE_SCALE[j]);
        let mut shifted = y;
        shifted[j] += delta;
        let fj = derivatives::<AnyLap>(
            params,
            &CylinderState::from_array(&shifted),
            x_s,
            p_supply,
            f_ext,
        );
        for i in 0..4 {
            jac[(i, j)] = (fj[i] - f0[i]) / delta;
        }
    }
    jac
}

#[test]
fn parameters_come_from_the_table_and_cross_checks_name_the_variable() {
    let defaults = CylinderParams::default();
    assert_eq!(
        (defaults.bore, defaults.mass, defaults.k_endstop, defaults.p_cavitation),
        (0.016, 5.0, 1e8, -0.9e5)
    );
    // Single values are checked against the table at the model boundary (model.rs tests),
    // the rules between them here.
    let bad = defaults.with_load(CylinderLoadParams { rod: 0.02, ..defaults.load });
    assert!(bad.validate().unwrap_err().contains("cylinder.rod"));
    let bad = defaults.with_load(CylinderLoadParams { p_cavitation: 1e5, ..defaults.load });
    assert!(bad.validate().unwrap_err().contains("hydraulics.p_cavitation"));
}

#[test]
fn equilibrium_start_has_zero_derivatives_and_stays_put() {
    let p = CylinderParams::default();
    let stall = p.stall_force(P_RATED);
    for f_ext in [0.0, 0.3 * stall, -0.3 * stall] {
        let s0 = equilibrium(&p, P_RATED, f_ext);
        assert!((s0.p_a + s0.p_b - P_RATED).abs() < 1e-6, "{s0:?}");
        assert!(s0.p_a > 0.0 && s0.p_a < P_RATED && s0.p_b > 0.0 && s0.p_b < P_RATED);
        let d = derivatives::<AnyLap>(&p, &s0, 0.0, P_RATED, f_ext);
        // Force residual below 1e-12 N equivalent; pressures and position exactly still.
        assert_eq!((d[0], d[1], d[2]), (0.0, 0.0, 0.0));
        assert!(d[3].abs() * p.mass < 1e-12 * stall, "{d:?}");
        let mut s = s0;
        let mut memory = RosenbrockMemory::default();
        let (stats, _) = simulate(
            &p,
            &mut s,
            &mut memory,
            &|_| 0.0,
            (P_RATED, f_ext),
            (0.0, 0.01, 1e-4),
            |_, _| {},
        );
        assert!(
            s.x.abs() < 1e-12 && (s.p_a - s0.p_a).abs() < 1e-3 && (s.p_b - s0.p_b).abs() < 1e-3,
            "{s:?}"
        );
        // Cheap at rest: after the first call's step-size ramp, one step per call.
        assert!(stats.accepted <= 100 + 10, "{stats:?}");
    }
    // Unloaded: p_A = p_S A_B/(A_A + A_B).
    let s = equilibrium(&p, P_RATED, 0.0);
    assert!((s.p_a - P_RATED * p.area_b() / (p.area_a() + p.area_b())).abs() < 1e-6);
}

#[test]
fn steady_velocity_equals_port_flow_over_area() {
    let p = CylinderParams::default();
    let mut s = equilibrium(&p, P_RATED, 0.0);
    s.x = -0.035;
    let mut memory = RosenbrockMemory::default();
    let x_s = 0.2e-3;
    simulate(&p, &mut s, &mut memory, &|_| x_s, (P_RATED, 0.0), (0.0, 0.04, 1e-4), |_, _| {});
    assert!(s.x < p.stroke / 2.0);
    let flows = port_flows::<AnyLap>(&p, [s.p_a, s.p_b], x_s, P_RATED);
    let (q_a, q_b) = (flows.q_a, flows.q_b);
    let v_a = q_a / p.area_a();
    let v_b = q_b / p.area_b();
    // Steady motion: constant pressures, no leakage, so continuity makes v = Q/A exactly
    // whatever beta or the mass; left are the decayed start transient and Rodas4's error
    // at rtol 1e-8: within 1e-9.
    assert!((s.v - v_a).abs() < 1e-9 * v_a, "v = {} vs Q_A/A_A = {v_a}", s.v);
    assert!((s.v - v_b).abs() < 1e-9 * v_b, "v = {} vs Q_B/A_B = {v_b}", s.v);
    // Independent steady state: for a speed v the port laws give p_A and p_B; bisect on
    // the force balance p_A A_A - p_B A_B = b v + friction (turbulent ports, p_T = 0).
    let half_drop = 0.5 * p.ports.dp_rated;
    let residual = |v: f64| {
        let p_a = P_RATED - half_drop * (p.area_a() * v / (p.ports.k3 * x_s)).powi(2);
        let p_b = half_drop * (p.area_b() * v / (p.ports.k3 * x_s)).powi(2);
        p_a * p.area_a() - p_b * p.area_b() - friction(&p, v).0
    };
    let (mut lo, mut hi) = (1e-3, 2.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if residual(mid) > 0.0 {
            lo = mid
        } else {
            hi = mid
        }
    }
    assert!((s.v - lo).abs() < 1e-4 * lo, "v = {} vs steady {lo}", s.v);
    // Unequal areas: Q_A is not K3 x_s even without load (about 1.28 K3 x_s; 1.19 here
    // with 180 N of friction).
    let ratio = q_a / (p.ports.k3 * x_s);
    assert!(ratio > 1.15 && ratio < 1.3, "Q_A/(K3 x_s) = {ratio}");
}

#[test]
fn volume_balance_of_chamber_a() {
    // integral Q_A dt = A_A dx + integral V_A/beta dp_A (trapezoid on 10 us samples).
    let p = CylinderParams::default();
    let s0 = equilibrium(&p, P_RATED, 0.0);
    let mut s = s0;
    let mut memory = RosenbrockMemory::default();
    let x_s = |t: f64| 0.2e-3 * (1.0 - (-t / 2e-3).exp());
    let volume_a = |s: &CylinderState| p.v_dead + p.area_a() * (s.x + p.stroke / 2.0);
    let (mut inflow, mut compressed) = (0.0, 0.0);
    let mut prev = (0.0, s0, port_flows::<AnyLap>(&p, [s0.p_a, s0.p_b], x_s(0.0), P_RATED).q_a);
    simulate(&p, &mut s, &mut memory, &x_s, (P_RATED, 0.0), (0.0, 0.03, 1e-5), |t, s| {
        let q = port_flows::<AnyLap>(&p, [s.p_a, s.p_b], x_s(t), P_RATED).q_a;
        inflow += 0.5 * (q + prev.2) * (t - prev.0);
        compressed += 0.5 * (volume_a(s) + volume_a(&prev.1)) / p.beta * (s.p_a - prev.1.p_a);
        prev = (t, *s, q);
    });
    let displaced = p.area_a() * (s.x - s0.x);
    let residual = inflow - displaced - compressed;
    // Exact in the equations: only the trapezoids on the 10 us samples of the 2 ms spool
    // ramp remain: within 1e-6.
    assert!(
        residual.abs() < 1e-6 * inflow.abs(),
        "in {inflow}, displaced {displaced}, compressed {compressed}"
    );
    assert!(compressed.abs() > 1e-9, "the test should see compression: {compressed}");
}

/// A slow approach (0.2 m/s impact) presses on the stop with p_A rising to p_S from below.
/// Faster impacts rebound off the stop and the returning piston compresses chamber A above
/// supply (oil flows back into the supply port): +97 kPa at 0.4 m/s, +437 kPa at 0.78 m/s,
/// the same at rtol 1e-8 and 1e-11, so this is the model's physics (a stop without
/// cushioning), not integration error. Those cases check the bounds that do hold.
#[test]
fn end_stop_holds_the_rod_and_pressure_stays_below_supply() {
    let p = CylinderParams::default();
    let stall = p.stall_force(P_RATED);
    let static_penetration = stall / p.k_endstop;
    for x_s in [0.05e-3, 0.1e-3, 0.2e-3] {
        let mut s = equilibrium(&p, P_RATED, 0.0);
        let mut memory = RosenbrockMemory::default();
        let (mut x_max, mut p_a_max, mut v_impact) = (f64::MIN, f64::MIN, 0.0);
        let t_end = 0.1 * 0.1e-3 / x_s + 0.05;
        simulate(&p, &mut s, &mut memory, &|_| x_s, (P_RATED, 0.0), (0.0, t_end, 1e-5), |_, s| {
            if x_max < p.stroke / 2.0 {
                v_impact = s.v;
            }
            x_max = x_max.max(s.x);
            p_a_max = p_a_max.max(s.p_a);
        });
        let penetration_max = x_max - p.stroke / 2.0;
        assert!(penetration_max > 0.0, "x_s {x_s}: never reached the stop: {x_max}");
        // Energy bound with the stall force still pushing: k d^2/2 <= m v^2/2 + F d.
        let bound = static_penetration
            + (static_penetration.powi(2) + p.mass * v_impact * v_impact / p.k_endstop).sqrt();
        assert!(penetration_max <= bound, "x_s {x_s}: {penetration_max} > {bound}");
        if x_s <= 0.1e-3 {
            assert!(penetration_max <= 1e-4, "x_s {x_s}: x_max = {x_max}");
        }
        if x_s <= 0.05e-3 {
            assert!(p_a_max <= P_RATED, "x_s {x_s}: p_A max {p_a_max}");
        } else {
            assert!(p_a_max <= 1.1 * P_RATED, "x_s {x_s}: p_A max {p_a_max}");
        }
        // Settled: A at supply, B at tank, pressed in by the stall force: d = p_S A_A / k.
        assert!((s.p_a - P_RATED).abs() < 1e-6 * P_RATED && s.p_b.abs() < 1e-6 * P_RATED, "{s:?}");
        let penetration = s.x - p.stroke / 2.0;
        assert!(
            (penetration - static_penetration).abs() < 1e-3 * static_penetration,
            "{penetration}"
        );
    }
}

#[test]
fn overrunning_load_never_pulls_pressure_below_the_cavitation_floor() {
    let p = CylinderParams::default();
    let f_ext = -6000.0; // pulls the rod in, faster than supply can fill B
    let mut s = equilibrium(&p, P_RATED, 0.0);
    let mut memory = RosenbrockMemory::default();
    let mut p_min = f64::MAX;
    let mut time_at_floor = 0.0;
    let (stats, _) = simulate(
        &p,
        &mut s,
        &mut memory,
        &|_| -0.5e-3,
        (P_RATED, f_ext),
        (0.0, 0.05, 1e-4),
        |_, s| {
            p_min = p_min.min(s.p_a).min(s.p_b);
            if s.p_b < p.p_cavitation + 0.01 * p.dp_cavitation_band {
                time_at_floor += 1e-4;
            }
        },
    );
    assert!(p_min >= p.p_cavitation, "p_min = {p_min}");
    assert!(
        time_at_floor > 1e-3,
        "the case must actually cavitate: {time_at_floor} s at the floor"
    );
    // The floor holds in the ODE itself, not only by the post-step clamp.
    assert!(stats.floor_clamp < 1.0, "clamped by {} Pa", stats.floor_clamp);
    assert!(s.x < -p.stroke / 2.0 + 1e-4 && s.x > -p.stroke / 2.0 - 1e-3, "{s:?}");
}

#[test]
fn jacobian_eigenvalues() {
    let p = CylinderParams::default();
    let rest = equilibrium(&p, P_RATED, 0.0);
    let mut moving = rest;
    let mut memory = RosenbrockMemory::default();
    simulate(
        &p,
        &mut moving,
        &mut memory,
        &|_| X_S_RATED,
        (P_RATED, 0.0),
        (0.0, 0.02, 1e-4),
        |_, _| {},
    );
    let mut at_stop = rest;
    let mut memory = RosenbrockMemory::default();
    simulate(
        &p,
        &mut at_stop,
        &mut memory,
        &|_| 0.2e-3,
        (P_RATED, 0.0),
        (0.0, 0.1, 1e-4),
        |_, _| {},
    );
    let cases = [
        ("at rest, x_s = 0", rest, 0.0),
        ("at rest, x_s = 1 um", rest, 1e-6),
        ("moving at rated flow", moving, X_S_RATED),
        ("held at the end stop, x_s = 0.2 mm", at_stop, 0.2e-3),
        ("at the stop, valve closed", at_stop, 0.0),
        (
            "impact: 50 um into the stop at 0.5 m/s",
            CylinderState { x: p.stroke / 2.0 + 5e-5, v: 0.5, ..moving },
            X_S_RATED,
        ),
        (
            "near supply, laminar port (p_S - p_A = 1 bar)",
            CylinderState { p_a: P_RATED - 1e5, ..rest },
            1e-3,
        ),
    ];
    let mut stiffest = [0.0; 7];
    for (k, (name, s, x_s)) in cases.iter().enumerate() {
        let eig = jacobian(&p, s, *x_s, P_RATED, 0.0).complex_eigenvalues();
        let text: Vec<String> = eig.iter().map(|l| format!("{:.3e}{:+.3e}i", l.re, l.im)).collect();
        println!("{name:40} x = {:+.4} v = {:+.3}: {}", s.x, s.v, text.join(", "));
        stiffest[k] = eig.iter().map(|l| l.norm()).fold(0.0, f64::max);
        assert!(eig.iter().all(|l| l.re < 1e3), "no fast growing mode: {text:?}");
    }
    // Stiff where it matters: friction at rest, end-stop contact and laminar port at the stop.
    assert!(stiffest[0] > 1e4 && stiffest[3] > 1e4, "{stiffest:?}");
}

/// The analytic linearisation against central differences of `derivatives`, in scaled
/// variables (`J_ij scale_j / scale_i`), at points away from the kinks but inside every
/// region of the piecewise laws.
#[test]
fn analytic_jacobian_matches_finite_differences() {
    let p = CylinderParams::default();
    let rest = equilibrium(&p, P_RATED, 0.0);
    let half = p.stroke / 2.0;
    let band = p.p_cavitation + 0.3 * p.dp_cavitation_band;
    let cases = [
        (
            "moving at rated flow",
            CylinderState { x: 0.01, v: 1.2, p_a: 5.0e6, p_b: 2.0e6 },
            X_S_RATED,
            0.0,
        ),
        (
            "retracting, x_s < 0",
            CylinderState { x: -0.01, v: -0.8, p_a: 1.0e6, p_b: 4.0e6 },
            -1e-4,
            300.0,
        ),
        (
            "laminar port near supply (0.4 bar)",
            CylinderState { p_a: P_RATED - 0.4e5, ..rest },
            1e-3,
            0.0,
        ),
        (
            "laminar port at tank, x_s < 0 (0.3 bar)",
            CylinderState { p_a: 0.3e5, ..rest },
            -2e-4,
            0.0,
        ),
        (
            "B emptying in the cavitation band",
            CylinderState { p_b: band, v: -0.3, x: -0.02, p_a: 1e6 },
            -0.5e-3,
            -6000.0,
        ),
        (
            "A emptying in the cavitation band",
            CylinderState { p_a: band, v: 0.3, x: 0.02, p_b: 1e6 },
            0.5e-3,
            6000.0,
        ),
        (
            "impact on the + stop (50 um, 0.5 m/s)",
            CylinderState { x: half + 5e-5, v: 0.5, ..rest },
            X_S_RATED,
            0.0,
        ),
        (
            "pressed on the + stop",
            CylinderState { x: half + 1.4e-5, v: 1e-6, p_a: P_RATED - 10.0, p_b: 10.0 },
            0.2e-3,
            0.0,
        ),
        (
            "impact on the - stop (30 um, -0.4 m/s)",
            CylinderState { x: -half - 3e-5, v: -0.4, ..rest },
            -X_S_RATED,
            0.0,
        ),
        ("friction near v = 0 (+30 um/s)", CylinderState { v: 3e-5, ..rest }, 1e-6, 0.0),
        ("friction near v = 0 (-80 um/s)", CylinderState { v: -8e-5, ..rest }, -3e-6, 50.0),
        ("Stribeck region (5 mm/s)", CylinderState { v: 5e-3, ..rest }, 1e-5, 0.0),
        ("with leakage", CylinderState { v: 0.1, ..rest }, 1e-4, 0.0),
        (
            "relief of A opening (0.3 of the override above cracking)",
            CylinderState { p_a: p.relief_p_crack + 0.3 * p.relief_dp_override, v: -1.0, ..rest },
            X_S_RATED,
            0.0,
        ),
        (
            "relief of B beyond its override",
            CylinderState { p_b: p.relief_p_crack + 1.7 * p.relief_dp_override, v: 1.2, ..rest },
            -X_S_RATED,
            0.0,
        ),
    ];
    let leaky = p.with_load(CylinderLoadParams { c_leak: 1e-12, c_leak_external: 3e-13, ..p.load });
    for (name, s, x_s, f_ext) in cases {
        let params = if name == "with leakage" { leaky } else { p };
        let y = s.to_array();
        let (f, jac, f_xs) = linearise::<AnyLap>(&params, &y, x_s, P_RATED, f_ext);
        assert_eq!(
            f,
            derivatives::<AnyLap>(&params, &s, x_s, P_RATED, f_ext),
            "{name}: f differs from derivatives()"
        );
        let mut worst: f64 = 0.0;
        for j in 0..4 {
            let delta = 1e-7 * STATE_SCALE[j];
            let (mut up, mut down) = (y, y);
            up[j] += delta;
            down[j] -= delta;
            let f_up = derivatives::<AnyLap>(
                &params,
                &CylinderState::from_array(&up),
                x_s,
                P_RATED,
                f_ext,
            );
            let f_down = derivatives::<AnyLap>(
                &params,
                &CylinderState::from_array(&down),
                x_s,
                P_RATED,
                f_ext,
            );
            for i in 0..4 {
                let fd = (f_up[i] - f_down[i]) / (2.0 * delta) * STATE_SCALE[j] / STATE_SCALE[i];
                let an = jac[i][j] * STATE_SCALE[j] / STATE_SCALE[i];
                let row: f64 = (0..4)
                    .map(|c| (jac[i][c] * STATE_SCALE[c] / STATE_SCALE[i]).abs())
                    .fold(0.0, f64::max);
                let e = (an - fd).abs() / (an.abs() + row);
                worst = worst.max(e);
                assert!(
                    e < 1e-6,
                    "{name}: J[{i}][{j}] analytic {} vs difference {}",
                    jac[i][j],
                    fd * STATE_SCALE[i] / STATE_SCALE[j]
                );
            }
        }
        let dx = 1e-7 * x_s.abs().max(1e-5);
        let (f_up, f_down) = (
            derivatives::<AnyLap>(&params, &s, x_s + dx, P_RATED, f_ext),
            derivatives::<AnyLap>(&params, &s, x_s - dx, P_RATED, f_ext),
        );
        for i in 0..4 {
            let fd = (f_up[i] - f_down[i]) / (2.0 * dx);
            assert!(
                (f_xs[i] - fd).abs()
                    <= 1e-6 * fd.abs().max(1e-3 * f_xs[0].abs().max(f_xs[1].abs())),
                "{name}: df/dx_s[{i}] {} vs {fd}",
                f_xs[i]
            );
        }
        println!("{name:42} largest scaled Jacobian difference {worst:.1e}");
    }
}

#[test]
fn relief_flow_opens_smoothly_to_rated_flow_at_crack_plus_override() {
    let p = CylinderParams::default();
    let (crack, over, rated) = (p.relief_p_crack, p.relief_dp_override, p.relief_q_rated);
    // Shut up to the cracking pressure (and so in every state the supply can produce).
    assert_eq!(relief_flow(&p, crack), (0.0, 0.0));
    assert!(crack > P_RATED, "set above the supply");
    assert_eq!(relief_flow(&p, crack + over).0, rated);
    // C1 at both joints: value and slope continuous.
    for joint in [crack, crack + over] {
        let (below, above) = (relief_flow(&p, joint - 1e-3), relief_flow(&p, joint + 1e-3));
        assert!((above.0 - below.0).abs() < 1e-6 * rated, "{joint}");
        assert!((above.1 - below.1).abs() < 1e-6 * rated / over, "{joint}");
    }
    // The slope is the derivative of the flow.
    for p_chamber in [crack + 0.4 * over, crack + 2.5 * over] {
        let d = 1.0;
        let fd = (relief_flow(&p, p_chamber + d).0 - relief_flow(&p, p_chamber - d).0) / (2.0 * d);
        assert!((relief_flow(&p, p_chamber).1 - fd).abs() < 1e-9 * fd, "{p_chamber}");
    }
    // 0 removes the valves.
    let none = p.with_load(CylinderLoadParams { relief_p_crack: 0.0, ..p.load });
    assert_eq!(relief_flow(&none, 1e9), (0.0, 0.0));
    // In the equations: a sealed chamber above cracking loses exactly the relief flow.
    let s = CylinderState { p_a: crack + over, ..equilibrium(&p, P_RATED, 0.0) };
    let volume_a = p.v_dead + p.area_a() * p.stroke / 2.0;
    let d = derivatives::<AnyLap>(&p, &s, 0.0, P_RATED, 0.0);
    assert!((d[PA] + p.beta / volume_a * rated).abs() < 1e-12 * d[PA].abs(), "{d:?}");
}

#[test]
fn check_inside_refuses_the_volume_clamp_and_names_the_chamber() {
    let p = CylinderParams::default();
    let half = p.stroke / 2.0;
    let s = equilibrium(&p, P_RATED, 0.0);
    // Deep in a stop but with dead volume left: fine.
    let depth_a = p.v_dead / p.area_a();
    assert!(check_inside(&p, &CylinderState { x: -half - 0.99 * depth_a, ..s }).is_ok());
    let e = check_inside(&p, &CylinderState { x: -half - depth_a, ..s }).unwrap_err();
    assert!(e.contains("chamber A") && e.contains("step refused"), "{e}");
    let depth_b = p.v_dead / p.area_b();
    let e = check_inside(&p, &CylinderState { x: half + depth_b, ..s }).unwrap_err();
    assert!(e.contains("chamber B"), "{e}");
    assert!(check_inside(&p, &CylinderState { x: f64::NAN, ..s }).is_err());
}

#[test]
fn supply_at_or_above_the_relief_setting_is_refused() {
    let p = CylinderParams::default();
    assert!(p.check_supply(P_RATED).is_ok());
    let e = p.check_supply(p.relief_p_crack).unwrap_err();
    assert!(e.contains("relief.p_crack"), "{e}");
    assert!(p
        .with_load(CylinderLoadParams { relief_p_crack: 0.0, ..p.load })
        .check_supply(1e8)
        .is_ok());
}

#[test]
fn friction_shortcuts_give_the_bits_of_the_full_formula() {
    // The friction law as written in the module docs and its slope, every term through libm.
    let full = |p: &CylinderParams, v: f64| {
        let stribeck = (v / p.v_stribeck).powi(2);
        let excess = p.f_static - p.f_coulomb;
        let decay = (-stribeck).exp();
        let dry = p.f_coulomb + excess * decay;
        let ddry_dv = excess * decay * (-2.0 * v / (p.v_stribeck * p.v_stribeck));
        let th = (v / p.v_friction_smooth).tanh();
        let slope = ddry_dv * th + dry * (1.0 - th * th) / p.v_friction_smooth + p.b_viscous;
        (dry * th + p.b_viscous * v, slope)
    };
    let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
    let defaults = CylinderParams::default();
    let load = |f_coulomb: f64, f_static: f64, b_viscous: f64| {
        defaults.with_load(CylinderLoadParams { f_coulomb, f_static, b_viscous, ..defaults.load })
    };
    // Defaults, no Coulomb part (the exact-Coulomb shortcut must not apply), a Stribeck peak
    // far above the Coulomb level, friction falling below it, no viscous part (the slope's
    // shortcut must not apply), a viscous slope just large enough for it (the decayed
    // part's slope within a factor 1.3 of a quarter of its ulp), and one too small, whose
    // bits the decayed part's slope moves.
    let cases = [
        defaults,
        load(0.0, 30.0, 200.0),
        load(1e-3, 3e4, 0.0),
        load(40.0, 20.0, 0.0),
        load(20.0, 30.0, 0.06),
        load(20.0, 30.0, 3.5e-3),
    ];
    for p in &cases {
        // Speeds across every cut-off (tanh saturating, the Stribeck tail, exp underflow),
        // densely around them, both signs.
        let mut speeds = vec![0.0, 1e-9, f64::INFINITY];
        let mut v = 1e-7;
        while v < 10.0 {
            speeds.push(v);
            v *= 1.0007;
        }
        for cut in
            [22.0 * p.v_friction_smooth, 50f64.sqrt() * p.v_stribeck, 750f64.sqrt() * p.v_stribeck]
        {
            for k in -50..=50 {
                speeds.push(f64::from_bits((cut.to_bits() as i64 + k) as u64));
            }
        }
        for v in speeds.iter().flat_map(|&v| [v, -v]) {
            let ((force, slope), (full_force, full_slope)) = (friction(p, v), full(p, v));
            assert!(same(force, full_force), "v = {v:e}, {p:?}: {force:e} vs {full_force:e}");
            assert!(same(slope, full_slope), "v = {v:e}, {p:?}: {slope:e} vs {full_slope:e}");
        }
    }
}

/// A fixed step that nearly closes the P -> A edge's drop (chamber A rising into the
/// supply's pressure) sees that edge by its secant, steeper than its tangent at the start,
/// by exactly the difference of the two; a step that moves the pressure by a small share
/// of the drop keeps the tangent.
#[test]
fn a_step_into_the_supply_pressure_sees_the_port_by_its_secant() {
    use crate::components::cylinder_jacobian::{linearisation, motion_row, secant_ports};
    let params = CylinderParams::default();
    let y = [P_RATED - 2e5, 1e6, 0.0, 0.0];
    let (h, x_s) = (5e-5, X_S_RATED);
    let motion = motion_row(&params, &y, 0.0, friction(&params, 0.0));
    let at_rate = |rate: f64| {
        let mut l = linearisation::<AnyLap>(&params, &y, x_s, P_RATED, &motion);
        l.rates[PA] = rate;
        let tangent = l.d_pa[PA];
        secant_ports::<AnyLap>(&params, (&y, x_s), P_RATED, h, &mut l);
        (tangent, l.d_pa[PA])
    };
    // Through the supply's pressure: 5e5 Pa over the step against a 2e5 Pa drop.
    let (tangent, secant) = at_rate(1e10);
    let p1 = y[PA] + h * 1e10;
    let (q0, q1) = (
        port_flows::<AnyLap>(&params, [y[PA], y[PB]], x_s, P_RATED),
        port_flows::<AnyLap>(&params, [p1, y[PB]], x_s, P_RATED),
    );
    let (volume_a, _) = free_volumes(&params, 0.0);
    let expected =
        tangent + params.beta / volume_a * ((q1.q_a - q0.q_a) / (p1 - y[PA]) - q0.dqa_dpa);
    assert!(secant < tangent, "{secant} {tangent}");
    assert!((secant - expected).abs() <= 1e-12 * expected.abs(), "{secant} {expected}");
    // 5e3 Pa over the step: the square root is close to its tangent there.
    let (tangent, kept) = at_rate(1e8);
    assert_eq!(kept, tangent);
}
