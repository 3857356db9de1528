//! The peer: the same equations integrated by SUNDIALS CVODE (BDF, Newton, dense LU),
//! stepped through the same communication grid as a CVODE-based co-simulation FMU does:
//! inputs are set at each communication point, the method is restarted (CVodeReInit)
//! whenever the right-hand side jumps (an input changed, a PWM edge, a sample of a digital
//! loop), and CVODE integrates to each point or time event with it as the stop time.
//! The equations are the physics' own whole-model right-hand side
//! (`ehsv_actuator::physics::rhs`, built from the same component functions the FMU
//! integrates), and so are the digital parts (H-bridge PWM and PI, the outer loops' PID,
//! `physics::rhs::Sampled`): the model is transcribed once.

mod cvode;

use std::ffi::{c_int, c_void};

use ehsv_actuator::physics::{ControlMode, DriverKind};
use ehsv_actuator::variables::{vr, N_VARIABLES};
use ehsv_physics::rhs::{RhsInputs, Sampled, WholeModel, I, NY, PA, PB, U, UI, V, X, XF, XS};

pub use cvode::{Api, Counters};

use crate::reference::Trace;
use crate::timing::Stopwatch;
use crate::workloads::{Signal, Workload};

/// What the solver's callback needs: the model and the inputs in force.
struct Context<'a> {
    model: WholeModel,
    held: RhsInputs,
    api: &'a Api,
}

unsafe extern "C" fn cvode_rhs(
    _t: f64,
    y: cvode::NVector,
    dy: cvode::NVector,
    data: *mut c_void,
) -> c_int {
    // SAFETY: `data` is the Context the solver was given (alive for the run); y and dy are
    // serial vectors of length NY owned by CVODE for the call.
    unsafe {
        let ctx = &*(data as *const Context);
        let y = &*((ctx.api.array)(y) as *const [f64; NY]);
        let dy = &mut *((ctx.api.array)(dy) as *mut [f64; NY]);
        ctx.model.rhs(&ctx.held, y, dy);
    }
    0
}

/// A peer run: thread-CPU and wall seconds of the stepping loop, work, outputs.
pub struct PeerRun {
    pub cpu: f64,
    pub wall: f64,
    pub counters: Counters,
    /// Right-hand-side jumps that restarted the method.
    pub restarts: u64,
    pub trace: Trace,
}

/// Runs `signal` of `workload` for `steps` communication steps of `h` with relative
/// tolerance `rtol`, from the FMU's own start state.
pub fn run(
    api: &Api,
    workload: &Workload,
    signal: Signal,
    h: f64,
    steps: usize,
    rtol: f64,
) -> Result<PeerRun, String> {
    let values = start_values(workload)?;
    let model = WholeModel::new(&ehsv_actuator::variables::params(&values)?)?;
    let rail = model.rail(values[vr::V_SUPPLY]);
    let y0 = initial_state(&model, &values);
    let [i_ref0, q_ref0, x_ref0, _] = signal.inputs(0.0);
    let reference = |q_ref: f64, x_ref: f64| match model.control_mode() {
        ControlMode::Flow => q_ref,
        ControlMode::Position => x_ref,
        ControlMode::Current => 0.0,
    };
    let mut sampled =
        Sampled::at_start(&model, values[vr::I_COIL], rail, reference(q_ref0, x_ref0), 0.0);
    let mut ctx = Box::new(Context {
        model,
        held: RhsInputs {
            i_cmd: sampled.command(&model, i_ref0),
            rail,
            u_bridge: sampled.bridge_output(&model, rail),
            p_supply: values[vr::P_SUPPLY],
            f_ext: values[vr::F_EXT],
        },
        api,
    });
    let atol = model.error_scales().map(|s| s * rtol);
    let data = &mut *ctx as *mut Context as *mut c_void;
    let mut solver = cvode::Solver::new(api, cvode_rhs, data, &y0, rtol, &atol)?;
    let mut trace = Trace::with_capacity(steps);
    let mut restarts = 0;
    let slack = 1e-9 * h;
    let clock = Stopwatch::start();
    for k in 0..steps {
        let t0 = k as f64 * h;
        let t1 = t0 + h;
        let [i_ref, q_ref, x_ref, f_ext] = signal.inputs(t0);
        let reference = reference(q_ref, x_ref);
        let held = RhsInputs { i_cmd: sampled.command(&model, i_ref), f_ext, ..ctx.held };
        if held != ctx.held {
            ctx.held = held;
            solver.restart()?;
            restarts += 1;
        }
        let mut t = t0;
        loop {
            let t_event = sampled.next_event(&model);
            let fire = t_event <= t1 + slack;
            let end = if fire { t_event.min(t1) } else { t1 };
            // An event within rounding of the current time happens there.
            if end > t + slack {
                solver.advance_to(end)?;
            }
            t = t.max(end);
            if !fire {
                break;
            }
            let y: &[f64; NY] = solver.state().try_into().unwrap();
            sampled.fire(&model, y, reference, i_ref, &mut ctx.held);
            solver.restart()?;
            restarts += 1;
        }
        let y: &[f64; NY] = solver.state().try_into().unwrap();
        trace.push(outputs(&model, &ctx.held, y));
    }
    let (wall, cpu) = clock.read();
    let counters = solver.counters();
    drop(solver);
    Ok(PeerRun { cpu, wall, counters, restarts, trace })
}

/// Every variable's value in the FMU's start state for `workload`.
fn start_values(workload: &Workload) -> Result<[f64; N_VARIABLES], String> {
    let start = crate::reference::start(workload, None)?;
    let mut values = [0.0; N_VARIABLES];
    for (k, v) in values.iter_mut().enumerate() {
        *v = start.get(k).unwrap();
    }
    Ok(values)
}

/// The solver's state vector at the FMU's start `values`.
fn initial_state(model: &WholeModel, values: &[f64; N_VARIABLES]) -> [f64; NY] {
    let mut y0 = [0.0; NY];
    y0[I] = values[vr::I_COIL];
    y0[UI] = values[vr::U_DRIVER]; // at the start equilibrium the error is 0: u = ui
    y0[U] = values[vr::U_DRIVER];
    y0[XF] = values[vr::X_FLAPPER];
    y0[XS] = values[vr::X_SPOOL];
    y0[PA] = values[vr::P_A];
    y0[PB] = values[vr::P_B];
    y0[X] = values[vr::X_PISTON];
    y0[V] = values[vr::V_PISTON];
    if model.driver() == DriverKind::HBridge {
        // The bridge's mean voltage R i holds the current; u and ui are not states there.
        y0[UI] = 0.0;
        y0[U] = 0.0;
    }
    y0
}

/// The recorded outputs at `y` (`workloads::OUTPUTS` order).
fn outputs(model: &WholeModel, held: &RhsInputs, y: &[f64; NY]) -> [f64; 12] {
    let o = model.outputs(held, y);
    [
        o.i_coil,
        o.u_driver,
        o.x_flapper,
        o.x_spool,
        o.q_valve,
        o.q_a,
        o.q_b,
        o.p_a,
        o.p_b,
        o.x_piston,
        o.v_piston,
        o.f_hydraulic,
    ]
}
