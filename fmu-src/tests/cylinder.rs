//! The cylinder side and the outer loops through the Model API: the paper's flow-loop
//! figures (rows 8, 9, 11), volume balance, end stops, the position loop and cavitation.

mod scenario;

use ehsv_actuator::variables::vr;
use scenario::{first_output, model, run, settling_time};
use std::f64::consts::PI;

const AREA_A: f64 = PI / 4.0 * 0.016 * 0.016;
const P_SUPPLY: f64 = 6.8948e6;
const STROKE: f64 = 0.08;
const BETA: f64 = 1.0e9;
const V_DEAD: f64 = 2.0e-6;

fn flow_step_settling(v_supply: f64) -> f64 {
    let mut m = model(&[("control_mode", 1.0), ("V_supply", v_supply)]);
    m.set(vr::Q_REF, 2e-4).unwrap();
    settling_time(&first_output(run(&mut m, 30e-3, 1e-6, &[vr::Q_VALVE])), 2e-4, 2e-4, 0.05)
}

#[test]
fn rows_8_and_9_flow_loop_with_high_and_low_supply() {
    let high = flow_step_settling(72.0);
    let low = flow_step_settling(10.0);
    println!(
        "row 8: {:.3} ms at 72 V, row 9: {:.3} ms at 10 V ({:.0} %)",
        high * 1e3,
        low * 1e3,
        low / high * 100.0
    );
    assert!(high <= 3.6e-3, "{high}");
    assert!((5.4e-3..=6.6e-3).contains(&low), "{low}");
    assert!(low >= 1.6 * high);
}

#[test]
fn row11_steady_flow_moves_the_piston_at_q_over_area_and_volume_balances() {
    // A modest flow so the piston stays clear of the end stops for the whole run.
    let mut m = model(&[("control_mode", 1.0)]);
    let start = (m.get(vr::X_PISTON).unwrap(), m.get(vr::P_A).unwrap());
    m.set(vr::Q_REF, 2e-5).unwrap();
    let h = 1e-5;
    let trace = run(&mut m, 0.1, h, &[vr::Q_A, vr::V_PISTON, vr::X_PISTON, vr::P_A]);
    let (_, last) = trace.last().unwrap();
    let (q_a, v, x, p_a) = (last[0], last[1], last[2], last[3]);
    println!("Q_A {q_a:e}, v {v:e}, Q_A/A_A {:e}, x {x:e}", q_a / AREA_A);
    assert!(x < STROKE / 2.0 - 1e-3, "still clear of the stop: {x}");
    assert!((v - q_a / AREA_A).abs() <= 0.01 * v.abs(), "v {v} vs Q_A/A_A {}", q_a / AREA_A);
    // Trapezoidal integral of Q_A against displaced plus compressed volume of chamber A.
    let inflow: f64 =
        trace.windows(2).map(|w| 0.5 * (w[0].1[0] + w[1].1[0]) * (w[1].0 - w[0].0)).sum();
    let volume = V_DEAD + AREA_A * (x + STROKE / 2.0);
    let stored = AREA_A * (x - start.0) + volume / BETA * (p_a - start.1);
    println!("inflow {inflow:e} m3, displaced + compressed {stored:e} m3");
    assert!((inflow - stored).abs() <= 0.01 * inflow.abs());
}

#[test]
fn end_stop_holds_the_rod_and_pressure_stays_below_supply() {
    // A slow approach (1 mA: ~0.13 m/s) into the + stop; see the README on fast impacts.
    let mut m = model(&[]);
    m.set(vr::I_REF, 1e-3).unwrap();
    let trace = run(&mut m, 0.5, 1e-4, &[vr::X_PISTON, vr::P_A, vr::P_B]);
    let x_max = trace.iter().map(|s| s.1[0]).fold(f64::MIN, f64::max);
    let p_max = trace.iter().map(|s| s.1[1]).fold(f64::MIN, f64::max);
    let last = &trace.last().unwrap().1;
    println!(
        "x max {:.4} mm, p_A max {:.4} bar, final p_A {:.4} bar",
        x_max * 1e3,
        p_max * 1e-5,
        last[1] * 1e-5
    );
    assert!(x_max > STROKE / 2.0 - 1e-6, "reached the stop: {x_max}");
    assert!(x_max <= STROKE / 2.0 + 0.1e-3);
    assert!(p_max <= P_SUPPLY, "{p_max}");
    assert!(last[1] > 0.999 * P_SUPPLY, "pressure approaches supply: {}", last[1]);
}

fn position_step(f_ext: f64) -> (f64, f64) {
    let mut m = model(&[("control_mode", 2.0), ("F_ext", f_ext)]);
    m.set(vr::X_REF, 10e-3).unwrap();
    let trace = run(&mut m, 0.3, 1e-4, &[vr::X_PISTON]);
    let error = trace.last().unwrap().1[0] - 10e-3;
    (settling_time(&first_output(trace), 10e-3, 10e-3, 0.02), error)
}

#[test]
fn position_step_settles_without_error_with_and_without_load() {
    let stall = P_SUPPLY * AREA_A;
    for f_ext in [0.0, 0.3 * stall, -0.3 * stall] {
        let (settle, error) = position_step(f_ext);
        println!("F_ext {f_ext:.0} N: settles (2 %) in {:.1} ms, error {error:e} m", settle * 1e3);
        assert!(settle < 0.1, "{settle}");
        assert!(error.abs() < 1e-6, "{error}");
    }
}

#[test]
fn pressures_never_fall_below_the_cavitation_floor() {
    // An overrunning load pulled out fast by a full-open valve: chamber A empties.
    let floor = -0.9e5;
    let mut m = model(&[("F_ext", 2000.0)]);
    m.set(vr::I_REF, 10e-3).unwrap();
    let trace = run(&mut m, 0.05, 1e-5, &[vr::P_A, vr::P_B]);
    let p_min = trace.iter().map(|s| s.1[0].min(s.1[1])).fold(f64::MAX, f64::min);
    println!("lowest chamber pressure {p_min:e} Pa");
    assert!(p_min >= floor - 1.0, "{p_min}");
    assert!(p_min < floor + 1e5, "the run really approaches the floor: {p_min}");
}

#[test]
fn cylinder_does_not_depend_on_the_communication_step() {
    // Events land at arbitrary instants inside steps, so pieces of any length (down to
    // ~1e-20 s) drive the cylinder; none may make a moving piston look at rest.
    let outputs = [vr::X_PISTON, vr::V_PISTON, vr::P_A, vr::P_B];
    let traces: Vec<_> = [1e-6, 1e-5, 1e-4]
        .iter()
        .map(|&h| {
            let mut m = model(&[("control_mode", 1.0)]);
            m.set(vr::Q_REF, 2e-5).unwrap();
            run(&mut m, 0.05, h, &outputs)
        })
        .collect();
    let scales = [1e-2, 0.1, 1e6, 1e6];
    for (trace, stride) in traces[1..].iter().zip([10, 100]) {
        for (k, (t, y)) in trace.iter().enumerate() {
            let fine = &traces[0][k * stride].1;
            for o in 0..4 {
                assert!(
                    (y[o] - fine[o]).abs() <= 1e-6 * scales[o],
                    "t {t} output {o}: {} vs {}",
                    y[o],
                    fine[o]
                );
            }
        }
    }
}
