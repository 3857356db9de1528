//! solver.method = fixed_cost against the exact method: accuracy on the well-conditioned
//! workloads, stability on the hard ones, independence of the communication step, and the
//! order of convergence as the internal step shrinks (docs/solvers.md).

mod scenario;

use ehsv_actuator::model::Model;
use ehsv_actuator::variables::vr;
use scenario::{control_mode, driver, enum_value, model};

const OUTPUTS: [usize; 6] = [vr::I_COIL, vr::U_DRIVER, vr::Q_VALVE, vr::P_A, vr::P_B, vr::X_PISTON];

fn method(name: &str) -> (&'static str, f64) {
    ("solver.method", enum_value("SolverMethod", name))
}

/// The input set before each step, from the time.
type Input<'a> = dyn Fn(f64) -> (usize, f64) + 'a;

fn sine(hz: f64, amplitude: f64) -> impl Fn(f64) -> f64 {
    move |t| amplitude * (2.0 * std::f64::consts::PI * hz * t).sin()
}

/// The outputs after each step of `h` over `duration`, `input` set from the time.
fn trace(
    m: &mut Model,
    duration: f64,
    h: f64,
    input: &dyn Fn(f64) -> (usize, f64),
) -> Vec<[f64; 6]> {
    let n = (duration / h).round() as usize;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let (vr, value) = input(m.time());
        m.set(vr, value).unwrap();
        m.do_step(m.time(), h).unwrap();
        out.push(OUTPUTS.map(|o| m.get(o).unwrap()));
    }
    out
}

/// Each output's largest difference over its range in the reference.
fn errors(reference: &[[f64; 6]], other: &[[f64; 6]]) -> [f64; 6] {
    std::array::from_fn(|k| {
        let (lo, hi) =
            reference.iter().fold((f64::MAX, f64::MIN), |(lo, hi), s| (lo.min(s[k]), hi.max(s[k])));
        let range = (hi - lo).max(1e-30);
        let (worst, _) = reference
            .iter()
            .zip(other)
            .enumerate()
            .map(|(n, (a, b))| ((a[k] - b[k]).abs(), n))
            .fold((0.0, 0), |m, x| if x.0 > m.0 { x } else { m });
        worst / range
    })
}

fn show(e: &[f64; 6]) -> String {
    e.iter().map(|x| format!("{x:.1e}")).collect::<Vec<_>>().join(" ")
}

fn compare(
    settings: &[(&str, f64)],
    duration: f64,
    h: f64,
    input: &dyn Fn(f64) -> (usize, f64),
) -> [f64; 6] {
    let fixed: Vec<_> = settings.iter().copied().chain([method("fixed_cost")]).collect();
    compare_with(settings, &fixed, duration, h, input)
}

/// Each output's largest error over its range, the `other` settings against the
/// `reference` ones, both stepped at `h`.
fn compare_with(
    reference: &[(&str, f64)],
    other: &[(&str, f64)],
    duration: f64,
    h: f64,
    input: &dyn Fn(f64) -> (usize, f64),
) -> [f64; 6] {
    let expected = trace(&mut model(reference), duration, h, input);
    errors(&expected, &trace(&mut model(other), duration, h, input))
}

/// Driver, coil and valve (the first three outputs) go by exact propagators between
/// boundaries: on every linear driver within 1e-5 of their range (the sines' command
/// changes every step: the op-amp's brief slews taken as jumps with their volt-seconds
/// made good; the squares' slews reach the rails, those mode changes placed by
/// interpolation). At the default internal step (50 us) the piston is
/// within 1e-3 of its range and the pressures within 1e-2 on the 2 Hz waves (which drive the
/// piston into its end stops) and the 20 Hz sines; the 20 Hz squares' pressure spikes, a
/// chamber emptied onto the cavitation floor at every reversal, within 2.5e-2
/// (docs/solvers.md: 25 us brings them within 1e-2).
#[test]
fn fixed_cost_follows_exact_on_sines_and_squares() {
    for kind in ["ideal_current", "voltage", "opamp_pi", "industrial"] {
        for hz in [2.0, 20.0] {
            let s = sine(hz, 5e-3);
            let sq = |t: f64| (vr::I_REF, if s(t) >= 0.0 { 5e-3 } else { -5e-3 });
            let runs: [(&str, &Input<'_>); 2] = [("sine", &|t| (vr::I_REF, s(t))), ("square", &sq)];
            for (shape, input) in runs {
                let e = compare(&[driver(kind)], 0.2, 1e-4, input);
                let case = format!("{kind} {shape} {hz} Hz: {}", show(&e));
                println!("{case}");
                assert!(e[..3].iter().all(|&x| x < 1e-5), "{case}");
                assert!(e[5] < 1e-3, "{case}");
                let pressures = if hz > 10.0 && shape == "square" { 2.5e-2 } else { 1e-2 };
                assert!(e[3] < pressures && e[4] < pressures, "{case}");
            }
        }
    }
}

/// The loops: every output within 5e-3 of its range (the position loop's piston within
/// 1e-5).
#[test]
fn fixed_cost_follows_exact_in_the_loops() {
    let s = sine(5.0, 2e-4);
    let flow =
        compare(&[driver("opamp_pi"), control_mode("flow")], 0.4, 1e-4, &|t| (vr::Q_REF, s(t)));
    println!("flow loop: {}", show(&flow));
    let s = sine(2.0, 0.01);
    let position =
        compare(&[driver("opamp_pi"), control_mode("position")], 1.0, 1e-4, &|t| (vr::X_REF, s(t)));
    println!("position loop: {}", show(&position));
    assert!(position[5] < 1e-5, "{}", show(&position));
    // The flow loop samples the valve alone: driver, coil and valve as exact as the brief
    // slews of its samples, taken as jumps, let them be.
    assert!(flow[..3].iter().all(|&x| x < 1e-5), "{}", show(&flow));
    for e in [flow, position] {
        assert!(e.iter().all(|&x| x < 5e-3), "{}", show(&e));
    }
}

/// The H-bridge in fixed_cost gives each PWM period its mean voltage: the coil current
/// within 1e-5 of its range of exact's (which switches the coil between the rails, its
/// ripple a few uA at 20 kHz), the valve's flow and the piston within 5e-4, the pressures
/// within 2e-2. Its u_driver is that mean, between the rails, where exact's at every
/// communication point (a period's start, the centred PWM's low side) is -V_supply; the
/// mean holds the current against the coil's resistance (`R i`, within the `L di/dt` of
/// the 5 Hz sine, under 1 V).
#[test]
fn fixed_cost_takes_the_h_bridge_by_its_periods_means() {
    let s = sine(5.0, 5e-3);
    let input = |t: f64| (vr::I_REF, s(t));
    let settings = [driver("hbridge_pid")];
    let exact = trace(&mut model(&settings), 0.2, 1e-4, &input);
    let mean = trace(&mut model(&[driver("hbridge_pid"), method("fixed_cost")]), 0.2, 1e-4, &input);
    let e = errors(&exact, &mean);
    println!("hbridge: {}", show(&e));
    assert!(e[0] < 1e-5 && e[2] < 5e-4 && e[5] < 5e-4, "{}", show(&e));
    assert!(e[3] < 2e-2 && e[4] < 2e-2, "{}", show(&e));
    let (rail, resistance) = (72.0, 1000.0);
    assert!(exact.iter().all(|o| o[1] == -rail), "exact's bridge at a period's start");
    for o in &mean {
        assert!(o[1].abs() < rail && (o[1] - resistance * o[0]).abs() < 1.0, "{o:?}");
    }
}

/// The outputs' largest error over their range, fixed_cost with internal steps of at most
/// `h_internal` against exact at `solver.rtol` 1e-10, both stepped at 1e-4 s.
fn error_at_internal_step(kind: &str, h_internal: f64) -> [f64; 6] {
    let s = sine(20.0, 5e-3);
    let fixed = [driver(kind), method("fixed_cost"), ("solver.h_internal", h_internal)];
    let tight = [driver(kind), ("solver.rtol", 1e-10)];
    compare_with(&tight, &fixed, 0.1, 1e-4, &|t| (vr::I_REF, s(t)))
}

/// Shrinking `solver.h_internal` 16-fold, from 25 to 1.5625 us, makes the pressures and the
/// position more than 100 times more accurate together (the trapezoidal step's second
/// order promises 256) and each of them more accurate, against a tight exact run.
#[test]
fn fixed_cost_converges_as_the_internal_step_shrinks() {
    let steps = [2.5e-5, 1.25e-5, 6.25e-6, 3.125e-6, 1.5625e-6];
    let errors: Vec<[f64; 6]> =
        steps.iter().map(|&h| error_at_internal_step("opamp_pi", h)).collect();
    let worst = |e: &[f64; 6]| e[3..].iter().cloned().fold(0.0, f64::max);
    for k in [3, 4, 5] {
        let row: Vec<String> = errors.iter().map(|e| format!("{:.1e}", e[k])).collect();
        println!("output {k} at {steps:?} s: {}", row.join(" "));
        assert!(errors[4][k] < errors[0][k], "output {k}: {}", row.join(" "));
    }
    let gain = worst(&errors[0]) / worst(&errors[4]);
    println!("the worst of them {gain:.1} times more accurate at 1.5625 us");
    assert!(gain > 100.0, "{gain}");
}

/// The same run with the communication step 1e-4 and 5e-5 (both multiples of the internal
/// step, 25 us and 50 us): the same internal grid, the same results to rounding.
#[test]
fn fixed_cost_does_not_depend_on_the_communication_step() {
    let s = sine(20.0, 5e-3);
    let command = |t: f64| (vr::I_REF, s((t / 1e-4 + 1e-6).floor() * 1e-4));
    for h_internal in [25e-6, 50e-6] {
        let settings =
            [driver("opamp_pi"), method("fixed_cost"), ("solver.h_internal", h_internal)];
        let coarse = trace(&mut model(&settings), 0.1, 1e-4, &command);
        let fine: Vec<_> = trace(&mut model(&settings), 0.1, 5e-5, &command)
            .into_iter()
            .skip(1)
            .step_by(2)
            .collect();
        let e = errors(&coarse, &fine);
        println!("h_internal {h_internal:e}, 1e-4 against 5e-5: {}", show(&e));
        assert!(e.iter().all(|&x| x < 1e-9), "{}", show(&e));
    }
}

/// Long runs stay bounded: 2 s of 100 Hz squares (impacts of the spool, pressure
/// transients at every reversal) keep the pressures inside the relief envelope and the
/// piston inside its travel.
#[test]
fn fixed_cost_stays_bounded_on_hard_workloads() {
    let mut m = model(&[driver("opamp_pi"), method("fixed_cost")]);
    let square =
        |t: f64| (vr::I_REF, if (200.0 * t).floor() as i64 % 2 == 0 { 10e-3 } else { -10e-3 });
    let run = trace(&mut m, 2.0, 1e-4, &square);
    let p_max = run.iter().map(|s| s[3].max(s[4])).fold(f64::MIN, f64::max);
    let p_min = run.iter().map(|s| s[3].min(s[4])).fold(f64::MAX, f64::min);
    println!("pressures {p_min:e} .. {p_max:e}");
    let floor = scenario::start(vr::HYDRAULICS_P_CAVITATION);
    let ceiling = scenario::start(vr::RELIEF_P_CRACK) + scenario::start(vr::RELIEF_DP_OVERRIDE);
    assert!(p_max < ceiling && p_min >= floor, "{p_min} {p_max}");
}

/// A saved fixed_cost instance continues bit for bit from its restored state (the method
/// is a parameter, saved with the rest; its propagators are a cache).
#[test]
fn a_restored_fixed_cost_instance_continues_bit_for_bit() {
    let s = sine(20.0, 5e-3);
    let command = |t: f64| (vr::I_REF, s(t));
    let mut m = model(&[driver("opamp_pi"), method("fixed_cost")]);
    trace(&mut m, 0.05, 1e-4, &command);
    let mut restored = Model::from_bytes(&m.to_bytes()).unwrap();
    assert_eq!(restored.get(vr::SOLVER_METHOD), Some(1.0));
    assert_eq!(trace(&mut m, 0.05, 1e-4, &command), trace(&mut restored, 0.05, 1e-4, &command));
}

/// A retune that rebuilds the driver's systems (a new `driver.Kp`) builds their propagators
/// in the setter, as initialisation does: the doSteps after it build none (the work counter
/// of matrix exponentials stands still over them, on a sine whose slews visit the modes).
#[test]
fn a_retune_builds_its_propagators_ahead() {
    let s = sine(20.0, 5e-3);
    let mut m = model(&[driver("opamp_pi"), method("fixed_cost")]);
    let input = |t: f64| (vr::I_REF, s(t));
    trace(&mut m, 0.05, 1e-4, &input);
    let kp = vr::DRIVER_KP;
    m.set(kp, 1.2 * m.get(kp).unwrap()).unwrap();
    let built = m.work().exponentials;
    trace(&mut m, 0.1, 1e-4, &input);
    assert_eq!(m.work().exponentials, built, "exponentials built in doSteps after the retune");
}
