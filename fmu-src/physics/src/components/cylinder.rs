//! Double-acting cylinder and its mechanical load, fed by the valve's metering ports (see
//! [`super::metering_ports`]). The terms of its equations, each with its slopes, are in
//! [`super::cylinder_terms`]; here they are summed to the rates, and its linearisation is in
//! [`super::cylinder_jacobian`].
//!
//! State `[p_A, p_B, x, v]`: chamber pressures, piston position (0 = mid-stroke, + = extension)
//! and velocity. The spool position `x_s(t)` comes from the exact integrator of [`crate`] as a function of
//! time over each step; the Rosenbrock integrator ([`crate::numerics::rosenbrock`]) advances it.
//!
//! # Modelling choices
//! * **Pressures are gauge** (relative to atmosphere); the tank is at `p_tank` = 0.
//! * **Valve ports** (critically centred, no lap, no leakage, [`super::metering_ports`]): for
//!   `x_s >= 0` `Q_A = K3 x_s rsqrt(p_S - p_A)/sqrt(dp_r/2)` and `Q_B = K3 x_s rsqrt(p_B - p_T)/sqrt(dp_r/2)`,
//!   mirrored for `x_s < 0`. `rsqrt` is a signed square root, replaced below `dp_laminar` by
//!   the odd cubic that matches value and slope at `dp_laminar` (C1, slope `1.25/sqrt(dp_lam)`
//!   at zero instead of infinite), so the Jacobian stays finite at a closed or balanced port.
//!   Reverse flow (load pressure above supply) follows the same law with the sign reversed.
//! * **Cavitation floor**: a chamber being emptied (net inflow < 0) has its effective bulk
//!   modulus faded to zero over `dp_cavitation_band` above `p_cavitation`
//!   (factor `u(2-u)`, `u = (p - p_cav)/band` clamped to [0, 1]: C1 where it starts, and it
//!   vanishes at the floor). `p = p_cav` is then a barrier the exact solution cannot cross:
//!   the chamber keeps growing at the floor (vapour/air) without the pressure falling further,
//!   and refills as soon as the net inflow turns positive. A filling chamber is never slowed.
//!   The flow law also reads `max(p, p_cav)`, and accepted steps clamp rounding-size
//!   undershoot (reported in [`crate::numerics::rosenbrock::Stats::floor_clamp`], which the tests require to be tiny).
//!   Not modelled: the vapour volume that must be refilled before pressure rises again.
//! * **Friction** (smooth, no stick-slip switching): `F = (Fc + (Fs - Fc) exp(-(v/vs)^2))
//!   tanh(v/v_smooth) + b v`. `v_smooth` (0.1 mm/s) is the creep speed scale of the `tanh`; it
//!   replaces the sign function so there is no sticking singularity. At rest `F = 0`.
//! * **End stops**: spring-dampers beyond `+-S/2`; the damper acts only while penetrating, and
//!   the total contact force is `max(0, k d + c d')`, so a separating stop never pulls.
//! * **Leakage**: internal `C_leak (p_A - p_B)` from A to B, external `C_leak_external (p - p_T)`
//!   from each chamber to the drain. Both default to 0.
//! * **Relief valves**, one from each chamber to tank (port relief, not cross-port): shut
//!   while `p - p_T <= p_crack`, then `Q = Q_rated (d/dp_ov)^2` for the rise
//!   `d = p - p_T - p_crack` up to the override `dp_ov` and `Q_rated (2 d/dp_ov - 1)` beyond
//!   (the slope matched: C1, so the Jacobian is finite and exact, and rated flow at crack +
//!   override). Chamber to tank bounds each chamber's pressure whatever the other one
//!   holds (a cross-port valve bounds only `p_A - p_B`, and from the rod side it cannot fill
//!   the larger cap side anyway). `p_crack = 0` removes them. The supply must stay below
//!   the setting (checked), so they are shut in normal operation.
//! * **Chamber volumes** are clamped at
//!   [`MIN_VOLUME_FRACTION`](super::cylinder_params::MIN_VOLUME_FRACTION) of the dead volume
//!   so the equations stay finite, but a state that reaches the clamp (the piston through the
//!   end of the cylinder) is refused ([`check_inside`]), never integrated on.
//! * **Equilibrium start**: with `x_s = 0` both chambers are sealed, so any pressure pair on the
//!   force balance is an equilibrium. We take the one an (infinitesimally) underlapped real valve
//!   would settle to at null: its four metering edges balance leak flows when
//!   `p_A + p_B = p_S + p_T` (see [`equilibrium`]); with the force balance that fixes both.
//!   Note: with this area ratio (A_B/A_A = 0.61) the no-load steady flow is NOT `K3 x_s`: equal
//!   piston speeds need `Q_B/Q_A = A_B/A_A`, which shifts both port drops (about
//!   `Q_A = 1.28 K3 x_s` at `p_S = dp_r`). `K3 x_s` is exact only for a symmetric cylinder.
//!

use crate::components::cylinder_terms::{
    chamber_terms, free_volumes, net_force, port_flows, relief_flow, supply_flow,
};
use crate::components::metering_ports::{AnyLap, PortLaw};
use crate::numerics::root_finding::newton_in_bracket;
use crate::params::{Outputs, RodPort};
use crate::readable::readable;

pub(crate) use crate::components::cylinder_params::{
    CylinderParams, CylinderState, Mat4, Vec4, N_STATES, PA, PB, V, X,
};

/// Rest state at mid-stroke for a centred valve: `p_A + p_B = p_S + p_T` (the null of an
/// underlapped valve: with leak openings `u + d` and `u - d` on P->A / A->T and the reverse on
/// the B side, both chambers balance when `p_A/(p_S - p_A) = r` and `p_B/(p_S - p_B) = 1/r`, i.e.
/// `p_A + p_B = p_S` with the tank at 0), together with `p_A A_A - p_B A_B + F_ext = 0`.
/// For F_ext = 0: `p_A = (p_S + p_T) A_B/(A_A + A_B)`. Loads the valve cannot hold with both
/// pressures in `[p_T, p_S]` are clamped there (then the force balance is not met).
pub(crate) fn equilibrium(params: &CylinderParams, p_supply: f64, f_ext: f64) -> CylinderState {
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let sum = p_supply + params.p_tank;
    let (lo, hi) = (params.p_tank.min(p_supply), params.p_tank.max(p_supply));
    let p_a = ((sum * area_b - f_ext) / (area_a + area_b)).clamp(lo, hi);
    let p_b = ((p_a * area_a + f_ext) / area_b).clamp(lo, hi);
    CylinderState { p_a, p_b, x: 0.0, v: 0.0 }
}

/// Refuses a state in which a chamber volume reached its clamp: the piston is through the
/// end stop and the dead volume (an end stop that cannot hold the load), where the
/// clamped equations no longer describe anything physical.
pub(crate) fn check_inside(params: &CylinderParams, state: &CylinderState) -> Result<(), String> {
    let (volume_a, volume_b) = free_volumes(params, state.x);
    let min_volume = params.min_volume();
    // A NaN position fails both comparisons: refused too.
    if volume_a >= min_volume && volume_b >= min_volume {
        return Ok(());
    }
    Err(through_the_stop(params, state.x))
}

/// [`check_inside`]'s message, naming the chamber (A first, as for a NaN position). Cold
/// and out of line: the check runs on every step, two comparisons.
#[cold]
#[inline(never)]
fn through_the_stop(params: &CylinderParams, x: f64) -> String {
    let (volume_a, volume_b) = free_volumes(params, x);
    let (volume, chamber, end) =
        if volume_a >= params.min_volume() { (volume_b, "B", "+") } else { (volume_a, "A", "-") };
    format!(
        "x_piston = {} m is through the {end}stroke/2 end stop into chamber {chamber}'s dead \
         volume (chamber volume {} m3, cylinder.V_dead = {} m3): the end stop \
         (cylinder.k_endstop) cannot hold the load; step refused",
        readable(x),
        readable(volume),
        readable(params.v_dead)
    )
}

/// Which chambers' relief valves pass flow at this state: `[A, B]`.
pub(crate) fn relief_open(params: &CylinderParams, state: &CylinderState) -> [bool; 2] {
    [state.p_a, state.p_b].map(|p| relief_flow(params, p).0 > 0.0)
}

/// `[p_A', p_B', x', v']` for spool position `x_s`, the ports by the law `L`.
pub(crate) fn derivatives<L: PortLaw>(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
    load: f64,
) -> [f64; 4] {
    let [a, b] = chamber_terms::<L>(params, state, x_s, p_supply);
    let [dp_a, dp_b] = [a.pressure_rate, b.pressure_rate];
    [dp_a, dp_b, state.v, acceleration(params, state, load)]
}

/// The rod's acceleration under `load`: with the force port `load` is F_ext and the
/// acceleration the net force over the moving mass; with the motion port `load` is the
/// acceleration the host prescribes over the step.
#[inline(always)]
pub(crate) fn acceleration(params: &CylinderParams, state: &CylinderState, load: f64) -> f64 {
    match params.port {
        RodPort::Force => net_force(params, state, load)[0] / params.mass,
        RodPort::Motion => load,
    }
}

/// Writes the hydraulic side's outputs at a state into `out`.
pub(crate) fn write_outputs(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
    out: &mut Outputs,
) {
    write_state_outputs(params, state, out);
    let flows = port_flows::<AnyLap>(params, [state.p_a, state.p_b], x_s, p_supply);
    (out.q_a, out.q_b) = (flows.q_a, flows.q_b);
    out.q_supply = supply_flow(params, [state.p_a, state.p_b], x_s, p_supply);
}

/// Writes the hydraulic side's outputs that are read off the state (not the port flows).
pub(crate) fn write_state_outputs(
    params: &CylinderParams,
    state: &CylinderState,
    out: &mut Outputs,
) {
    out.p_a = state.p_a;
    out.p_b = state.p_b;
    out.x_piston = state.x;
    out.v_piston = state.v;
    out.f_hydraulic = state.p_a * params.area_a() - state.p_b * params.area_b();
}

/// Time from `y` to the first end-stop contact switch within `(0, span]`, from the Taylor
/// polynomial of the switching function (`x'' = f_V`, `x''' = (J f + f_t)_V` from the
/// linearisation). Switches: `x` reaching `+-stroke/2` from outside the stop (the contact
/// force jumps in by `c |v|`), and inside a stop the contact force `k d + c d'` crossing zero
/// (separation or re-engagement: a kink). Leaving a stop is smooth (the force is already 0).
/// Inlined in each law's copy of the cylinder's integrator.
#[inline(always)]
pub(crate) fn next_contact_switch(
    params: &CylinderParams,
    y: &Vec4,
    (f0, jac, f_t): (&Vec4, &Mat4, &Vec4),
    span: f64,
) -> Option<f64> {
    let half = params.half_stroke();
    let (x, v, a) = (y[X], y[V], f0[V]);
    let jerk = (0..N_STATES).map(|j| jac[V][j] * f0[j]).sum::<f64>() + f_t[V];
    let (k, c) = (params.k_endstop, params.c_endstop);
    // Taylor coefficients [g, dg, d2g, d3g] of the switching function, positive inside the
    // stop / in contact. For the contact force the third derivative is not available from
    // the linearisation: that polynomial is quadratic.
    let g = if x > half {
        let s = k * (x - half) + c * v;
        [s, k * v + c * a, k * a + c * jerk, 0.0]
    } else if x < -half {
        let s = k * (-half - x) - c * v;
        [s, -k * v - c * a, -k * a - c * jerk, 0.0]
    } else if x >= 0.0 {
        [x - half, v, a, jerk]
    } else {
        [-half - x, -v, -a, -jerk]
    };
    let poly = |t: f64| g[0] + t * (g[1] + t * (0.5 * g[2] + t * g[3] / 6.0));
    let slope = |t: f64| g[1] + t * (g[2] + t * 0.5 * g[3]);
    let inside = g[0] > 0.0;
    let crossed = |value: f64| (value > 0.0) != inside;
    if !crossed(poly(span)) {
        // A double crossing within the span (touch and leave) is not looked for.
        return None;
    }
    let start = if g[1] != 0.0 { -g[0] / g[1] } else { 0.5 * span };
    let (_, hi) = newton_in_bracket(|t| (poly(t), slope(t)), crossed, (0.0, span), start, 1e-12);
    Some(hi)
}

/// Time from `y` to the first point within `(0, span]` where a chamber in the cavitation band
/// turns from filling to emptying or back: its bulk-modulus factor changes there from 1 to
/// `u(2-u) < 1` (or back), a kink in `p'`. Predicted from the first-order Taylor polynomial of
/// `p'`, which has the net inflow's sign while the factor is positive.
#[inline(never)]
pub(crate) fn next_cavitation_switch(
    params: &CylinderParams,
    y: &Vec4,
    (f0, jac, f_t): (&Vec4, &Mat4, &Vec4),
    span: f64,
) -> Option<f64> {
    let band_top = params.cavitation_band_top();
    let mut first: Option<f64> = None;
    for k in [PA, PB] {
        if y[k] >= band_top {
            continue;
        }
        let rate = (0..N_STATES).map(|j| jac[k][j] * f0[j]).sum::<f64>() + f_t[k];
        let t = -f0[k] / rate;
        if t > 0.0 && t <= span {
            first = Some(first.map_or(t, |f| f.min(t)));
        }
    }
    first
}

#[cfg(test)]
#[path = "cylinder_tests.rs"]
mod tests;
