//! The inputs held over one step, in the form the equations use them.

use crate::components::coefficients::Coefficients;
use crate::components::driver;
use crate::params::{ControlMode, Inputs, RodPort};

/// Inputs held over one step, as the equations use them.
#[derive(Clone, Copy)]
pub(crate) struct HeldInputs {
    pub(crate) i_ref: f64,
    pub(crate) rail: f64,
    pub(crate) p_supply: f64,
    /// The load on the rod: F_ext (N) with the force port, the host's acceleration of the
    /// rod (m/s2) with the motion port.
    pub(crate) load: f64,
    /// Reference of the outer loop (Q_ref or x_ref).
    pub(crate) reference: f64,
}

impl HeldInputs {
    pub(crate) fn new(c: &Coefficients, inputs: &Inputs) -> HeldInputs {
        let reference = match c.loops.mode {
            ControlMode::Flow => inputs.q_ref,
            ControlMode::Position => inputs.x_ref,
            ControlMode::Current => 0.0,
        };
        HeldInputs {
            i_ref: inputs.i_ref,
            rail: driver::rail(c, inputs.v_supply),
            p_supply: inputs.p_supply,
            load: match c.cylinder.port {
                RodPort::Force => inputs.f_ext,
                RodPort::Motion => inputs.a_rod,
            },
            reference,
        }
    }
}
