//! The terms of the cylinder's equations ([`super::cylinder`]), each from one formula that
//! gives its value and its slopes: chamber volumes, port flows as the chambers read them,
//! relief flows, the cavitation fade, friction, the end-stop force, and what they sum to
//! (the chambers' pressure rates, the force on the piston). [`super::cylinder::derivatives`]
//! takes the values, [`super::cylinder_jacobian::linearise`] the values and the slopes. The
//! functions that a hot caller uses for values alone are inlined, so that the slopes it
//! drops are not computed.
//!
//! At a kink of a piecewise law (a clamp, the branch of a `max`) the slope is the one of the
//! side the state is on, ties broken towards increasing argument (as a forward difference
//! would see it), except at the contact switching surfaces of the end stop where it is the
//! side without contact.

use crate::components::cylinder_params::{CylinderParams, CylinderState, STRIBECK_TAIL};
use crate::components::metering_ports::{PortFlows, PortLaw};

/// Chamber volumes `(V_A, V_B)` at position `x`, before the clamp (m3).
pub(crate) fn free_volumes(params: &CylinderParams, x: f64) -> (f64, f64) {
    let half = params.half_stroke();
    (params.v_dead + params.area_a() * (x + half), params.v_dead + params.area_b() * (half - x))
}

/// Chamber volumes `[(V_A, dV_A/dx), (V_B, dV_B/dx)]` at position `x` (m3, m2): clamped at
/// [`MIN_VOLUME_FRACTION`](super::cylinder_params::MIN_VOLUME_FRACTION) of the dead volume, where
/// they have no slope.
#[inline(always)]
pub(crate) fn chamber_volumes(params: &CylinderParams, x: f64) -> [(f64, f64); 2] {
    let min_volume = params.min_volume();
    let (volume_a, volume_b) = free_volumes(params, x);
    let clamped = |volume: f64, area: f64| {
        if volume >= min_volume {
            (volume, area)
        } else {
            (min_volume, 0.0)
        }
    };
    [clamped(volume_a, params.area_a()), clamped(volume_b, -params.area_b())]
}

/// `x.max(floor)` for a `floor` that is not NaN (a NaN `x` gives `floor`, as with `max`) in one
/// comparison, without `max`'s handling of a NaN `floor`.
#[inline(always)]
pub(crate) fn at_least(x: f64, floor: f64) -> f64 {
    if x >= floor {
        x
    } else {
        floor
    }
}

/// The metering ports' flows (into A, out of B) at chamber pressures `p_a`, `p_b` for spool
/// position `x_s`, with their slopes. A pressure below the cavitation floor (rounding only)
/// is read at the floor, where the flow has no slope in it.
#[inline(always)]
pub(crate) fn port_flows<L: PortLaw>(
    params: &CylinderParams,
    [p_a, p_b]: [f64; 2],
    x_s: f64,
    p_supply: f64,
) -> PortFlows {
    let floor = params.p_cavitation;
    let at_floor = [at_least(p_a, floor), at_least(p_b, floor)];
    let mut flows = L::flows(&params.ports, x_s, at_floor, p_supply, params.p_tank);
    flows.dqa_dpa *= if p_a >= floor { 1.0 } else { 0.0 };
    flows.dqb_dpb *= if p_b >= floor { 1.0 } else { 0.0 };
    flows
}

/// The flow drawn from the supply (the P -> A and P -> B edges and the pilot) at chamber
/// pressures `p_a`, `p_b` for spool position `x_s`, the pressures read as [`port_flows`]
/// reads them.
pub(crate) fn supply_flow(
    params: &CylinderParams,
    [p_a, p_b]: [f64; 2],
    x_s: f64,
    p_supply: f64,
) -> f64 {
    let floor = params.p_cavitation;
    let at_floor = [at_least(p_a, floor), at_least(p_b, floor)];
    params.ports.supply_flow(x_s, at_floor, p_supply, params.p_tank)
}

/// Flow through a chamber's relief valve to tank at chamber pressure `p` (m3/s), and its
/// slope `dQ/dp`: zero up to the cracking pressure, quadratic over the override, then
/// linear with the slope matched (C1).
pub(crate) fn relief_flow(params: &CylinderParams, p: f64) -> (f64, f64) {
    if !params.has_relief() {
        return (0.0, 0.0);
    }
    let rise = p - params.p_tank - params.relief_p_crack;
    if rise <= 0.0 {
        return (0.0, 0.0);
    }
    let (q_rated, override_) = (params.relief_q_rated, params.relief_dp_override);
    let s = rise / override_;
    if s < 1.0 {
        (q_rated * s * s, 2.0 * q_rated * s / override_)
    } else {
        (q_rated * (2.0 * s - 1.0), 2.0 * q_rated / override_)
    }
}

/// Factor on the bulk modulus of a chamber at pressure `p` with net inflow `net_inflow`,
/// and its slope in `p`: 1 while filling; fades to 0 at the cavitation floor while emptying
/// (`u (2 - u)` over the band above the floor), so the pressure cannot pass the floor.
#[inline(always)]
pub(crate) fn cavitation_factor(params: &CylinderParams, p: f64, net_inflow: f64) -> (f64, f64) {
    if net_inflow >= 0.0 {
        return (1.0, 0.0);
    }
    let band = params.dp_cavitation_band;
    let u_raw = (p - params.p_cavitation) / band;
    if u_raw >= 1.0 {
        // Above the band, where an emptying chamber spends most of its time: the clamp
        // below gives exactly these.
        return (1.0, 0.0);
    }
    let u = u_raw.clamp(0.0, 1.0);
    let slope = if (0.0..1.0).contains(&u_raw) { (2.0 - 2.0 * u) / band } else { 0.0 };
    (u * (2.0 - u), slope)
}

/// Friction force opposing motion at velocity `v`, viscous part included (N), and its slope
/// `dF/dv`.
#[inline(always)]
pub(crate) fn friction(params: &CylinderParams, v: f64) -> (f64, f64) {
    let stribeck = (v / params.v_stribeck).powi(2);
    let excess = params.friction_excess();
    let a = v / params.v_friction_smooth;
    // Well past the Stribeck speed the decayed part is below half an ulp of F_coulomb
    // (F_coulomb * 2^-54 bounds that from below), so the sum is F_coulomb exactly. The
    // decay is then needed for the slope alone: computed in each branch, so that a caller
    // that drops the slope does not compute it there, and only where the slope can see it.
    let (dry, decay) = if stribeck > STRIBECK_TAIL.0 && params.stribeck_tails().force_lost {
        (params.f_coulomb, slope_decay(params, stribeck, a))
    } else {
        let decay = stribeck_decay(stribeck);
        (params.f_coulomb + excess * decay, decay)
    };
    let ddry_dv = excess * decay * (-2.0 * v / params.v_stribeck_squared());
    let th = smooth_sign(a);
    let force = dry * th + params.b_viscous * v;
    let slope = ddry_dv * th + dry * (1.0 - th * th) / params.v_friction_smooth + params.b_viscous;
    (force, slope)
}

/// [`friction`]'s force alone, out of line: its libm calls (exp, tanh) then save and restore
/// only the few values live in it, not every value of a caller that is in the middle of
/// a linearisation (the friction's secant).
#[inline(never)]
pub(crate) fn friction_force(params: &CylinderParams, v: f64) -> f64 {
    friction(params, v).0
}

/// The Stribeck decay past its tail ([`STRIBECK_TAIL`]), where only the friction's slope
/// reads it, at `stribeck = (v/v_s)^2` and `a = v/v_smooth`: 0 where that changes none of
/// the slope's bits (the smooth sign saturated, so the slope is the decayed part's plus
/// the viscous one, and the decayed part below a quarter ulp of the viscous one: the sum
/// rounds to the viscous slope either way), else [`stribeck_decay`].
#[inline(always)]
fn slope_decay(params: &CylinderParams, stribeck: f64, a: f64) -> f64 {
    if a.abs() >= TANH_SATURATED && params.stribeck_tails().slope_lost {
        0.0
    } else {
        stribeck_decay(stribeck)
    }
}

/// `exp(-stribeck)` for `stribeck >= 0`. Beyond [`DECAY_UNDERFLOW`] that is exactly 0 in
/// f64; returned without the call (a moving piston is there: libm's underflow path is slow).
#[inline]
pub(crate) fn stribeck_decay(stribeck: f64) -> f64 {
    if stribeck > DECAY_UNDERFLOW {
        0.0
    } else {
        (-stribeck).exp()
    }
}

/// `exp(-x)` rounds to 0 for every `x` above about 745.13 (`e^-x` below half the smallest
/// subnormal); a margin above that.
const DECAY_UNDERFLOW: f64 = 750.0;

/// From here on `tanh` is `+-1` exactly in f64 (the cut-off of glibc's and musl's own
/// shortcut).
const TANH_SATURATED: f64 = 22.0;

/// `tanh(a)`, the friction's smooth sign. For `|a| >=` [`TANH_SATURATED`] returned without
/// the call.
pub(crate) fn smooth_sign(a: f64) -> f64 {
    if a.abs() >= TANH_SATURATED {
        1.0_f64.copysign(a)
    } else {
        a.tanh()
    }
}

/// End-stop contact force on the piston at `(x, v)`, positive towards +x (N), and its slopes
/// in `x` and `v`. Never pulls; where the spring-damper force `k d + c d'` is not positive
/// (separating, or exactly at zero penetration) there is no contact and no slope.
#[inline(always)]
pub(crate) fn endstop_force(params: &CylinderParams, x: f64, v: f64) -> (f64, f64, f64) {
    let (k, c) = (params.k_endstop, params.c_endstop);
    let half = params.half_stroke();
    let beyond_top = x - half;
    let beyond_bottom = -half - x;
    let slopes = |s: f64| if s > 0.0 { (-k, -c) } else { (0.0, 0.0) };
    if beyond_top > 0.0 {
        let s = k * beyond_top + c * v;
        let (dx, dv) = slopes(s);
        (-s.max(0.0), dx, dv)
    } else if beyond_bottom > 0.0 {
        let s = k * beyond_bottom - c * v;
        let (dx, dv) = slopes(s);
        (s.max(0.0), dx, dv)
    } else {
        (0.0, 0.0, 0.0)
    }
}

/// The force on the piston and load: pressures, friction, the load and the end stops (N),
/// and its slopes `(dF/dx, dF/dv)` (the pressures' are the areas).
#[inline(always)]
pub(crate) fn net_force(params: &CylinderParams, state: &CylinderState, f_ext: f64) -> [f64; 3] {
    net_force_with(params, state, f_ext, friction(params, state.v))
}

/// [`net_force`] with the friction and its slope at the state's velocity already known.
#[inline(always)]
pub(crate) fn net_force_with(
    params: &CylinderParams,
    state: &CylinderState,
    f_ext: f64,
    (friction, dfriction_dv): (f64, f64),
) -> [f64; 3] {
    let (contact, dcontact_dx, dcontact_dv) = endstop_force(params, state.x, state.v);
    let force =
        state.p_a * params.area_a() - state.p_b * params.area_b() - friction + f_ext + contact;
    [force, dcontact_dx, dcontact_dv - dfriction_dv]
}

/// The chambers' terms `[A, B]` at `state` for spool position `x_s`: port flows, leakage
/// and relief flows make each chamber's net inflow, which its stiffness `beta / V` and
/// cavitation factor turn into its pressure rate.
#[inline(always)]
pub(crate) fn chamber_terms<L: PortLaw>(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
) -> [Chamber; 2] {
    let [volume_a, volume_b] = chamber_volumes(params, state.x);
    let ports = port_flows::<L>(params, [state.p_a, state.p_b], x_s, p_supply);
    [chamber_a(params, state, volume_a, &ports), chamber_b(params, state, volume_b, &ports)]
}

/// One chamber's side of the equations at a state, each term with its slopes in the
/// chamber's own pressure.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Chamber {
    /// `(V, dV/dx)` ([`chamber_volumes`]).
    pub volume: (f64, f64),
    /// `dQ/dp` of its relief flow.
    pub relief_slope: f64,
    /// Net inflow (m3/s).
    pub inflow: f64,
    /// Bulk-modulus factor and its slope in the chamber's pressure.
    pub cavitation: (f64, f64),
    /// `beta / V` (Pa/m3).
    pub stiffness: f64,
    /// `p'` (Pa/s).
    pub pressure_rate: f64,
}

/// Chamber A's terms at `state`, its volume `volume` and the ports' flows `ports` given.
#[inline(always)]
pub(crate) fn chamber_a(
    params: &CylinderParams,
    state: &CylinderState,
    volume: (f64, f64),
    ports: &PortFlows,
) -> Chamber {
    let inflow = ports.q_a - params.area_a() * state.v - internal_leak(params, state);
    chamber(params, state.p_a, volume, inflow)
}

/// Chamber B's terms, as [`chamber_a`]'s.
#[inline(always)]
pub(crate) fn chamber_b(
    params: &CylinderParams,
    state: &CylinderState,
    volume: (f64, f64),
    ports: &PortFlows,
) -> Chamber {
    let inflow = -ports.q_b + params.area_b() * state.v + internal_leak(params, state);
    chamber(params, state.p_b, volume, inflow)
}

/// The leak across the piston, from A to B (m3/s).
#[inline(always)]
fn internal_leak(params: &CylinderParams, state: &CylinderState) -> f64 {
    params.c_leak * (state.p_a - state.p_b)
}

/// A chamber's terms at pressure `p` and volume `volume`, with `inflow` flowing in through
/// its port, the piston's displacement and the internal leak: the external leak and the
/// relief valve take their flows from that.
#[inline(always)]
fn chamber(params: &CylinderParams, p: f64, volume: (f64, f64), inflow: f64) -> Chamber {
    let q_external = params.c_leak_external * (p - params.p_tank);
    let (relief, relief_slope) = relief_flow(params, p);
    let inflow = inflow - q_external - relief;
    let cavitation = cavitation_factor(params, p, inflow);
    let stiffness = params.beta / volume.0;
    let pressure_rate = stiffness * inflow * cavitation.0;
    Chamber { volume, relief_slope, inflow, cavitation, stiffness, pressure_rate }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::components::metering_ports::AnyLap;
    use crate::params::CylinderLoadParams;
    use std::f64::consts::FRAC_PI_4;

    const P_SUPPLY: f64 = 6.8948e6;

    /// The paper's cylinder with the return line at `p_tank` above atmosphere: the default
    /// tank at 0 cannot tell a law that measures from the tank from one that does not.
    fn with_tank(p_tank: f64) -> CylinderParams {
        let p = CylinderParams::default();
        p.with_load(CylinderLoadParams { p_tank, ..p.load })
    }

    /// The relief valve's rise is counted from the tank (`d = p - p_T - p_crack`): with the
    /// return line at 3 bar it opens at `p_T + p_crack`, then follows `Q_r s^2` over the
    /// override (`s = d/dp_ov`) and `Q_r (2 s - 1)` beyond, with their slopes.
    #[test]
    fn relief_flow_rises_from_the_tank_pressure() {
        let p = with_tank(3e5);
        let (crack, over, rated) = (p.relief_p_crack, p.relief_dp_override, p.relief_q_rated);
        let opening = p.p_tank + crack;
        // Shut past the gauge cracking pressure, up to and at the setting above tank.
        assert_eq!(relief_flow(&p, crack + 0.5 * p.p_tank), (0.0, 0.0));
        assert_eq!(relief_flow(&p, opening), (0.0, 0.0));
        for s in [0.2, 0.7, 1.0, 1.6, 4.0] {
            let (q, dq) = relief_flow(&p, opening + s * over);
            let (q_law, dq_law) = if s < 1.0 {
                (rated * s * s, 2.0 * rated * s / over)
            } else {
                (rated * (2.0 * s - 1.0), 2.0 * rated / over)
            };
            assert!((q - q_law).abs() <= 1e-9 * q_law, "s = {s}: {q:e} vs {q_law:e}");
            assert!((dq - dq_law).abs() <= 1e-9 * dq_law, "s = {s}: {dq:e} vs {dq_law:e}");
        }
    }

    /// With the valve closed a chamber's net inflow is the piston's displacement and the
    /// leakage: `Q_A = -A_A v - C_l (p_A - p_B) - C_e (p_A - p_T)`, `Q_B = A_B v + C_l (p_A -
    /// p_B) - C_e (p_B - p_T)`, the external leak measured from the tank (here at 2 bar); its
    /// pressure rate `beta / V` times that, with `V_A = V_0 + A_A (x + S/2)`, `V_B = V_0 + A_B
    /// (S/2 - x)` (no fade: the chambers are far above the cavitation band).
    #[test]
    fn leakage_and_displacement_make_the_chambers_net_inflows() {
        let base = with_tank(2e5);
        let p = base.with_load(CylinderLoadParams {
            c_leak: 1e-12,
            c_leak_external: 3e-13,
            ..base.load
        });
        let area_a = FRAC_PI_4 * p.bore * p.bore;
        let area_b = area_a - FRAC_PI_4 * p.rod * p.rod;
        let x = 0.01;
        let volumes =
            [p.v_dead + area_a * (x + 0.5 * p.stroke), p.v_dead + area_b * (0.5 * p.stroke - x)];
        for (p_a, p_b, v) in [(5e6, 1e6, 0.0), (1.5e6, 4e6, 0.02), (1e6, 3e5, -0.01)] {
            let s = CylinderState { p_a, p_b, x, v };
            let terms = chamber_terms::<AnyLap>(&p, &s, 0.0, P_SUPPLY);
            let internal = p.c_leak * (p_a - p_b);
            let external =
                [p.c_leak_external * (p_a - p.p_tank), p.c_leak_external * (p_b - p.p_tank)];
            let parts =
                [[-area_a * v, -internal, -external[0]], [area_b * v, internal, -external[1]]];
            for k in 0..2 {
                let inflow: f64 = parts[k].iter().sum();
                // Rounding of the sum: a few ulps of its largest part.
                let scale = parts[k].iter().map(|q| q.abs()).fold(0.0, f64::max);
                assert!((terms[k].inflow - inflow).abs() <= 1e-14 * scale, "{k} {s:?}");
                let rate = p.beta / volumes[k] * inflow;
                let rate_scale = p.beta / volumes[k] * scale;
                assert!((terms[k].pressure_rate - rate).abs() <= 1e-13 * rate_scale, "{k} {s:?}");
            }
        }
    }

    /// A chamber below the cavitation floor (rounding, or a floor raised by a retune of
    /// `hydraulics.p_cavitation` while the chamber sat at the old one, where the next step
    /// linearises) is read at the floor: the flows are the floor's, with no slope in that
    /// chamber's pressure; at the floor itself the slope is the orifice law's.
    #[test]
    fn port_flows_read_a_pressure_below_the_floor_at_the_floor() {
        let p = CylinderParams::default();
        let floor = p.p_cavitation;
        let slopes = |f: &PortFlows| [f.dqa_dpa, f.dqb_dpb];
        for x_s in [2e-4, -2e-4] {
            for chamber in 0..2 {
                let mut at = [3e6, 3e6];
                at[chamber] = floor;
                let mut below = at;
                below[chamber] = floor - 2e4;
                let f_at = port_flows::<AnyLap>(&p, at, x_s, P_SUPPLY);
                let f_below = port_flows::<AnyLap>(&p, below, x_s, P_SUPPLY);
                assert_eq!((f_below.q_a, f_below.q_b), (f_at.q_a, f_at.q_b), "{x_s} {chamber}");
                let mut expected = slopes(&f_at);
                assert!(expected[chamber] != 0.0, "{x_s} {chamber}");
                expected[chamber] = 0.0;
                assert_eq!(slopes(&f_below), expected, "{x_s} {chamber}");
            }
        }
    }

    /// An emptying chamber's bulk modulus fades by `u (2 - u)`, `u = (p - p_cav)/band`
    /// clamped to [0, 1], with the slope `(2 - 2 u)/band` inside the band (against
    /// differences); 0 at and below the floor, 1 above the band and for a filling chamber.
    #[test]
    fn cavitation_fade_is_u_times_two_minus_u() {
        let p = CylinderParams::default();
        let (floor, band) = (p.p_cavitation, p.dp_cavitation_band);
        let emptying = |pressure: f64| cavitation_factor(&p, pressure, -1e-6);
        for u in [0.0, 0.1, 0.35, 0.5, 0.8, 0.99] {
            let pressure = floor + u * band;
            let (factor, slope) = emptying(pressure);
            assert!((factor - u * (2.0 - u)).abs() <= 1e-12, "u = {u}: {factor}");
            assert!((slope - (2.0 - 2.0 * u) / band).abs() <= 1e-12 / band, "u = {u}: {slope}");
            // The slope is the factor's: a forward difference (the tie at the floor is taken
            // towards increasing pressure), error d/band^2 of the quadratic.
            let d = 1e-6 * band;
            let fd = (emptying(pressure + d).0 - factor) / d;
            assert!((slope - fd).abs() <= 1e-5 / band, "u = {u}: {slope} vs {fd}");
            // Filling is never slowed.
            assert_eq!(cavitation_factor(&p, pressure, 1e-6), (1.0, 0.0));
        }
        assert_eq!(emptying(floor - 1e3), (0.0, 0.0));
        assert_eq!(emptying(floor + band), (1.0, 0.0));
        assert_eq!(emptying(3e6), (1.0, 0.0));
    }

    /// The end stops push back with `k d + c d'` beyond `+-S/2` (`d` the penetration), with
    /// slopes `(-k, -c)`, and never pull; exactly at the face there is no contact yet, moving
    /// in or not: what a motion-port host reads that puts the rod at its end of stroke
    /// (`x_rod = S/2`, exact in f64) with the rod moving into the stop.
    #[test]
    fn end_stop_force_starts_beyond_the_face() {
        let p = CylinderParams::default();
        let (k, c, half) = (p.k_endstop, p.c_endstop, 0.5 * p.stroke);
        for side in [1.0, -1.0] {
            for v in [0.3, 0.0, -0.3] {
                assert_eq!(endstop_force(&p, side * half, side * v), (0.0, 0.0, 0.0), "{side} {v}");
            }
            // 20 um in, penetrating, still or withdrawing slower than the spring pushes.
            let d = 2e-5;
            for rate in [0.1, 0.0, -0.1] {
                let (force, dx, dv) = endstop_force(&p, side * (half + d), side * rate);
                let push = k * d + c * rate;
                assert!((force + side * push).abs() <= 1e-9 * push, "{side} {rate}: {force}");
                assert_eq!((dx, dv), (-k, -c), "{side} {rate}");
            }
            // Withdrawing faster: the damper would pull, the stop lets go.
            assert_eq!(endstop_force(&p, side * (half + d), -side * 0.5), (0.0, 0.0, 0.0));
        }
    }
}
