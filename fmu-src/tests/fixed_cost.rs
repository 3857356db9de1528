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

/// A command that drives a run: the input set before each step from the time.
type Command = fn(f64) -> (usize, f64);

fn sine(hz: f64, amplitude: f64) -> impl Fn(f64) -> f64 {
    move |t| amplitude * (2.0 * std::f64::consts::PI * hz * t).sin()
}

/// The outputs after each step of `h` over `duration`, `input` set from the time.
fn trace(m: &mut Model, duration: f64, h: f64, input: &dyn Fn(f64) -> (usize, f64)) -> Vec<[f64; 6]> {
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
        let (lo, hi) = reference.iter().fold((f64::MAX, f64::MIN), |(lo, hi), s| (lo.min(s[k]), hi.max(s[k])));
        let range = (hi - lo).max(1e-30);
        reference.iter().zip(other).map(|(a, b)| (a[k] - b[k]).abs()).fold(0.0, f64::max) / range
    })
}

fn show(e: &[f64; 6]) -> String {
    e.iter().map(|x| format!("{x:.1e}")).collect::<Vec<_>>().join(" ")
}

fn compare(settings: &[(&str, f64)], duration: f64, h: f64, input: &dyn Fn(f64) -> (usize, f64)) -> [f64; 6] {
    let mut exact = model(settings);
    let fixed_settings: Vec<_> = settings.iter().copied().chain([method("fixed_cost")]).collect();
    let mut fixed = model(&fixed_settings);
    let reference = trace(&mut exact, duration, h, input);
    errors(&reference, &trace(&mut fixed, duration, h, input))
}

#[test]
fn fixed_cost_follows_exact_on_sines_and_squares() {
    let drivers = ["ideal_current", "voltage", "opamp_pi", "industrial"];
    for kind in drivers {
        for hz in [2.0, 20.0] {
            let s = sine(hz, 5e-3);
            let e = compare(&[driver(kind)], 0.2, 1e-4, &|t| (vr::I_REF, s(t)));
            println!("{kind} sine {hz} Hz: {}", show(&e));
            let sq = move |t: f64| (vr::I_REF, if s(t) >= 0.0 { 5e-3 } else { -5e-3 });
            let e = compare(&[driver(kind)], 0.2, 1e-4, &sq);
            println!("{kind} square {hz} Hz: {}", show(&e));
        }
    }
}

#[test]
fn fixed_cost_follows_exact_in_the_loops() {
    let s = sine(5.0, 2e-4);
    let e = compare(&[driver("opamp_pi"), control_mode("flow")], 0.4, 1e-4, &|t| (vr::Q_REF, s(t)));
    println!("flow loop: {}", show(&e));
    let s = sine(2.0, 0.01);
    let e = compare(&[driver("opamp_pi"), control_mode("position")], 1.0, 1e-4, &|t| (vr::X_REF, s(t)));
    println!("position loop: {}", show(&e));
    let s = sine(5.0, 5e-3);
    let e = compare(&[driver("hbridge_pid")], 0.2, 1e-4, &|t| (vr::I_REF, s(t)));
    println!("hbridge: {}", show(&e));
}

/// The pressures' and position's largest error over their range, fixed_cost against exact
/// both stepped at `h` (the internal step is `h` itself below 25 us), sampled every 0.1 ms.
fn error_at_step(kind: &str, h: f64) -> [f64; 6] {
    let mut e = model(&[driver(kind)]);
    let mut f = model(&[driver(kind), method("fixed_cost")]);
    let s = sine(20.0, 5e-3);
    let every = (1e-4 / h).round() as usize;
    let command = |t: f64| (vr::I_REF, s((t / 1e-4).floor() * 1e-4));
    let a: Vec<_> = trace(&mut e, 0.1, h, &command).into_iter().step_by(every).collect();
    let b: Vec<_> = trace(&mut f, 0.1, h, &command).into_iter().step_by(every).collect();
    errors(&a, &b)
}

#[test]
fn debug_convergence() {
    for h in [2.5e-5, 1.25e-5, 6.25e-6, 3.125e-6] {
        println!("h {h:e}: {}", show(&error_at_step("opamp_pi", h)));
    }
}
