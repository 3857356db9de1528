//! The peer: the same equations integrated by SUNDIALS CVODE (BDF, Newton, dense LU),
//! stepped through the same communication grid as a CVODE-based co-simulation FMU does:
//! inputs are set at each communication point, the method is restarted (CVodeReInit)
//! whenever the right-hand side jumps (an input changed, a PWM edge, a sample of a digital
//! loop), and CVODE integrates to each point or time event with it as the stop time.
//! The digital parts (H-bridge PWM and PI, the outer loops' PID) are the rlib's own
//! `physics::hbridge::Digital` and `physics::outer::OuterLoop`.

mod cvode;
mod rhs;

use std::ffi::{c_int, c_void};

use ehsv_actuator::hydraulics::{self, CylinderState};
use ehsv_actuator::physics::hbridge::Digital;
use ehsv_actuator::physics::outer::{ControlMode, OuterLoop};
use ehsv_actuator::physics::Params;
use ehsv_actuator::variables::{vr, N_VARIABLES};

pub use cvode::{Api, Counters};
pub use rhs::{Held, Rhs, NY, TRANSCRIBED};
use rhs::{I, PA, PB, U, UI, V, X, XF, XS};

use crate::reference::Trace;
use crate::timing::Stopwatch;
use crate::workloads::{Signal, Workload};

/// What the solver's callback needs: the model and the inputs in force.
struct Context<'a> {
    rhs: Rhs,
    params: Params,
    held: Held,
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
        (ctx.rhs)(&ctx.params, &ctx.held, y, dy);
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

/// Error weights: the tolerance of state k is `rtol * SCALE[k]` absolute (the FMU weighs
/// the cylinder the same way, `hydraulics::STATE_SCALE`).
fn scales(p: &Params) -> [f64; NY] {
    let i = 1e-2;
    let xf = p.k1 * i / p.kf;
    let [pa, pb, x, v] = hydraulics::STATE_SCALE;
    [i, 100.0, 100.0, xf, xf * p.wn, p.k1 * i / p.kw, pa, pb, x, v]
}

/// Runs `signal` of `workload` for `steps` communication steps of `h` with relative
/// tolerance `rtol`, from the FMU's own start state.
pub fn run(
    api: &Api,
    rhs: Rhs,
    workload: &Workload,
    signal: Signal,
    h: f64,
    steps: usize,
    rtol: f64,
) -> Result<PeerRun, String> {
    let start = crate::reference::start(workload, None)?;
    let mut values = [0.0; N_VARIABLES];
    for (k, v) in values.iter_mut().enumerate() {
        *v = start.get(k).unwrap();
    }
    let p = Params::from_values(&values)?;
    if p.x_flapper_max > 0.0 || p.x_spool_max > 0.0 {
        return Err("the peer does not model valve travel stops".into());
    }
    let rail = (values[vr::V_SUPPLY] - p.v_drop).max(0.0);
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
    // The equilibrium voltage R i (the H-bridge's output is one of the rails, its mean is this).
    let u_mean = (p.r_total * values[vr::I_COIL]).clamp(-rail, rail);
    let mut digital = Digital::at_equilibrium(&p.hbridge, u_mean, u_mean, rail, 0.0);
    let mut outer = OuterLoop::at_start(&p.loops, 0.0, 0.0);
    let mut ctx = Box::new(Context {
        rhs,
        params: p,
        held: Held {
            i_cmd: 0.0,
            rail,
            u_bridge: digital.output(rail),
            p_supply: values[vr::P_SUPPLY],
            f_ext: values[vr::F_EXT],
        },
        api,
    });
    let atol = scales(&p).map(|s| s * rtol);
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
        let reference = match p.loops.mode {
            ControlMode::Flow => q_ref,
            ControlMode::Position => x_ref,
            ControlMode::Current => 0.0,
        };
        let command = |outer: &OuterLoop| {
            if p.loops.mode == ControlMode::Current {
                i_ref
            } else {
                outer.command
            }
        };
        let held = Held { i_cmd: command(&outer), f_ext, ..ctx.held };
        if held != ctx.held {
            ctx.held = held;
            solver.restart()?;
            restarts += 1;
        }
        let mut t = t0;
        loop {
            let t_event = digital.next_event(&p.hbridge).min(outer.next_event(&p.loops));
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
            let y = solver.state();
            if outer.next_event(&p.loops) <= digital.next_event(&p.hbridge) {
                let measured = if p.loops.mode == ControlMode::Flow { p.k3 * y[XS] } else { y[X] };
                outer.sample(&p.loops, reference, measured);
                ctx.held.i_cmd = command(&outer);
            } else {
                digital.fire(&p.hbridge, y[I], ctx.held.i_cmd, p.r_total, rail);
                ctx.held.u_bridge = digital.output(rail);
            }
            solver.restart()?;
            restarts += 1;
        }
        let y: &[f64; NY] = solver.state().try_into().unwrap();
        trace.push(outputs(&p, &ctx.held, y));
    }
    let (wall, cpu) = clock.read();
    let counters = solver.counters();
    drop(solver);
    Ok(PeerRun { cpu, wall, counters, restarts, trace })
}

/// The recorded outputs at `y` (`workloads::OUTPUTS` order).
fn outputs(p: &Params, held: &Held, y: &[f64; NY]) -> [f64; 12] {
    let cylinder = CylinderState { p_a: y[PA], p_b: y[PB], x: y[X], v: y[V] };
    let c = hydraulics::outputs(&p.cylinder, &cylinder, y[XS], held.p_supply);
    let u = rhs::driver_voltage(p, held, y);
    [
        y[I],
        u,
        y[XF],
        y[XS],
        p.k3 * y[XS],
        c.q_a,
        c.q_b,
        c.p_a,
        c.p_b,
        c.x_piston,
        c.v_piston,
        c.f_hydraulic,
    ]
}
