//! The fixed-cost method's step of the cylinder: one linearly implicit step per internal
//! step, whatever happens in it. The model is linearised once at the step's start
//! ([`linearisation`]: the rates, the analytic Jacobian `J` and the spool's sensitivity), and
//!
//! ```text
//! (I - gamma h J) k = h (f(y0) + gamma h df/dx_s x_s'),    y1 = y0 + k
//! ```
//!
//! with `gamma` = [`GAMMA`] is solved by elimination written out for the cylinder's pattern
//! (`x' = v`, so the 4x4 folds to a 3x3 in `p_A`, `p_B`, `v`; no pivoting, no loops). At
//! `gamma = 1/2` this is the linearly implicit trapezoidal rule: second order, A-stable,
//! the hydraulic resonance neither damped nor excited. Its stiff modes (the orifices' laminar
//! slope near balance, the friction's creep band) are damped but flip sign from step to step
//! where `h |lambda| > 2` (above one half they would decay faster, at a first-order error
//! `(gamma - 1/2) h^2 J f`: 0.52 to 1 were all less accurate on the impacts, docs/solvers.md).
//! Where a step crosses the friction's creep band, a chamber heads into the cavitation band
//! or rises into its relief valve's law, that slope is replaced by its secant over the step
//! ([`secant_friction`], [`secant_cavitation`], [`secant_relief`]); a pressure that ends
//! below the cavitation floor is held at it. A step is cut where the piston meets or leaves
//! a stop's contact or a pressure crosses a kink of its laws, and taken in halves in a
//! stop's contact ([`advance`]).

use crate::actuator::Actuator;
use crate::components::cylinder::{CylinderParams, CylinderState, Vec4, PA, PB, V, X};
use crate::components::cylinder_jacobian::{
    linearisation, motion_row, secant_cavitation, secant_friction, secant_ports, Linearisation,
};
use crate::components::cylinder_terms::{
    at_least, chamber_volumes, endstop_force, friction, relief_flow,
};
use crate::components::metering_ports::PortLaw;
use crate::held_inputs::HeldInputs;
use crate::params::RodPort;

/// The implicitness of the step: 1/2 is the trapezoidal rule (above it the stiff modes'
/// factor `(1 - (1 - gamma) z) / (1 - gamma z)` stays further from -1, but the impacts lose
/// accuracy).
pub(crate) const GAMMA: f64 = 0.5;

/// Advances the actuator's cylinder by `h`, the spool moving from `spool[0]` to `spool[1]`
/// (positions, m) on a straight line, the ports by the law `L`.
#[inline(always)]
pub(crate) fn step<L: PortLaw>(
    actuator: &mut Actuator,
    spool: [f64; 2],
    h: f64,
    inputs: &HeldInputs,
) -> Result<(), String> {
    let params = &actuator.params.cylinder;
    let y0 = actuator.cylinder.state.to_array();
    let (y1, steps) = advance::<L>(params, &y0, spool, h, (inputs.p_supply, inputs.load));
    if !y1.iter().all(|v| v.is_finite()) {
        return Err("the cylinder's state is not finite; step refused".into());
    }
    actuator.cylinder.state = CylinderState::from_array(&y1);
    // Each linearised step: one Jacobian and one solve of its 4x4.
    actuator.work.steps_accepted += steps;
    actuator.work.jacobians += steps;
    actuator.work.factorisations += steps;
    Ok(())
}

/// The state after one internal step of `h` from `y0` (see the module documentation): one
/// linearly implicit step ([`advance_once`]), two of half the size in a stop's contact;
/// with the number of linearised steps taken (a cut step takes two). The ports by the law `L`.
pub(crate) fn advance<L: PortLaw>(
    params: &CylinderParams,
    y0: &Vec4,
    spool: [f64; 2],
    h: f64,
    loads: (f64, f64),
) -> (Vec4, u64) {
    let contact = match params.port {
        RodPort::Force => contact_force(params, y0),
        RodPort::Motion => 0.0,
    };
    if contact != 0.0 {
        // In a stop's contact (1e8 N/m against the load: h w = 0.45 at 1e-4 s) in halves,
        // held there too: in one step the 2 Hz squares' p_B was 1.6e-2 of its range off
        // (4.8e-3 in halves), the pressure changing while the valve reverses.
        let middle = 0.5 * (spool[0] + spool[1]);
        let (y_half, first) =
            advance_once::<L>(params, (y0, contact), [spool[0], middle], 0.5 * h, loads);
        let contact_half = contact_force(params, &y_half);
        let (y1, second) =
            advance_once::<L>(params, (&y_half, contact_half), [middle, spool[1]], 0.5 * h, loads);
        return (y1, first + second);
    }
    advance_once::<L>(params, (y0, contact), spool, h, loads)
}

/// One linearly implicit step of `h` from `y0`, at which the end stop's contact force is
/// `contact0` ([`contact_force`]; 0 with the motion port). A step whose end-stop contact
/// switches (the piston reaching a stop's face, where the damper's force jumps in, or the
/// contact force falling to zero, a kink) or whose chamber pressure crosses a kink of its
/// laws ([`pressure_switch`]), or whose spool reaches a land's opening (with a lap,
/// [`MeteringPorts::edge_crossing`](crate::components::metering_ports::MeteringPorts::edge_crossing)),
/// is cut there, the switch placed by one interpolation along
/// the step, and the rest taken from a new linearisation (two linearised steps, else one).
fn advance_once<L: PortLaw>(
    params: &CylinderParams,
    (y0, contact0): (&Vec4, f64),
    spool: [f64; 2],
    h: f64,
    loads: (f64, f64),
) -> (Vec4, u64) {
    let linear = Linearised::at::<L>(params, y0, spool, h, loads);
    let y1 = linear.step(params, y0, h);
    // A land's opening (with a lap) changes the flows' slope in the spool's position: the
    // step is cut where the spool, on its straight line, reaches it.
    let edge = L::edge_crossing(&params.ports, spool);
    let (contact, first_switch) = match params.port {
        RodPort::Force => {
            let contact = contact_switch(params, (y0, contact0), &y1);
            let pressure = pressure_switch(params, y0, &y1);
            (contact, contact.into_iter().chain(pressure).chain(edge).reduce(f64::min))
        }
        RodPort::Motion => (None, edge),
    };
    match first_switch {
        None => (y1, 1),
        Some(fraction) => {
            let cut = (fraction, contact == Some(fraction) && contact0 == 0.0);
            (cut_step::<L>(params, (y0, &linear), cut, spool, h, loads), 2)
        }
    }
}

/// The rest of [`advance_once`] for a step cut at `fraction` of it (`onto_face`: the cut is
/// the piston reaching a stop's face): the state at the cut, and from there the rest of the
/// step from a new linearisation. Out of line and cold: most steps are not cut, and their
/// path then keeps none of this one's values.
#[cold]
#[inline(never)]
fn cut_step<L: PortLaw>(
    params: &CylinderParams,
    (y0, linear): (&Vec4, &Linearised),
    (fraction, onto_face): (f64, bool),
    spool: [f64; 2],
    h: f64,
    loads: (f64, f64),
) -> Vec4 {
    let mut y_cut = linear.step(params, y0, fraction * h);
    if onto_face {
        // Onto the face: a hair inside, so that the damper's force and both slopes act.
        let half = params.half_stroke();
        y_cut[X] = y_cut[X].signum() * half * (1.0 + 1e-12);
    }
    let spool_cut = spool[0] + fraction * (spool[1] - spool[0]);
    let rest = h - fraction * h;
    let rest_of_step = Linearised::at::<L>(params, &y_cut, [spool_cut, spool[1]], rest, loads);
    rest_of_step.step(params, &y_cut, rest)
}

/// The model linearised at a step's start: rates, Jacobian (with the secants a fixed step
/// needs) and the rates' drift with the spool's motion.
struct Linearised {
    model: Linearisation,
    /// `[d p_A'/dt, d p_B'/dt] = df/dx_s x_s'` over the step.
    drift: [f64; 2],
}

impl Linearised {
    fn at<L: PortLaw>(
        params: &CylinderParams,
        y0: &Vec4,
        spool: [f64; 2],
        h: f64,
        loads: (f64, f64),
    ) -> Self {
        let (p_supply, load) = loads;
        // The friction (in a frame of its own) and its secant before the pressures' rows:
        // little is live across their libm calls.
        let friction = friction_at(params, y0[V]);
        let mut motion = motion_row(params, y0, load, friction);
        secant_friction(params, y0[V], h, &mut motion);
        let mut model = linearisation::<L>(params, y0, spool[0], p_supply, &motion);
        if !predictions_clear_of_kinks(params, y0, h, &model.rates) {
            secant_cavitation(params, y0, h, &mut model);
            secant_relief(params, y0, h, &mut model);
        }
        secant_ports::<L>(params, (y0, spool[0]), p_supply, h, &mut model);
        let spool_rate = (spool[1] - spool[0]) / h;
        Linearised { drift: model.d_xs.map(|d| d * spool_rate), model }
    }

    /// One linearly implicit step of `h` from `y0`, the pressures held at the floor.
    fn step(&self, params: &CylinderParams, y0: &Vec4, h: f64) -> Vec4 {
        let s = GAMMA * h;
        let (f, drift) = (&self.model.rates, &self.drift);
        let rhs = [h * (f[PA] + s * drift[0]), h * (f[PB] + s * drift[1]), h * f[X], h * f[V]];
        let k = solve_shifted(&self.model, s, &rhs);
        let mut y1 = [y0[PA] + k[PA], y0[PB] + k[PB], y0[X] + k[X], y0[V] + k[V]];
        for p in [PA, PB] {
            y1[p] = at_least(y1[p], params.p_cavitation);
        }
        y1
    }
}

/// [`friction`] at `v`, not inlined.
#[inline(never)]
fn friction_at(params: &CylinderParams, v: f64) -> (f64, f64) {
    friction(params, v)
}

/// Whether both chambers' explicit predictions `p + h p'` end between the cavitation band's
/// top and the relief valves' cracking pressure ([`CylinderParams::relief_ceiling`]), where
/// neither [`secant_cavitation`] nor [`secant_relief`] replaces a slope: one test for most
/// steps before their detailed ones.
fn predictions_clear_of_kinks(params: &CylinderParams, y: &Vec4, h: f64, rates: &Vec4) -> bool {
    let (top, ceiling) = (params.cavitation_band_top(), params.relief_ceiling());
    [PA, PB].into_iter().all(|k| {
        let p1 = y[k] + h * rates[k];
        p1 >= top && p1 <= ceiling
    })
}

/// For a step in which a chamber's pressure rises into its relief valve's law, the valve's
/// slope in `l` replaced by its secant from `p` to the explicit prediction `p + h p'`
/// where that is the steeper: the law starts with zero slope at the cracking pressure, so
/// a step from there saw no valve and ran 9 % past the override (100 Hz 10 mA squares).
/// Inlined in each law's copy of the step, as it was in the one step before the laws.
#[inline(always)]
fn secant_relief(params: &CylinderParams, y: &Vec4, h: f64, l: &mut Linearisation) {
    if !params.has_relief() {
        return;
    }
    let crack = params.relief_opening();
    for k in [PA, PB] {
        let (p0, rate) = (y[k], l.rates[k]);
        let p1 = p0 + h * rate;
        // Below the cracking pressure at the prediction the valve stays shut: no slope.
        if rate <= 0.0 || p1 <= crack {
            continue;
        }
        let ((q0, tangent), (q1, _)) = (relief_flow(params, p0), relief_flow(params, p1));
        let secant = (q1 - q0) / (p1 - p0);
        if secant > tangent {
            let volume = chamber_volumes(params, y[X])[k].0;
            *l.diagonal_mut(k) -= params.beta / volume * (secant - tangent);
        }
    }
}

/// Where in a step from `y0` to `y1` a chamber's pressure first crosses a kink of its
/// laws, by linear interpolation: entering the cavitation band from above (its bulk
/// modulus starts to fade there) or rising through the relief valve's cracking pressure.
/// Inlined in each law's copy of the step.
#[inline(always)]
fn pressure_switch(params: &CylinderParams, y0: &Vec4, y1: &Vec4) -> Option<f64> {
    let band_top = params.cavitation_band_top();
    // Either kink is crossed only by a pressure that ends below the band's top or above a
    // valve's cracking pressure: most steps end between them in both chambers.
    let (p_a, p_b, ceiling) = (y1[PA], y1[PB], params.relief_ceiling());
    if p_a >= band_top && p_b >= band_top && p_a <= ceiling && p_b <= ceiling {
        return None;
    }
    let crack = params.relief_opening();
    let relief = params.has_relief();
    let crossing = |k: usize| {
        let (p0, p1) = (y0[k], y1[k]);
        let level = if p0 > band_top && p1 < band_top {
            band_top
        } else if relief && p0 < crack && p1 > crack {
            crack
        } else {
            return None;
        };
        let fraction = (p0 - level) / (p0 - p1);
        (fraction > 0.0 && fraction < 1.0).then_some(fraction)
    };
    earliest(crossing(PA), crossing(PB))
}

/// The earlier of two chambers' switches inside a step (fractions of it), either possibly
/// absent. Written out rather than reduced over a filtered iterator: [`pressure_switch`] is
/// inlined in each law's copy of the step, and that reduction, shared by both copies, was
/// left out of line.
#[inline(always)]
fn earliest(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        _ => a.or(b),
    }
}

/// The size of the end stop's contact force at `y` (N): `k d + c d'` while the stop pushes,
/// zero out of contact.
fn contact_force(params: &CylinderParams, y: &Vec4) -> f64 {
    endstop_force(params, y[X], y[V]).0.abs()
}

/// Where in a step from `y0` (its contact force `contact0`) to `y1` the end-stop contact
/// switches, as a fraction of the step in (0, 1): reaching a stop's face (the position
/// interpolated linearly onto it), or the contact force falling to zero (interpolated
/// linearly from its value at `y0` to its linear extension at `y1`). `None` where neither
/// happens.
fn contact_switch(params: &CylinderParams, (y0, contact0): (&Vec4, f64), y1: &Vec4) -> Option<f64> {
    let half = params.half_stroke();
    if contact0 == 0.0 && y1[X].abs() <= half {
        // Out of contact and ending between the faces: no face reached (`side * x <= |x|`).
        return None;
    }
    let side = if y0[X] + y1[X] >= 0.0 { 1.0 } else { -1.0 };
    let depth = |y: &Vec4| side * y[X] - half;
    let fraction = if contact0 == 0.0 {
        let (d0, d1) = (depth(y0), depth(y1));
        (d0 <= 0.0 && d1 > 0.0).then(|| -d0 / (d1 - d0))?
    } else {
        let push = |y: &Vec4| params.k_endstop * depth(y) + params.c_endstop * side * y[V];
        let (s0, s1) = (push(y0), push(y1));
        (s1 < 0.0).then(|| s0 / (s0 - s1))?
    };
    (fraction > 0.0 && fraction < 1.0).then_some(fraction)
}

/// Solves `(I - s J) k = r` for the cylinder's Jacobian `J` (`model`'s rows; its position
/// row is `x' = v`, `J[X] = e_V`): `k_x = r_x + s k_v` folds it into the other three rows,
/// which elimination in the order `p_A`, `p_B`, `v` solves. No pivoting: the pressures'
/// diagonal entries `1 - s dp'/dp` are at least 1 (each term of a chamber's pressure rate
/// falls as its own pressure rises: the orifices, leaks and relief valves pass less in or
/// more out, the fade closes, and the secants that replace their slopes are steeper still),
/// and the leak's coupling between the chambers is weaker than either diagonal, so that
/// the second pivot stays above 1 as well.
fn solve_shifted(model: &Linearisation, s: f64, r: &Vec4) -> Vec4 {
    // Rows PA, PB, V of (I - s J) with the X column folded into the V column.
    let row = |i: usize, j: &Vec4| {
        let diagonal = |c: usize| if c == i { 1.0 } else { 0.0 };
        let m = [PA, PB, V].map(|c| diagonal(c) - s * j[c]);
        let folded_v = m[2] - s * s * j[X];
        ([m[0], m[1], folded_v], r[i] + s * j[X] * r[X])
    };
    let (a0, b0) = row(PA, &model.d_pa);
    let (a1, b1) = row(PB, &model.d_pb);
    let (a2, b2) = row(V, &model.d_v);
    // k_pa out of the rows PB and V, then k_pb out of the row V.
    let without_pa = |a: [f64; 3], b: f64| {
        let l = a[0] / a0[0];
        ([a[1] - l * a0[1], a[2] - l * a0[2]], b - l * b0)
    };
    let (c1, d1) = without_pa(a1, b1);
    let (c2, d2) = without_pa(a2, b2);
    let l = c2[0] / c1[0];
    let k_v = (d2 - l * d1) / (c2[1] - l * c1[1]);
    let k_pb = (d1 - c1[1] * k_v) / c1[0];
    let k_pa = (b0 - a0[1] * k_pb - a0[2] * k_v) / a0[0];
    [k_pa, k_pb, r[X] + s * k_v, k_v]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The folded 3x3 solves the full 4x4 system.
    #[test]
    fn the_folded_solve_solves_the_whole_system() {
        let model = Linearisation {
            rates: [0.0; 4],
            d_pa: [-3.0e4, 2.0e2, 5.0e6, -1.0e8],
            d_pb: [1.5e2, -2.5e4, -4.0e6, 6.0e7],
            d_v: [4.0e-5, -2.5e-5, -1.0e3, -40.0],
            d_xs: [0.0; 2],
        };
        let jac = [model.d_pa, model.d_pb, [0.0, 0.0, 0.0, 1.0], model.d_v];
        let r = [1.0e3, -2.0e3, 1.0e-6, 3.0e-3];
        let s = 5.5e-5;
        let k = solve_shifted(&model, s, &r);
        for i in 0..4 {
            let applied: f64 =
                (0..4).map(|c| (if c == i { 1.0 } else { 0.0 } - s * jac[i][c]) * k[c]).sum();
            let scale = r[i].abs().max(1e-12);
            assert!((applied - r[i]).abs() <= 1e-9 * scale, "row {i}: {applied} vs {}", r[i]);
        }
    }
}
