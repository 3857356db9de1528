//! A workload through the FMU's C API: every instance gets its inputs, one doStep and a
//! GetReal of all recorded outputs per communication point, in lock-step.

use crate::fmi::{Fmu, Slave};
use crate::reference::Trace;
use crate::timing::{self, Samples, Stopwatch};
use crate::workloads::{Workload, INPUTS, OUTPUTS};

/// One run of a workload.
pub struct FmuRun {
    /// Wall and thread-CPU seconds of the whole stepping loop (all instances).
    pub wall: f64,
    pub cpu: f64,
    /// Per-doStep wall and thread-CPU time in call order (empty unless timed; every
    /// instance's calls: step after step, leg after leg).
    pub step_wall: Samples,
    pub step_cpu: Samples,
    /// Outputs of the first instance after every step.
    pub trace: Trace,
}

/// Runs `workload` for `steps` steps of `h`; `timed` puts a stopwatch around every doStep
/// (two clock reads per call, so the untimed run gives the real-time factor).
pub fn run(
    fmu: &Fmu,
    workload: &Workload,
    h: f64,
    steps: usize,
    timed: bool,
) -> Result<FmuRun, String> {
    let t_end = steps as f64 * h;
    let slaves = workload
        .legs
        .iter()
        .map(|_| Slave::start(fmu, &workload.enums(), &workload.reals(), t_end))
        .collect::<Result<Vec<_>, _>>()?;
    let input_vrs = INPUTS.map(|v| v as u32);
    let output_vrs = OUTPUTS.map(|v| v as u32);
    let mut trace = Trace::with_capacity(steps);
    let n_calls = if timed { steps * slaves.len() } else { 0 };
    let (mut wall_samples, mut cpu_samples) =
        (Samples::with_capacity(n_calls), Samples::with_capacity(n_calls));
    let mut y = [0.0; OUTPUTS.len()];
    // Everything the loop writes is allocated above: an allocation inside it would be timed
    // as the FMU's work.
    let (clock_wall, clock_cpu) = timing::clock_cost();
    let clock = Stopwatch::start();
    for k in 0..steps {
        let t = k as f64 * h;
        for (leg, (slave, signal)) in slaves.iter().zip(&workload.legs).enumerate() {
            slave.set_reals(&input_vrs, &signal.inputs(t))?;
            if timed {
                let watch = Stopwatch::start();
                slave.do_step(t, h)?;
                let (wall, cpu) = watch.read();
                wall_samples.push((wall - clock_wall).max(0.0));
                cpu_samples.push((cpu - clock_cpu).max(0.0));
            } else {
                slave.do_step(t, h)?;
            }
            slave.get_reals(&output_vrs, &mut y)?;
            if leg == 0 {
                trace.push(y);
            }
        }
    }
    let (wall, cpu) = clock.read();
    Ok(FmuRun { wall, cpu, step_wall: wall_samples, step_cpu: cpu_samples, trace })
}
