//! The whole model as one explicit right-hand side `dy = f(y, held inputs)`, for the peer.
//!
//! The interface ([`Rhs`], [`Held`], the state order) is what the physics should expose so
//! that there is one transcription of the model. Until it does, [`TRANSCRIBED`] builds it
//! from what the `ehsv_actuator` rlib makes public: the cylinder is the FMU's own
//! `hydraulics::derivatives`; the coil, the Moog 30 first stage and spool and the op-amp PI
//! driver are written out here from the public `physics::Params` (the FMU keeps them as
//! private mode matrices). Differences from the FMU, by design of a smooth-ODE peer: the
//! op-amp output is a state that tracks `clamp(Kp e + ui, +-rail)` at the rate
//! [`TRACKING`] (1e8 1/s: 10 ns behind) limited to +-slew_rate, where the FMU switches
//! exactly between slewing and following; and the valve travel stops are not modelled
//! (off by default). The slew limit itself matters: it binds ~3.5 us after each command
//! jump, worth ~1 % of the coil current right after a 5 mA step.

use ehsv_actuator::hydraulics::{self, CylinderState};
use ehsv_actuator::physics::{DriverKind, Params};

/// State: coil current, PI integrator output, driver output, flapper position and velocity, spool,
/// chamber pressures, piston position and velocity.
pub const NY: usize = 10;
pub const I: usize = 0;
pub const UI: usize = 1;
pub const U: usize = 2;
pub const XF: usize = 3;
pub const VF: usize = 4;
pub const XS: usize = 5;
pub const PA: usize = 6;
pub const PB: usize = 7;
pub const X: usize = 8;
pub const V: usize = 9;

/// Rate at which the op-amp output follows its unsaturated target (1/s).
pub const TRACKING: f64 = 1e8;

/// Inputs and discrete states held between events.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Held {
    /// Coil current command (i_ref, or the outer loop's output) (A).
    pub i_cmd: f64,
    /// Driver rail V_supply - V_drop (V).
    pub rail: f64,
    /// H-bridge output between switching instants (V) (other drivers: unused).
    pub u_bridge: f64,
    pub p_supply: f64,
    pub f_ext: f64,
}

/// `dy = f(y)` of the whole model for the held inputs.
pub type Rhs = fn(&Params, &Held, &[f64; NY], &mut [f64; NY]);

/// The right-hand side built from the rlib's public pieces (see the module note).
pub const TRANSCRIBED: Rhs = transcribed;

/// The driver output voltage at `y` (op-amp: rails; H-bridge: the held switch output).
pub fn driver_voltage(p: &Params, held: &Held, y: &[f64; NY]) -> f64 {
    match p.driver {
        DriverKind::HBridge => held.u_bridge,
        _ => y[U],
    }
}

fn transcribed(p: &Params, held: &Held, y: &[f64; NY], dy: &mut [f64; NY]) {
    let e = held.i_cmd - y[I];
    let u = driver_voltage(p, held, y);
    let u_lin = p.kp * e + y[UI];
    let pull = TRACKING * (u_lin.clamp(-held.rail, held.rail) - y[U]);
    let slewing = pull.abs() > p.slew_rate;
    // Anti-windup: the integrator stops while the output is on a rail (not slewing to it)
    // and the error pushes further.
    let frozen = !slewing && ((u_lin >= held.rail && e > 0.0) || (u_lin <= -held.rail && e < 0.0));
    if p.driver == DriverKind::HBridge {
        dy[UI] = 0.0;
        dy[U] = 0.0;
    } else {
        dy[UI] = if frozen { 0.0 } else { p.ki * e };
        dy[U] = pull.clamp(-p.slew_rate, p.slew_rate);
    }
    dy[I] = (u - p.r_total * y[I] - p.k_backemf * y[VF]) / p.inductance;
    let wn2 = p.wn * p.wn;
    dy[XF] = y[VF];
    dy[VF] = -wn2 * y[XF] - 2.0 * p.zeta * p.wn * y[VF] + wn2 * (p.k1 * y[I] - p.kw * y[XS]) / p.kf;
    dy[XS] = p.k2 / p.spool_area * y[XF];
    let cylinder = CylinderState { p_a: y[PA], p_b: y[PB], x: y[X], v: y[V] };
    let d = hydraulics::derivatives(&p.cylinder, &cylinder, y[XS], held.p_supply, held.f_ext);
    dy[PA..].copy_from_slice(&d);
}
