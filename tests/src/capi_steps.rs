//! A workload stepped through the FMU's FMI 2 C API as a user steps it, for counting the
//! instructions of a communication step with callgrind (issue 37's measure: instruction
//! counts do not move with the machine's load). Per instance and step of `h`:
//! `fmi2SetReal` of the workload's inputs, `fmi2DoStep`, `fmi2GetReal` of i_coil, x_piston,
//! p_A and Q_valve ([`READ`]), each group inside one call of `communication_step`, which
//! is never inlined. The extern "C" functions are called directly (the rlib exposes them),
//! not through dlopen: the same code as the cdylib's, without the PLT.
//!
//! ```text
//! valgrind --tool=callgrind --toggle-collect='*communication_step*' PROGRAM ...
//! ```
//!
//! counts the instructions inside those calls only (start-up, initialisation, the signals
//! and the driving loop fall outside); total Ir / [`run`]'s calls = instructions per step.

use std::ffi::CString;
use std::hint::black_box;
use std::ptr::null;

use ehsv_actuator::fmi2::{
    fmi2CoSimulation, fmi2Component, fmi2DoStep, fmi2EnterInitializationMode,
    fmi2ExitInitializationMode, fmi2FreeInstance, fmi2GetReal, fmi2Instantiate, fmi2SetInteger,
    fmi2SetReal, fmi2SetupExperiment, fmi2True,
};
use ehsv_actuator::fmi_common::Status;
use ehsv_actuator::variables::{interface_token, vr};

use crate::workloads::{Workload, INPUTS};

/// The outputs a user reads after every step (issue 37): i_coil, x_piston, p_A, Q_valve.
pub const READ: [usize; 4] = [vr::I_COIL, vr::X_PISTON, vr::P_A, vr::Q_VALVE];
/// The name callgrind's `--toggle-collect` matches (`*communication_step*`).
pub const MARKER: &str = "communication_step";

/// A live FMI 2 instance, freed when dropped.
struct Instance(fmi2Component);

impl Drop for Instance {
    fn drop(&mut self) {
        // SAFETY: a live instance from fmi2Instantiate, not used afterwards.
        unsafe { fmi2FreeInstance(self.0) }
    }
}

fn check(what: &str, status: Status) -> Result<(), String> {
    match status {
        Status::OK => Ok(()),
        other => Err(format!("{what} returned {other:?}")),
    }
}

/// Instantiates `workload` (its enumerations and reals set) and initialises it at t = 0.
fn start(workload: &Workload, t_end: f64) -> Result<Instance, String> {
    let name = CString::new("capi_steps").unwrap();
    let token = CString::new(interface_token()).unwrap();
    // SAFETY: NUL-terminated strings that outlive the call; no callbacks (nothing logged).
    let c = unsafe {
        fmi2Instantiate(name.as_ptr(), fmi2CoSimulation, token.as_ptr(), null(), null(), 0, 0)
    };
    if c.is_null() {
        return Err("fmi2Instantiate returned NULL".into());
    }
    let instance = Instance(c);
    for (vr, value) in workload.enums() {
        let (r, v) = (vr as u32, value as i32);
        // SAFETY: live instance, arrays of one element.
        check("fmi2SetInteger", unsafe { fmi2SetInteger(c, &r, 1, &v) })?;
    }
    for (vr, value) in workload.reals() {
        let r = vr as u32;
        // SAFETY: as above.
        check("fmi2SetReal", unsafe { fmi2SetReal(c, &r, 1, &value) })?;
    }
    // SAFETY: live instance, the standard's order of calls.
    unsafe {
        check("fmi2SetupExperiment", fmi2SetupExperiment(c, 0, 0.0, 0.0, fmi2True, t_end))?;
        check("fmi2EnterInitializationMode", fmi2EnterInitializationMode(c))?;
        check("fmi2ExitInitializationMode", fmi2ExitInitializationMode(c))?;
    }
    Ok(instance)
}

/// The value references of one step's calls.
struct References {
    inputs: [u32; INPUTS.len()],
    read: [u32; READ.len()],
}

/// One communication step of one instance as a user makes it: the inputs set, the step,
/// the four outputs read. Never inlined: callgrind counts the instructions inside it.
#[inline(never)]
fn communication_step(
    c: fmi2Component,
    refs: &References,
    inputs: &[f64; INPUTS.len()],
    (t, h): (f64, f64),
    out: &mut [f64; READ.len()],
) -> [Status; 3] {
    // SAFETY: live instance; the arrays hold as many elements as passed.
    unsafe {
        [
            fmi2SetReal(c, refs.inputs.as_ptr(), INPUTS.len(), inputs.as_ptr()),
            fmi2DoStep(c, t, h, fmi2True),
            fmi2GetReal(c, refs.read.as_ptr(), READ.len(), out.as_mut_ptr()),
        ]
    }
}

/// Steps every instance of `workload` (12 for the quadruped) in lock-step for `steps`
/// steps of `h` from t = 0; returns the number of communication steps of all instances
/// (the divisor of the instruction count).
pub fn run(workload: &Workload, steps: usize, h: f64) -> Result<usize, String> {
    let t_end = steps as f64 * h;
    let instances =
        workload.legs.iter().map(|_| start(workload, t_end)).collect::<Result<Vec<_>, _>>()?;
    let refs = References { inputs: INPUTS.map(|v| v as u32), read: READ.map(|v| v as u32) };
    let mut out = [0.0; READ.len()];
    for k in 0..steps {
        let t = k as f64 * h;
        for (instance, signal) in instances.iter().zip(&workload.legs) {
            let inputs = signal.inputs(t);
            let status = communication_step(instance.0, &refs, &inputs, (t, h), &mut out);
            for (what, s) in ["fmi2SetReal", "fmi2DoStep", "fmi2GetReal"].iter().zip(status) {
                check(what, s).map_err(|e| format!("{e} at t = {t}"))?;
            }
            black_box(&out);
        }
    }
    Ok(steps * workload.legs.len())
}

/// Steps every instance of `workload` as [`run`] does, reading every real output of the
/// table after each step through `fmi2GetReal` (all at once, in table order); returns the
/// FNV-1a hash of their bits over the run and the last instance's final x_piston and p_A:
/// what `output_digest` prints to show that a change left the results alone.
/// Outputs named in `skip` are left out (to compare with a build that predates them).
pub fn digest(
    workload: &Workload,
    steps: usize,
    h: f64,
    skip: &[String],
) -> Result<(u64, [f64; 2]), String> {
    use ehsv_actuator::variables::{Causality, VarType, VARIABLES};
    let t_end = steps as f64 * h;
    let instances =
        workload.legs.iter().map(|_| start(workload, t_end)).collect::<Result<Vec<_>, _>>()?;
    let refs = References { inputs: INPUTS.map(|v| v as u32), read: READ.map(|v| v as u32) };
    let outputs: Vec<u32> = (0..VARIABLES.len())
        .filter(|&i| {
            VARIABLES[i].causality == Causality::Output
                && VARIABLES[i].ty == VarType::Real
                && !skip.iter().any(|name| name == VARIABLES[i].name)
        })
        .map(|i| i as u32)
        .collect();
    let (mut values, mut out) = (vec![0.0; outputs.len()], [0.0; READ.len()]);
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for k in 0..steps {
        let t = k as f64 * h;
        for (instance, signal) in instances.iter().zip(&workload.legs) {
            let status = communication_step(instance.0, &refs, &signal.inputs(t), (t, h), &mut out);
            for (what, s) in ["fmi2SetReal", "fmi2DoStep", "fmi2GetReal"].iter().zip(status) {
                check(what, s).map_err(|e| format!("{e} at t = {t}"))?;
            }
            // SAFETY: live instance; arrays of outputs.len() elements.
            check("fmi2GetReal", unsafe {
                fmi2GetReal(instance.0, outputs.as_ptr(), outputs.len(), values.as_mut_ptr())
            })?;
            for v in out.iter().chain(&values) {
                for byte in v.to_bits().to_le_bytes() {
                    hash = (hash ^ byte as u64).wrapping_mul(0x0100_0000_01b3);
                }
            }
        }
    }
    Ok((hash, [out[1], out[2]]))
}
