//! Double-acting cylinder and its mechanical load, fed by the valve ports (see
//! [`super::valve::port_flows`]).
//!
//! State `[p_A, p_B, x, v]`: chamber pressures, piston position (0 = mid-stroke, + = extension)
//! and velocity. The spool position `x_s(t)` comes from the exact integrator of [`crate`] as a function of
//! time over each step; the Rosenbrock integrator ([`super::rosenbrock`]) advances it.
//!
//! # Modelling choices
//! * **Pressures are gauge** (relative to atmosphere); the tank is at `hydraulics.p_tank` = 0.
//! * **Valve ports** (critically centred, no lap, no leakage): for `x_s >= 0`
//!   `Q_A = K3 x_s rsqrt(p_S - p_A)/sqrt(dp_r/2)` and `Q_B = K3 x_s rsqrt(p_B - p_T)/sqrt(dp_r/2)`,
//!   mirrored for `x_s < 0`. `rsqrt` is a signed square root, replaced below `dp_laminar` by
//!   the odd cubic that matches value and slope at `dp_laminar` (C1, slope `1.25/sqrt(dp_lam)`
//!   at zero instead of infinite), so the Jacobian stays finite at a closed or balanced port.
//!   Reverse flow (load pressure above supply) follows the same law with the sign reversed.
//! * **Cavitation floor**: a chamber being emptied (net inflow < 0) has its effective bulk
//!   modulus faded to zero over `hydraulics.dp_cavitation_band` above `hydraulics.p_cavitation`
//!   (factor `u(2-u)`, `u = (p - p_cav)/band` clamped to [0, 1]: C1 where it starts, and it
//!   vanishes at the floor). `p = p_cav` is then a barrier the exact solution cannot cross:
//!   the chamber keeps growing at the floor (vapour/air) without the pressure falling further,
//!   and refills as soon as the net inflow turns positive. A filling chamber is never slowed.
//!   The flow law also reads `max(p, p_cav)`, and accepted steps clamp rounding-size
//!   undershoot (reported in [`super::rosenbrock::Stats::floor_clamp`], which the tests require to be tiny).
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
//! * **Chamber volumes** are clamped at [`MIN_VOLUME_FRACTION`] of the dead volume so the
//!   equations stay finite, but a state that reaches the clamp (the piston through the end
//!   of the cylinder) is refused ([`check_inside`]), never integrated on.
//! * **Equilibrium start**: with `x_s = 0` both chambers are sealed, so any pressure pair on the
//!   force balance is an equilibrium. We take the one an (infinitesimally) underlapped real valve
//!   would settle to at null: its four metering edges balance leak flows when
//!   `p_A + p_B = p_S + p_T` (see [`equilibrium`]); with the force balance that fixes both.
//!   Note: with this area ratio (A_B/A_A = 0.61) the no-load steady flow is NOT `K3 x_s`: equal
//!   piston speeds need `Q_B/Q_A = A_B/A_A`, which shifts both port drops (about
//!   `Q_A = 1.28 K3 x_s` at `p_S = dp_r`). `K3 x_s` is exact only for a symmetric cylinder.
//!

use super::params::{CylinderLoadParams, Outputs, ValveParams};
use super::root_finding::newton_in_bracket;
use super::valve::port_flows;

/// Number of states: `[p_A, p_B, x, v]`.
pub(crate) const N_STATES: usize = 4;
pub(crate) const PA: usize = 0;
pub(crate) const PB: usize = 1;
pub(crate) const X: usize = 2;
pub(crate) const V: usize = 3;

pub(crate) type Vec4 = [f64; N_STATES];
pub(crate) type Mat4 = [[f64; N_STATES]; N_STATES];

/// Physical parameters of valve ports, cylinder and load, in SI (pressures gauge): the
/// cylinder, load and fluid as the model gives them (reached through `Deref`) and the
/// valve's metering-port data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CylinderParams {
    /// Cylinder, load, leakage and fluid.
    pub load: CylinderLoadParams,
    /// Spool/bushing flow gain K3 (the same value as the valve's `valve.K3`) (m2/s).
    pub k3: f64,
    /// Total rated valve pressure drop at which the no-load flow is K3*x_s (Pa).
    pub dp_rated: f64,
    /// Port pressure drop below which the orifice law turns laminar (regularisation) (Pa).
    pub dp_laminar: f64,
}

impl std::ops::Deref for CylinderParams {
    type Target = CylinderLoadParams;

    fn deref(&self) -> &CylinderLoadParams {
        &self.load
    }
}

#[cfg(test)]
impl Default for CylinderParams {
    /// The start values of the variable table.
    fn default() -> Self {
        let p = crate::Params::PAPER;
        CylinderParams::new(&p.cylinder, &p.valve).expect("start values are valid")
    }
}

impl CylinderParams {
    /// The hydraulic side's parameters: cylinder, load and fluid, with the valve's
    /// metering-port data. Checks the rules between parameters (single values were
    /// checked against their ranges at the model boundary).
    pub(crate) fn new(
        cylinder: &CylinderLoadParams,
        valve: &ValveParams,
    ) -> Result<CylinderParams, String> {
        let p = CylinderParams {
            load: *cylinder,
            k3: valve.k3,
            dp_rated: valve.dp_rated,
            dp_laminar: valve.dp_laminar,
        };
        p.validate()?;
        Ok(p)
    }

    /// The rules between parameters.
    pub(crate) fn validate(&self) -> Result<(), String> {
        if !(self.k3.is_finite() && self.k3 > 0.0) {
            return Err(format!("valve.K3 = {} rejected: must be positive", self.k3));
        }
        if self.rod >= self.bore {
            return Err(format!(
                "cylinder.rod = {} rejected: must be smaller than cylinder.bore = {}",
                self.rod, self.bore
            ));
        }
        if self.p_cavitation >= self.p_tank {
            return Err(format!(
                "hydraulics.p_cavitation = {} rejected: must be below hydraulics.p_tank = {}",
                self.p_cavitation, self.p_tank
            ));
        }
        Ok(())
    }

    /// The relief valves must be set above the supply, or they would open in normal
    /// operation (a chamber holds up to p_S at stall or on a stop).
    pub(crate) fn check_supply(&self, p_supply: f64) -> Result<(), String> {
        if self.relief_p_crack > 0.0 && p_supply - self.p_tank >= self.relief_p_crack {
            return Err(format!(
                "p_supply = {p_supply} Pa is not below the relief valves' setting \
                 hydraulics.p_tank + relief.p_crack = {} Pa: they would open in normal \
                 operation; raise relief.p_crack, or set it to 0 to remove them",
                self.p_tank + self.relief_p_crack
            ));
        }
        Ok(())
    }

    /// Piston area on the A (cap) side (m2).
    pub(crate) fn area_a(&self) -> f64 {
        std::f64::consts::FRAC_PI_4 * self.bore * self.bore
    }

    /// Annulus area on the B (rod) side (m2).
    pub(crate) fn area_b(&self) -> f64 {
        self.area_a() - std::f64::consts::FRAC_PI_4 * self.rod * self.rod
    }

    #[cfg(test)]
    /// Extension stall force p_S*A_A (B at tank) (N).
    pub(crate) fn stall_force(&self, p_supply: f64) -> f64 {
        (p_supply - self.p_tank) * self.area_a()
    }
}

/// Chamber pressures (Pa, gauge), piston position (m) and velocity (m/s).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct CylinderState {
    pub p_a: f64,
    pub p_b: f64,
    pub x: f64,
    pub v: f64,
}

impl CylinderState {
    pub(crate) fn to_array(self) -> [f64; N_STATES] {
        [self.p_a, self.p_b, self.x, self.v]
    }
    pub(crate) fn from_array(y: &[f64; N_STATES]) -> CylinderState {
        CylinderState { p_a: y[PA], p_b: y[PB], x: y[X], v: y[V] }
    }
}

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
/// Friction force opposing motion, viscous part included (N).
fn friction(params: &CylinderParams, v: f64) -> f64 {
    let stribeck = (v / params.v_stribeck).powi(2);
    let excess = params.f_static - params.f_coulomb;
    // Well past the Stribeck speed the decayed part is below half an ulp of F_coulomb
    // (F_coulomb * 2^-54 bounds that from below), so the sum is F_coulomb exactly.
    let dry = if stribeck > STRIBECK_TAIL.0
        && excess.abs() * STRIBECK_TAIL.1 <= params.f_coulomb * (0.25 * f64::EPSILON)
    {
        params.f_coulomb
    } else {
        params.f_coulomb + excess * stribeck_decay(stribeck)
    };
    dry * smooth_sign(v / params.v_friction_smooth) + params.b_viscous * v
}

/// `(s, b)`: for `stribeck > s` the computed `exp(-stribeck)` is below `b` (`e^-50 =
/// 1.93e-22`, with room for libm's rounding).
const STRIBECK_TAIL: (f64, f64) = (50.0, 2.0e-22);

/// `exp(-stribeck)` for `stribeck >= 0`. Beyond [`DECAY_UNDERFLOW`] that is exactly 0 in
/// f64; returned without the call (a moving piston is there: libm's underflow path is slow).
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

/// `tanh(a)`, the friction's smooth sign. For `|a| >= 22` tanh is `+-1` exactly in f64 (the
/// cut-off of glibc's and musl's own shortcut); returned without the call.
pub(crate) fn smooth_sign(a: f64) -> f64 {
    if a.abs() >= 22.0 {
        1.0_f64.copysign(a)
    } else {
        a.tanh()
    }
}

/// End-stop contact force on the piston, positive towards +x (N). Never pulls.
fn endstop_force(params: &CylinderParams, x: f64, v: f64) -> f64 {
    let half = 0.5 * params.stroke;
    let beyond_top = x - half;
    let beyond_bottom = -half - x;
    if beyond_top > 0.0 {
        -(params.k_endstop * beyond_top + params.c_endstop * v).max(0.0)
    } else if beyond_bottom > 0.0 {
        (params.k_endstop * beyond_bottom - params.c_endstop * v).max(0.0)
    } else {
        0.0
    }
}

/// Factor on the bulk modulus of a chamber: 1 while filling; fades to 0 at the cavitation
/// floor while emptying, so the pressure cannot pass the floor.
fn cavitation_factor(params: &CylinderParams, p: f64, net_inflow: f64) -> f64 {
    if net_inflow >= 0.0 {
        return 1.0;
    }
    let u = ((p - params.p_cavitation) / params.dp_cavitation_band).clamp(0.0, 1.0);
    u * (2.0 - u)
}

/// Chamber volumes never shrink below this fraction of the dead volume (keeps the pressure
/// equations finite). Reaching it means the piston went through the end of the cylinder:
/// [`check_inside`] refuses such a state.
pub(crate) const MIN_VOLUME_FRACTION: f64 = 1e-3;

/// Chamber volumes `(V_A, V_B)` at position `x`, before the clamp (m3).
fn free_volumes(params: &CylinderParams, x: f64) -> (f64, f64) {
    let half = 0.5 * params.stroke;
    (params.v_dead + params.area_a() * (x + half), params.v_dead + params.area_b() * (half - x))
}

/// Refuses a state in which a chamber volume reached its clamp: the piston is through the
/// end stop and the dead volume (an end stop that cannot hold the load), where the
/// clamped equations no longer describe anything physical.
pub(crate) fn check_inside(params: &CylinderParams, state: &CylinderState) -> Result<(), String> {
    let (volume_a, volume_b) = free_volumes(params, state.x);
    let min_volume = MIN_VOLUME_FRACTION * params.v_dead;
    for (volume, chamber, end) in [(volume_a, "A", "-"), (volume_b, "B", "+")] {
        // A NaN position is refused too.
        if volume.is_nan() || volume < min_volume {
            return Err(format!(
                "x_piston = {} m is through the {end}stroke/2 end stop into chamber {chamber}'s \
                 dead volume (chamber volume {volume:e} m3, cylinder.V_dead = {} m3): the end \
                 stop (cylinder.k_endstop) cannot hold the load; step refused",
                state.x, params.v_dead
            ));
        }
    }
    Ok(())
}

/// Flow through a chamber's relief valve to tank at chamber pressure `p` (m3/s), and its
/// slope `dQ/dp`: zero up to the cracking pressure, quadratic over the override, then
/// linear with the slope matched (C1).
pub(crate) fn relief_flow(params: &CylinderParams, p: f64) -> (f64, f64) {
    let rise = p - params.p_tank - params.relief_p_crack;
    if params.relief_p_crack == 0.0 || rise <= 0.0 {
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

/// Which chambers' relief valves pass flow at this state: `[A, B]`.
pub(crate) fn relief_open(params: &CylinderParams, state: &CylinderState) -> [bool; 2] {
    [state.p_a, state.p_b].map(|p| relief_flow(params, p).0 > 0.0)
}

/// `[p_A', p_B', x', v']` for spool position `x_s`.
pub(crate) fn derivatives(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
    f_ext: f64,
) -> [f64; 4] {
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let min_volume = MIN_VOLUME_FRACTION * params.v_dead;
    let (volume_a, volume_b) = free_volumes(params, state.x);
    let (volume_a, volume_b) = (volume_a.max(min_volume), volume_b.max(min_volume));
    let (q_a, q_b) = port_flows(params, state, x_s, p_supply);
    let q_internal = params.c_leak * (state.p_a - state.p_b);
    let q_external_a = params.c_leak_external * (state.p_a - params.p_tank);
    let q_external_b = params.c_leak_external * (state.p_b - params.p_tank);
    let relief_a = relief_flow(params, state.p_a).0;
    let relief_b = relief_flow(params, state.p_b).0;
    let inflow_a = q_a - area_a * state.v - q_internal - q_external_a - relief_a;
    let inflow_b = -q_b + area_b * state.v + q_internal - q_external_b - relief_b;
    let dp_a = params.beta / volume_a * inflow_a * cavitation_factor(params, state.p_a, inflow_a);
    let dp_b = params.beta / volume_b * inflow_b * cavitation_factor(params, state.p_b, inflow_b);
    [dp_a, dp_b, state.v, net_force(params, state, f_ext) / params.mass]
}

/// The force on the piston and load: pressures, friction, the load and the end stops (N).
#[inline]
pub(crate) fn net_force(params: &CylinderParams, state: &CylinderState, f_ext: f64) -> f64 {
    state.p_a * params.area_a() - state.p_b * params.area_b() - friction(params, state.v)
        + f_ext
        + endstop_force(params, state.x, state.v)
}

/// Writes the hydraulic side's outputs at a state into `out`.
pub(crate) fn write_outputs(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
    out: &mut Outputs,
) {
    (out.q_a, out.q_b) = port_flows(params, state, x_s, p_supply);
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
pub(crate) fn next_contact_switch(
    params: &CylinderParams,
    y: &Vec4,
    (f0, jac, f_t): (&Vec4, &Mat4, &Vec4),
    span: f64,
) -> Option<f64> {
    let half = 0.5 * params.stroke;
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
    let band_top = params.p_cavitation + params.dp_cavitation_band;
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
