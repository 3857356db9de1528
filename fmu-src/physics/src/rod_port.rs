//! The rod's port to its load: with `cylinder.port = force` the model moves its own mass
//! under F_ext; with `motion` a host (a multibody simulator) owns the mass, gives the rod's
//! motion at each communication point and takes the force on the rod. What the host reads
//! back: the force's mean over the step (the momentum the step passes to the host's mass,
//! which keeps the plainest host loop stable for any mass: docs/coupling.md), and the
//! rod's local stiffness and damping, for hosts with implicit integrators.

use super::actuator::{current_system, Actuator};
use super::cylinder::{self, check_inside, CylinderState};
use super::cylinder_terms::{chamber_terms, net_force};
use super::*;

/// The span (s) over which [`Physics::outputs_along`] moves the state: short against every
/// time constant of the model (the fastest, the oil columns', is ~7 us), long enough that
/// the outputs' rounding does not swamp their change.
pub const RATE_PROBE: f64 = 1e-9;

impl Actuator {
    /// Puts the cylinder at rest in equilibrium for the held inputs; with the motion port
    /// the rod where the host says.
    pub(crate) fn start_cylinder(&mut self, held: &HeldInputs, inputs: &Inputs) {
        let c = &self.params.cylinder;
        let force = if c.port == RodPort::Force { held.load } else { 0.0 };
        self.cylinder.state = cylinder::equilibrium(c, held.p_supply, force);
        if c.port == RodPort::Motion {
            (self.cylinder.state.x, self.cylinder.state.v) = (inputs.x_rod, inputs.v_rod);
        }
    }

    /// With the motion port, moves the rod to the host's position and velocity at the
    /// start of a step (refused, nothing changed, if that puts the piston through the end
    /// of the cylinder); returns the force on the rod there.
    pub(crate) fn take_rod_motion(&mut self, inputs: &Inputs) -> Result<f64, String> {
        if self.params.cylinder.port == RodPort::Motion {
            let moved = CylinderState { x: inputs.x_rod, v: inputs.v_rod, ..self.cylinder.state };
            check_inside(&self.params.cylinder, &moved)?;
            self.cylinder.state = moved;
        }
        Ok(self.rod_force())
    }

    /// The force of the actuator on the rod at the current state (N, + = extension).
    pub(crate) fn rod_force(&self) -> f64 {
        net_force(&self.params.cylinder, &self.cylinder.state, 0.0)[0]
    }

    /// See [`Physics::outputs_along`].
    pub(crate) fn outputs_along(&self, inputs: &Inputs, span: f64) -> Outputs {
        let system = current_system(&self.params, &self.active, &self.systems, self.mode);
        let dz = system.a * self.z;
        let held = HeldInputs::new(&self.params, inputs);
        let state = &self.cylinder.state;
        let c = &self.params.cylinder;
        let dy = cylinder::derivatives(c, state, self.z[XS], held.p_supply, held.load);
        let z = self.z + dz * span;
        let mut y = state.to_array();
        for (y, d) in y.iter_mut().zip(dy) {
            *y += d * span;
        }
        let moved = CylinderState::from_array(&y);
        self.outputs_at(&z, &moved)
    }
}

/// The rod's local stiffness and damping at `state` (N/m, N s/m): a rod displaced by `dx`
/// compresses one oil column and expands the other (`dp = -beta A dx / V`, the bulk modulus
/// faded near the cavitation floor), plus the end stop's contact; the damping is the
/// friction's slope and the contact's.
pub(crate) fn rod_stiffness(
    params: &cylinder::CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
) -> (f64, f64) {
    let chambers = chamber_terms(params, state, x_s, p_supply);
    let [stiff_a, stiff_b] = chambers.stiffness;
    let [(fade_a, _), (fade_b, _)] = chambers.cavitation;
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let [_, dforce_dx, dforce_dv] = net_force(params, state, 0.0);
    let oil = stiff_a * fade_a * area_a * area_a + stiff_b * fade_b * area_b * area_b;
    (dforce_dx - oil, dforce_dv)
}

impl Physics {
    /// The outputs with the state moved `span` seconds along its current rates (the valve
    /// and driver by their mode's matrix, the cylinder by its equations under `inputs`):
    /// differences of these give the outputs' time derivatives. F_rod is the force at that
    /// state, not a step's mean.
    pub fn outputs_along(&self, inputs: &Inputs, span: f64) -> Outputs {
        self.actuator.outputs_along(inputs, span)
    }
}
