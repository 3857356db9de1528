//! One benchmark workload through the model's Rust API (the code behind the C API), for an
//! instruction profile of its doSteps: `scripts/profile-step.sh` runs this under callgrind and
//! splits the instructions counted inside [`one_do_step`] by part of the step.
//!
//!     step_profile WORKLOAD exact|fixed_cost [STEPS] [H] [--c-api]
//!
//! WORKLOAD is a bench workload's name (`bench --help` lists them in its table; e.g.
//! `gait_position`); STEPS defaults to 5000 and H to 1e-4 s (0.5 s, as the bench's
//! `--t-end 0.5`). Every instance of the workload (12 for the quadruped) is stepped in
//! lock-step, inputs set before each doStep as the bench does through the C API. Prints the
//! number of doSteps taken, which the script divides by.
//!
//! With `--c-api` the workload goes through the FMI 2 C API instead (`ehsv_tests::capi_steps`,
//! as the bench's `instr/step` counts it): each communication step (SetReal of the inputs,
//! DoStep, GetReal of i_coil, x_piston, p_A and Q_valve) inside
//! `capi_steps::communication_step`, the function the script then counts under.

use std::hint::black_box;
use std::process::ExitCode;

use ehsv_actuator::model::Model;
use ehsv_tests::capi_steps;
use ehsv_tests::workloads::{self, Signal, Workload, INPUTS};

const DEFAULT_STEPS: usize = 5000;
const DEFAULT_H: f64 = 1e-4;

struct Options {
    workload: Workload,
    steps: usize,
    h: f64,
    /// Through the FMI 2 C API (`--c-api`), not the model's Rust API.
    c_api: bool,
}

fn parse() -> Result<Options, String> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let c_api = args.last().is_some_and(|a| a == "--c-api");
    if c_api {
        args.pop();
    }
    let [name, method, rest @ ..] = args.as_slice() else {
        return Err("usage: step_profile WORKLOAD exact|fixed_cost [STEPS] [H] [--c-api]".into());
    };
    let method = match method.as_str() {
        "exact" => workloads::EXACT,
        "fixed_cost" => workloads::FIXED_COST,
        other => return Err(format!("method {other}: exact or fixed_cost")),
    };
    let names = || workloads::all().into_iter().map(|w| w.name).collect::<Vec<_>>().join(", ");
    let workload = workloads::all()
        .into_iter()
        .find(|w| &w.name == name)
        .ok_or_else(|| format!("no workload {name}; there are {}", names()))?
        .with_method(method);
    let number = |i: usize, default: f64| -> Result<f64, String> {
        rest.get(i).map_or(Ok(default), |s| s.parse().map_err(|_| format!("bad number {s}")))
    };
    let steps = number(0, DEFAULT_STEPS as f64)? as usize;
    Ok(Options { workload, steps, h: number(1, DEFAULT_H)?, c_api })
}

/// A started instance of `workload` (its enumerations and reals set, initialised).
fn start(workload: &Workload) -> Result<Model, String> {
    let mut m = Model::new();
    for (vr, value) in workload.enums() {
        m.set(vr, value as f64)?;
    }
    for (vr, value) in workload.reals() {
        m.set(vr, value)?;
    }
    m.initialize()?;
    Ok(m)
}

/// The inputs of one instance for the step from `t`. Not inlined, so that the profile can
/// tell setting inputs from the step.
#[inline(never)]
fn set_inputs(m: &mut Model, signal: Signal, t: f64) -> Result<(), String> {
    for (vr, value) in INPUTS.iter().zip(signal.inputs(t)) {
        m.set(*vr, value)?;
    }
    Ok(())
}

/// One doStep. Never inlined: `scripts/profile-step.sh` counts the instructions under this
/// function's name, which is what makes the start-up (instantiation, initialisation) and the
/// driving loop fall outside the figures.
#[inline(never)]
fn one_do_step(m: &mut Model, t: f64, h: f64) -> Result<(), String> {
    black_box(m.do_step(t, h)?);
    Ok(())
}

fn run(o: &Options) -> Result<usize, String> {
    if o.c_api {
        return capi_steps::run(&o.workload, o.steps, o.h);
    }
    let legs = &o.workload.legs;
    let mut models = legs.iter().map(|_| start(&o.workload)).collect::<Result<Vec<_>, _>>()?;
    for k in 0..o.steps {
        let t = k as f64 * o.h;
        for (m, &signal) in models.iter_mut().zip(legs) {
            set_inputs(m, signal, t)?;
            one_do_step(m, t, o.h)?;
        }
    }
    Ok(o.steps * legs.len())
}

fn main() -> ExitCode {
    let result = parse().and_then(|o| run(&o).map(|calls| (o, calls)));
    match result {
        Ok((o, calls)) => {
            println!("{}: {calls} doSteps of {} s", o.workload.name, o.h);
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("step_profile: {e}");
            ExitCode::FAILURE
        }
    }
}
