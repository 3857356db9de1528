//! The rod's port to its load: with `cylinder.port = force` the model moves its own mass
//! under F_ext; with `motion` a host (a multibody simulator) owns the mass, gives the rod's
//! motion at each communication point and takes the force on the rod. What the host reads
//! back: the force's mean over the step (the momentum the step passes to the host's mass,
//! which keeps the plainest host loop stable for any mass: docs/coupling.md), and the
//! rod's local stiffness and damping, for hosts with implicit integrators.

use crate::components::cylinder::{self, CylinderState};
use crate::components::cylinder_terms::{chamber_terms, net_force};
use crate::components::metering_ports::AnyLap;

/// The span (s) over which [`Physics::outputs_along`](crate::Physics::outputs_along) moves the state: short against every
/// time constant of the model (the fastest, the oil columns', is ~7 us), long enough that
/// the outputs' rounding does not swamp their change.
pub const RATE_PROBE: f64 = 1e-9;

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
    let [a, b] = chamber_terms::<AnyLap>(params, state, x_s, p_supply);
    let [stiff_a, stiff_b] = [a.stiffness, b.stiffness];
    let [(fade_a, _), (fade_b, _)] = [a.cavitation, b.cavitation];
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let [_, dforce_dx, dforce_dv] = net_force(params, state, 0.0);
    let oil = stiff_a * fade_a * area_a * area_a + stiff_b * fade_b * area_b * area_b;
    (dforce_dx - oil, dforce_dv)
}
