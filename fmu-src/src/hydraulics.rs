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
//! corners but ordinary operating states (measured in `tests::jacobian_eigenvalues`):
//! friction at rest `~ -Fs/(m v_smooth) = -6e4 1/s`, a port in its laminar region at the end
//! stop or at a pressure near supply `~ -1e5 .. -1e6 1/s`, the end stop `-1000 +- 4500i`. An
//! explicit method would sit on its stability boundary there (several steps per 0.1 ms);
//! Rodas4 takes steps set by accuracy only, and one step per call at rest. Order 4 matters at
//! the 1e-8 tolerance (an order-3 method needs ~3x the steps while moving).
//! The 4x4 Jacobian is a forward difference, `df/dt` too (the only time dependence is
//! `x_s(t)`); the linear systems use a hand-written 4x4 LU with partial pivoting.
//! Everything lives on the stack: no allocation in [`advance`].

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
    fn default() -> Self {
        CylinderParams {
            bore: 0.016,
            rod: 0.010,
            stroke: 0.080,
            mass: 5.0,
            beta: 1.0e9,
            v_dead: 2.0e-6,
            b_viscous: 200.0,
            f_coulomb: 20.0,
            f_static: 30.0,
            v_stribeck: 0.01,
            v_friction_smooth: 1.0e-4,
            k_endstop: 1.0e8,
            c_endstop: 1.0e4,
            c_leak: 0.0,
            c_leak_external: 0.0,
            k3: 0.664515,
            dp_rated: 6.8948e6,
            dp_laminar: 1.0e5,
            p_tank: 0.0,
            p_cavitation: -0.9e5,
            dp_cavitation_band: 5.0e4,
        }
    }
}

/// One parameter as the variable table needs it.
#[derive(Clone, Copy, Debug)]
pub struct ParameterInfo {
    pub name: &'static str,
    pub unit: Option<&'static str>,
    pub start: f64,
    pub min: Option<f64>,
    pub max: Option<f64>,
    /// `min` itself is not allowed.
    pub min_exclusive: bool,
    pub description: &'static str,
}

const fn info(
    name: &'static str,
    unit: &'static str,
    start: f64,
    min: Option<f64>,
    max: Option<f64>,
    min_exclusive: bool,
    description: &'static str,
) -> ParameterInfo {
    ParameterInfo { name, unit: Some(unit), start, min, max, min_exclusive, description }
}

/// Parameters of this module for the variable table (`valve.K3` already exists there).
/// Starts equal [`CylinderParams::default`] (checked by a test). Cross-parameter rules
/// (rod < bore, p_cavitation < p_tank) are in [`CylinderParams::validate`].
pub const CYLINDER_PARAMETERS: &[ParameterInfo] = &[
    info("cylinder.bore", "m", 0.016, Some(0.0), None, true, "Piston (bore) diameter"),
    info("cylinder.rod", "m", 0.010, Some(0.0), None, false, "Rod diameter (rod on the B side; 0 = double-rod equal areas is not implied: B area = bore area)"),
    info("cylinder.stroke", "m", 0.080, Some(0.0), None, true, "Full stroke; x_piston = 0 at mid-stroke, end stops at +-stroke/2"),
    info("cylinder.mass", "kg", 5.0, Some(0.0), None, true, "Moving mass of piston, rod and load"),
    info("cylinder.beta", "Pa", 1.0e9, Some(0.0), None, true, "Effective bulk modulus of oil, hoses and walls"),
    info("cylinder.V_dead", "m3", 2.0e-6, Some(0.0), None, true, "Dead volume of each chamber at its end of stroke (ports, hoses)"),
    info("cylinder.b_viscous", "N.s/m", 200.0, Some(0.0), None, false, "Viscous friction coefficient"),
    info("cylinder.F_coulomb", "N", 20.0, Some(0.0), None, false, "Coulomb friction force"),
    info("cylinder.F_static", "N", 30.0, Some(0.0), None, false, "Breakaway (static) friction force: peak of the Stribeck curve"),
    info("cylinder.v_stribeck", "m/s", 0.01, Some(0.0), None, true, "Stribeck velocity: friction falls from F_static to F_coulomb over this speed"),
    info("cylinder.v_friction_smooth", "m/s", 1.0e-4, Some(0.0), None, true, "Creep velocity scale of tanh(v/v) replacing sign(v) in the friction (no sticking singularity)"),
    info("cylinder.k_endstop", "N/m", 1.0e8, Some(0.0), None, true, "End-stop contact stiffness beyond +-stroke/2"),
    info("cylinder.c_endstop", "N.s/m", 1.0e4, Some(0.0), None, false, "End-stop contact damping (only while penetrating; the contact never pulls)"),
    info("cylinder.C_leak", "m3/(s.Pa)", 0.0, Some(0.0), None, false, "Internal leakage coefficient across the piston, A to B"),
    info("cylinder.C_leak_external", "m3/(s.Pa)", 0.0, Some(0.0), None, false, "External leakage coefficient from each chamber to the drain at p_tank"),
    info("valve.dp_rated", "Pa", 6.8948e6, Some(0.0), None, true, "Total rated valve pressure drop (1000 psi): the no-load flow K3*x_s is specified at this drop"),
    info("valve.dp_laminar", "Pa", 1.0e5, Some(0.0), None, true, "Port pressure drop below which the orifice flow law is regularised (laminar, finite slope)"),
    info("hydraulics.p_tank", "Pa", 0.0, Some(-1.01325e5), None, false, "Tank (return) pressure, gauge"),
    info("hydraulics.p_cavitation", "Pa", -0.9e5, Some(-1.01325e5), None, false, "Cavitation floor (gauge; -0.9e5 = 0.1 bar absolute): chamber pressures never fall below it"),
    info("hydraulics.dp_cavitation_band", "Pa", 5.0e4, Some(0.0), None, true, "Pressure band above the floor over which an emptying chamber's bulk modulus fades to zero"),
];

impl CylinderParams {
    /// Builds the parameters from named values (e.g. the variable table), then validates them.
    pub fn from_lookup(get: impl Fn(&str) -> f64, k3: f64) -> Result<CylinderParams, String> {
        let p = CylinderParams {
            bore: get("cylinder.bore"),
            rod: get("cylinder.rod"),
            stroke: get("cylinder.stroke"),
            mass: get("cylinder.mass"),
            beta: get("cylinder.beta"),
            v_dead: get("cylinder.V_dead"),
            b_viscous: get("cylinder.b_viscous"),
            f_coulomb: get("cylinder.F_coulomb"),
            f_static: get("cylinder.F_static"),
            v_stribeck: get("cylinder.v_stribeck"),
            v_friction_smooth: get("cylinder.v_friction_smooth"),
            k_endstop: get("cylinder.k_endstop"),
            c_endstop: get("cylinder.c_endstop"),
            c_leak: get("cylinder.C_leak"),
            c_leak_external: get("cylinder.C_leak_external"),
            k3,
            dp_rated: get("valve.dp_rated"),
            dp_laminar: get("valve.dp_laminar"),
            p_tank: get("hydraulics.p_tank"),
            p_cavitation: get("hydraulics.p_cavitation"),
            dp_cavitation_band: get("hydraulics.dp_cavitation_band"),
        };
        p.validate()?;
        Ok(p)
    }

    /// Single-value ranges (as in [`CYLINDER_PARAMETERS`]) and the rules between parameters.
    pub fn validate(&self) -> Result<(), String> {
        let values = [
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
        ];
        for (info, &value) in CYLINDER_PARAMETERS.iter().zip(values.iter()) {
            let below = match info.min {
                Some(min) if info.min_exclusive => value <= min,
                Some(min) => value < min,
                None => false,
            };
            let above = matches!(info.max, Some(max) if value > max);
            if !value.is_finite() || below || above {
                return Err(format!("{} = {value} rejected: outside its allowed range", info.name));
            }
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
#[derive(Clone, Copy, Debug, PartialEq)]
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
pub fn port_flows(params: &CylinderParams, state: &CylinderState, x_s: f64, p_supply: f64) -> (f64, f64) {
    // Chamber pressures below the floor (rounding only) are read at the floor.
    let p_a = state.p_a.max(params.p_cavitation);
    let p_b = state.p_b.max(params.p_cavitation);
    let gain = params.k3 * x_s / (0.5 * params.dp_rated).sqrt();
    let lam = params.dp_laminar;
    if x_s >= 0.0 {
        // P -> A and B -> T open.
        (gain * regularised_sqrt(p_supply - p_a, lam), gain * regularised_sqrt(p_b - params.p_tank, lam))
    } else {
        // A -> T and P -> B open (gain < 0 turns the flows around).
        (gain * regularised_sqrt(p_a - params.p_tank, lam), gain * regularised_sqrt(p_supply - p_b, lam))
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
pub fn derivatives(params: &CylinderParams, state: &CylinderState, x_s: f64, p_supply: f64, f_ext: f64) -> [f64; 4] {
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

/// All outputs at a state.
pub fn outputs(params: &CylinderParams, state: &CylinderState, x_s: f64, p_supply: f64) -> CylinderOutputs {
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

/// Rodas4 coefficients (Hairer & Wanner's `rodas.f`, METH = 1), in their transformed form:
/// `(I/(h gamma) - J) k_i = f(t + c_i h, y + sum_j a_ij k_j) + sum_j (c_ij/h) k_j + h d_i f_t`,
/// `y_new = y + sum_j a_6j k_j + k_6`, error estimate `k_6`.
mod rodas4 {
    pub const GAMMA: f64 = 0.25;
    pub const NODES: [f64; 6] = [0.0, 0.386, 0.21, 0.63, 1.0, 1.0];
    pub const D: [f64; 6] = [0.25, -0.1043, 0.1035, -0.3620000000000023e-01, 0.0, 0.0];
    pub const A: [[f64; 5]; 6] = [
        [0.0; 5],
        [1.544, 0.0, 0.0, 0.0, 0.0],
        [0.9466785280815826, 0.2557011698983284, 0.0, 0.0, 0.0],
        [3.314825187068521, 2.896124015972201, 0.9986419139977817, 0.0, 0.0],
        [1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 0.0],
        // Stage 6 is evaluated at the embedded solution y_5 + k_5.
        [1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 1.0],
    ];
    pub const C: [[f64; 5]; 6] = [
        [0.0; 5],
        [-5.6688, 0.0, 0.0, 0.0, 0.0],
        [-2.430093356833875, -0.2063599157091915, 0.0, 0.0, 0.0],
        [-0.1073529058151375, -9.594562251023355, -20.47028614809616, 0.0, 0.0],
        [7.496443313967647, -10.24680431464352, -33.99990352819905, 11.70890893206160, 0.0],
        [8.083246795921522, -7.981132988064893, -31.52159432874371, 16.31930543123136, -6.058818238834054],
    ];
}

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
}

/// Work done in one call of [`advance`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    pub accepted: u32,
    pub rejected: u32,
    pub function_evaluations: u32,
    /// Largest amount a pressure was lifted back to the cavitation floor after a step [Pa].
    pub floor_clamp: f64,
}

/// Advances the state by `h` seconds; `x_s(tau)` is the spool position at `tau` in `[0, h]`.
/// On error the state is left as it was.
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
    let mut stats = Stats::default();
    if h == 0.0 {
        return Ok(stats);
    }
    if !(h.is_finite() && h > 0.0) {
        return Err(format!("hydraulics: step {h} s is not a positive finite number"));
    }
    let mut f = |tau: f64, y: &Vec4, stats: &mut Stats| -> Vec4 {
        stats.function_evaluations += 1;
        derivatives(params, &CylinderState::from_array(y), x_s(tau), p_supply, f_ext)
    };
    let mut y = state.to_array();
    let mut tau = 0.0;
    let mut step = if work.h_next > 0.0 { work.h_next } else { INITIAL_STEP };
    let mut rejected_last = false;
    loop {
        if stats.accepted + stats.rejected >= MAX_STEPS_PER_CALL {
            return Err(format!("hydraulics: more than {MAX_STEPS_PER_CALL} internal steps in one step of {h} s"));
        }
        // The last step lands exactly on h; remember the untruncated size for the next call.
        let wanted = step;
        let last = tau + step * 1.0001 >= h;
        if last {
            step = h - tau;
        }
        if step <= 1e-14 * h.max(1e-6) {
            return Err(format!("hydraulics: step size underflow at {tau} s into a step of {h} s"));
        }
        let (y_new, err) = rodas4_step(&mut f, tau, &y, step, work.rtol, &mut stats)?;
        if err <= 1.0 {
            stats.accepted += 1;
            let mut factor = (err.powf(0.25) / SAFETY).clamp(1.0 / MAX_FACTOR, 1.0 / MIN_FACTOR);
            // Gustafsson: also use the trend of the error between accepted steps.
            if work.h_accepted > 0.0 {
                let predictive = (work.h_accepted / step) * (err * err / work.err_accepted).powf(0.25) / SAFETY;
                factor = factor.max(predictive.clamp(1.0 / MAX_FACTOR, 1.0 / MIN_FACTOR));
            }
            work.h_accepted = step;
            work.err_accepted = err.max(1e-2);
            y = y_new;
            for k in [PA, PB] {
                if y[k] < params.p_cavitation {
                    stats.floor_clamp = stats.floor_clamp.max(params.p_cavitation - y[k]);
                    y[k] = params.p_cavitation;
                }
            }
            tau += step;
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

/// One Rodas4 step from `(tau, y)` of size `h`: the new state and its scaled error norm.
fn rodas4_step(
    f: &mut impl FnMut(f64, &Vec4, &mut Stats) -> Vec4,
    tau: f64,
    y: &Vec4,
    h: f64,
    rtol: f64,
    stats: &mut Stats,
) -> Result<(Vec4, f64), String> {
    use rodas4::*;
    let f0 = f(tau, y, stats);
    // Forward-difference Jacobian, perturbations scaled with the state.
    let mut jac: Mat4 = [[0.0; N_STATES]; N_STATES];
    for j in 0..N_STATES {
        let delta = f64::EPSILON.sqrt() * y[j].abs().max(STATE_SCALE[j]);
        let mut shifted = *y;
        shifted[j] += delta;
        let fj = f(tau, &shifted, stats);
        for i in 0..N_STATES {
            jac[i][j] = (fj[i] - f0[i]) / delta;
        }
    }
    // df/dt through x_s(t); dt <= h keeps the time inside the caller's interval.
    let dt = (f64::EPSILON.sqrt() * h.max(1e-6)).min(h);
    let f_t = {
        let forward = f(tau + dt, y, stats);
        let mut d = [0.0; N_STATES];
        for i in 0..N_STATES {
            d[i] = (forward[i] - f0[i]) / dt;
        }
        d
    };
    // W = I/(h gamma) - J
    let mut w = jac;
    for (i, row) in w.iter_mut().enumerate() {
        for value in row.iter_mut() {
            *value = -*value;
        }
        row[i] += 1.0 / (h * GAMMA);
    }
    let lu = Lu4::factor(w).ok_or_else(|| "hydraulics: singular iteration matrix".to_string())?;
    let mut k = [[0.0; N_STATES]; 6];
    for stage in 0..6 {
        let fi = if stage == 0 {
            f0
        } else {
            let mut yi = *y;
            for j in 0..stage {
                for n in 0..N_STATES {
                    yi[n] += A[stage][j] * k[j][n];
                }
            }
            f(tau + NODES[stage] * h, &yi, stats)
        };
        let mut rhs = fi;
        for n in 0..N_STATES {
            rhs[n] += h * D[stage] * f_t[n];
            for j in 0..stage {
                rhs[n] += C[stage][j] / h * k[j][n];
            }
        }
        k[stage] = lu.solve(rhs);
    }
    let mut y_new = *y;
    let mut sum = 0.0;
    for n in 0..N_STATES {
        for j in 0..5 {
            y_new[n] += A[5][j] * k[j][n];
        }
        y_new[n] += k[5][n];
        let scale = rtol * y[n].abs().max(y_new[n].abs()).max(STATE_SCALE[n]);
        sum += (k[5][n] / scale).powi(2);
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
            for row in col + 1..N_STATES {
                let m = a[row][col] / a[col][col];
                a[row][col] = m;
                for c in col + 1..N_STATES {
                    a[row][c] -= m * a[col][c];
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
