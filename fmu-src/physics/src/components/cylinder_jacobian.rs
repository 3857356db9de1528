//! The cylinder's equations linearised at a state, analytically: the Rosenbrock
//! integrator's Jacobian and time derivative (checked against differences in the
//! cylinder's tests).

use crate::components::cylinder::{
    CylinderParams, CylinderState, Mat4, Vec4, N_STATES, PA, PB, V, X,
};
use crate::components::cylinder_terms::{cavitation_factor, chamber_terms, friction, net_force};
use crate::params::RodPort;

/// The model linearised at a state: `f` as [`super::cylinder::derivatives`] computes it
/// (from the same terms), the analytic Jacobian `df/dy` from the terms' slopes, and the
/// sensitivity `df/dx_s` (the only time dependence: `df/dt = df/dx_s x_s'`). Where a term's
/// law has a kink, its slope is taken as [`super::cylinder_terms`] says.
pub(crate) fn linearise(
    params: &CylinderParams,
    y: &Vec4,
    x_s: f64,
    p_supply: f64,
    load: f64,
) -> (Vec4, Mat4, Vec4) {
    let state = CylinderState::from_array(y);
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let chambers = chamber_terms(params, &state, x_s, p_supply);
    let [force, dforce_dx, dforce_dv] = net_force(params, &state, load);
    let [dp_a, dp_b] = chambers.pressure_rates;
    let mut f = [dp_a, dp_b, state.v, force / params.mass];

    let [(volume_a, dva_dx), (volume_b, dvb_dx)] = chambers.volumes;
    let [inflow_a, inflow_b] = chambers.inflows;
    let [(cf_a, dcfa_dpa), (cf_b, dcfb_dpb)] = chambers.cavitation;
    let [stiff_a, stiff_b] = chambers.stiffness;
    let [drelief_a, drelief_b] = chambers.relief_slopes;
    let ports = &chambers.ports;
    let (dqa_dpa, dqb_dpb) = (ports.dqa_dpa, ports.dqb_dpb);
    let (c_leak, c_ext) = (params.c_leak, params.c_leak_external);
    let mut jac: Mat4 = [[0.0; N_STATES]; N_STATES];
    // d inflow_a / d(p_a, p_b, x, v) = (dqa_dpa - c_leak - c_ext - drelief_a, c_leak, 0, -A_A)
    jac[PA][PA] = stiff_a * (cf_a * (dqa_dpa - c_leak - c_ext - drelief_a) + inflow_a * dcfa_dpa);
    jac[PA][PB] = stiff_a * cf_a * c_leak;
    jac[PA][X] = -stiff_a / volume_a * dva_dx * inflow_a * cf_a;
    jac[PA][V] = -stiff_a * cf_a * area_a;
    // d inflow_b / d(p_a, p_b, x, v) = (c_leak, -dqb_dpb - c_leak - c_ext - drelief_b, 0, A_B)
    jac[PB][PA] = stiff_b * cf_b * c_leak;
    jac[PB][PB] = stiff_b * (cf_b * (-dqb_dpb - c_leak - c_ext - drelief_b) + inflow_b * dcfb_dpb);
    jac[PB][X] = -stiff_b / volume_b * dvb_dx * inflow_b * cf_b;
    jac[PB][V] = stiff_b * cf_b * area_b;
    jac[X][V] = 1.0;
    jac[V][PA] = area_a / params.mass;
    jac[V][PB] = -area_b / params.mass;
    jac[V][X] = dforce_dx / params.mass;
    jac[V][V] = dforce_dv / params.mass;
    if params.port == RodPort::Motion {
        // The host moves the rod at the acceleration `load`: nothing here acts back on it.
        f[V] = load;
        jac[V] = [0.0; N_STATES];
    }
    let f_xs = [stiff_a * cf_a * ports.dqa_dxs, -stiff_b * cf_b * ports.dqb_dxs, 0.0, 0.0];
    (f, jac, f_xs)
}

/// Friction's creep band, in `cylinder.v_friction_smooth`: past this many its `tanh` is 1 to
/// rounding (tanh(20) = 1 - 8e-18), and a step outside it sees the friction's tangent.
const CREEP_BAND: f64 = 20.0;

/// For a fixed step of `h` that starts in the friction's creep band or crosses or reaches it
/// (`v` through zero: starting from rest, a reversal), the friction's slope in `jac` replaced
/// by its secant from `v` to the explicit prediction `v + h v'`. The band is 1e-4 m/s wide:
/// its tangent (3e5 N s/m at rest) holds a Rosenbrock step's velocity as a damper would,
/// though the piston leaves the band in a microsecond (a step from rest lost a sixth of its
/// velocity); the secant is the damping the step actually crosses. Outside the band the
/// tangent stays, and with it the method's order.
pub(crate) fn secant_friction(
    params: &CylinderParams,
    y: &Vec4,
    acceleration: f64,
    h: f64,
    jac: &mut Mat4,
) {
    if params.port == RodPort::Motion {
        return;
    }
    let (v0, v1) = (y[V], y[V] + h * acceleration);
    let band = CREEP_BAND * params.v_friction_smooth;
    if (v0 * v1 > 0.0 && v0.abs().min(v1.abs()) > band) || v1 == v0 {
        return;
    }
    let (f0, tangent) = friction(params, v0);
    let secant = (friction(params, v1).0 - f0) / (v1 - v0);
    jac[V][V] += (tangent - secant) / params.mass;
}

/// For a fixed step of `h` in which a chamber being emptied heads into the cavitation band
/// (the explicit prediction `p + h p'` below the band's top), the fade's slope in `jac`
/// replaced by its secant from `p` to the prediction, held at the floor, where the secant is
/// the steeper. Above the band and at its top the fade's tangent is zero, yet inside the
/// band the pressure settles onto the floor within microseconds: a step that saw only the
/// tangent ran its stages far below the floor (2e5 Pa on the 20 Hz squares, lifted back by
/// the floor's clamp), and the rod's force with them (the step was 4e-6 m/s off in the
/// velocity). With the secant the undershoot is 1e4 Pa at most. Elsewhere the tangent stays,
/// and with it the method's order.
pub(crate) fn secant_cavitation(
    params: &CylinderParams,
    y: &Vec4,
    rates: &Vec4,
    h: f64,
    jac: &mut Mat4,
) {
    let top = params.p_cavitation + params.dp_cavitation_band;
    for k in [PA, PB] {
        let (p0, rate) = (y[k], rates[k]);
        let p1 = (p0 + h * rate).max(params.p_cavitation);
        if rate >= 0.0 || p1 >= top {
            continue;
        }
        // Emptying (the rate is negative), so the fade's branch of the factor applies.
        let (factor, tangent) = cavitation_factor(params, p0, -1.0);
        if factor <= 0.0 {
            // On the floor (or below it by rounding, where `p1`, held at the floor, is not
            // below `p0`): its tangent is the steepest slope there is.
            continue;
        }
        let secant = (cavitation_factor(params, p1, -1.0).0 - factor) / (p1 - p0);
        if secant > tangent {
            // The fade's term of dp'/dp is (beta/V) * inflow * slope, and p' is
            // (beta/V) * inflow * factor.
            jac[k][k] += rate / factor * (secant - tangent);
        }
    }
}
