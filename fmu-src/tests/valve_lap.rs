//! The spool's lap (docs/model.md, "Lap and leakage") through the model: the exact method
//! against a tight run of itself and fixed_cost against exact, with the spool crossing the
//! lands' openings many times; an overlap's dead band holding the piston; an underlap's
//! null leakage in Q_supply.

mod scenario;

use ehsv_actuator::model::Model;
use ehsv_actuator::variables::vr;
use scenario::{driver, enum_value, model};

const OUTPUTS: [usize; 6] = [vr::X_SPOOL, vr::Q_A, vr::Q_B, vr::P_A, vr::P_B, vr::X_PISTON];
/// The Moog 30's spool moves K1/Kw = 38 um per mA.
const SPOOL_PER_AMP: f64 = 2.82462 / 74.2853;

fn sine(hz: f64, amplitude: f64) -> impl Fn(f64) -> f64 {
    move |t| amplitude * (2.0 * std::f64::consts::PI * hz * t).sin()
}

/// The outputs after each step of `h` over `duration`, i_ref set from the time.
fn trace(m: &mut Model, duration: f64, h: f64, i_ref: &dyn Fn(f64) -> f64) -> Vec<[f64; 6]> {
    let n = (duration / h).round() as usize;
    (0..n)
        .map(|_| {
            m.set(vr::I_REF, i_ref(m.time())).unwrap();
            m.do_step(m.time(), h).unwrap();
            OUTPUTS.map(|o| m.get(o).unwrap())
        })
        .collect()
}

/// Each output's largest difference over its range in the reference.
fn errors(reference: &[[f64; 6]], other: &[[f64; 6]]) -> [f64; 6] {
    std::array::from_fn(|k| {
        let (lo, hi) =
            reference.iter().fold((f64::MAX, f64::MIN), |(lo, hi), s| (lo.min(s[k]), hi.max(s[k])));
        let worst =
            reference.iter().zip(other).map(|(a, b)| (a[k] - b[k]).abs()).fold(0.0, f64::max);
        worst / (hi - lo).max(1e-30)
    })
}

fn show(e: &[f64; 6]) -> String {
    e.iter().map(|x| format!("{x:.1e}")).collect::<Vec<_>>().join(" ")
}

fn method(name: &str) -> (&'static str, f64) {
    ("solver.method", enum_value("SolverMethod", name))
}

/// A 5 mA sine around a small offset sweeps the spool through both lands' openings (5 um
/// either side of null) twice per period: exact at its default tolerance stays within 1e-5
/// of each output's range of a run at rtol 1e-10, and fixed_cost within 1e-2 of exact, with
/// an underlap and with an overlap.
#[test]
fn both_methods_carry_the_lap_across_the_lands_openings() {
    let s = sine(20.0, 0.4e-3);
    let i_ref = |t: f64| 0.05e-3 + s(t);
    for lap in [5e-6, -5e-6] {
        let base = [driver("ideal_current"), ("valve.lap", lap)];
        let tight =
            trace(&mut model(&[base[0], base[1], ("solver.rtol", 1e-10)]), 0.1, 1e-4, &i_ref);
        let exact = trace(&mut model(&base), 0.1, 1e-4, &i_ref);
        let fixed = trace(&mut model(&[base[0], base[1], method("fixed_cost")]), 0.1, 1e-4, &i_ref);
        let (e_exact, e_fixed) = (errors(&tight, &exact), errors(&exact, &fixed));
        let case = format!("lap {lap:e}: exact {}, fixed_cost {}", show(&e_exact), show(&e_fixed));
        println!("{case}");
        assert!(e_exact.iter().all(|&e| e < 1e-5), "{case}");
        assert!(e_fixed.iter().all(|&e| e < 1e-2), "{case}");
        // The spool's swing crosses both openings.
        let (lo, hi) =
            exact.iter().fold((0.0f64, 0.0f64), |(lo, hi), o| (lo.min(o[0]), hi.max(o[0])));
        assert!(lo < -lap.abs() && hi > lap.abs(), "{lo} {hi}");
    }
}

/// A current whose spool travel stays inside an overlap's dead band moves nothing: no port
/// flow and the piston where it started; the same current on a critically centred valve
/// drives it.
#[test]
fn an_overlap_is_a_dead_band() {
    let lap: f64 = -10e-6;
    let i_small = 0.5 * lap.abs() / SPOOL_PER_AMP;
    for m in [&mut model(&[("valve.lap", lap)]), &mut model(&[])] {
        let run = trace(m, 0.05, 1e-4, &|_| i_small);
        let last = run.last().unwrap();
        let centred = m.get(vr::VALVE_DERIVED_LAP).unwrap() == 0.0;
        if centred {
            assert!(last[5] > 1e-5, "a critically centred valve moves the piston: {last:?}");
        } else {
            assert!(last[1] == 0.0 && last[2] == 0.0 && last[5].abs() < 1e-12, "{last:?}");
        }
    }
}

/// An underlapped valve, rod held at mid-stroke and spool centred, settles both chambers at
/// half the supply and draws its null leakage `2 K3 u sqrt(p_S/dp_r)` from the supply.
#[test]
fn an_underlap_leaks_its_null_leakage_from_the_supply() {
    let lap = 3e-6;
    let port = ("cylinder.port", enum_value("RodPort", "motion"));
    let mut m = model(&[driver("ideal_current"), port, ("valve.lap", lap)]);
    // The chambers settle with beta/V times the edges' slope, about 58/s at this lap.
    trace(&mut m, 0.4, 1e-3, &|_| 0.0);
    let p_s = m.get(vr::P_SUPPLY).unwrap();
    let dp_rated = m.get(vr::VALVE_DP_RATED).unwrap();
    let k3 = m.get(vr::VALVE_DERIVED_K3).unwrap();
    let expected = 2.0 * k3 * lap * (p_s / dp_rated).sqrt();
    let q_supply = m.get(vr::Q_SUPPLY).unwrap();
    assert!((q_supply - expected).abs() < 1e-6 * expected, "{q_supply} vs {expected}");
    for p in [vr::P_A, vr::P_B] {
        assert!((m.get(p).unwrap() - 0.5 * p_s).abs() < 1e-6 * p_s);
    }
}

/// The warning for a current command above the valve's rating reads the valve's own rated
/// current: a datasheet valve rated at 40 mA takes 20 mA without one and warns at 50 mA;
/// the paper's valve (gains form) warns above its 10 mA.
#[test]
fn the_current_warning_follows_the_valves_rated_current() {
    use ehsv_actuator::model::InputWarning;
    let above = InputWarning::ALL.iter().position(|w| *w == InputWarning::CurrentAboveRating);
    let warns = |m: &Model| m.input_warnings()[above.expect("a warning of its own")];
    let form = ("valve.parameterization", enum_value("ValveParameterization", "datasheet"));
    let mut m = model(&[form, ("valve.i_rated", 0.04), ("valve.Q_rated", 1e-4)]);
    m.set(vr::I_REF, 0.02).unwrap();
    assert!(!warns(&m));
    m.set(vr::I_REF, 0.05).unwrap();
    assert!(warns(&m));
    let mut paper = model(&[]);
    paper.set(vr::I_REF, 0.02).unwrap();
    assert!(warns(&paper));
}
