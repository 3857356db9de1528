//! Hydraulic side: valve ports, double-acting cylinder and mechanical load.
//!
//! State `[p_A, p_B, x, v]`: chamber pressures, piston position (0 = mid-stroke, + = extension)
//! and velocity. The spool position `x_s(t)` comes from [`crate::physics`] as a function of
//! time over each step.
//!
//! # Modelling choices (MODEL.md leaves these open)
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
//!   undershoot (reported in [`Stats::floor_clamp`], which the tests require to be tiny).
//!   Not modelled: the vapour volume that must be refilled before pressure rises again.
//! * **Friction** (smooth, no stick-slip switching): `F = (Fc + (Fs - Fc) exp(-(v/vs)^2))
//!   tanh(v/v_smooth) + b v`. `v_smooth` (0.1 mm/s) is the creep speed scale of the `tanh`; it
//!   replaces the sign function so there is no sticking singularity. At rest `F = 0`.
//! * **End stops**: spring-dampers beyond `+-S/2`; the damper acts only while penetrating, and
//!   the total contact force is `max(0, k d + c d')`, so a separating stop never pulls.
//! * **Leakage**: internal `C_leak (p_A - p_B)` from A to B, external `C_leak_external (p - p_T)`
//!   from each chamber to the drain. Both default to 0.
//! * **Equilibrium start**: with `x_s = 0` both chambers are sealed, so any pressure pair on the
//!   force balance is an equilibrium. We take the one an (infinitesimally) underlapped real valve
//!   would settle to at null: its four metering edges balance leak flows when
//!   `p_A + p_B = p_S + p_T` (see [`equilibrium`]); with the force balance that fixes both.
//!   Note: with this area ratio (A_B/A_A = 0.61) the no-load steady flow is NOT `K3 x_s`: equal
//!   piston speeds need `Q_B/Q_A = A_B/A_A`, which shifts both port drops (about
//!   `Q_A = 1.28 K3 x_s` at `p_S = dp_r`). `K3 x_s` is exact only for a symmetric cylinder.
//!
//! # Integrator
//! Rodas4 (Hairer & Wanner, *Solving ODEs II*, IV.7; coefficients of `rodas.f`, METH = 1):
//! a 6-stage Rosenbrock method of order 4, stiffly accurate and L-stable, with an embedded
//! order-3 solution for error control. Why implicit: the Jacobian's stiff modes are not rare
//! corners but ordinary operating states (eigenvalues measured in `tests::jacobian_eigenvalues`):
//! at rest the friction tanh gives `-6.0e4 1/s` (`~ -Fs/(m v_smooth)`); pressed on the end stop
//! `-1.4e5, -6.2e4, -1.6e4` (laminar port near supply, friction); a port in its laminar region
//! `-6e4`; during an impact the contact mode `-1.07e3 +- 4.4e3i` plus `-2.7e4`; moving at rated
//! flow only `-1.3e4, -1.9e3, -4.0e2`. An explicit method would sit on its stability boundary
//! (`|lambda h| < 3.3`: steps of 2..50 us) in most of these; Rodas4 takes steps set by accuracy
//! only: one step per 0.1 ms call at rest, in steady motion and pressed on a stop. Order 4
//! keeps the step count low at the 1e-8 tolerance.
//! The 4x4 Jacobian and `df/dt = df/dx_s x_s'` are analytic (`linearise`, checked against
//! differences in `tests::analytic_jacobian_matches_finite_differences`); the linear systems
//! use a hand-written 4x4 LU with partial pivoting. A step that the call boundary cuts to at
//! most half the controller's size first tries Rodas3 (Sandu et al. 1997; 4 stages, 2 model
//! evaluations after the linearisation) and keeps it only if its own embedded estimate passes
//! the same tolerance. Steps are cut to land on the end-stop contact switches (x reaching
//! `+-S/2`, the contact force crossing zero), predicted from the Taylor polynomial that the
//! linearisation gives, instead of rejecting their way across the jump in `v'`.
//! Everything lives on the stack: no allocation in [`advance`].

use crate::variables::{index_of, VARIABLES};

/// Number of states: `[p_A, p_B, x, v]`.
pub const N_STATES: usize = 4;
const PA: usize = 0;
const PB: usize = 1;
const X: usize = 2;
const V: usize = 3;

type Vec4 = [f64; N_STATES];
type Mat4 = [[f64; N_STATES]; N_STATES];

/// Physical parameters of valve ports, cylinder and load, in SI (pressures gauge).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CylinderParams {
    /// Piston (bore) diameter [m].
    pub bore: f64,
    /// Rod diameter [m]; the rod is on the B side.
    pub rod: f64,
    /// Full stroke [m]; x runs from -stroke/2 to +stroke/2.
    pub stroke: f64,
    /// Moving mass: piston, rod and load [kg].
    pub mass: f64,
    /// Effective bulk modulus of oil, hoses and walls [Pa].
    pub beta: f64,
    /// Dead volume per chamber at its end of stroke [m3].
    pub v_dead: f64,
    pub b_viscous: f64,
    pub f_coulomb: f64,
    /// Breakaway force (peak of the Stribeck curve) [N].
    pub f_static: f64,
    pub v_stribeck: f64,
    /// Velocity scale of the tanh that replaces sign(v) in the Coulomb/Stribeck term [m/s].
    pub v_friction_smooth: f64,
    pub k_endstop: f64,
    pub c_endstop: f64,
    /// Internal (cross-piston) leakage A -> B per pressure difference [m3/(s.Pa)].
    pub c_leak: f64,
    /// External leakage from each chamber to the drain (at p_tank) [m3/(s.Pa)].
    pub c_leak_external: f64,
    /// Spool/bushing flow gain K3 (the same value as the valve's `valve.K3`) [m2/s].
    pub k3: f64,
    /// Total rated valve pressure drop at which the no-load flow is K3*x_s [Pa].
    pub dp_rated: f64,
    /// Port pressure drop below which the orifice law turns laminar (regularisation) [Pa].
    pub dp_laminar: f64,
    pub p_tank: f64,
    /// Lowest chamber pressure (gauge) [Pa].
    pub p_cavitation: f64,
    /// Band above the floor over which an emptying chamber's bulk modulus fades out [Pa].
    pub dp_cavitation_band: f64,
}

impl Default for CylinderParams {
    /// The start values of the variable table.
    fn default() -> Self {
        let start = |name: &str| {
            VARIABLES[index_of(name).expect("cylinder parameter in the variable table")].start
        };
        CylinderParams::from_lookup(start, start("valve.K3")).expect("table start values are valid")
    }
}

/// Table names of the parameters, in the order of [`CylinderParams::values`].
const PARAMETER_NAMES: [&str; 20] = [
    "cylinder.bore",
    "cylinder.rod",
    "cylinder.stroke",
    "cylinder.mass",
    "cylinder.beta",
    "cylinder.V_dead",
    "cylinder.b_viscous",
    "cylinder.F_coulomb",
    "cylinder.F_static",
    "cylinder.v_stribeck",
    "cylinder.v_friction_smooth",
    "cylinder.k_endstop",
    "cylinder.c_endstop",
    "cylinder.C_leak",
    "cylinder.C_leak_external",
    "valve.dp_rated",
    "valve.dp_laminar",
    "hydraulics.p_tank",
    "hydraulics.p_cavitation",
    "hydraulics.dp_cavitation_band",
];

impl CylinderParams {
    /// Builds the parameters from named values (e.g. the variable table), then validates them.
    pub fn from_lookup(get: impl Fn(&str) -> f64, k3: f64) -> Result<CylinderParams, String> {
        let v = PARAMETER_NAMES.map(get);
        let p = CylinderParams {
            bore: v[0],
            rod: v[1],
            stroke: v[2],
            mass: v[3],
            beta: v[4],
            v_dead: v[5],
            b_viscous: v[6],
            f_coulomb: v[7],
            f_static: v[8],
            v_stribeck: v[9],
            v_friction_smooth: v[10],
            k_endstop: v[11],
            c_endstop: v[12],
            c_leak: v[13],
            c_leak_external: v[14],
            k3,
            dp_rated: v[15],
            dp_laminar: v[16],
            p_tank: v[17],
            p_cavitation: v[18],
            dp_cavitation_band: v[19],
        };
        p.validate()?;
        Ok(p)
    }

    /// Values in the order of `PARAMETER_NAMES`.
    fn values(&self) -> [f64; 20] {
        [
            self.bore,
            self.rod,
            self.stroke,
            self.mass,
            self.beta,
            self.v_dead,
            self.b_viscous,
            self.f_coulomb,
            self.f_static,
            self.v_stribeck,
            self.v_friction_smooth,
            self.k_endstop,
            self.c_endstop,
            self.c_leak,
            self.c_leak_external,
            self.dp_rated,
            self.dp_laminar,
            self.p_tank,
            self.p_cavitation,
            self.dp_cavitation_band,
        ]
    }

    /// Single-value ranges (from the variable table) and the rules between parameters.
    pub fn validate(&self) -> Result<(), String> {
        for (name, value) in PARAMETER_NAMES.iter().zip(self.values()) {
            VARIABLES[index_of(name).expect("cylinder parameter in the variable table")]
                .check(value)?;
        }
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

    /// Piston area on the A (cap) side [m2].
    pub fn area_a(&self) -> f64 {
        std::f64::consts::FRAC_PI_4 * self.bore * self.bore
    }

    /// Annulus area on the B (rod) side [m2].
    pub fn area_b(&self) -> f64 {
        self.area_a() - std::f64::consts::FRAC_PI_4 * self.rod * self.rod
    }

    /// Extension stall force p_S*A_A (B at tank) [N].
    pub fn stall_force(&self, p_supply: f64) -> f64 {
        (p_supply - self.p_tank) * self.area_a()
    }
}

/// Chamber pressures [Pa, gauge], piston position [m] and velocity [m/s].
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct CylinderState {
    pub p_a: f64,
    pub p_b: f64,
    pub x: f64,
    pub v: f64,
}

impl CylinderState {
    pub fn to_array(&self) -> [f64; N_STATES] {
        [self.p_a, self.p_b, self.x, self.v]
    }
    pub fn from_array(y: &[f64; N_STATES]) -> CylinderState {
        CylinderState { p_a: y[PA], p_b: y[PB], x: y[X], v: y[V] }
    }
}

/// The outputs MODEL.md names for the hydraulic side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CylinderOutputs {
    /// Flow into chamber A [m3/s].
    pub q_a: f64,
    /// Flow out of chamber B [m3/s].
    pub q_b: f64,
    pub p_a: f64,
    pub p_b: f64,
    pub x_piston: f64,
    pub v_piston: f64,
    /// p_A*A_A - p_B*A_B [N].
    pub f_hydraulic: f64,
}

/// Rest state at mid-stroke for a centred valve: `p_A + p_B = p_S + p_T` (the null of an
/// underlapped valve: with leak openings `u + d` and `u - d` on P->A / A->T and the reverse on
/// the B side, both chambers balance when `p_A/(p_S - p_A) = r` and `p_B/(p_S - p_B) = 1/r`, i.e.
/// `p_A + p_B = p_S` with the tank at 0), together with `p_A A_A - p_B A_B + F_ext = 0`.
/// For F_ext = 0: `p_A = (p_S + p_T) A_B/(A_A + A_B)`. Loads the valve cannot hold with both
/// pressures in `[p_T, p_S]` are clamped there (then the force balance is not met).
pub fn equilibrium(params: &CylinderParams, p_supply: f64, f_ext: f64) -> CylinderState {
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let sum = p_supply + params.p_tank;
    let (lo, hi) = (params.p_tank.min(p_supply), params.p_tank.max(p_supply));
    let p_a = ((sum * area_b - f_ext) / (area_a + area_b)).clamp(lo, hi);
    let p_b = ((p_a * area_a + f_ext) / area_b).clamp(lo, hi);
    CylinderState { p_a, p_b, x: 0.0, v: 0.0 }
}

/// Signed square root, regularised below `dp_lam` by the odd cubic `a dp + b dp^3` that
/// matches value and slope of `sqrt` at `dp_lam` (C1; slope 1.25/sqrt(dp_lam) at zero).
fn regularised_sqrt(dp: f64, dp_lam: f64) -> f64 {
    let magnitude = dp.abs();
    if magnitude >= dp_lam {
        dp.signum() * magnitude.sqrt()
    } else {
        let s = dp / dp_lam;
        dp_lam.sqrt() * s * (1.25 - 0.25 * s * s)
    }
}

/// Actual port flows `(Q_A into A, Q_B out of B)` [m3/s] for spool position `x_s`.
pub fn port_flows(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
) -> (f64, f64) {
    // Chamber pressures below the floor (rounding only) are read at the floor.
    let p_a = state.p_a.max(params.p_cavitation);
    let p_b = state.p_b.max(params.p_cavitation);
    let gain = params.k3 * x_s / (0.5 * params.dp_rated).sqrt();
    let lam = params.dp_laminar;
    if x_s >= 0.0 {
        // P -> A and B -> T open.
        (
            gain * regularised_sqrt(p_supply - p_a, lam),
            gain * regularised_sqrt(p_b - params.p_tank, lam),
        )
    } else {
        // A -> T and P -> B open (gain < 0 turns the flows around).
        (
            gain * regularised_sqrt(p_a - params.p_tank, lam),
            gain * regularised_sqrt(p_supply - p_b, lam),
        )
    }
}

/// Friction force opposing motion, viscous part included [N].
fn friction(params: &CylinderParams, v: f64) -> f64 {
    let stribeck = (v / params.v_stribeck).powi(2);
    let dry = params.f_coulomb + (params.f_static - params.f_coulomb) * (-stribeck).exp();
    dry * (v / params.v_friction_smooth).tanh() + params.b_viscous * v
}

/// End-stop contact force on the piston, positive towards +x [N]. Never pulls.
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

/// Chamber volumes never shrink below this fraction of the dead volume (only reachable with
/// absurd end-stop penetration; keeps the pressure equations finite).
const MIN_VOLUME_FRACTION: f64 = 1e-3;

/// `[p_A', p_B', x', v']` for spool position `x_s`.
pub fn derivatives(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
    f_ext: f64,
) -> [f64; 4] {
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let half = 0.5 * params.stroke;
    let min_volume = MIN_VOLUME_FRACTION * params.v_dead;
    let volume_a = (params.v_dead + area_a * (state.x + half)).max(min_volume);
    let volume_b = (params.v_dead + area_b * (half - state.x)).max(min_volume);
    let (q_a, q_b) = port_flows(params, state, x_s, p_supply);
    let q_internal = params.c_leak * (state.p_a - state.p_b);
    let q_external_a = params.c_leak_external * (state.p_a - params.p_tank);
    let q_external_b = params.c_leak_external * (state.p_b - params.p_tank);
    let inflow_a = q_a - area_a * state.v - q_internal - q_external_a;
    let inflow_b = -q_b + area_b * state.v + q_internal - q_external_b;
    let dp_a = params.beta / volume_a * inflow_a * cavitation_factor(params, state.p_a, inflow_a);
    let dp_b = params.beta / volume_b * inflow_b * cavitation_factor(params, state.p_b, inflow_b);
    let force = state.p_a * area_a - state.p_b * area_b - friction(params, state.v)
        + f_ext
        + endstop_force(params, state.x, state.v);
    [dp_a, dp_b, state.v, force / params.mass]
}

/// Slope of [`regularised_sqrt`] with respect to `dp` (finite everywhere, 1.25/sqrt(dp_lam) at 0).
fn regularised_sqrt_slope(dp: f64, dp_lam: f64) -> f64 {
    let magnitude = dp.abs();
    if magnitude >= dp_lam {
        0.5 / magnitude.sqrt()
    } else {
        let s = dp / dp_lam;
        (1.25 - 0.75 * s * s) / dp_lam.sqrt()
    }
}

/// The model linearised at a state: `f` exactly as [`derivatives`] computes it, the analytic
/// Jacobian `df/dy` and the sensitivity `df/dx_s` (the only time dependence: `df/dt = df/dx_s
/// x_s'`). At a kink of a piecewise law (a clamp, the branch of a `max`) the derivative is
/// taken on the side the state is on, ties broken towards increasing argument (as a forward
/// difference would see it), except at the contact switching surfaces of the end stop where it
/// is the side the state is on (no contact at exactly zero penetration or zero contact force).
#[allow(clippy::needless_range_loop)]
fn linearise(
    params: &CylinderParams,
    y: &Vec4,
    x_s: f64,
    p_supply: f64,
    f_ext: f64,
) -> (Vec4, Mat4, Vec4) {
    let (p_a_raw, p_b_raw, x, v) = (y[PA], y[PB], y[X], y[V]);
    let (area_a, area_b) = (params.area_a(), params.area_b());
    let half = 0.5 * params.stroke;
    let min_volume = MIN_VOLUME_FRACTION * params.v_dead;
    let volume_a_free = params.v_dead + area_a * (x + half);
    let volume_b_free = params.v_dead + area_b * (half - x);
    let (volume_a, dva_dx) =
        if volume_a_free >= min_volume { (volume_a_free, area_a) } else { (min_volume, 0.0) };
    let (volume_b, dvb_dx) =
        if volume_b_free >= min_volume { (volume_b_free, -area_b) } else { (min_volume, 0.0) };
    // Port flows, as `port_flows`, with their slopes in the chamber pressures and in x_s.
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
    let (q_a, q_b) = (gain * r_a, gain * r_b);
    let (dqa_dpa, dqb_dpb) = (gain * dra_dpa * clamp_a, gain * drb_dpb * clamp_b);
    let (dqa_dxs, dqb_dxs) = (gain_per_xs * r_a, gain_per_xs * r_b);
    let q_internal = params.c_leak * (p_a_raw - p_b_raw);
    let q_external_a = params.c_leak_external * (p_a_raw - params.p_tank);
    let q_external_b = params.c_leak_external * (p_b_raw - params.p_tank);
    let inflow_a = q_a - area_a * v - q_internal - q_external_a;
    let inflow_b = -q_b + area_b * v + q_internal - q_external_b;
    // Cavitation factors and their slopes in the chamber's own pressure.
    let factor = |p: f64, inflow: f64| -> (f64, f64) {
        if inflow >= 0.0 {
            return (1.0, 0.0);
        }
        let band = params.dp_cavitation_band;
        let u_raw = (p - params.p_cavitation) / band;
        let u = u_raw.clamp(0.0, 1.0);
        let slope = if (0.0..1.0).contains(&u_raw) { (2.0 - 2.0 * u) / band } else { 0.0 };
        (u * (2.0 - u), slope)
    };
    let (cf_a, dcfa_dpa) = factor(p_a_raw, inflow_a);
    let (cf_b, dcfb_dpb) = factor(p_b_raw, inflow_b);
    let (stiff_a, stiff_b) = (params.beta / volume_a, params.beta / volume_b);
    let dp_a = stiff_a * inflow_a * cf_a;
    let dp_b = stiff_b * inflow_b * cf_b;
    // Mechanics.
    let stribeck = (v / params.v_stribeck).powi(2);
    let decay = (-stribeck).exp();
    let dry = params.f_coulomb + (params.f_static - params.f_coulomb) * decay;
    let ddry_dv = (params.f_static - params.f_coulomb)
        * decay
        * (-2.0 * v / (params.v_stribeck * params.v_stribeck));
    let th = (v / params.v_friction_smooth).tanh();
    let friction = dry * th + params.b_viscous * v;
    let dfriction_dv =
        ddry_dv * th + dry * (1.0 - th * th) / params.v_friction_smooth + params.b_viscous;
    let (beyond_top, beyond_bottom) = (x - half, -half - x);
    let (contact, dcontact_dx, dcontact_dv) = if beyond_top > 0.0 {
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
    };
    let force = p_a_raw * area_a - p_b_raw * area_b - friction + f_ext + contact;
    let f = [dp_a, dp_b, v, force / params.mass];

    let mut jac: Mat4 = [[0.0; N_STATES]; N_STATES];
    let (c_leak, c_ext) = (params.c_leak, params.c_leak_external);
    // d inflow_a / d(p_a, p_b, x, v) = (dqa_dpa - c_leak - c_ext, c_leak, 0, -A_A)
    jac[PA][PA] = stiff_a * (cf_a * (dqa_dpa - c_leak - c_ext) + inflow_a * dcfa_dpa);
    jac[PA][PB] = stiff_a * cf_a * c_leak;
    jac[PA][X] = -stiff_a / volume_a * dva_dx * inflow_a * cf_a;
    jac[PA][V] = -stiff_a * cf_a * area_a;
    // d inflow_b / d(p_a, p_b, x, v) = (c_leak, -dqb_dpb - c_leak - c_ext, 0, A_B)
    jac[PB][PA] = stiff_b * cf_b * c_leak;
    jac[PB][PB] = stiff_b * (cf_b * (-dqb_dpb - c_leak - c_ext) + inflow_b * dcfb_dpb);
    jac[PB][X] = -stiff_b / volume_b * dvb_dx * inflow_b * cf_b;
    jac[PB][V] = stiff_b * cf_b * area_b;
    jac[X][V] = 1.0;
    jac[V][PA] = area_a / params.mass;
    jac[V][PB] = -area_b / params.mass;
    jac[V][X] = dcontact_dx / params.mass;
    jac[V][V] = (dcontact_dv - dfriction_dv) / params.mass;
    let f_xs = [stiff_a * cf_a * dqa_dxs, -stiff_b * cf_b * dqb_dxs, 0.0, 0.0];
    (f, jac, f_xs)
}

/// All outputs at a state.
pub fn outputs(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
) -> CylinderOutputs {
    let (q_a, q_b) = port_flows(params, state, x_s, p_supply);
    CylinderOutputs {
        q_a,
        q_b,
        p_a: state.p_a,
        p_b: state.p_b,
        x_piston: state.x,
        v_piston: state.v,
        f_hydraulic: state.p_a * params.area_a() - state.p_b * params.area_b(),
    }
}

// ---------------------------------------------------------------------------------------
// Integrator: Rodas4 with error control.
// ---------------------------------------------------------------------------------------

/// A Rosenbrock method in the transformed form of Hairer & Wanner and of KPP (Sandu et al.):
/// `(I/(h gamma) - J) k_i = f(t + c_i h, y + sum_j a_ij k_j) + sum_j (c_ij/h) k_j + h d_i f_t`,
/// `y_new = y + sum_j m_j k_j`, error estimate `sum_j e_j k_j`. `new_f[i] = false`: stage i
/// evaluates `f` at the same point as stage i - 1 (reused, no model evaluation).
struct Rosenbrock<const S: usize> {
    gamma: f64,
    nodes: [f64; S],
    d: [f64; S],
    a: [[f64; S]; S],
    c: [[f64; S]; S],
    m: [f64; S],
    e: [f64; S],
    new_f: [bool; S],
}

/// Rodas4 (Hairer & Wanner's `rodas.f`, METH = 1): order 4, embedded order 3, stiffly
/// accurate, L-stable; 6 stages, 5 model evaluations besides the linearisation point.
const RODAS4: Rosenbrock<6> = {
    const A6: [f64; 6] =
        [1.221224509226641, 6.019134481288629, 12.53708332932087, -0.687886036105895, 1.0, 0.0];
    Rosenbrock {
        gamma: 0.25,
        nodes: [0.0, 0.386, 0.21, 0.63, 1.0, 1.0],
        d: [0.25, -0.1043, 0.1035, -0.3620000000000023e-01, 0.0, 0.0],
        a: [
            [0.0; 6],
            [1.544, 0.0, 0.0, 0.0, 0.0, 0.0],
            [0.9466785280815826, 0.2557011698983284, 0.0, 0.0, 0.0, 0.0],
            [3.314825187068521, 2.896124015972201, 0.9986419139977817, 0.0, 0.0, 0.0],
            [1.221224509226641, 6.019134481288629, 12.53708332932087, -0.687886036105895, 0.0, 0.0],
            // Stage 6 is evaluated at the embedded solution y_5 + k_5.
            A6,
        ],
        c: [
            [0.0; 6],
            [-5.6688, 0.0, 0.0, 0.0, 0.0, 0.0],
            [-2.430093356833875, -0.2063599157091915, 0.0, 0.0, 0.0, 0.0],
            [-0.1073529058151375, -9.594562251023355, -20.47028614809616, 0.0, 0.0, 0.0],
            [7.496443313967647, -10.24680431464352, -33.99990352819905, 11.7089089320616, 0.0, 0.0],
            [
                8.083246795921522,
                -7.981132988064893,
                -31.52159432874371,
                16.31930543123136,
                -6.058818238834054,
                0.0,
            ],
        ],
        m: [A6[0], A6[1], A6[2], A6[3], 1.0, 1.0],
        e: [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        new_f: [true; 6],
    }
};

/// Rodas3 (Sandu, Verwer, Blom, Spee, Carmichael, Potra 1997, as in KPP): order 3, embedded
/// order 2, stiffly accurate, L-stable; 4 stages, 2 model evaluations besides the
/// linearisation point (stage 2 reuses `f(y)`).
const RODAS3: Rosenbrock<4> = Rosenbrock {
    gamma: 0.5,
    nodes: [0.0, 0.0, 1.0, 1.0],
    d: [0.5, 1.5, 0.0, 0.0],
    a: [[0.0; 4], [0.0; 4], [2.0, 0.0, 0.0, 0.0], [2.0, 0.0, 1.0, 0.0]],
    c: [[0.0; 4], [4.0, 0.0, 0.0, 0.0], [1.0, -1.0, 0.0, 0.0], [1.0, -1.0, -8.0 / 3.0, 0.0]],
    m: [2.0, 0.0, 1.0, 1.0],
    e: [0.0, 0.0, 0.0, 1.0],
    new_f: [true, false, true, true],
};

/// Step controller limits (as in `rodas.f`): the step changes by a factor in [0.2, 6].
const SAFETY: f64 = 0.9;
const MIN_FACTOR: f64 = 0.2;
const MAX_FACTOR: f64 = 6.0;
/// First step when nothing is known yet [s].
const INITIAL_STEP: f64 = 1e-6;
/// Refuse a call that needs more internal steps than this (rejected ones included).
const MAX_STEPS_PER_CALL: u32 = 100_000;

/// Error weights: the error of state i is measured against `rtol * max(|y_i|, STATE_SCALE[i])`.
pub const STATE_SCALE: [f64; N_STATES] = [1.0e6, 1.0e6, 1.0e-2, 1.0e-1];

/// What the integrator carries from one call to the next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntegratorMemory {
    /// Relative tolerance on the scaled states.
    pub rtol: f64,
    /// Step size to try next [s]; 0 = not known yet.
    pub h_next: f64,
    /// Last accepted step and its error, for Gustafsson's predictive controller.
    h_accepted: f64,
    err_accepted: f64,
}

impl Default for IntegratorMemory {
    fn default() -> Self {
        IntegratorMemory::new(1e-8)
    }
}

impl IntegratorMemory {
    pub fn new(rtol: f64) -> IntegratorMemory {
        IntegratorMemory { rtol, h_next: 0.0, h_accepted: 0.0, err_accepted: 1.0 }
    }
    /// Forget step history (after a state jump or a reset).
    pub fn reset(&mut self) {
        *self = IntegratorMemory::new(self.rtol);
    }
    /// `[rtol, h_next, h_accepted, err_accepted]`, for serialising the instance state.
    pub fn to_array(&self) -> [f64; 4] {
        [self.rtol, self.h_next, self.h_accepted, self.err_accepted]
    }
    pub fn from_array(a: &[f64; 4]) -> IntegratorMemory {
        IntegratorMemory { rtol: a[0], h_next: a[1], h_accepted: a[2], err_accepted: a[3] }
    }
}

/// Work done in one call of [`advance`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    pub accepted: u32,
    pub rejected: u32,
    /// Model evaluations (an analytic linearisation counts as one, and in `jacobian_evaluations`).
    pub function_evaluations: u32,
    pub jacobian_evaluations: u32,
    /// Accepted steps taken with Rodas3 (included in `accepted`), and Rodas3 attempts whose
    /// error estimate failed (followed by Rodas4 on the same step; not in `rejected`).
    pub cheap: u32,
    pub cheap_failed: u32,
    /// Accepted steps cut short to land on an end-stop contact switch (included in `accepted`).
    pub landings: u32,
    /// Largest amount a pressure was lifted back to the cavitation floor after a step [Pa].
    pub floor_clamp: f64,
}

/// The spool path over one call: the quintic Hermite interpolant through position, rate
/// and acceleration at both ends of `[0, h]` (the physics core knows them exactly).
#[derive(Clone, Copy, Debug)]
pub struct SpoolPath {
    pub h: f64,
    pub start: [f64; 3],
    pub end: [f64; 3],
}

impl SpoolPath {
    pub fn position(&self, tau: f64) -> f64 {
        let (h, a, b) = (self.h, &self.start, &self.end);
        let s = tau / h;
        let (s2, s3) = (s * s, s * s * s);
        let (s4, s5) = (s3 * s, s3 * s2);
        let h00 = 1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5;
        let h10 = s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5;
        let h20 = 0.5 * (s2 - 3.0 * s3 + 3.0 * s4 - s5);
        let h01 = 10.0 * s3 - 15.0 * s4 + 6.0 * s5;
        let h11 = -4.0 * s3 + 7.0 * s4 - 3.0 * s5;
        let h21 = 0.5 * (s3 - 2.0 * s4 + s5);
        a[0] * h00
            + h * a[1] * h10
            + h * h * a[2] * h20
            + b[0] * h01
            + h * b[1] * h11
            + h * h * b[2] * h21
    }

    /// d/dtau of [`SpoolPath::position`].
    pub fn rate(&self, tau: f64) -> f64 {
        let (h, a, b) = (self.h, &self.start, &self.end);
        let s = tau / h;
        let (s2, s3, s4) = (s * s, s * s * s, s * s * s * s);
        let d00 = -30.0 * s2 + 60.0 * s3 - 30.0 * s4;
        let d10 = 1.0 - 18.0 * s2 + 32.0 * s3 - 15.0 * s4;
        let d20 = s - 4.5 * s2 + 6.0 * s3 - 2.5 * s4;
        let d11 = -12.0 * s2 + 28.0 * s3 - 15.0 * s4;
        let d21 = 1.5 * s2 - 4.0 * s3 + 2.5 * s4;
        (a[0] - b[0]) * d00 / h + a[1] * d10 + h * a[2] * d20 + b[1] * d11 + h * b[2] * d21
    }
}

/// Advances the state by `h` seconds; `x_s(tau)` is the spool position at `tau` in `[0, h]`.
/// Its rate (for `df/dt`) is taken by differencing `x_s` alone (no extra model evaluation);
/// the physics core uses [`advance_with_rate`] with the exact rate, the tests this form
/// for arbitrary spool paths. On error the state is left as it was.
#[cfg(test)]
#[allow(clippy::too_many_arguments)]
pub fn advance(
    params: &CylinderParams,
    state: &mut CylinderState,
    h: f64,
    p_supply: f64,
    f_ext: f64,
    x_s: impl Fn(f64) -> f64,
    work: &mut IntegratorMemory,
) -> Result<Stats, String> {
    // Central difference inside [0, h], one-sided second order at its ends: O(1e-10) relative
    // error for a smooth path, which only enters through the h d_i f_t terms of the stages.
    let dt = 6e-6 * h;
    let spool = |tau: f64| {
        let value = x_s(tau);
        let rate = if tau - dt >= 0.0 && tau + dt <= h {
            (x_s(tau + dt) - x_s(tau - dt)) / (2.0 * dt)
        } else if tau + 2.0 * dt <= h {
            (-3.0 * value + 4.0 * x_s(tau + dt) - x_s(tau + 2.0 * dt)) / (2.0 * dt)
        } else {
            (3.0 * value - 4.0 * x_s(tau - dt) + x_s(tau - 2.0 * dt)) / (2.0 * dt)
        };
        (value, rate)
    };
    advance_with_rate(params, state, h, p_supply, f_ext, spool, work)
}

/// As [`advance`], with `spool(tau) = (x_s, dx_s/dtau)` at `tau` in `[0, h]`.
#[allow(clippy::too_many_arguments)]
pub fn advance_with_rate(
    params: &CylinderParams,
    state: &mut CylinderState,
    h: f64,
    p_supply: f64,
    f_ext: f64,
    spool: impl Fn(f64) -> (f64, f64),
    work: &mut IntegratorMemory,
) -> Result<Stats, String> {
    let mut stats = Stats::default();
    if h == 0.0 {
        return Ok(stats);
    }
    if !(h.is_finite() && h > 0.0) {
        return Err(format!("hydraulics: step {h} s is not a positive finite number"));
    }
    let model = Model { params, p_supply, f_ext, spool: &spool };
    let mut y = state.to_array();
    let mut tau = 0.0;
    let mut step = if work.h_next > 0.0 { work.h_next } else { INITIAL_STEP };
    let mut rejected_last = false;
    // The linearisation at (tau, y), kept across rejected attempts from the same point.
    let mut lin: Option<Linearisation> = None;
    // Consecutive steps cut to a contact switch; bounded so a switch the state cannot be
    // moved across (rounding) falls back to plain error control.
    let mut landings = 0;
    loop {
        if stats.accepted + stats.rejected >= MAX_STEPS_PER_CALL {
            return Err(format!(
                "hydraulics: more than {MAX_STEPS_PER_CALL} internal steps in one step of {h} s"
            ));
        }
        // The last step lands exactly on h; remember the untruncated size for the next call.
        let wanted = step;
        let mut last = tau + step * 1.0001 >= h;
        if last {
            step = h - tau;
        }
        let here = match lin {
            Some(ref l) => l,
            None => lin.insert(model.linearise(tau, &y, &mut stats)),
        };
        // Step onto the next end-stop contact switch instead of across it.
        let mut landing = false;
        if landings < MAX_LANDINGS {
            if let Some(t_switch) = next_contact_switch(params, &y, here, step) {
                let t_land = if t_switch <= 1e-3 * wanted {
                    // Close: the Taylor prediction is exact to far below this margin.
                    t_switch * (1.0 + 1e-6)
                } else {
                    // Far: land just short; the next step, from very close, lands on it.
                    t_switch * (1.0 - 1e-4)
                };
                let t_land = t_land.max(1e-12 * h);
                if t_land < step {
                    step = t_land;
                    last = false;
                    landing = true;
                }
            }
        }
        if step <= 1e-14 * h.max(1e-6) {
            return Err(format!("hydraulics: step size underflow at {tau} s into a step of {h} s"));
        }
        // A step the call boundary cut to at most half of what Rodas4's controller wants is
        // smooth at this size: try the cheaper Rodas3 under the same tolerance first and keep
        // its result only if its own error estimate passes; else Rodas4 from the same
        // linearisation. The controller only ever learns from Rodas4 steps.
        if last && step * 2.0 <= wanted {
            let (y3, err3) =
                rosenbrock_step(&RODAS3, &model, here, (tau, &y, step), work.rtol, &mut stats)?;
            if err3 <= 1.0 {
                stats.accepted += 1;
                stats.cheap += 1;
                y = y3;
                clamp_to_floor(params, &mut y, &mut stats);
                work.h_next = wanted;
                break;
            }
            stats.cheap_failed += 1;
        }
        let (y_new, err) =
            rosenbrock_step(&RODAS4, &model, here, (tau, &y, step), work.rtol, &mut stats)?;
        if err <= 1.0 {
            stats.accepted += 1;
            lin = None;
            y = y_new;
            clamp_to_floor(params, &mut y, &mut stats);
            tau += step;
            if landing {
                // A step cut short by a switch says nothing about the step size past it:
                // continue with what the controller wanted before.
                stats.landings += 1;
                landings += 1;
                step = wanted.min(h);
                continue;
            }
            landings = 0;
            let mut factor = (err.powf(0.25) / SAFETY).clamp(1.0 / MAX_FACTOR, 1.0 / MIN_FACTOR);
            // Gustafsson: also use the trend of the error between accepted steps.
            if work.h_accepted > 0.0 {
                let predictive =
                    (work.h_accepted / step) * (err * err / work.err_accepted).powf(0.25) / SAFETY;
                factor = factor.max(predictive.clamp(1.0 / MAX_FACTOR, 1.0 / MIN_FACTOR));
            }
            work.h_accepted = step;
            work.err_accepted = err.max(1e-2);
            let mut next = step / factor;
            if rejected_last {
                next = next.min(step);
            }
            rejected_last = false;
            if last {
                work.h_next = if next >= step { next.max(wanted) } else { next };
                break;
            }
            step = next.min(h);
        } else {
            stats.rejected += 1;
            rejected_last = true;
            let factor = (err.powf(0.25) / SAFETY).min(1.0 / MIN_FACTOR);
            step /= factor;
        }
    }
    if !y.iter().all(|v| v.is_finite()) {
        return Err("hydraulics: the state became non-finite; step refused".into());
    }
    *state = CylinderState::from_array(&y);
    Ok(stats)
}

/// Consecutive steps [`advance_with_rate`] cuts to a contact switch before it gives up on it.
const MAX_LANDINGS: u32 = 4;

/// Time from `y` to the first end-stop contact switch within `(0, span]`, from the Taylor
/// polynomial of the switching function (`x'' = f_V`, `x''' = (J f + f_t)_V` from the
/// linearisation). Switches: `x` reaching `+-stroke/2` from outside the stop (the contact
/// force jumps in by `c |v|`), and inside a stop the contact force `k d + c d'` crossing zero
/// (separation or re-engagement: a kink). Leaving a stop is smooth (the force is already 0).
fn next_contact_switch(
    params: &CylinderParams,
    y: &Vec4,
    lin: &Linearisation,
    span: f64,
) -> Option<f64> {
    let half = 0.5 * params.stroke;
    let (x, v, a) = (y[X], y[V], lin.f0[V]);
    let jerk = (0..N_STATES).map(|j| lin.jac[V][j] * lin.f0[j]).sum::<f64>() + lin.f_t[V];
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
    let crossed = |t: f64| (poly(t) > 0.0) != inside;
    if !crossed(span) {
        // A double crossing within the span (touch and leave) is not looked for.
        return None;
    }
    // The crossing lies in [lo, hi]; Newton, safeguarded by bisection.
    let (mut lo, mut hi) = (0.0, span);
    let mut t = if g[1] != 0.0 { -g[0] / g[1] } else { 0.5 * span };
    for _ in 0..60 {
        if !(t > lo && t < hi) {
            t = 0.5 * (lo + hi);
        }
        if crossed(t) {
            hi = t;
        } else {
            lo = t;
        }
        if hi - lo <= 1e-12 * hi {
            break;
        }
        let d = slope(t);
        t = if d != 0.0 { t - poly(t) / d } else { 0.5 * (lo + hi) };
    }
    Some(hi)
}

/// Lifts rounding-size undershoot of the cavitation floor back to it (recorded in `stats`).
fn clamp_to_floor(params: &CylinderParams, y: &mut Vec4, stats: &mut Stats) {
    for k in [PA, PB] {
        if y[k] < params.p_cavitation {
            stats.floor_clamp = stats.floor_clamp.max(params.p_cavitation - y[k]);
            y[k] = params.p_cavitation;
        }
    }
}

/// The right-hand side over one call: parameters, inputs and the spool path.
struct Model<'a, S: Fn(f64) -> (f64, f64)> {
    params: &'a CylinderParams,
    p_supply: f64,
    f_ext: f64,
    spool: &'a S,
}

impl<S: Fn(f64) -> (f64, f64)> Model<'_, S> {
    fn f(&self, tau: f64, y: &Vec4, stats: &mut Stats) -> Vec4 {
        stats.function_evaluations += 1;
        derivatives(
            self.params,
            &CylinderState::from_array(y),
            (self.spool)(tau).0,
            self.p_supply,
            self.f_ext,
        )
    }

    /// `f`, `df/dy` and `df/dt` at `(tau, y)`, analytic.
    fn linearise(&self, tau: f64, y: &Vec4, stats: &mut Stats) -> Linearisation {
        stats.function_evaluations += 1;
        stats.jacobian_evaluations += 1;
        let (x_s, rate) = (self.spool)(tau);
        let (f0, jac, f_xs) = linearise(self.params, y, x_s, self.p_supply, self.f_ext);
        Linearisation { f0, jac, f_t: f_xs.map(|d| d * rate) }
    }
}

/// The model linearised at the start of a step, shared by the methods tried on it.
struct Linearisation {
    f0: Vec4,
    jac: Mat4,
    f_t: Vec4,
}

/// One step of `method` from `(tau, y)` of size `h`: the new state and its scaled error norm.
#[allow(clippy::needless_range_loop)]
fn rosenbrock_step<const S: usize, F: Fn(f64) -> (f64, f64)>(
    method: &Rosenbrock<S>,
    model: &Model<'_, F>,
    lin: &Linearisation,
    (tau, y, h): (f64, &Vec4, f64),
    rtol: f64,
    stats: &mut Stats,
) -> Result<(Vec4, f64), String> {
    // W = I/(h gamma) - J
    let mut w = lin.jac;
    for (i, row) in w.iter_mut().enumerate() {
        for value in row.iter_mut() {
            *value = -*value;
        }
        row[i] += 1.0 / (h * method.gamma);
    }
    let lu = Lu4::factor(w).ok_or_else(|| "hydraulics: singular iteration matrix".to_string())?;
    let mut k = [[0.0; N_STATES]; S];
    let mut fi = lin.f0;
    for stage in 0..S {
        if stage > 0 && method.new_f[stage] {
            let mut yi = *y;
            for j in 0..stage {
                for n in 0..N_STATES {
                    yi[n] += method.a[stage][j] * k[j][n];
                }
            }
            fi = model.f(tau + method.nodes[stage] * h, &yi, stats);
        }
        let mut rhs = fi;
        for n in 0..N_STATES {
            rhs[n] += h * method.d[stage] * lin.f_t[n];
            for j in 0..stage {
                rhs[n] += method.c[stage][j] / h * k[j][n];
            }
        }
        k[stage] = lu.solve(rhs);
    }
    let mut y_new = *y;
    let mut sum = 0.0;
    for n in 0..N_STATES {
        let mut error = 0.0;
        for j in 0..S {
            y_new[n] += method.m[j] * k[j][n];
            error += method.e[j] * k[j][n];
        }
        let scale = rtol * y[n].abs().max(y_new[n].abs()).max(STATE_SCALE[n]);
        sum += (error / scale).powi(2);
    }
    let err = (sum / N_STATES as f64).sqrt();
    // A non-finite stage is an error estimate of infinity: the step is rejected and shrunk.
    Ok((y_new, if err.is_finite() { err } else { f64::INFINITY }))
}

/// LU factors of a 4x4 matrix with partial pivoting.
struct Lu4 {
    lu: Mat4,
    pivot: [usize; N_STATES],
}

impl Lu4 {
    fn factor(mut a: Mat4) -> Option<Lu4> {
        let mut pivot = [0; N_STATES];
        for col in 0..N_STATES {
            let mut best = col;
            for row in col + 1..N_STATES {
                if a[row][col].abs() > a[best][col].abs() {
                    best = row;
                }
            }
            if a[best][col] == 0.0 || !a[best][col].is_finite() {
                return None;
            }
            a.swap(col, best);
            pivot[col] = best;
            let pivot_row = a[col];
            for row in a.iter_mut().skip(col + 1) {
                let m = row[col] / pivot_row[col];
                row[col] = m;
                for (value, above) in row.iter_mut().zip(pivot_row.iter()).skip(col + 1) {
                    *value -= m * above;
                }
            }
        }
        Some(Lu4 { lu: a, pivot })
    }

    fn solve(&self, mut b: Vec4) -> Vec4 {
        for col in 0..N_STATES {
            b.swap(col, self.pivot[col]);
        }
        for row in 1..N_STATES {
            for c in 0..row {
                b[row] -= self.lu[row][c] * b[c];
            }
        }
        for row in (0..N_STATES).rev() {
            for c in row + 1..N_STATES {
                b[row] -= self.lu[row][c] * b[c];
            }
            b[row] /= self.lu[row][row];
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P_RATED: f64 = 6.8948e6;
    /// Spool opening for the rated 10 mA flow of MODEL.md row 10 (2.5268e-4 m3/s).
    const X_S_RATED: f64 = 2.5268e-4 / 0.664515;

    /// Runs `t_end` seconds in calls of `interval`, spool position `x_s(t)` in absolute time;
    /// `observe` sees the state after every call. Returns the summed statistics.
    fn simulate(
        params: &CylinderParams,
        state: &mut CylinderState,
        work: &mut IntegratorMemory,
        x_s: &dyn Fn(f64) -> f64,
        (p_supply, f_ext): (f64, f64),
        (t_start, t_end, interval): (f64, f64, f64),
        mut observe: impl FnMut(f64, &CylinderState),
    ) -> (Stats, u32) {
        let mut total = Stats::default();
        let mut most_steps = 0;
        let calls = ((t_end - t_start) / interval).round() as usize;
        for n in 0..calls {
            let t = t_start + n as f64 * interval;
            let s = advance(params, state, interval, p_supply, f_ext, |tau| x_s(t + tau), work)
                .unwrap();
            total.accepted += s.accepted;
            total.rejected += s.rejected;
            total.function_evaluations += s.function_evaluations;
            total.jacobian_evaluations += s.jacobian_evaluations;
            total.cheap += s.cheap;
            total.cheap_failed += s.cheap_failed;
            total.landings += s.landings;
            total.floor_clamp = total.floor_clamp.max(s.floor_clamp);
            most_steps = most_steps.max(s.accepted + s.rejected);
            observe(t + interval, state);
        }
        (total, most_steps)
    }

    fn jacobian(
        params: &CylinderParams,
        state: &CylinderState,
        x_s: f64,
        p_supply: f64,
        f_ext: f64,
    ) -> nalgebra::Matrix4<f64> {
        let y = state.to_array();
        let f0 = derivatives(params, state, x_s, p_supply, f_ext);
        let mut jac = nalgebra::Matrix4::zeros();
        for j in 0..4 {
            let delta = 1e-7 * y[j].abs().max(STATE_SCALE[j]);
            let mut shifted = y;
            shifted[j] += delta;
            let fj =
                derivatives(params, &CylinderState::from_array(&shifted), x_s, p_supply, f_ext);
            for i in 0..4 {
                jac[(i, j)] = (fj[i] - f0[i]) / delta;
            }
        }
        jac
    }

    #[test]
    fn regularised_sqrt_is_c1_and_exact_above_laminar() {
        let lam = 1e5;
        for dp in [1e5, 2e5, 3.4474e6, -5e6] {
            assert_eq!(regularised_sqrt(dp, lam), f64::signum(dp) * f64::sqrt(dp.abs()));
        }
        let below = regularised_sqrt(lam * (1.0 - 1e-9), lam);
        assert!((below - lam.sqrt()).abs() < 1e-9 * lam.sqrt());
        let slope =
            |dp: f64| (regularised_sqrt(dp + 1e-3, lam) - regularised_sqrt(dp - 1e-3, lam)) / 2e-3;
        assert!((slope(lam - 1.0) - slope(lam + 1.0)).abs() < 1e-4 * slope(lam + 1.0));
        assert!((slope(0.0) - 1.25 / lam.sqrt()).abs() < 1e-9);
        assert_eq!(regularised_sqrt(-3e4, lam), -regularised_sqrt(3e4, lam));
    }

    #[test]
    fn parameters_come_from_the_table_and_validation_names_the_variable() {
        let defaults = CylinderParams::default();
        assert_eq!(
            (defaults.bore, defaults.mass, defaults.k_endstop, defaults.p_cavitation),
            (0.016, 5.0, 1e8, -0.9e5)
        );
        let bad = CylinderParams { mass: 0.0, ..defaults };
        assert!(bad.validate().unwrap_err().contains("cylinder.mass"));
        let bad = CylinderParams { rod: 0.02, ..defaults };
        assert!(bad.validate().unwrap_err().contains("cylinder.rod"));
        let bad = CylinderParams { beta: f64::NAN, ..defaults };
        assert!(bad.validate().unwrap_err().contains("cylinder.beta"));
        let bad = CylinderParams { p_cavitation: 1e5, ..defaults };
        assert!(bad.validate().unwrap_err().contains("hydraulics.p_cavitation"));
    }

    #[test]
    fn valve_ports_follow_the_orifice_law() {
        let p = CylinderParams::default();
        // Each port at dp_r/2 gives exactly the paper's no-load flow K3*x_s.
        let half = 0.5 * P_RATED;
        let balanced = CylinderState { p_a: half, p_b: half, x: 0.0, v: 0.0 };
        let (q_a, q_b) = port_flows(&p, &balanced, 1e-4, P_RATED);
        assert!((q_a - p.k3 * 1e-4).abs() < 1e-12 * q_a.abs() && (q_b - q_a).abs() < 1e-18);
        let (q_a, q_b) = port_flows(&p, &balanced, -1e-4, P_RATED);
        assert!((q_a + p.k3 * 1e-4).abs() < 1e-12 * q_a.abs() && (q_b - q_a).abs() < 1e-18);
        // Closed valve: no flow at any pressure; load pressure above supply: reverse flow.
        assert_eq!(port_flows(&p, &balanced, 0.0, P_RATED), (0.0, 0.0));
        let over = CylinderState { p_a: 1.2 * P_RATED, ..balanced };
        assert!(port_flows(&p, &over, 1e-4, P_RATED).0 < 0.0);
    }

    #[test]
    fn equilibrium_start_has_zero_derivatives_and_stays_put() {
        let p = CylinderParams::default();
        let stall = p.stall_force(P_RATED);
        for f_ext in [0.0, 0.3 * stall, -0.3 * stall] {
            let s0 = equilibrium(&p, P_RATED, f_ext);
            assert!((s0.p_a + s0.p_b - P_RATED).abs() < 1e-6, "{s0:?}");
            assert!(s0.p_a > 0.0 && s0.p_a < P_RATED && s0.p_b > 0.0 && s0.p_b < P_RATED);
            let d = derivatives(&p, &s0, 0.0, P_RATED, f_ext);
            // Force residual below 1e-12 N equivalent; pressures and position exactly still.
            assert_eq!((d[0], d[1], d[2]), (0.0, 0.0, 0.0));
            assert!(d[3].abs() * p.mass < 1e-12 * stall, "{d:?}");
            let mut s = s0;
            let mut work = IntegratorMemory::default();
            let (stats, _) = simulate(
                &p,
                &mut s,
                &mut work,
                &|_| 0.0,
                (P_RATED, f_ext),
                (0.0, 0.01, 1e-4),
                |_, _| {},
            );
            assert!(
                s.x.abs() < 1e-12 && (s.p_a - s0.p_a).abs() < 1e-3 && (s.p_b - s0.p_b).abs() < 1e-3,
                "{s:?}"
            );
            // Cheap at rest: after the first call's step-size ramp, one step per call.
            assert!(stats.accepted <= 100 + 10, "{stats:?}");
        }
        // Unloaded: p_A = p_S A_B/(A_A + A_B).
        let s = equilibrium(&p, P_RATED, 0.0);
        assert!((s.p_a - P_RATED * p.area_b() / (p.area_a() + p.area_b())).abs() < 1e-6);
    }

    #[test]
    fn steady_velocity_equals_port_flow_over_area() {
        let p = CylinderParams::default();
        let mut s = equilibrium(&p, P_RATED, 0.0);
        s.x = -0.035;
        let mut work = IntegratorMemory::default();
        let x_s = 0.2e-3;
        simulate(&p, &mut s, &mut work, &|_| x_s, (P_RATED, 0.0), (0.0, 0.04, 1e-4), |_, _| {});
        assert!(s.x < p.stroke / 2.0);
        let (q_a, q_b) = port_flows(&p, &s, x_s, P_RATED);
        let v_a = q_a / p.area_a();
        let v_b = q_b / p.area_b();
        assert!((s.v - v_a).abs() < 0.01 * v_a, "v = {} vs Q_A/A_A = {v_a}", s.v);
        assert!((s.v - v_b).abs() < 0.01 * v_b, "v = {} vs Q_B/A_B = {v_b}", s.v);
        // Independent steady state: for a speed v the port laws give p_A and p_B; bisect on
        // the force balance p_A A_A - p_B A_B = b v + friction (turbulent ports, p_T = 0).
        let half_drop = 0.5 * p.dp_rated;
        let residual = |v: f64| {
            let p_a = P_RATED - half_drop * (p.area_a() * v / (p.k3 * x_s)).powi(2);
            let p_b = half_drop * (p.area_b() * v / (p.k3 * x_s)).powi(2);
            p_a * p.area_a() - p_b * p.area_b() - friction(&p, v)
        };
        let (mut lo, mut hi) = (1e-3, 2.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if residual(mid) > 0.0 {
                lo = mid
            } else {
                hi = mid
            }
        }
        assert!((s.v - lo).abs() < 1e-4 * lo, "v = {} vs steady {lo}", s.v);
        // Unequal areas: Q_A is not K3 x_s even without load (about 1.28 K3 x_s; 1.19 here
        // with 180 N of friction).
        let ratio = q_a / (p.k3 * x_s);
        assert!(ratio > 1.15 && ratio < 1.3, "Q_A/(K3 x_s) = {ratio}");
    }

    #[test]
    fn volume_balance_of_chamber_a() {
        // integral Q_A dt = A_A dx + integral V_A/beta dp_A (trapezoid on 10 us samples).
        let p = CylinderParams::default();
        let s0 = equilibrium(&p, P_RATED, 0.0);
        let mut s = s0;
        let mut work = IntegratorMemory::default();
        let x_s = |t: f64| 0.2e-3 * (1.0 - (-t / 2e-3).exp());
        let volume_a = |s: &CylinderState| p.v_dead + p.area_a() * (s.x + p.stroke / 2.0);
        let (mut inflow, mut compressed) = (0.0, 0.0);
        let mut prev = (0.0, s0, port_flows(&p, &s0, x_s(0.0), P_RATED).0);
        simulate(&p, &mut s, &mut work, &x_s, (P_RATED, 0.0), (0.0, 0.03, 1e-5), |t, s| {
            let q = port_flows(&p, s, x_s(t), P_RATED).0;
            inflow += 0.5 * (q + prev.2) * (t - prev.0);
            compressed += 0.5 * (volume_a(s) + volume_a(&prev.1)) / p.beta * (s.p_a - prev.1.p_a);
            prev = (t, *s, q);
        });
        let displaced = p.area_a() * (s.x - s0.x);
        let residual = inflow - displaced - compressed;
        assert!(
            residual.abs() < 1e-3 * inflow.abs(),
            "in {inflow}, displaced {displaced}, compressed {compressed}"
        );
        assert!(compressed.abs() > 1e-9, "the test should see compression: {compressed}");
    }

    /// A slow approach (0.2 m/s impact) presses on the stop with p_A rising to p_S from below.
    /// Faster impacts rebound off the stop and the returning piston compresses chamber A above
    /// supply (oil flows back into the supply port): +97 kPa at 0.4 m/s, +437 kPa at 0.78 m/s,
    /// the same at rtol 1e-8 and 1e-11, so this is the model's physics (a stop without
    /// cushioning), not integration error. Those cases check the bounds that do hold.
    #[test]
    fn end_stop_holds_the_rod_and_pressure_stays_below_supply() {
        let p = CylinderParams::default();
        let stall = p.stall_force(P_RATED);
        let static_penetration = stall / p.k_endstop;
        for x_s in [0.05e-3, 0.1e-3, 0.2e-3] {
            let mut s = equilibrium(&p, P_RATED, 0.0);
            let mut work = IntegratorMemory::default();
            let (mut x_max, mut p_a_max, mut v_impact) = (f64::MIN, f64::MIN, 0.0);
            let t_end = 0.1 * 0.1e-3 / x_s + 0.05;
            simulate(
                &p,
                &mut s,
                &mut work,
                &|_| x_s,
                (P_RATED, 0.0),
                (0.0, t_end, 1e-5),
                |_, s| {
                    if x_max < p.stroke / 2.0 {
                        v_impact = s.v;
                    }
                    x_max = x_max.max(s.x);
                    p_a_max = p_a_max.max(s.p_a);
                },
            );
            let penetration_max = x_max - p.stroke / 2.0;
            assert!(penetration_max > 0.0, "x_s {x_s}: never reached the stop: {x_max}");
            // Energy bound with the stall force still pushing: k d^2/2 <= m v^2/2 + F d.
            let bound = static_penetration
                + (static_penetration.powi(2) + p.mass * v_impact * v_impact / p.k_endstop).sqrt();
            assert!(penetration_max <= bound, "x_s {x_s}: {penetration_max} > {bound}");
            if x_s <= 0.1e-3 {
                assert!(penetration_max <= 1e-4, "x_s {x_s}: x_max = {x_max}");
            }
            if x_s <= 0.05e-3 {
                assert!(p_a_max <= P_RATED, "x_s {x_s}: p_A max {p_a_max}");
            } else {
                assert!(p_a_max <= 1.1 * P_RATED, "x_s {x_s}: p_A max {p_a_max}");
            }
            // Settled: A at supply, B at tank, pressed in by the stall force: d = p_S A_A / k.
            assert!(
                (s.p_a - P_RATED).abs() < 1e-6 * P_RATED && s.p_b.abs() < 1e-6 * P_RATED,
                "{s:?}"
            );
            let penetration = s.x - p.stroke / 2.0;
            assert!(
                (penetration - static_penetration).abs() < 1e-3 * static_penetration,
                "{penetration}"
            );
        }
    }

    #[test]
    fn overrunning_load_never_pulls_pressure_below_the_cavitation_floor() {
        let p = CylinderParams::default();
        let f_ext = -6000.0; // pulls the rod in, faster than supply can fill B
        let mut s = equilibrium(&p, P_RATED, 0.0);
        let mut work = IntegratorMemory::default();
        let mut p_min = f64::MAX;
        let mut time_at_floor = 0.0;
        let (stats, _) = simulate(
            &p,
            &mut s,
            &mut work,
            &|_| -0.5e-3,
            (P_RATED, f_ext),
            (0.0, 0.05, 1e-4),
            |_, s| {
                p_min = p_min.min(s.p_a).min(s.p_b);
                if s.p_b < p.p_cavitation + 0.01 * p.dp_cavitation_band {
                    time_at_floor += 1e-4;
                }
            },
        );
        assert!(p_min >= p.p_cavitation, "p_min = {p_min}");
        assert!(
            time_at_floor > 1e-3,
            "the case must actually cavitate: {time_at_floor} s at the floor"
        );
        // The floor holds in the ODE itself, not only by the post-step clamp.
        assert!(stats.floor_clamp < 1.0, "clamped by {} Pa", stats.floor_clamp);
        assert!(s.x < -p.stroke / 2.0 + 1e-4 && s.x > -p.stroke / 2.0 - 1e-3, "{s:?}");
    }

    #[test]
    fn result_does_not_depend_on_the_call_interval() {
        // A time-varying spool through both directions, an end stop and back: 1 us ... 10 ms calls.
        let p = CylinderParams::default();
        let x_s = |t: f64| 0.3e-3 * (2.0 * std::f64::consts::PI * 10.0 * t).sin();
        let run = |interval: f64, rtol: f64| {
            let mut s = equilibrium(&p, P_RATED, 200.0);
            let mut work = IntegratorMemory::new(rtol);
            simulate(
                &p,
                &mut s,
                &mut work,
                &x_s,
                (P_RATED, 200.0),
                (0.0, 0.06, interval),
                |_, _| {},
            );
            s
        };
        let reference = run(1e-3, 1e-11);
        for interval in [1e-6, 1e-4, 1e-3, 1e-2] {
            let s = run(interval, 1e-8);
            let e = [
                (s.p_a - reference.p_a) / 1e6,
                (s.p_b - reference.p_b) / 1e6,
                (s.x - reference.x) / 1e-2,
                (s.v - reference.v) / 1e-1,
            ];
            assert!(e.iter().all(|e| e.abs() < 1e-5), "interval {interval}: {e:?}");
        }
    }

    #[test]
    fn restored_state_and_memory_repeat_the_run_bit_for_bit() {
        let p = CylinderParams::default();
        let x_s = |t: f64| 0.2e-3 * (1.0 - (-t / 1e-3).exp());
        let mut s = equilibrium(&p, P_RATED, 100.0);
        let mut work = IntegratorMemory::default();
        simulate(&p, &mut s, &mut work, &x_s, (P_RATED, 100.0), (0.0, 0.005, 1e-3), |_, _| {});
        let (saved_state, saved_memory) = (s.to_array(), work.to_array());
        simulate(&p, &mut s, &mut work, &x_s, (P_RATED, 100.0), (0.005, 0.01, 1e-3), |_, _| {});
        let mut again = CylinderState::from_array(&saved_state);
        let mut again_work = IntegratorMemory::from_array(&saved_memory);
        simulate(
            &p,
            &mut again,
            &mut again_work,
            &x_s,
            (P_RATED, 100.0),
            (0.005, 0.01, 1e-3),
            |_, _| {},
        );
        assert_eq!(again, s);
        assert_eq!(again_work, work);
        // A refused step leaves the state alone.
        let before = s;
        assert!(advance(&p, &mut s, f64::NAN, P_RATED, 0.0, |_| 0.0, &mut work).is_err());
        assert_eq!(s, before);
    }

    #[test]
    fn jacobian_eigenvalues() {
        let p = CylinderParams::default();
        let rest = equilibrium(&p, P_RATED, 0.0);
        let mut moving = rest;
        let mut work = IntegratorMemory::default();
        simulate(
            &p,
            &mut moving,
            &mut work,
            &|_| X_S_RATED,
            (P_RATED, 0.0),
            (0.0, 0.02, 1e-4),
            |_, _| {},
        );
        let mut at_stop = rest;
        let mut work = IntegratorMemory::default();
        simulate(
            &p,
            &mut at_stop,
            &mut work,
            &|_| 0.2e-3,
            (P_RATED, 0.0),
            (0.0, 0.1, 1e-4),
            |_, _| {},
        );
        let cases = [
            ("at rest, x_s = 0", rest, 0.0),
            ("at rest, x_s = 1 um", rest, 1e-6),
            ("moving at rated flow", moving, X_S_RATED),
            ("held at the end stop, x_s = 0.2 mm", at_stop, 0.2e-3),
            ("at the stop, valve closed", at_stop, 0.0),
            (
                "impact: 50 um into the stop at 0.5 m/s",
                CylinderState { x: p.stroke / 2.0 + 5e-5, v: 0.5, ..moving },
                X_S_RATED,
            ),
            (
                "near supply, laminar port (p_S - p_A = 1 bar)",
                CylinderState { p_a: P_RATED - 1e5, ..rest },
                1e-3,
            ),
        ];
        let mut stiffest = [0.0; 7];
        for (k, (name, s, x_s)) in cases.iter().enumerate() {
            let eig = jacobian(&p, s, *x_s, P_RATED, 0.0).complex_eigenvalues();
            let text: Vec<String> =
                eig.iter().map(|l| format!("{:.3e}{:+.3e}i", l.re, l.im)).collect();
            println!("{name:40} x = {:+.4} v = {:+.3}: {}", s.x, s.v, text.join(", "));
            stiffest[k] = eig.iter().map(|l| l.norm()).fold(0.0, f64::max);
            assert!(eig.iter().all(|l| l.re < 1e3), "no fast growing mode: {text:?}");
        }
        // Stiff where it matters: friction at rest, end-stop contact and laminar port at the stop.
        assert!(stiffest[0] > 1e4 && stiffest[3] > 1e4, "{stiffest:?}");
    }

    /// The analytic linearisation against central differences of `derivatives`, in scaled
    /// variables (`J_ij scale_j / scale_i`), at points away from the kinks but inside every
    /// region of the piecewise laws.
    #[test]
    fn analytic_jacobian_matches_finite_differences() {
        let p = CylinderParams::default();
        let rest = equilibrium(&p, P_RATED, 0.0);
        let half = p.stroke / 2.0;
        let band = p.p_cavitation + 0.3 * p.dp_cavitation_band;
        let cases = [
            (
                "moving at rated flow",
                CylinderState { x: 0.01, v: 1.2, p_a: 5.0e6, p_b: 2.0e6 },
                X_S_RATED,
                0.0,
            ),
            (
                "retracting, x_s < 0",
                CylinderState { x: -0.01, v: -0.8, p_a: 1.0e6, p_b: 4.0e6 },
                -1e-4,
                300.0,
            ),
            (
                "laminar port near supply (0.4 bar)",
                CylinderState { p_a: P_RATED - 0.4e5, ..rest },
                1e-3,
                0.0,
            ),
            (
                "laminar port at tank, x_s < 0 (0.3 bar)",
                CylinderState { p_a: 0.3e5, ..rest },
                -2e-4,
                0.0,
            ),
            (
                "B emptying in the cavitation band",
                CylinderState { p_b: band, v: -0.3, x: -0.02, p_a: 1e6 },
                -0.5e-3,
                -6000.0,
            ),
            (
                "A emptying in the cavitation band",
                CylinderState { p_a: band, v: 0.3, x: 0.02, p_b: 1e6 },
                0.5e-3,
                6000.0,
            ),
            (
                "impact on the + stop (50 um, 0.5 m/s)",
                CylinderState { x: half + 5e-5, v: 0.5, ..rest },
                X_S_RATED,
                0.0,
            ),
            (
                "pressed on the + stop",
                CylinderState { x: half + 1.4e-5, v: 1e-6, p_a: P_RATED - 10.0, p_b: 10.0 },
                0.2e-3,
                0.0,
            ),
            (
                "impact on the - stop (30 um, -0.4 m/s)",
                CylinderState { x: -half - 3e-5, v: -0.4, ..rest },
                -X_S_RATED,
                0.0,
            ),
            ("friction near v = 0 (+30 um/s)", CylinderState { v: 3e-5, ..rest }, 1e-6, 0.0),
            ("friction near v = 0 (-80 um/s)", CylinderState { v: -8e-5, ..rest }, -3e-6, 50.0),
            ("Stribeck region (5 mm/s)", CylinderState { v: 5e-3, ..rest }, 1e-5, 0.0),
            ("with leakage", CylinderState { v: 0.1, ..rest }, 1e-4, 0.0),
        ];
        let leaky = CylinderParams { c_leak: 1e-12, c_leak_external: 3e-13, ..p };
        for (name, s, x_s, f_ext) in cases {
            let params = if name == "with leakage" { leaky } else { p };
            let y = s.to_array();
            let (f, jac, f_xs) = linearise(&params, &y, x_s, P_RATED, f_ext);
            assert_eq!(
                f,
                derivatives(&params, &s, x_s, P_RATED, f_ext),
                "{name}: f differs from derivatives()"
            );
            let mut worst: f64 = 0.0;
            for j in 0..4 {
                let delta = 1e-7 * STATE_SCALE[j];
                let (mut up, mut down) = (y, y);
                up[j] += delta;
                down[j] -= delta;
                let f_up =
                    derivatives(&params, &CylinderState::from_array(&up), x_s, P_RATED, f_ext);
                let f_down =
                    derivatives(&params, &CylinderState::from_array(&down), x_s, P_RATED, f_ext);
                for i in 0..4 {
                    let fd =
                        (f_up[i] - f_down[i]) / (2.0 * delta) * STATE_SCALE[j] / STATE_SCALE[i];
                    let an = jac[i][j] * STATE_SCALE[j] / STATE_SCALE[i];
                    let row: f64 = (0..4)
                        .map(|c| (jac[i][c] * STATE_SCALE[c] / STATE_SCALE[i]).abs())
                        .fold(0.0, f64::max);
                    let e = (an - fd).abs() / (an.abs() + row);
                    worst = worst.max(e);
                    assert!(
                        e < 1e-6,
                        "{name}: J[{i}][{j}] analytic {} vs difference {}",
                        jac[i][j],
                        fd * STATE_SCALE[i] / STATE_SCALE[j]
                    );
                }
            }
            let dx = 1e-7 * x_s.abs().max(1e-5);
            let (f_up, f_down) = (
                derivatives(&params, &s, x_s + dx, P_RATED, f_ext),
                derivatives(&params, &s, x_s - dx, P_RATED, f_ext),
            );
            for i in 0..4 {
                let fd = (f_up[i] - f_down[i]) / (2.0 * dx);
                assert!(
                    (f_xs[i] - fd).abs()
                        <= 1e-6 * fd.abs().max(1e-3 * f_xs[0].abs().max(f_xs[1].abs())),
                    "{name}: df/dx_s[{i}] {} vs {fd}",
                    f_xs[i]
                );
            }
            println!("{name:42} largest scaled Jacobian difference {worst:.1e}");
        }
    }

    #[test]
    fn spool_path_rate_is_the_derivative_of_its_position() {
        let path = SpoolPath { h: 1e-4, start: [1.0e-4, 0.3, -2.0e3], end: [1.3e-4, 0.1, 5.0e3] };
        for tau in [0.0, 0.1, 0.5, 0.77, 1.0].map(|s| s * path.h) {
            let d = 1e-6 * path.h;
            let fd = (path.position(tau + d) - path.position(tau - d)) / (2.0 * d);
            assert!(
                (path.rate(tau) - fd).abs() < 1e-8 * 0.3,
                "tau {tau}: {} vs {fd}",
                path.rate(tau)
            );
        }
        assert!(
            (path.position(0.0) - path.start[0]).abs() < 1e-18
                && (path.position(path.h) - path.end[0]).abs() < 1e-18
        );
        assert!((path.rate(0.0) - path.start[1]).abs() < 1e-15);
        assert!((path.rate(path.h) - path.end[1]).abs() < 1e-14);
    }

    /// Every 0.1 ms call at the default tolerance (Rodas3 where it passes, located contact
    /// instants) against a reference at rtol 1e-12, over motion, impact on both stops,
    /// cavitation and a spool through zero: the largest scaled deviation along the trajectory.
    #[test]
    fn default_tolerance_tracks_a_tight_reference() {
        let p = CylinderParams::default();
        let sine = |t: f64| 0.3e-3 * (2.0 * std::f64::consts::PI * 10.0 * t).sin();
        type Case<'a> = (&'a str, &'a dyn Fn(f64) -> f64, f64, f64);
        let cases: [Case; 4] = [
            ("rated flow into the + stop", &|_| X_S_RATED, 0.0, 0.08),
            ("0.2 mm into the + stop, pressing", &|_| 0.2e-3, 0.0, 0.12),
            ("overrunning load, cavitating, - stop", &|_| -0.5e-3, -6000.0, 0.05),
            ("10 Hz sine through both directions", &sine, 200.0, 0.1),
        ];
        for (name, x_s, f_ext, t_end) in cases {
            let run = |rtol: f64| {
                let mut s = equilibrium(&p, P_RATED, 0.0);
                let mut work = IntegratorMemory::new(rtol);
                let mut trace = Vec::new();
                let (stats, most) = simulate(
                    &p,
                    &mut s,
                    &mut work,
                    x_s,
                    (P_RATED, f_ext),
                    (0.0, t_end, 1e-4),
                    |_, s| trace.push(*s),
                );
                (trace, stats, most)
            };
            let (reference, _, _) = run(1e-12);
            let (trace, stats, most) = run(1e-8);
            let mut worst: f64 = 0.0;
            for (s, r) in trace.iter().zip(&reference) {
                let e = [
                    (s.p_a - r.p_a) / 1e6,
                    (s.p_b - r.p_b) / 1e6,
                    (s.x - r.x) / 1e-2,
                    (s.v - r.v) / 1e-1,
                ];
                worst = e.iter().fold(worst, |w, e| w.max(e.abs()));
            }
            println!(
                "{name:38} max scaled deviation {worst:.2e}; {} steps ({} Rodas3, {} Rodas3 failed, {} rejected), {} f-evals, max {most} per call",
                stats.accepted, stats.cheap, stats.cheap_failed, stats.rejected, stats.function_evaluations
            );
            assert!(worst < 1e-5, "{name}: {worst}");
        }
    }

    /// The calls in which the piston reaches the + stop (0.2 mm spool, 10 us calls, three
    /// bounces) step onto the contact instant: 38, 28, 39 internal steps (accepted + rejected)
    /// without the location (`MAX_LANDINGS = 0`), 27, 7, 28 with it.
    #[test]
    fn contact_instants_are_stepped_onto() {
        let p = CylinderParams::default();
        let mut s = equilibrium(&p, P_RATED, 0.0);
        let mut work = IntegratorMemory::default();
        let (mut entries, mut landings, mut most) = (0, 0, 0);
        for n in 0..60_000 {
            let before = s.x;
            let stats = advance(&p, &mut s, 1e-5, P_RATED, 0.0, |_| 0.2e-3, &mut work).unwrap();
            if before <= p.stroke / 2.0 && s.x > p.stroke / 2.0 {
                entries += 1;
                landings += stats.landings;
                most = most.max(stats.accepted + stats.rejected);
                println!(
                    "entry in call {n}: {} steps ({} rejected, {} landings)",
                    stats.accepted, stats.rejected, stats.landings
                );
            }
        }
        assert!(entries >= 2 && landings >= entries, "{entries} entries, {landings} landings");
        assert!(most <= 30, "{most} steps in an entry call");
    }

    #[test]
    fn cost_per_interval() {
        let p = CylinderParams::default();
        let interval = 1e-4;
        let measure = |name: &str, mut s: CylinderState, x_s: f64, warmup: f64, span: f64| {
            let mut work = IntegratorMemory::default();
            simulate(
                &p,
                &mut s,
                &mut work,
                &|_| x_s,
                (P_RATED, 0.0),
                (0.0, warmup, interval),
                |_, _| {},
            );
            let calls = (span / interval).round();
            let start = std::time::Instant::now();
            let (stats, most) = simulate(
                &p,
                &mut s,
                &mut work,
                &|_| x_s,
                (P_RATED, 0.0),
                (0.0, span, interval),
                |_, _| {},
            );
            let per_call = start.elapsed().as_secs_f64() / calls;
            println!(
                "{name:44} per 0.1 ms call: {:.2} steps ({:.2} rejected, max {most}), {:.1} f-evals, {:.2} us",
                stats.accepted as f64 / calls,
                stats.rejected as f64 / calls,
                stats.function_evaluations as f64 / calls,
                per_call * 1e6
            );
            stats.accepted as f64 / calls
        };
        let rest = equilibrium(&p, P_RATED, 0.0);
        let start_low = CylinderState { x: -0.035, ..rest };
        let at_rest = measure("at rest, x_s = 0", rest, 0.0, 0.001, 0.02);
        measure("rated flow from rest (first 20 ms)", start_low, X_S_RATED, 0.0, 0.02);
        measure("rated flow, steady", start_low, X_S_RATED, 0.02, 0.02);
        measure("0.2 mm, impact on the end stop (40..60 ms)", rest, 0.2e-3, 0.04, 0.02);
        measure("0.2 mm, pressing on the end stop", rest, 0.2e-3, 0.1, 0.02);
        assert!(at_rest <= 1.0, "at rest: {at_rest} steps per call");
    }
}
