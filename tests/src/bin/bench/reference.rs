//! The accuracy yardstick: the same model (the rlib `ehsv_actuator::model::Model`, the code
//! behind the C API) on the same communication grid and inputs, with the cylinder
//! integrator's tolerance `solver.rtol` tightened from the FMU's 1e-7 to [`REFERENCE_RTOL`]
//! (or as asked). The valve and driver are propagated exactly either way.

use std::ops::Range;

use ehsv_actuator::model::Model;
use ehsv_actuator::physics::Work;
use ehsv_actuator::variables::vr;

use crate::workloads::{Signal, Workload, INPUTS, OUTPUTS};

pub const REFERENCE_RTOL: f64 = 1e-10;
/// See [`deviation`].
const RANGE_FLOOR: f64 = 1e-3;

/// Outputs after every communication step, `OUTPUTS` order.
pub type Trace = Vec<[f64; OUTPUTS.len()]>;

/// A started model of `workload` through the rlib, at the workload's tolerance or `rtol`.
pub fn start(workload: &Workload, rtol: Option<f64>) -> Result<Model, String> {
    let mut m = Model::new();
    for (vr, value) in workload.enums() {
        m.set(vr, value as f64)?;
    }
    for (vr, value) in workload.reals() {
        m.set(vr, value)?;
    }
    if let Some(rtol) = rtol {
        // The yardstick is the exact method, whichever the workload runs.
        m.set(vr::SOLVER_METHOD, 0.0)?;
        m.set(vr::SOLVER_RTOL, rtol)?;
    }
    m.initialize()?;
    Ok(m)
}

/// Runs one signal of `workload` through the rlib at cylinder tolerance `rtol` and records the outputs.
pub fn run(
    workload: &Workload,
    signal: Signal,
    h: f64,
    steps: usize,
    rtol: f64,
) -> Result<Trace, String> {
    Ok(run_model(&mut start(workload, Some(rtol))?, signal, h, 0..steps)?.0)
}

/// The work the FMU's integrators do on one signal of `workload` (the same computation as
/// through the C API, at the FMU's own tolerance, through the rlib, which can read it).
pub fn fmu_work(workload: &Workload, signal: Signal, h: f64, steps: usize) -> Result<Work, String> {
    Ok(run_model(&mut start(workload, None)?, signal, h, 0..steps)?.1)
}

/// The work of the FMU's integrators in step `k` alone: what makes that doStep cost what it does.
pub fn work_of_step(workload: &Workload, signal: Signal, h: f64, k: usize) -> Result<Work, String> {
    let mut m = start(workload, None)?;
    run_model(&mut m, signal, h, 0..k)?;
    Ok(run_model(&mut m, signal, h, k..k + 1)?.1)
}

/// Steps `steps` (indices on the grid of `h`) of `m`: the outputs after each and the work done.
fn run_model(
    m: &mut Model,
    signal: Signal,
    h: f64,
    steps: Range<usize>,
) -> Result<(Trace, Work), String> {
    let mut trace = Trace::with_capacity(steps.len());
    let before = m.work();
    for k in steps {
        let t = k as f64 * h;
        for (vr, value) in INPUTS.iter().zip(signal.inputs(t)) {
            m.set(*vr, value)?;
        }
        m.do_step(t, h)?; // the master's time base, as through the C API
        trace.push(OUTPUTS.map(|vr| m.get(vr).unwrap()));
    }
    let work = m.work().since(&before);
    Ok((trace, work))
}

/// Largest deviation of each output from the reference as a fraction of the reference's
/// range over the run, the range taken as at least [`RANGE_FLOOR`] of the output's largest
/// magnitude (an output that barely moves, e.g. u_driver sampled at rest, has no range to
/// speak of).
pub fn deviation(trace: &Trace, reference: &Trace) -> [f64; OUTPUTS.len()] {
    let mut out = [0.0; OUTPUTS.len()];
    for (j, o) in out.iter_mut().enumerate() {
        let (lo, hi) = reference
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| (lo.min(r[j]), hi.max(r[j])));
        let range = hi - lo;
        let scale = range.max(RANGE_FLOOR * hi.abs().max(lo.abs())).max(f64::MIN_POSITIVE);
        let worst =
            trace.iter().zip(reference).map(|(a, r)| (a[j] - r[j]).abs()).fold(0.0, f64::max);
        *o = worst / scale;
    }
    out
}

/// Where output `j` deviates most: (step index, value, reference value).
pub fn worst_point(trace: &Trace, reference: &Trace, j: usize) -> (usize, f64, f64) {
    let k = (0..trace.len().min(reference.len()))
        .max_by(|&a, &b| {
            (trace[a][j] - reference[a][j]).abs().total_cmp(&(trace[b][j] - reference[b][j]).abs())
        })
        .unwrap_or(0);
    (k, trace[k][j], reference[k][j])
}
