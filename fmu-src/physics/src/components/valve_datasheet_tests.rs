use super::*;
use crate::params::Params;

fn paper() -> ValveParams {
    Params::PAPER.valve
}

fn datasheet(edit: impl FnOnce(&mut ValveParams)) -> ValveParams {
    let mut v = paper();
    v.parameterization = ValveParameterization::Datasheet;
    edit(&mut v);
    v
}

/// The complex denominator `D(jW)` of the small-signal flow.
fn denominator(v: &ValveParams, w: f64) -> (f64, f64) {
    let tau = v.spool_area * v.kf / (v.kw * v.k2);
    let wn = 2.0 * PI * v.f_n;
    (1.0 - 2.0 * v.zeta * tau * w * w / wn, w * tau * (1.0 - w * w / (wn * wn)))
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs()
}

#[test]
fn the_paper_valve_in_datasheet_form_has_the_papers_gains() {
    let gains = resolve(&paper()).unwrap();
    assert_eq!(gains, paper(), "gains form: the parameters as given, bit for bit");
    let from_sheet = resolve(&datasheet(|_| {})).unwrap();
    for (name, got, want) in [
        ("K1", from_sheet.k1, gains.k1),
        ("K2", from_sheet.k2, gains.k2),
        ("K3", from_sheet.k3, gains.k3),
        ("f_n", from_sheet.f_n, gains.f_n),
    ] {
        assert!(close(got, want, 1e-12), "{name}: {got} vs {want}");
    }
    assert_eq!((from_sheet.lap, from_sheet.q_pilot), (0.0, 0.0));
}

/// The figures read back from the gains are the small-signal response's: the -90 degree
/// point where the real part of `D` vanishes, the -3 dB point where `|D|^2 = 2`, the DC
/// gain `K3 K1/Kw`; and a valve set from them gives them back.
#[test]
fn figures_are_the_responses_and_round_trip() {
    for (f_90, f_3db, zeta) in [(368.0, 161.0, 0.4), (150.0, 100.0, 0.5), (200.0, 250.0, 0.7)] {
        let v = datasheet(|v| {
            (v.datasheet.f_90, v.datasheet.f_3db, v.zeta) = (f_90, f_3db, zeta);
            (v.datasheet.q_rated, v.datasheet.i_rated) = (1.0e-4, 0.04);
        });
        let resolved = resolve(&v).unwrap();
        let (re, im) = denominator(&resolved, 2.0 * PI * f_90);
        assert!(re.abs() < 1e-9 && im > 0.0, "{f_90}: D = {re} + j {im}");
        let (re, im) = denominator(&resolved, 2.0 * PI * f_3db);
        assert!(close(re * re + im * im, 2.0, 1e-9), "{f_3db}: |D|^2 = {}", re * re + im * im);
        assert!(close(resolved.k3 * resolved.k1 / resolved.kw, 1.0e-4 / 0.04, 1e-12));
        let figures = figures(&resolved);
        assert!(close(figures.f_90, f_90, 1e-12) && close(figures.f_3db, f_3db, 1e-9));
    }
}

#[test]
fn without_a_3db_point_the_first_stage_keeps_the_papers_ratio() {
    let v = resolve(&datasheet(|v| v.datasheet.f_3db = 0.0)).unwrap();
    let tau = v.spool_area * v.kf / (v.kw * v.k2);
    assert!(close(2.0 * PI * v.f_n * tau, PAPER_WN_TAU, 1e-12));
    assert!(close(figures(&v).f_90, paper().datasheet.f_90, 1e-12));
    // The paper's own valve has that ratio, so it comes out as the paper's.
    assert!(close(v.f_n, 814.0, 1e-9), "{}", v.f_n);
}

#[test]
fn figures_no_valve_has_are_refused_with_the_possible_range() {
    let err = resolve(&datasheet(|v| v.datasheet.f_3db = 3.0 * v.datasheet.f_90)).unwrap_err();
    assert!(err.contains("valve.f_3dB") && err.contains("valve.f_90"), "{err}");
    // The range it gives holds valves, and its ends are where they stop.
    let (lo, hi) = possible_ratios(0.4, MAX_FIRST_STAGE_HZ / paper().datasheet.f_90);
    assert!(lo < 0.05 && hi > 1.5 && hi < 1.56, "{lo} {hi}");
    for ratio in [1.05 * lo, 0.5, 0.98 * hi] {
        let v = datasheet(|v| v.datasheet.f_3db = ratio * v.datasheet.f_90);
        assert!(resolve(&v).is_ok(), "{ratio}: {:?}", resolve(&v));
    }
    let undamped = resolve(&datasheet(|v| v.zeta = 0.0)).unwrap_err();
    assert!(undamped.contains("valve.zeta"), "{undamped}");
}

#[test]
fn datasheet_figures_in_gains_form_are_refused_by_name() {
    let mut v = paper();
    v.datasheet.q_leak_null = 1e-6;
    let err = resolve(&v).unwrap_err();
    assert!(err.contains("valve.Q_leak_null") && err.contains("valve.parameterization"), "{err}");
    v = paper();
    v.datasheet.p_leak_ref = 7e6; // read in both forms: no refusal
    assert!(resolve(&v).is_ok());
}

/// The leakage alone sets the lap (all of it through the lands), with the pressure gain
/// beside it the lap that gives that gain and the rest as pilot flow; a pressure gain
/// that would need a wider lap than the leakage allows is refused.
#[test]
fn leakage_and_pressure_gain_give_lap_and_pilot() {
    let (q_leak, p_ref) = (5.0e-6, 2.1e7);
    let leak_only =
        datasheet(|v| (v.datasheet.q_leak_null, v.datasheet.p_leak_ref) = (q_leak, p_ref));
    let r = resolve(&leak_only).unwrap();
    assert!(close(2.0 * r.k3 * r.lap * (p_ref / r.dp_rated).sqrt(), q_leak, 1e-12));
    assert_eq!(r.q_pilot, 0.0);
    let f = figures(&r);
    assert!(close(f.q_leak_null, q_leak, 1e-12));
    assert!(close(f.pressure_gain, 2.0 * p_ref * r.k1 / (r.kw * r.lap), 1e-12));

    let stiffer = datasheet(|v| {
        (v.datasheet.q_leak_null, v.datasheet.p_leak_ref) = (q_leak, p_ref);
        v.datasheet.pressure_gain = 2.0 * f.pressure_gain;
    });
    let r2 = resolve(&stiffer).unwrap();
    assert!(close(r2.lap, 0.5 * r.lap, 1e-12));
    assert!(close(r2.q_pilot, 0.5 * q_leak, 1e-12), "{}", r2.q_pilot);
    assert!(close(figures(&r2).q_leak_null, q_leak, 1e-12));

    let softer = datasheet(|v| {
        (v.datasheet.q_leak_null, v.datasheet.p_leak_ref) = (q_leak, p_ref);
        v.datasheet.pressure_gain = 0.5 * f.pressure_gain;
    });
    let err = resolve(&softer).unwrap_err();
    assert!(err.contains("valve.pressure_gain") && err.contains("valve.Q_leak_null"), "{err}");
    let both = datasheet(|v| (v.datasheet.q_leak_null, v.lap) = (q_leak, 1e-6));
    assert!(resolve(&both).unwrap_err().contains("valve.lap"));
}
