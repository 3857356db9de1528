//! Scenarios through the Model API, shared by the physics and cylinder tests.
#![allow(dead_code)]

use ehsv_actuator::model::Model;
use ehsv_actuator::variables::index_of;

/// A model with these parameters and inputs set, initialised.
pub fn model(settings: &[(&str, f64)]) -> Model {
    let mut m = Model::new();
    for (name, value) in settings {
        m.set(index_of(name).unwrap_or_else(|| panic!("{name}")), *value).unwrap();
    }
    m.initialize().unwrap();
    m
}

/// Steps `m` for `duration` with steps `h`: (time, outputs) at the start and after every step.
pub fn run(m: &mut Model, duration: f64, h: f64, outputs: &[usize]) -> Vec<(f64, Vec<f64>)> {
    let n = (duration / h).round() as usize;
    let sample = |m: &Model| (m.time(), outputs.iter().map(|&o| m.get(o).unwrap()).collect());
    let mut trace = vec![sample(m)];
    for _ in 0..n {
        m.do_step(m.time(), h).unwrap();
        trace.push(sample(m));
    }
    trace
}

/// The first output of a trace as (time, value).
pub fn first_output(trace: Vec<(f64, Vec<f64>)>) -> Vec<(f64, f64)> {
    trace.into_iter().map(|(t, y)| (t, y[0])).collect()
}

/// Last time, from the first sample, the signal is outside +-band*|step| of `final_value`.
pub fn settling_time(trace: &[(f64, f64)], step: f64, final_value: f64, band: f64) -> f64 {
    let t0 = trace[0].0;
    match trace.iter().rposition(|&(_, y)| (y - final_value).abs() > band * step.abs()) {
        Some(k) => trace[k + 1].0 - t0,
        None => 0.0,
    }
}

/// Settling around the trace's own final value, for a step from its first value.
pub fn settling_to_end(trace: &[(f64, f64)], band: f64) -> f64 {
    let (first, last) = (trace[0].1, trace.last().unwrap().1);
    settling_time(trace, last - first, last, band)
}

/// The start value of a variable in the table (the defaults are never re-declared here).
pub fn start(vr: usize) -> f64 {
    ehsv_actuator::variables::VARIABLES[vr].start
}

/// The value of an enumeration item, by the names of the table (`enum_value("DriverType",
/// "opamp_pi")`), so tests name drivers and control modes instead of numbering them.
pub fn enum_value(enumeration: &str, item: &str) -> f64 {
    let e = ehsv_actuator::variables::ENUMERATIONS
        .iter()
        .find(|e| e.name == enumeration)
        .unwrap_or_else(|| panic!("no enumeration {enumeration}"));
    let (value, _, _) = e
        .valued_items()
        .find(|(_, name, _)| *name == item)
        .unwrap_or_else(|| panic!("{enumeration} has no item {item}"));
    value as f64
}

/// A `driver` setting by name.
pub fn driver(name: &str) -> (&'static str, f64) {
    ("driver", enum_value("DriverType", name))
}

/// A `control_mode` setting by name.
pub fn control_mode(name: &str) -> (&'static str, f64) {
    ("control_mode", enum_value("ControlMode", name))
}

/// Piston area on the A side from the table's bore (m2).
pub fn area_a() -> f64 {
    let bore = start(ehsv_actuator::variables::vr::CYLINDER_BORE);
    std::f64::consts::FRAC_PI_4 * bore * bore
}

/// Annulus area on the B side from the table's bore and rod (m2).
pub fn area_b() -> f64 {
    let rod = start(ehsv_actuator::variables::vr::CYLINDER_ROD);
    area_a() - std::f64::consts::FRAC_PI_4 * rod * rod
}

/// The signed square root of the orifice law, replaced below `lam` by the odd cubic that
/// matches its value and slope there (the documented regularisation), written again from
/// the documentation for the tests' independent transcriptions of the ports.
pub fn rsqrt(dp: f64, lam: f64) -> f64 {
    if dp.abs() >= lam {
        dp.signum() * dp.abs().sqrt()
    } else {
        let s = dp / lam;
        lam.sqrt() * s * (1.25 - 0.25 * s * s)
    }
}
