//! The cylinder's equations linearised at a state, analytically: the Rosenbrock
//! integrator's Jacobian and time derivative (checked against differences in the
//! cylinder's tests).

use crate::components::cylinder::{
    CylinderParams, CylinderState, Mat4, Vec4, N_STATES, PA, PB, V, X,
};
use crate::components::cylinder_terms::{
    at_least, cavitation_factor, chamber_a, chamber_b, chamber_volumes, friction, friction_force,
    net_force_with, port_flows, Chamber,
};
use crate::components::metering_ports::PortLaw;
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
/// The ports by the law `L`.
pub(crate) fn linearise<L: PortLaw>(
    params: &CylinderParams,
    y: &Vec4,
    x_s: f64,
    p_supply: f64,
    load: f64,
) -> (Vec4, Mat4, Vec4) {
    let motion = motion_row(params, y, load, friction(params, y[V]));
    let l = linearisation::<L>(params, y, x_s, p_supply, &motion);
    let jac = [l.d_pa, l.d_pb, [0.0, 0.0, 0.0, 1.0], l.d_v];
    (l.rates, jac, [l.d_xs[0], l.d_xs[1], 0.0, 0.0])
}

/// [`linearise`] in the shape of [`Linearisation`], the rod's row `motion` ([`motion_row`])
/// given: the friction in it takes libm calls (exp, tanh), which save and restore every
/// value live across them, so a caller computes that row (and any secant of the friction)
/// first, while few values are live. Inlined: the fixed-cost step keeps its rows where they
/// are computed.
#[inline(always)]
pub(crate) fn linearisation<L: PortLaw>(
    params: &CylinderParams,
    y: &Vec4,
    x_s: f64,
    p_supply: f64,
    motion: &MotionRow,
) -> Linearisation {
    let state = CylinderState::from_array(y);
    let chambers = pressure_rows::<L>(params, &state, x_s, p_supply);
    Linearisation {
        rates: [chambers.rates[0], chambers.rates[1], state.v, motion.acceleration],
        d_pa: chambers.d_pa,
        d_pb: chambers.d_pb,
        d_v: motion.d_v,
        d_xs: chambers.d_xs,
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
/// the spool position, from the chambers' terms ([`chamber_a`], [`chamber_b`]). Chamber A's
/// row is finished before B's terms are computed: fewer values are live at once.
#[inline(always)]
fn pressure_rows<L: PortLaw>(
    params: &CylinderParams,
    state: &CylinderState,
    x_s: f64,
    p_supply: f64,
) -> PressureRows {
    let [volume_a, volume_b] = chamber_volumes(params, state.x);
    let ports = port_flows::<L>(params, [state.p_a, state.p_b], x_s, p_supply);
    // d inflow_a / d(p_a, p_b, x, v) = (dqa_dpa - c_leak - c_ext - drelief_a, c_leak, 0, -A_A)
    let a = chamber_a(params, state, volume_a, &ports);
    let ([own_a, other_a, x_a, v_a], xs_a) =
        chamber_row(params, &a, ports.dqa_dpa, -params.area_a(), ports.dqa_dxs);
    // d inflow_b / d(p_a, p_b, x, v) = (c_leak, -dqb_dpb - c_leak - c_ext - drelief_b, 0, A_B)
    let b = chamber_b(params, state, volume_b, &ports);
    let ([own_b, other_b, x_b, v_b], xs_b) =
        chamber_row(params, &b, -ports.dqb_dpb, params.area_b(), -ports.dqb_dxs);
    PressureRows {
        rates: [a.pressure_rate, b.pressure_rate],
        d_pa: [own_a, other_a, x_a, v_a],
        d_pb: [other_b, own_b, x_b, v_b],
        d_xs: [xs_a, xs_b],
    }
}

/// A chamber's slopes of its pressure rate, `[in its own pressure, in the other chamber's,
/// in x, in v]` and in the spool position, from its terms `c` and its inflow's slopes
/// through the port in its own pressure (`dport_dp`) and the spool position (`dport_dxs`)
/// and in the rod's velocity (`dinflow_dv`, the displaced area with its sign).
#[inline(always)]
fn chamber_row(
    params: &CylinderParams,
    c: &Chamber,
    dport_dp: f64,
    dinflow_dv: f64,
    dport_dxs: f64,
) -> ([f64; 4], f64) {
    let (c_leak, c_ext) = (params.c_leak, params.c_leak_external);
    let ((volume, dvolume_dx), (cf, dcf_dp)) = (c.volume, c.cavitation);
    let stiff = c.stiffness;
    let row = [
        stiff * (cf * (dport_dp - c_leak - c_ext - c.relief_slope) + c.inflow * dcf_dp),
        stiff * cf * c_leak,
        -stiff / volume * dvolume_dx * c.inflow * cf,
        stiff * cf * dinflow_dv,
    ];
    (row, stiff * cf * dport_dxs)
}

/// The rod's side of a [`Linearisation`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct MotionRow {
    /// `v'`.
    pub acceleration: f64,
    /// The row `d v'/dy` of the Jacobian.
    pub d_v: Vec4,
    /// The friction and its slope at the state's velocity ([`friction`]), which the
    /// friction's secant starts from.
    pub friction: (f64, f64),
}

/// The rod's acceleration at `y` under `load` and its row of the Jacobian, with the
/// friction and its slope `friction` at the state's velocity.
#[inline(always)]
pub(crate) fn motion_row(
    params: &CylinderParams,
    y: &Vec4,
    load: f64,
    friction: (f64, f64),
) -> MotionRow {
    let (acceleration, d_v) = match params.port {
        RodPort::Force => {
            let state = CylinderState::from_array(y);
            let [force, dforce_dx, dforce_dv] = net_force_with(params, &state, load, friction);
            let (a_per_mass, b_per_mass) = params.areas_per_mass();
            (
                force / params.mass,
                [a_per_mass, -b_per_mass, dforce_dx / params.mass, dforce_dv / params.mass],
            )
        }
        // The host moves the rod at the acceleration `load`: nothing here acts back on it.
        RodPort::Motion => (load, [0.0; N_STATES]),
    };
    MotionRow { acceleration, d_v, friction }
}

/// For a fixed step of `h` from velocity `v` that starts in the friction's creep band or
/// crosses or reaches it (`v` through zero: starting from rest, a reversal), the friction's
/// slope in the rod's row `motion` replaced by its secant from `v` to the explicit
/// prediction `v + h v'`. The band is 1e-4 m/s wide: its tangent (3e5 N s/m at rest) holds
/// a Rosenbrock step's velocity as a damper would, though the piston leaves the band in a
/// microsecond (a step from rest lost a sixth of its velocity); the secant is the damping
/// the step actually crosses. Outside the band the tangent stays, and with it the method's
/// order.
pub(crate) fn secant_friction(params: &CylinderParams, v: f64, h: f64, motion: &mut MotionRow) {
    if params.port == RodPort::Motion {
        return;
    }
    let (v0, v1) = (v, v + h * motion.acceleration);
    let band = params.creep_band();
    if (v0 * v1 > 0.0 && v0.abs() > band && v1.abs() > band) || v1 == v0 {
        return;
    }
    let (f0, tangent) = motion.friction;
    let secant = (friction_force(params, v1) - f0) / (v1 - v0);
    motion.d_v[V] += (tangent - secant) / params.mass;
}

/// For a fixed step of `h` whose explicit prediction `p + h p'` moves a chamber's pressure
/// towards the supply's or the tank's pressure across its open metering edge (or past it)
/// by more than [`STEEP_APPROACH`] of the drop across that edge, the edge's slope in `l` replaced by its
/// secant from `p` to the prediction where the secant is the steeper. The orifice's law is
/// a square root of the drop, steepest where the drop vanishes: a chamber driven into the
/// supply's pressure (the rod stopped by its load) ran past it by tens of kilopascals from
/// the tangent at the step's start, and the port's flow, steep there, changed its sign. The
/// spool is taken where it is at the step's start. Only above the cavitation band, where the
/// chamber's stiffness is `beta / V` alone; elsewhere the tangent stays.
pub(crate) fn secant_ports<L: PortLaw>(
    params: &CylinderParams,
    (y, x_s): (&Vec4, f64),
    p_supply: f64,
    h: f64,
    l: &mut Linearisation,
) {
    let p0 = [y[PA], y[PB]];
    let moves = [h * l.rates[PA], h * l.rates[PB]];
    // The drops across the open edges (P -> A and B -> T for x_s >= 0, A -> T and P -> B
    // otherwise) and their changes over the prediction. Away from a zero drop the square
    // root flattens, so its secant is never the steeper: only an approach is looked at.
    let (drops, changes) = if x_s >= 0.0 {
        ([p_supply - p0[0], p0[1] - params.p_tank], [-moves[0], moves[1]])
    } else {
        ([p0[0] - params.p_tank, p_supply - p0[1]], [moves[0], -moves[1]])
    };
    let p1 = [p0[0] + moves[0], p0[1] + moves[1]];
    let top = params.cavitation_band_top();
    let steep = |k: usize| {
        -changes[k] * drops[k] > STEEP_APPROACH * drops[k] * drops[k] && p0[k] > top && p1[k] > top
    };
    let (steep_a, steep_b) = (steep(0), steep(1));
    if !(steep_a || steep_b) {
        return;
    }
    let (start, end) =
        (port_flows::<L>(params, p0, x_s, p_supply), port_flows::<L>(params, p1, x_s, p_supply));
    let volumes = chamber_volumes(params, y[X]);
    // Chamber A's inflow is Q_A and B's is -Q_B: the slopes of each in its own pressure,
    // tangent and secant, are negative where they damp.
    let edges = [
        (steep_a, PA, start.dqa_dpa, end.q_a - start.q_a),
        (steep_b, PB, -start.dqb_dpb, start.q_b - end.q_b),
    ];
    for (steep, k, tangent, inflow_change) in edges {
        if !steep {
            continue;
        }
        let secant = inflow_change / (p1[k] - p0[k]);
        if secant < tangent {
            *l.diagonal_mut(k) += params.beta / volumes[k].0 * (secant - tangent);
        }
    }
}

/// The share of its open edge's pressure drop by which a chamber's predicted pressure
/// change makes [`secant_ports`] replace the edge's tangent: over a smaller change the
/// square root is close to its tangent.
const STEEP_APPROACH: f64 = 0.25;

/// For a fixed step of `h` in which a chamber being emptied heads into the cavitation band
/// (the explicit prediction `p + h p'` below the band's top), the fade's slope in `l`
/// replaced by its secant from `p` to the prediction, held at the floor, where the secant is
/// the steeper. Above the band and at its top the fade's tangent is zero, yet inside the
/// band the pressure settles onto the floor within microseconds: a step that saw only the
/// tangent ran its stages far below the floor (2e5 Pa on the 20 Hz squares, lifted back by
/// the floor's clamp), and the rod's force with them (the step was 4e-6 m/s off in the
/// velocity). With the secant the undershoot is 1e4 Pa at most. Elsewhere the tangent stays,
/// and with it the method's order. Inlined in each law's copy of the fixed-cost step.
#[inline(always)]
pub(crate) fn secant_cavitation(params: &CylinderParams, y: &Vec4, h: f64, l: &mut Linearisation) {
    let top = params.cavitation_band_top();
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
