//! The cylinder's equations linearised at a state, analytically: the Rosenbrock
//! integrator's Jacobian and time derivative (checked against differences in the
//! cylinder's tests).

use crate::components::cylinder::{CylinderParams, CylinderState, Mat4, Vec4, N_STATES, PA, PB, V};
use crate::components::cylinder_terms::{
    at_least, cavitation_factor, chamber_terms, friction, net_force_with,
};
use crate::params::RodPort;

/// The model linearised at a state, in the shape of its Jacobian: `x' = v` makes the row
/// of `x` the constant `e_V`, and the spool acts on the pressures' rates alone, so three rows
/// and two sensitivities are all that a state changes. [`linearise`] spreads it into the
/// 4x4; the fixed-cost step keeps it as it is.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Linearisation {
    /// `f` as [`super::cylinder::derivatives`] computes it (from the same terms).
    pub rates: Vec4,
    /// The rows `d p_A'/dy`, `d p_B'/dy` and `d v'/dy` of the Jacobian.
    pub d_pa: Vec4,
    pub d_pb: Vec4,
    pub d_v: Vec4,
    /// `[d p_A'/dx_s, d p_B'/dx_s]`.
    pub d_xs: [f64; 2],
    /// The friction and its slope at the state's velocity ([`friction`]), which the
    /// friction's secant starts from.
    pub friction: (f64, f64),
}

impl Linearisation {
    /// The Jacobian's diagonal entry `d p'/dp` of chamber `k` (`PA` or `PB`).
    pub(crate) fn diagonal_mut(&mut self, k: usize) -> &mut f64 {
        if k == PA {
            &mut self.d_pa[PA]
        } else {
            &mut self.d_pb[PB]
        }
    }
}

/// The model linearised at a state: `f`, the analytic Jacobian `df/dy` from the terms'
/// slopes, and the sensitivity `df/dx_s` (the only time dependence: `df/dt = df/dx_s x_s'`).
/// Where a term's law has a kink, its slope is taken as [`super::cylinder_terms`] says.
pub(crate) fn linearise(
    params: &CylinderParams,
    y: &Vec4,
    x_s: f64,
    p_supply: f64,
    load: f64,
) -> (Vec4, Mat4, Vec4) {
    let l = linearisation(params, y, x_s, p_supply, load, friction(params, y[V]));
    let jac = [l.d_pa, l.d_pb, [0.0, 0.0, 0.0, 1.0], l.d_v];
    (l.rates, jac, [l.d_xs[0], l.d_xs[1], 0.0, 0.0])
}

/// [`linearise`] in the shape of [`Linearisation`], with the friction and its slope at the
/// state's velocity `friction` ([`friction`]) given: a caller computes it where few values
/// are live across its libm calls (exp, tanh), which save and restore every one. Inlined:
/// the fixed-cost step keeps its rows where they are computed.
#[inline(always)]
pub(crate) fn linearisation(
    params: &CylinderParams,
    y: &Vec4,
    x_s: f64,
    p_supply: f64,
    load: f64,
    friction: (f64, f64),
) -> Linearisation {
    let state = CylinderState::from_array(y);
    let chambers = pressure_rows(params, &state, x_s, p_supply);
    let (acceleration, d_v) = motion_row(params, &state, load, friction);
    Linearisation {
        rates: [chambers.rates[0], chambers.rates[1], state.v, acceleration],
        d_pa: chambers.d_pa,
        d_pb: chambers.d_pb,
        d_v,
        d_xs: chambers.d_xs,
        friction,
    }
}

/// The pressures' side of a [`Linearisation`].
struct PressureRows {
    rates: [f64; 2],
    d_pa: Vec4,
    d_pb: Vec4,
    d_xs: [f64; 2],
}

/// The chambers' pressure rates at `state`, their rows of the Jacobian and their slopes in
/// the spool position, from [`chamber_terms`].
#[inline(always)]
fn pressure_rows(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
) -> PressureRows {
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let chambers = chamber_terms(params, state, x_s, p_supply);
    let [(volume_a, dva_dx), (volume_b, dvb_dx)] = chambers.volumes;
    let [inflow_a, inflow_b] = chambers.inflows;
    let [(cf_a, dcfa_dpa), (cf_b, dcfb_dpb)] = chambers.cavitation;
    let [stiff_a, stiff_b] = chambers.stiffness;
    let [drelief_a, drelief_b] = chambers.relief_slopes;
    let ports = &chambers.ports;
    let (dqa_dpa, dqb_dpb) = (ports.dqa_dpa, ports.dqb_dpb);
    let (c_leak, c_ext) = (params.c_leak, params.c_leak_external);
    // d inflow_a / d(p_a, p_b, x, v) = (dqa_dpa - c_leak - c_ext - drelief_a, c_leak, 0, -A_A)
    let d_pa = [
        stiff_a * (cf_a * (dqa_dpa - c_leak - c_ext - drelief_a) + inflow_a * dcfa_dpa),
        stiff_a * cf_a * c_leak,
        -stiff_a / volume_a * dva_dx * inflow_a * cf_a,
        -stiff_a * cf_a * area_a,
    ];
    // d inflow_b / d(p_a, p_b, x, v) = (c_leak, -dqb_dpb - c_leak - c_ext - drelief_b, 0, A_B)
    let d_pb = [
        stiff_b * cf_b * c_leak,
        stiff_b * (cf_b * (-dqb_dpb - c_leak - c_ext - drelief_b) + inflow_b * dcfb_dpb),
        -stiff_b / volume_b * dvb_dx * inflow_b * cf_b,
        stiff_b * cf_b * area_b,
    ];
    PressureRows {
        rates: chambers.pressure_rates,
        d_pa,
        d_pb,
        d_xs: [stiff_a * cf_a * ports.dqa_dxs, -stiff_b * cf_b * ports.dqb_dxs],
    }
}

/// The rod's acceleration at `state` under `load` and its row of the Jacobian, with the
/// friction and its slope `friction` at the state's velocity.
#[inline(always)]
fn motion_row(
    params: &CylinderParams,
    state: &CylinderState,
    load: f64,
    friction: (f64, f64),
) -> (f64, Vec4) {
    match params.port {
        RodPort::Force => {
            let [force, dforce_dx, dforce_dv] = net_force_with(params, state, load, friction);
            let (area_a, area_b) = (params.area_a(), params.area_b());
            (
                force / params.mass,
                [
                    area_a / params.mass,
                    -area_b / params.mass,
                    dforce_dx / params.mass,
                    dforce_dv / params.mass,
                ],
            )
        }
        // The host moves the rod at the acceleration `load`: nothing here acts back on it.
        RodPort::Motion => (load, [0.0; N_STATES]),
    }
}

/// Friction's creep band, in `cylinder.v_friction_smooth`: past this many its `tanh` is 1 to
/// rounding (tanh(20) = 1 - 8e-18), and a step outside it sees the friction's tangent.
const CREEP_BAND: f64 = 20.0;

/// For a fixed step of `h` that starts in the friction's creep band or crosses or reaches it
/// (`v` through zero: starting from rest, a reversal), the friction's slope in `l` replaced
/// by its secant from `v` to the explicit prediction `v + h v'`. The band is 1e-4 m/s wide:
/// its tangent (3e5 N s/m at rest) holds a Rosenbrock step's velocity as a damper would,
/// though the piston leaves the band in a microsecond (a step from rest lost a sixth of its
/// velocity); the secant is the damping the step actually crosses. Outside the band the
/// tangent stays, and with it the method's order.
pub(crate) fn secant_friction(params: &CylinderParams, y: &Vec4, h: f64, l: &mut Linearisation) {
    if params.port == RodPort::Motion {
        return;
    }
    let (v0, v1) = (y[V], y[V] + h * l.rates[V]);
    let band = CREEP_BAND * params.v_friction_smooth;
    if (v0 * v1 > 0.0 && v0.abs() > band && v1.abs() > band) || v1 == v0 {
        return;
    }
    let (f0, tangent) = l.friction;
    let secant = (friction(params, v1).0 - f0) / (v1 - v0);
    l.d_v[V] += (tangent - secant) / params.mass;
}

/// For a fixed step of `h` in which a chamber being emptied heads into the cavitation band
/// (the explicit prediction `p + h p'` below the band's top), the fade's slope in `l`
/// replaced by its secant from `p` to the prediction, held at the floor, where the secant is
/// the steeper. Above the band and at its top the fade's tangent is zero, yet inside the
/// band the pressure settles onto the floor within microseconds: a step that saw only the
/// tangent ran its stages far below the floor (2e5 Pa on the 20 Hz squares, lifted back by
/// the floor's clamp), and the rod's force with them (the step was 4e-6 m/s off in the
/// velocity). With the secant the undershoot is 1e4 Pa at most. Elsewhere the tangent stays,
/// and with it the method's order.
pub(crate) fn secant_cavitation(params: &CylinderParams, y: &Vec4, h: f64, l: &mut Linearisation) {
    let top = params.p_cavitation + params.dp_cavitation_band;
    for k in [PA, PB] {
        let (p0, rate) = (y[k], l.rates[k]);
        let p1 = at_least(p0 + h * rate, params.p_cavitation);
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
            *l.diagonal_mut(k) += rate / factor * (secant - tangent);
        }
    }
}
