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
