//! The cylinder's equations linearised at a state, analytically: the Rosenbrock
//! integrator's Jacobian and time derivative (checked against differences in the
//! cylinder's tests).

use super::cylinder::{
    relief_flow, smooth_sign, stribeck_decay, CylinderParams, Mat4, Vec4, MIN_VOLUME_FRACTION,
    N_STATES, PA, PB, V, X,
};
use super::valve::{regularised_sqrt, regularised_sqrt_slope};

/// The model linearised at a state: `f` exactly as [`super::cylinder::derivatives`] computes it, the analytic
/// Jacobian `df/dy` and the sensitivity `df/dx_s` (the only time dependence: `df/dt = df/dx_s
/// x_s'`). At a kink of a piecewise law (a clamp, the branch of a `max`) the derivative is
/// taken on the side the state is on, ties broken towards increasing argument (as a forward
/// difference would see it), except at the contact switching surfaces of the end stop where it
/// is the side the state is on (no contact at exactly zero penetration or zero contact force).
pub(crate) fn linearise(
    params: &CylinderParams,
    y: &Vec4,
    x_s: f64,
    p_supply: f64,
    f_ext: f64,
) -> (Vec4, Mat4, Vec4) {
    let (p_a_raw, p_b_raw, x, v) = (y[PA], y[PB], y[X], y[V]);
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let [(volume_a, dva_dx), (volume_b, dvb_dx)] = chamber_volumes(params, x);
    let ports = port_flows(params, p_a_raw, p_b_raw, x_s, p_supply);
    let q_internal = params.c_leak * (p_a_raw - p_b_raw);
    let q_external_a = params.c_leak_external * (p_a_raw - params.p_tank);
    let q_external_b = params.c_leak_external * (p_b_raw - params.p_tank);
    let (relief_a, drelief_a) = relief_flow(params, p_a_raw);
    let (relief_b, drelief_b) = relief_flow(params, p_b_raw);
    let inflow_a = ports.q_a - area_a * v - q_internal - q_external_a - relief_a;
    let inflow_b = -ports.q_b + area_b * v + q_internal - q_external_b - relief_b;
    let (cf_a, dcfa_dpa) = cavitation_factor(params, p_a_raw, inflow_a);
    let (cf_b, dcfb_dpb) = cavitation_factor(params, p_b_raw, inflow_b);
    let (stiff_a, stiff_b) = (params.beta / volume_a, params.beta / volume_b);
    let dp_a = stiff_a * inflow_a * cf_a;
    let dp_b = stiff_b * inflow_b * cf_b;
    // Mechanics.
    let (friction, dfriction_dv) = friction(params, v);
    let (contact, dcontact_dx, dcontact_dv) = endstop_force(params, x, v);
    let force = p_a_raw * area_a - p_b_raw * area_b - friction + f_ext + contact;
    let f = [dp_a, dp_b, v, force / params.mass];

    let mut jac: Mat4 = [[0.0; N_STATES]; N_STATES];
    let (c_leak, c_ext) = (params.c_leak, params.c_leak_external);
    let (dqa_dpa, dqb_dpb) = (ports.dqa_dpa, ports.dqb_dpb);
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
    jac[V][X] = dcontact_dx / params.mass;
    jac[V][V] = (dcontact_dv - dfriction_dv) / params.mass;
    let f_xs = [stiff_a * cf_a * ports.dqa_dxs, -stiff_b * cf_b * ports.dqb_dxs, 0.0, 0.0];
    (f, jac, f_xs)
}

/// Chamber volumes `[(V_A, dV_A/dx), (V_B, dV_B/dx)]` at position `x`, clamped at
/// [`MIN_VOLUME_FRACTION`] of the dead volume (no slope there).
fn chamber_volumes(params: &CylinderParams, x: f64) -> [(f64, f64); 2] {
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let half = 0.5 * params.stroke;
    let min_volume = MIN_VOLUME_FRACTION * params.v_dead;
    let volume_a_free = params.v_dead + area_a * (x + half);
    let volume_b_free = params.v_dead + area_b * (half - x);
    [
        if volume_a_free >= min_volume { (volume_a_free, area_a) } else { (min_volume, 0.0) },
        if volume_b_free >= min_volume { (volume_b_free, -area_b) } else { (min_volume, 0.0) },
    ]
}

/// Port flows (`Q_A` into A, `Q_B` out of B) as `port_flows` computes them, with their
/// slopes in the chamber's own pressure and in `x_s`.
struct PortFlows {
    q_a: f64,
    q_b: f64,
    dqa_dpa: f64,
    dqb_dpb: f64,
    dqa_dxs: f64,
    dqb_dxs: f64,
}

/// The port flows at chamber pressures `p_a_raw`, `p_b_raw` (read at the cavitation floor
/// below it, where they have no slope) and their slopes.
fn port_flows(
    params: &CylinderParams,
    p_a_raw: f64,
    p_b_raw: f64,
    x_s: f64,
    p_supply: f64,
) -> PortFlows {
    let p_a = p_a_raw.max(params.p_cavitation);
    let p_b = p_b_raw.max(params.p_cavitation);
    let clamp_a = if p_a_raw >= params.p_cavitation { 1.0 } else { 0.0 };
    let clamp_b = if p_b_raw >= params.p_cavitation { 1.0 } else { 0.0 };
    let gain_per_xs = params.k3 / (0.5 * params.dp_rated).sqrt();
    let gain = params.k3 * x_s / (0.5 * params.dp_rated).sqrt();
    let lam = params.dp_laminar;
    let (r_a, dra_dpa, r_b, drb_dpb) = if x_s >= 0.0 {
        let (da, db) = (p_supply - p_a, p_b - params.p_tank);
        (
            regularised_sqrt(da, lam),
            -regularised_sqrt_slope(da, lam),
            regularised_sqrt(db, lam),
            regularised_sqrt_slope(db, lam),
        )
    } else {
        let (da, db) = (p_a - params.p_tank, p_supply - p_b);
        (
            regularised_sqrt(da, lam),
            regularised_sqrt_slope(da, lam),
            regularised_sqrt(db, lam),
            -regularised_sqrt_slope(db, lam),
        )
    };
    PortFlows {
        q_a: gain * r_a,
        q_b: gain * r_b,
        dqa_dpa: gain * dra_dpa * clamp_a,
        dqb_dpb: gain * drb_dpb * clamp_b,
        dqa_dxs: gain_per_xs * r_a,
        dqb_dxs: gain_per_xs * r_b,
    }
}

/// A chamber's bulk-modulus factor at pressure `p` with net inflow `inflow` and its slope
/// in `p`.
fn cavitation_factor(params: &CylinderParams, p: f64, inflow: f64) -> (f64, f64) {
    if inflow >= 0.0 {
        return (1.0, 0.0);
    }
    let band = params.dp_cavitation_band;
    let u_raw = (p - params.p_cavitation) / band;
    let u = u_raw.clamp(0.0, 1.0);
    let slope = if (0.0..1.0).contains(&u_raw) { (2.0 - 2.0 * u) / band } else { 0.0 };
    (u * (2.0 - u), slope)
}

/// Friction force at velocity `v` and its slope `dF/dv`.
fn friction(params: &CylinderParams, v: f64) -> (f64, f64) {
    let stribeck = (v / params.v_stribeck).powi(2);
    let decay = stribeck_decay(stribeck);
    let dry = params.f_coulomb + (params.f_static - params.f_coulomb) * decay;
    let ddry_dv = (params.f_static - params.f_coulomb)
        * decay
        * (-2.0 * v / (params.v_stribeck * params.v_stribeck));
    let th = smooth_sign(v / params.v_friction_smooth);
    let friction = dry * th + params.b_viscous * v;
    let dfriction_dv =
        ddry_dv * th + dry * (1.0 - th * th) / params.v_friction_smooth + params.b_viscous;
    (friction, dfriction_dv)
}

/// End-stop contact force at `(x, v)` and its slopes in `x` and `v`; on the switching
/// surfaces (zero penetration or zero contact force) the side without contact.
fn endstop_force(params: &CylinderParams, x: f64, v: f64) -> (f64, f64, f64) {
    let half = 0.5 * params.stroke;
    let (beyond_top, beyond_bottom) = (x - half, -half - x);
    if beyond_top > 0.0 {
        let s = params.k_endstop * beyond_top + params.c_endstop * v;
        if s > 0.0 {
            (-s, -params.k_endstop, -params.c_endstop)
        } else {
            (0.0, 0.0, 0.0)
        }
    } else if beyond_bottom > 0.0 {
        let s = params.k_endstop * beyond_bottom - params.c_endstop * v;
        if s > 0.0 {
            (s, -params.k_endstop, -params.c_endstop)
        } else {
            (0.0, 0.0, 0.0)
        }
    } else {
        (0.0, 0.0, 0.0)
    }
}
