//! The cylinder's internal step in the fixed-cost integrator ([`super::fixed_cost`]).
//!
//! One step of Rodas3 (L-stable, stiffly accurate, order 3; one analytic Jacobian, one 4x4
//! LU, two right-hand sides) along the spool's cubic path through its positions and
//! velocities at the step's ends (a path error of order h^4, below the method's own), with
//! no step control. A step that crossed something its stages cannot see from its start is
//! taken again in parts, cut where that happened ([`Cut`]): an end stop reached (the contact
//! force jumps in) or left (the contact force reaches zero: a kink), the friction's creep
//! band left (the piston starting from rest) or entered (the piston stopping or reversing:
//! the friction flips within a microsecond, in a part of its own), or, found by the
//! embedded estimate alone, another kink (a relief valve cracking, a chamber at the
//! cavitation floor). A step that starts in a stop's contact, the piston moving, goes in
//! two halves. An internal step so costs one to four Rodas3 steps: bounded, with no
//! iteration.

use crate::actuator::Actuator;
use crate::components::cylinder::CylinderParams;
use crate::components::cylinder::CylinderState;
use crate::components::cylinder::{derivatives, Vec4, V, X};
use crate::held_inputs::HeldInputs;
use crate::numerics::root_finding::time_to_close;
use crate::numerics::rosenbrock::{rodas3_fixed_step, Stats};
use crate::params::RodPort;

/// Rodas3's embedded error estimate, as a share of the state's scale (1 MPa for the
/// pressures; 10 mm and 0.1 m/s, or the state itself where larger), beyond which the step
/// is taken again in two halves. Smooth 25 us steps stay far below it; a step across a kink
/// exceeds it (without the halves Rodas3 overshot an end stop's pressure peak by 1.6 MPa
/// on 100 Hz squares at twice the rated current). Looser thresholds let that through,
/// tighter ones change little.
const HALVING_RTOL: f64 = 1e-3;

/// The edge of the friction's creep band in `cylinder.v_friction_smooth` (tanh(3) = 0.995:
/// the friction is there), where a step from rest is cut.
const CREEP_EDGE: f64 = 3.0;

/// How much short of the estimated contact, as a share of the time to it, a step into an
/// end stop is cut: Rodas3 evaluates its last stages at the part's end, and a stage a
/// fraction of a nanometre inside the stop meets the whole contact force there (a step
/// that ended on the estimate was 0.4 % off in the velocity, one a thousandth short 3e-5;
/// the piston is then carried onto the surface, nanometres: [`InternalStep::onto_surface`]).
const CONTACT_MARGIN: f64 = 1e-3;

/// The spool's position and velocity at the start and the end of an internal step.
pub(crate) type SpoolEnds = ([f64; 2], [f64; 2]);

/// Where a step is cut in two.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Cut {
    /// At `tau` the piston reaches the end stop on `side` (+1 top, -1 bottom): the second
    /// step starts on the stop's surface, so that its start sees the contact force.
    Contact { tau: f64, side: f64 },
    /// At `tau` the piston leaves the friction's creep band.
    CreepExit(f64),
    /// At `tau` the piston's velocity enters the creep band to change sign (the friction
    /// flips), at `through` it has crossed it.
    Reversal { tau: f64, through: Option<f64> },
    /// At `tau` the stop's contact force reaches zero: the piston leaves it.
    Separation(f64),
    /// In the middle: the estimate failed without a known cause.
    Halve,
}

impl Cut {
    /// Where in a step of `h` the cut is.
    fn at(self, h: f64) -> f64 {
        match self {
            Cut::Contact { tau, .. }
            | Cut::CreepExit(tau)
            | Cut::Reversal { tau, .. }
            | Cut::Separation(tau) => tau,
            Cut::Halve => 0.5 * h,
        }
    }
}

/// Advances the actuator's cylinder by `h`, the spool moving from `spool.0` to `spool.1`.
pub(crate) fn step(
    actuator: &mut Actuator,
    spool: SpoolEnds,
    h: f64,
    inputs: &HeldInputs,
) -> Result<(), String> {
    let y0 = actuator.cylinder.state.to_array();
    let mut stats = Stats::default();
    let loads = (inputs.p_supply, inputs.load);
    let y1 = advance(&actuator.params.cylinder, &y0, spool, h, loads, &mut stats)?;
    actuator.cylinder.state = CylinderState::from_array(&y1);
    actuator.work.add(&stats);
    Ok(())
}

/// The state after one internal step of `h` from `y0`: one Rodas3 step, or, where that step
/// crossed something ([`cut_of`]), two or three (the one counted as rejected); in an end
/// stop's contact, two halves ([`InternalStep::halves_in_contact`]).
fn advance(
    params: &CylinderParams,
    y0: &Vec4,
    spool: SpoolEnds,
    h: f64,
    loads: (f64, f64),
    stats: &mut Stats,
) -> Result<Vec4, String> {
    let step = InternalStep { params, path: cubic_path(spool, h), h, loads };
    let y1 = if moving_in_contact(params, y0) {
        step.halves_in_contact(y0, stats)?
    } else {
        let path = &step.path;
        let (whole, err, acceleration) =
            rodas3_fixed_step(params, (y0, h), path, loads, HALVING_RTOL, stats)?;
        match cut_of(params, (y0, &whole), err, h, acceleration) {
            None => {
                stats.accepted += 1;
                whole
            }
            Some(cut) => {
                stats.rejected += 1;
                step.cut_in_parts(y0, cut, stats)?
            }
        }
    };
    if y1.iter().any(|v| !v.is_finite()) {
        return Err("the cylinder's state is not finite; step refused".into());
    }
    Ok(y1)
}

/// One internal step of `h` being taken in parts: the cylinder, the spool's path over the
/// whole step, the supply pressure and load.
struct InternalStep<'a, P: Fn(f64) -> (f64, f64)> {
    params: &'a CylinderParams,
    path: P,
    h: f64,
    loads: (f64, f64),
}

impl<P: Fn(f64) -> (f64, f64)> InternalStep<'_, P> {
    /// The step from `y0` again, in the parts `cut` makes: up to it, then (a reversal)
    /// through the creep band, then the rest; a part that ended short of a contact carried
    /// onto the stop's surface ([`Self::onto_surface`]).
    fn cut_in_parts(&self, y0: &Vec4, cut: Cut, stats: &mut Stats) -> Result<Vec4, String> {
        let (h, mut tau) = (self.h, cut.at(self.h));
        let mut y = self.along(y0, (0.0, tau), stats)?;
        if let Cut::Contact { side, .. } = cut {
            tau = self.onto_surface(&mut y, tau, side);
        }
        // A reversal's second cut, where it falls inside the step.
        let through = match cut {
            Cut::Reversal { through: Some(t), .. } if t > tau && t < h => t,
            _ => tau,
        };
        let y = self.along(&y, (tau, through), stats)?; // nothing where there is no second cut
        self.along(&y, (through, h), stats)
    }

    /// Carries `y`, a part's end at `tau` into the step just short of the stop on `side`,
    /// over the time its closing speed takes to close the gap (every state at its rate
    /// there: the gap is nanometres, the time tens of nanoseconds), and puts the piston on
    /// the surface ([`onto_stop`]); the time it reached it. Moving the piston alone would
    /// put it on the surface too early by that time: the 20 Hz squares' piston then
    /// gathered a position error at every impact.
    fn onto_surface(&self, y: &mut Vec4, tau: f64, side: f64) -> f64 {
        let (gap, closing) = (0.5 * self.params.stroke - side * y[X], side * y[V]);
        let mut reached = tau;
        if gap > 0.0 && closing > 0.0 {
            let delay = (gap / closing).min(self.h - tau);
            let state = CylinderState::from_array(y);
            let (p_supply, load) = self.loads;
            let rates = derivatives(self.params, &state, (self.path)(tau).0, p_supply, load);
            for (value, rate) in y.iter_mut().zip(rates) {
                *value += delay * rate;
            }
            reached += delay;
        }
        onto_stop(self.params, side, y);
        reached
    }

    /// A step that starts in an end stop's contact, the piston moving: two half steps, the
    /// half in which the contact force reaches zero cut there ([`separation`]): at most three
    /// Rodas3 steps. The contact's spring and damper ring at 4.5e3 rad/s with the chambers:
    /// one 25 us step over a bounce was up to 7e-5 m/s off, an error the next impact
    /// magnifies (with halves, the 20 Hz squares' worst output went from 2.5e-3 to 1.8e-3 of
    /// its range).
    fn halves_in_contact(&self, y0: &Vec4, stats: &mut Stats) -> Result<Vec4, String> {
        let (mut y, mut cut) = (*y0, false);
        for (t0, t1) in [(0.0, 0.5 * self.h), (0.5 * self.h, self.h)] {
            let y1 = self.along(&y, (t0, t1), stats)?;
            y = match separation(self.params, &y, &y1, t1 - t0).filter(|_| !cut) {
                Some(separated) => {
                    (cut, stats.rejected, stats.accepted) =
                        (true, stats.rejected + 1, stats.accepted - 1);
                    let t = t0 + separated.at(t1 - t0);
                    let left = self.along(&y, (t0, t), stats)?;
                    self.along(&left, (t, t1), stats)?
                }
                None => y1,
            };
        }
        Ok(y)
    }

    /// One accepted Rodas3 step from `y` over `(t0, t1)` of the internal step.
    fn along(&self, y: &Vec4, (t0, t1): (f64, f64), stats: &mut Stats) -> Result<Vec4, String> {
        if t1 <= t0 {
            return Ok(*y); // a cut estimated at the step's start: nothing before it
        }
        let piece = |tau: f64| (self.path)(t0 + tau);
        stats.accepted += 1;
        let (y1, ..) =
            rodas3_fixed_step(self.params, (y, t1 - t0), &piece, self.loads, 1.0, stats)?;
        Ok(y1)
    }
}

/// Whether a step from `y0` starts in an end stop's contact with the piston moving (outside
/// the friction's creep band: a piston held in the stop is stepped as any other).
fn moving_in_contact(params: &CylinderParams, y0: &Vec4) -> bool {
    let moving = y0[V].abs() > CREEP_EDGE * params.v_friction_smooth;
    params.port == RodPort::Force && y0[X].abs() > 0.5 * params.stroke && moving
}

/// Where a step from `y0` that ended at `y1` with scaled error estimate `err` is to be cut:
/// at the first end-stop contact or separation, creep-band exit or velocity reversal inside
/// it, else in the middle if the estimate failed [`HALVING_RTOL`], else nowhere. With the
/// motion port the host moves the rod: contact and friction act on the reported rod force
/// alone, not on the state stepped here, so only the estimate cuts. `acceleration`: the
/// rod's at `y0`, as the step computed it.
fn cut_of(
    params: &CylinderParams,
    (y0, y1): (&Vec4, &Vec4),
    err: f64,
    h: f64,
    acceleration: f64,
) -> Option<Cut> {
    let failed = (err > 1.0).then_some(Cut::Halve);
    if params.port == RodPort::Motion {
        return failed;
    }
    let located = [
        contact_entry(params, y0, y1, h, acceleration),
        creep_exit(params, y0, y1, h),
        reversal(params, y0, y1, h, acceleration),
        separation(params, y0, y1, h),
    ];
    located.into_iter().flatten().min_by(|a, b| a.at(h).total_cmp(&b.at(h))).or(failed)
}

/// Where a step from `y0` to `y1` reached an end stop from outside: the earlier of the
/// time at the starting closing speed and acceleration and, where the step ended past the
/// surface, the linear interpolation of the gap (the step's own end is slowed by the
/// contact, and may even have bounced back short of the surface), less
/// [`CONTACT_MARGIN`]. An estimate: the next step starts on the surface. (At the starting
/// speed alone a piston accelerating into the stop at 234 m/s^2 was found 0.18 us late, 61
/// nm inside, where the contact's damping had already pushed back with 3 kN: the step was
/// 0.75 % off in the velocity.)
fn contact_entry(params: &CylinderParams, y0: &Vec4, y1: &Vec4, h: f64, a0: f64) -> Option<Cut> {
    let half = 0.5 * params.stroke;
    [1.0, -1.0].into_iter().find_map(|side: f64| {
        let (gap0, gap1) = (half - side * y0[X], half - side * y1[X]);
        let interpolated = if gap1 < 0.0 { h * gap0 / (gap0 - gap1) } else { h };
        let closing = time_to_close(gap0, side * y0[V], side * a0).unwrap_or(h);
        let reached = closing.min(interpolated);
        (gap0 > 0.0 && reached < h)
            .then_some(Cut::Contact { tau: reached * (1.0 - CONTACT_MARGIN), side })
    })
}

/// Where a step from `y0`, in contact with an end stop, to `y1` saw the contact force
/// `k d + c d'` reach zero (the piston leaves; a kink), by linear interpolation.
fn separation(params: &CylinderParams, y0: &Vec4, y1: &Vec4, h: f64) -> Option<Cut> {
    let half = 0.5 * params.stroke;
    let (k, c) = (params.k_endstop, params.c_endstop);
    [1.0, -1.0].into_iter().find_map(|side: f64| {
        let force = |y: &Vec4| k * (side * y[X] - half) + c * side * y[V];
        let (f0, f1) = (force(y0), force(y1));
        let inside = side * y0[X] > half;
        (inside && f0 > 0.0 && f1 < 0.0).then(|| Cut::Separation(h * f0 / (f0 - f1)))
    })
}

/// Puts a piston that ended a step just short of the stop on `side` onto its surface (a
/// hair inside, so that the contact's jump is in the next step's start): the cut's time was
/// estimated, and the stages of a step that starts outside would meet the jump mid-step.
fn onto_stop(params: &CylinderParams, side: f64, y: &mut Vec4) {
    let surface = 0.5 * params.stroke * (1.0 + f64::EPSILON);
    if side * y[X] < surface {
        y[X] = side * surface;
    }
}

/// Where a step from `y0`, which started inside the friction's creep band, left it, by
/// linear interpolation of the velocity to the band's edge [`CREEP_EDGE`]: the friction
/// rose from nothing to its full value in that first part (a piston starting from rest).
fn creep_exit(params: &CylinderParams, y0: &Vec4, y1: &Vec4, h: f64) -> Option<Cut> {
    let edge = CREEP_EDGE * params.v_friction_smooth;
    let (v0, v1) = (y0[V], y1[V]);
    if v0.abs() >= edge || v1.abs() <= edge {
        return None;
    }
    // Inside (0, h): the velocity went from inside the band to beyond its edge.
    Some(Cut::CreepExit(h * (edge.copysign(v1) - v0) / (v1 - v0)))
}

/// Where a step from `y0`, outside the friction's creep band, to `y1` saw the velocity
/// change sign: the friction flips within a microsecond around the zero. Cut where the
/// velocity reaches the band's edge, estimated as the earlier of its linear interpolation
/// and the time at the starting acceleration (the step's own end is off by the flip it
/// could not follow, late), so that the flip falls into the second part, whose friction
/// slope is the secant across it (cut at the zero, Rodas3's last stages of the first part
/// meet the flip: twice the error).
fn reversal(params: &CylinderParams, y0: &Vec4, y1: &Vec4, h: f64, a0: f64) -> Option<Cut> {
    let (v0, v1) = (y0[V], y1[V]);
    let edge = CREEP_EDGE * params.v_friction_smooth;
    let to_edge = v0.abs() - edge;
    let reversed = v0 * v1 < 0.0;
    if to_edge < 0.0 || !(reversed || v1.abs() < edge) {
        return None;
    }
    let interpolated = h * to_edge / (v0 - v1).abs();
    let slowing = -v0.signum() * a0;
    let at_start_rate = if slowing > 0.0 { to_edge / slowing } else { h };
    let tau = interpolated.min(at_start_rate);
    let crossing = 2.0 * edge / slowing.abs().max(1e-300);
    Some(Cut::Reversal { tau, through: (reversed && slowing > 0.0).then_some(tau + crossing) })
}

/// The cubic (Hermite) through the spool's position and velocity at both ends of a step of
/// `h`: position and rate at a time into the step.
fn cubic_path(([x0, v0], [x1, v1]): SpoolEnds, h: f64) -> impl Fn(f64) -> (f64, f64) {
    move |tau: f64| {
        let s = tau / h;
        let r = 1.0 - s;
        let position =
            (1.0 + 2.0 * s) * r * r * x0 + s * r * r * h * v0 + s * s * (3.0 - 2.0 * s) * x1
                - s * s * r * h * v1;
        let rate =
            6.0 * s * r * (x1 - x0) / h + r * (1.0 - 3.0 * s) * v0 + s * (3.0 * s - 2.0) * v1;
        (position, rate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::components::coefficients::Coefficients;
    use crate::components::cylinder;
    use crate::components::cylinder::{equilibrium, PA, PB};
    use crate::params::{Inputs, Params};

    fn paper_cylinder() -> (CylinderParams, f64) {
        let c = Coefficients::new(&Params::PAPER).unwrap();
        (c.cylinder, Inputs::PAPER.p_supply)
    }

    /// Why a naive fixed step fails here: with the spool open (0.3 mm) and chamber A near
    /// the supply pressure (a piston pushing at full command), the port's laminar slope puts
    /// the chambers' rates at -4e4 to -6e4 1/s (the stiffest, -1.4e5, elsewhere on the
    /// stroke); explicit Euler at 1e-4 s (|1 + h lambda| >= 3) overshoots and leaves the
    /// range the pressures can physically reach (between tank and supply) by several bar
    /// within 2 ms, where the fixed-cost step (80 internal steps of 25 us) keeps both inside
    /// it. The orifice law's square root flattens as the pressure drop grows, which is what
    /// stops Euler's growth here short of overflow.
    #[test]
    fn explicit_euler_at_a_tenth_of_a_millisecond_leaves_the_physical_range() {
        let (params, p_supply) = paper_cylinder();
        let xs = 3e-4;
        let mut start = equilibrium(&params, p_supply, 0.0).to_array();
        (start[cylinder::PA], start[cylinder::PB]) = (p_supply - 1e3, 1e3);
        let (_, jac, _) =
            crate::components::cylinder_jacobian::linearise(&params, &start, xs, p_supply, 0.0);
        assert!(jac[cylinder::PA][cylinder::PA] * 1e-4 < -2.0, "{:e}", jac[0][0]);
        let mut euler = start;
        let mut euler_worst: f64 = 0.0;
        for _ in 0..20 {
            let state = CylinderState::from_array(&euler);
            let f = cylinder::derivatives(&params, &state, xs, p_supply, 0.0);
            for (y, d) in euler.iter_mut().zip(f) {
                *y += 1e-4 * d;
            }
            let outside = |p: f64| (p - p_supply).max(params.p_tank - p).max(0.0);
            euler_worst = euler_worst.max(outside(euler[0])).max(outside(euler[1]));
        }
        let mut y = start;
        let held = ([xs, 0.0], [xs, 0.0]);
        for _ in 0..80 {
            y = advance(&params, &y, held, 25e-6, (p_supply, 0.0), &mut Stats::default()).unwrap();
        }
        println!("explicit Euler: {euler_worst:e} Pa outside [tank, supply]");
        assert!(euler_worst > 1e5, "explicit Euler: {euler_worst:e} Pa outside");
        for p in [y[cylinder::PA], y[cylinder::PB]] {
            assert!((params.p_cavitation..=p_supply + 1e3).contains(&p), "fixed cost: {p:e}");
        }
    }

    /// One internal step: parameters, state, spool ends, step, supply pressure and load.
    type StepFn<'a> = dyn Fn(&CylinderParams, &Vec4, SpoolEnds, f64, (f64, f64)) -> Vec4 + 'a;

    /// A smooth spool path: opening from 0.1 to 0.3 mm over 4 ms, position and velocity.
    fn opening(t: f64) -> [f64; 2] {
        let s = t / 4e-3;
        [1e-4 + 2e-4 * s * s * (3.0 - 2.0 * s), 2e-4 * 6.0 * s * (1.0 - s) / 4e-3]
    }

    /// The state after `n` steps of `step` over 4 ms from a piston already moving, relative
    /// to the state scale (1 MPa, 10 mm, 0.1 m/s).
    fn run_opening(n: usize, step: &StepFn) -> Vec4 {
        let (params, p_supply) = paper_cylinder();
        let mut y = equilibrium(&params, p_supply, 0.0).to_array();
        y[cylinder::V] = 0.05;
        let h = 4e-3 / n as f64;
        for k in 0..n {
            let ends = (opening(k as f64 * h), opening((k + 1) as f64 * h));
            y = step(&params, &y, ends, h, (p_supply, 0.0));
        }
        std::array::from_fn(|i| y[i] / crate::numerics::rosenbrock::STATE_SCALE[i])
    }

    /// The order of a step on a smooth run (no contact, no cavitation, the piston moving
    /// away from the friction's steep zero-velocity region): the error of 64, 128, 256 steps
    /// (62.5 to 15.6 us) against 8192.
    fn measured_orders(step: &StepFn) -> [f64; 2] {
        let reference = run_opening(8192, step);
        let error = |n| {
            let y = run_opening(n, step);
            (0..4).map(|i| (y[i] - reference[i]).abs()).fold(0.0, f64::max)
        };
        let e: Vec<f64> = [64, 128, 256].into_iter().map(error).collect();
        println!("errors {:?}", e.iter().map(|x| format!("{x:.2e}")).collect::<Vec<_>>());
        [(e[0] / e[1]).log2(), (e[1] / e[2]).log2()]
    }

    /// Rodas3 along the cubic spool path converges with order 3, approaching it from below
    /// as the step shrinks (stiff modes to -1.4e5 1/s are not resolved at these steps).
    #[test]
    fn the_fixed_cost_step_is_of_order_three() {
        let rodas3 = |p: &CylinderParams, y: &Vec4, ends, h, loads| {
            let path = cubic_path(ends, h);
            rodas3_fixed_step(p, (y, h), &path, loads, 1.0, &mut Stats::default()).unwrap().0
        };
        // At the default internal step the run never cuts a step: it is one Rodas3 each.
        let work = std::cell::Cell::new((0, 0));
        run_opening(160, &|p, y, ends, h, loads| {
            let mut stats = Stats::default();
            let y1 = advance(p, y, ends, h, loads, &mut stats).unwrap();
            let (accepted, rejected) = work.get();
            work.set((accepted + stats.accepted, rejected + stats.rejected));
            y1
        });
        assert_eq!(work.get(), (160, 0));
        let o3 = measured_orders(&rodas3);
        println!("Rodas3 along the cubic path: {o3:.2?}");
        assert!(o3.iter().all(|&o| o > 2.6), "Rodas3: {o3:?}");
    }

    /// The internal step of the tests below.
    const STEP: f64 = 25e-6;

    /// The spool from `x0` at `rate`, accelerating at `a`: position and rate at time `t`
    /// (written out here rather than through [`cubic_path`], which the tests test).
    fn parabola((x0, rate, a): (f64, f64, f64), t: f64) -> (f64, f64) {
        (x0 + rate * t + 0.5 * a * t * t, rate + a * t)
    }

    /// `y` after [`STEP`] in 1000 plain Rodas3 steps, the spool on the [`parabola`] of
    /// `spool`: the reference for one internal step (steps of 25 ns resolve the friction's
    /// band and the contact).
    fn fine(params: &CylinderParams, y: &Vec4, spool: (f64, f64, f64), loads: (f64, f64)) -> Vec4 {
        finer(1000, params, y, spool, loads)
    }

    /// [`fine`] in `n` steps.
    fn finer(
        n: usize,
        params: &CylinderParams,
        y: &Vec4,
        spool: (f64, f64, f64),
        loads: (f64, f64),
    ) -> Vec4 {
        let mut y = *y;
        let h = STEP / n as f64;
        for k in 0..n {
            let start = k as f64 * h;
            let path = move |tau: f64| parabola(spool, start + tau);
            y = rodas3_fixed_step(params, (&y, h), &path, loads, 1.0, &mut Stats::default())
                .unwrap()
                .0;
        }
        y
    }

    /// The spool moving from 1e-4 m (`-1e-4 m` on the bottom `side`) at `rate`, the rate
    /// doubling over the step: a [`parabola`].
    fn opening_spool(side: f64, rate: f64) -> (f64, f64, f64) {
        (side * 1e-4, rate, rate / STEP)
    }

    /// One internal step from `y`, the spool on the [`parabola`] `motion`: its error in
    /// velocity against [`fine`] as a share of the velocity reached, in the pressures (Pa),
    /// and its work.
    fn one_step_errors(
        params: &CylinderParams,
        y: &Vec4,
        motion: (f64, f64, f64),
        loads: (f64, f64),
    ) -> (f64, f64, Stats) {
        let end = |t: f64| -> [f64; 2] { parabola(motion, t).into() };
        let mut stats = Stats::default();
        let y1 = advance(params, y, (end(0.0), end(STEP)), STEP, loads, &mut stats).unwrap();
        let reference = fine(params, y, motion, loads);
        let pressures = (y1[PA] - reference[PA]).abs().max((y1[PB] - reference[PB]).abs());
        println!("v {:e}, reference {:e}; pressures {pressures:e} Pa off", y1[V], reference[V]);
        (((y1[V] - reference[V]) / reference[V]).abs(), pressures, stats)
    }

    /// A step cut in `parts`: the whole step tried (rejected), then its parts (accepted).
    fn cut_in(parts: u32, stats: &Stats) -> bool {
        (stats.rejected, stats.accepted) == (1, parts)
    }

    /// A piston at rest under a load applied at once (a leg standing up) leaves the
    /// friction's creep band within a microsecond. One step over it from rest, its Jacobian
    /// taking the band's tangent, held the piston as a damper would: 17 % of the velocity
    /// lost, or 2 % with the secant alone. Cut where the band was left, 1 % at most, the
    /// spool closed.
    #[test]
    fn a_step_from_rest_is_cut_where_the_friction_has_risen() {
        let (params, p_supply) = paper_cylinder();
        let rest = equilibrium(&params, p_supply, 0.0).to_array();
        let closed = (0.0, 0.0, 0.0);
        let (error, _, stats) = one_step_errors(&params, &rest, closed, (p_supply, -750.0));
        assert!(error < 1e-2 && cut_in(2, &stats), "{error:e} of the velocity, {stats:?}");
    }

    /// A piston running into either stop 10 us into a step, the spool opening further: the
    /// contact force jumps in by `c v` there. The step is cut a thousandth short of the
    /// contact and the second part starts on the stop's surface; the velocity after the step
    /// within 3e-4 of the reference (halved instead, 3.4e-3), the pressures within 1 kPa
    /// (the second part's spool path a step too long, 26 kPa).
    #[test]
    fn a_step_into_an_end_stop_is_cut_at_the_contact() {
        for side in [1.0, -1.0] {
            let (error, pressures, stats) = at_a_stop(side, -3e-6, 0.3);
            let case = format!("side {side}: {error:e}, {pressures:e} Pa, {stats:?}");
            assert!(error < 3e-4 && pressures < 1e3 && cut_in(2, &stats), "{case}");
        }
    }

    /// One step from a piston `depth` into the stop on `side` (negative: short of it) moving
    /// at `speed` into it (negative: out), the spool opening the way it moves: as
    /// [`one_step_errors`].
    fn at_a_stop(side: f64, depth: f64, speed: f64) -> (f64, f64, Stats) {
        let (params, p_supply) = paper_cylinder();
        let mut y = equilibrium(&params, p_supply, 0.0).to_array();
        (y[X], y[V]) = (side * (0.5 * params.stroke + depth), side * speed);
        let way = side * speed.signum();
        one_step_errors(&params, &y, opening_spool(way, way * 2.0), (p_supply, 0.0))
    }

    /// A piston 35 um into either stop, pulled out at 0.3 m/s: the contact force
    /// `k d + c d'` reaches zero within the step, and the piston leaves (a kink). Taken in
    /// halves, the one it leaves in cut there: the velocity after the step within 1e-6 of
    /// the reference (6e-8; one step cut there, 4e-6; one step across it, 7.2e-4).
    #[test]
    fn a_step_out_of_an_end_stop_is_cut_where_the_contact_lets_go() {
        for side in [1.0, -1.0] {
            let (error, pressures, stats) = at_a_stop(side, 35e-6, -0.3);
            let case = format!("side {side}: {error:e}, {pressures:e} Pa, {stats:?}");
            assert!(error < 1e-6 && pressures < 1e3 && cut_in(3, &stats), "{case}");
        }
    }

    /// A piston pushed back hard (300 m/s^2) through zero velocity 22 us into a step, the
    /// spool opening: the friction flips from +30 N to -30 N within a microsecond there. The
    /// step is cut where the velocity reaches the creep band's edge and again where it has
    /// crossed the band, the flip in the short middle part: the velocity after the step within
    /// 0.2 % of the reference (0.06 %; without the middle part 1.4 %, uncut 8 %, cut at the
    /// zero 3.6 %).
    #[test]
    fn a_step_through_a_velocity_reversal_is_cut_before_the_friction_flips() {
        let (params, p_supply) = paper_cylinder();
        for side in [1.0, -1.0] {
            let mut y = equilibrium(&params, p_supply, 0.0).to_array();
            y[V] = -side * 6.5e-3;
            let spool = opening_spool(side, side * 0.07);
            let (error, _, stats) = one_step_errors(&params, &y, spool, (p_supply, side * 1500.0));
            let case = format!("side {side}: {error:e}, {stats:?}");
            assert!(error < 2e-3 && cut_in(3, &stats), "{case}");
        }
    }

    /// With the motion port the host moves the rod (here at a steady 0.05 m/s into either
    /// stop, reached 10 us into the step, and through zero velocity at 300 m/s^2): contact
    /// and friction act on the reported force alone, so no step is cut for them, and the rod
    /// goes where the host takes it (not onto the stop's surface).
    #[test]
    fn with_the_motion_port_contact_and_friction_cut_nothing() {
        let mut paper = Params::PAPER;
        paper.cylinder.port = RodPort::Motion;
        let (params, p_supply) =
            (Coefficients::new(&paper).unwrap().cylinder, Inputs::PAPER.p_supply);
        let spool = ([1e-4, 0.0], [1e-4, 0.0]);
        for side in [1.0, -1.0] {
            for (x0, v0, acceleration) in
                [(0.5 * params.stroke - 0.5e-6, 0.05, 0.0), (0.0, -6.5e-3, 300.0)]
            {
                let mut y = equilibrium(&params, p_supply, 0.0).to_array();
                (y[X], y[V]) = (side * x0, side * v0);
                let mut stats = Stats::default();
                let loads = (p_supply, side * acceleration);
                let y1 = advance(&params, &y, spool, STEP, loads, &mut stats).unwrap();
                let x1 = y[X] + STEP * y[V] + 0.5 * side * acceleration * STEP * STEP;
                let case = format!("side {side}, v0 {v0}: {stats:?}, x {:e} vs {x1:e}", y1[X]);
                assert_eq!((stats.accepted, stats.rejected), (1, 0), "{case}");
                assert!((y1[X] - x1).abs() < 1e-12, "{case}");
            }
        }
    }

    /// A piston bouncing in the top stop (124 um in, still moving in at 0.05 m/s against the
    /// contact's 12 kN, to reverse within the step; chamber B near the tank), the spool held
    /// open, as a 2 Hz square leaves it: the step goes in two halves, the velocity after it
    /// within 3e-5 m/s of the reference (1.8e-5; cut as a reversal, 3.8e-5; one step, 7.2e-5).
    #[test]
    fn a_step_in_an_end_stops_contact_goes_in_halves() {
        let (params, p_supply) = paper_cylinder();
        let mut y = equilibrium(&params, p_supply, 0.0).to_array();
        (y[X], y[V], y[PA], y[PB]) = (0.5 * params.stroke + 124e-6, 0.0496, 2.9495e6, 3.6129e4);
        let open = (1.9e-4, 0.0, 0.0);
        let (error, _, stats) = one_step_errors(&params, &y, open, (p_supply, 0.0));
        let reference = fine(&params, &y, open, (p_supply, 0.0));
        let off = error * reference[V].abs();
        let case = format!("{off:e} m/s, {stats:?}");
        assert!(off < 3e-5 && (stats.rejected, stats.accepted) == (0, 2), "{case}");
    }

    /// Where a step that enters the creep band is cut: at the earlier of the band edge's
    /// interpolation between the step's ends and its time at the starting deceleration; a
    /// stop (no reversal) has no second cut, a reversal one a band's crossing later.
    #[test]
    fn the_band_entry_is_placed_at_the_earlier_estimate() {
        let (params, p_supply) = paper_cylinder();
        let edge = CREEP_EDGE * params.v_friction_smooth;
        let h = STEP;
        let with_v = |v: f64| {
            let mut y = equilibrium(&params, p_supply, 0.0).to_array();
            y[V] = v;
            y
        };
        let slowing = |y: &Vec4, load: f64| {
            cylinder::acceleration(&params, &CylinderState::from_array(y), load)
        };
        // Stopping, pushed on (no deceleration at the start): the interpolation.
        let (y0, y1) = (with_v(-5e-3), with_v(-1e-4));
        assert!(slowing(&y0, -200.0) < 0.0);
        let tau = h * (5e-3 - edge) / (5e-3 - 1e-4);
        let cut = reversal(&params, &y0, &y1, h, slowing(&y0, -200.0));
        assert_eq!(cut, Some(Cut::Reversal { tau, through: None }));
        // Stopping, slowed down by the friction: still no second cut.
        assert!(slowing(&y0, 0.0) > 0.0);
        let cut = reversal(&params, &y0, &y1, h, slowing(&y0, 0.0));
        assert!(matches!(cut, Some(Cut::Reversal { through: None, .. })), "{cut:?}");
        // Reversing under a weak push: the interpolation is the earlier.
        let (y0, y1) = (with_v(-6.5e-3), with_v(1e-3));
        let a = slowing(&y0, 0.0);
        let tau = h * (6.5e-3 - edge) / 7.5e-3;
        assert!(a > 0.0 && (6.5e-3 - edge) / a > tau, "{a}");
        let cut = reversal(&params, &y0, &y1, h, slowing(&y0, 0.0));
        assert_eq!(cut, Some(Cut::Reversal { tau, through: Some(tau + 2.0 * edge / a) }));
        // Reversing under a hard push: the time at the starting deceleration.
        let a = slowing(&y0, 1500.0);
        let tau = (6.5e-3 - edge) / a;
        assert!(tau < h * (6.5e-3 - edge) / 7.5e-3, "{a}");
        let cut = reversal(&params, &y0, &y1, h, slowing(&y0, 1500.0));
        assert_eq!(cut, Some(Cut::Reversal { tau, through: Some(tau + 2.0 * edge / a) }));
        // Staying outside the band, or starting inside it: no such cut.
        assert_eq!(reversal(&params, &y0, &with_v(-1e-3), h, slowing(&y0, 0.0)), None);
        let inside = with_v(1e-4);
        assert_eq!(reversal(&params, &inside, &with_v(-1e-3), h, slowing(&inside, 0.0)), None);
    }

    /// Where a step that reaches an end stop is cut: the earlier of the gap's interpolation
    /// between the step's ends (where it ended past the surface) and the time the gap closes
    /// at the starting speed and acceleration, a thousandth short; none where the piston
    /// stops short of the stop or moves away.
    #[test]
    fn the_contact_is_placed_at_the_earlier_estimate() {
        let (params, p_supply) = paper_cylinder();
        let (h, half) = (STEP, 0.5 * params.stroke);
        let at = |x: f64, v: f64| {
            let mut y = equilibrium(&params, p_supply, 0.0).to_array();
            (y[X], y[V]) = (x, v);
            y
        };
        // The cut's time on `side`, to rounding of `expected` (the gap is a difference).
        let placed = |cut: Option<Cut>, expected: f64, side: f64| match cut {
            Some(Cut::Contact { tau, side: s }) => {
                s == side && (tau - expected * (1.0 - CONTACT_MARGIN)).abs() < 1e-9 * expected
            }
            _ => false,
        };
        for side in [1.0, -1.0] {
            let acceleration = |y: &Vec4, load: f64| {
                cylinder::acceleration(&params, &CylinderState::from_array(y), load)
            };
            let a = |y: &Vec4, load: f64| side * acceleration(y, load);
            let y0 = at(side * (half - 3e-6), side * 0.3);
            let a0 = acceleration(&y0, 0.0);
            // Ended short of the surface: the starting speed and acceleration decide.
            let t = time_to_close(3e-6, 0.3, a(&y0, 0.0)).unwrap();
            let cut = contact_entry(&params, &y0, &at(side * (half - 1e-7), 0.0), h, a0);
            assert!(placed(cut, t, side), "side {side}: {cut:?}, {t:e}");
            // Ended 6 um past it (pushed hard on the way): the interpolation, earlier.
            let tau = h * 3e-6 / 9e-6;
            let cut = contact_entry(&params, &y0, &at(side * (half + 6e-6), 0.0), h, a0);
            assert!(tau < t && placed(cut, tau, side), "side {side}: {cut:?}, {tau:e}");
            // Pulled back hard: stops 2 um short, ends short.
            let load = -side * 3e5;
            assert!(time_to_close(3e-6, 0.3, a(&y0, load)).is_none(), "side {side}");
            let back = at(side * (half - 2e-6), 0.0);
            let pulled = acceleration(&y0, load);
            assert_eq!(contact_entry(&params, &y0, &back, h, pulled), None, "side {side}");
            // Moving away.
            let away = at(side * (half - 3e-6), -side * 0.3);
            let a_away = acceleration(&away, 0.0);
            assert_eq!(contact_entry(&params, &away, &at(0.0, 0.0), h, a_away), None);
        }
    }

    /// A piston running at 0.75 m/s into either stop 20 us into a step: the step's first
    /// part ends a thousandth of that short of the contact, 15 nm from the surface. Carried
    /// onto it over the 20 ns the gap takes, the piston is within 1e-9 m of the reference
    /// after the step and its velocity within 5e-6 m/s (moved onto the surface at once, the
    /// piston ran 20 ns ahead: 1.5e-8 m and 3.3e-5 m/s off).
    #[test]
    fn a_piston_short_of_the_stop_is_carried_onto_it_in_time() {
        let (params, p_supply) = paper_cylinder();
        for side in [1.0, -1.0] {
            let mut y = equilibrium(&params, p_supply, 0.0).to_array();
            (y[X], y[V]) = (side * (0.5 * params.stroke - 15e-6), side * 0.75);
            let spool = opening_spool(side, side * 2.0);
            let end = |t: f64| -> [f64; 2] { parabola(spool, t).into() };
            let mut stats = Stats::default();
            let loads = (p_supply, 0.0);
            let y1 = advance(&params, &y, (end(0.0), end(STEP)), STEP, loads, &mut stats).unwrap();
            let reference = finer(8000, &params, &y, spool, loads);
            let (dx, dv) = (y1[X] - reference[X], y1[V] - reference[V]);
            let case = format!("side {side}: {dx:e} m, {dv:e} m/s, {stats:?}");
            assert!(dx.abs() < 1e-9 && dv.abs() < 5e-6 && cut_in(2, &stats), "{case}");
        }
    }

    /// A piston still rising at 0.73 m/s after its spool reversed (a 20 Hz square's edge),
    /// chamber A emptied to tank and expanding: its pressure falls through the cavitation
    /// band onto the floor within the step (the reference ends 3 kPa above it). One Rodas3
    /// step whose Jacobian took the fade's tangent (zero above the band) ran 59 kPa below
    /// the floor, lifted back by the clamp, and its velocity was 6e-5 m/s off; with the
    /// fade's secant it stays above the floor and within 2e-6 m/s (4e-7).
    #[test]
    fn a_chamber_emptied_into_the_cavitation_band_stays_above_the_floor() {
        let (params, p_supply) = paper_cylinder();
        let mut y = equilibrium(&params, p_supply, 0.0).to_array();
        (y[PA], y[PB], y[X], y[V]) = (7.9e4, 6.7e6, 0.0348, 0.727);
        let reversed = (-1.9e-4, 0.0, 0.0);
        let path = |t: f64| parabola(reversed, t);
        let (mut stats, loads) = (Stats::default(), (p_supply, 0.0));
        let (y1, ..) =
            rodas3_fixed_step(&params, (&y, STEP), &path, loads, 1.0, &mut stats).unwrap();
        let reference = finer(8000, &params, &y, reversed, loads);
        let dv = y1[V] - reference[V];
        let case = format!("{dv:e} m/s, lifted {:e} Pa", stats.floor_clamp);
        assert!(reference[PA] < params.p_cavitation + 1e4, "{case}: not at the floor");
        assert!(stats.floor_clamp == 0.0 && dv.abs() < 2e-6, "{case}");
    }

    /// A piston leaving the top stop at 0.33 m/s, the spool open: chamber A compressed
    /// through the supply pressure (6.80 to 6.91 MPa; the port's drop through zero, where
    /// the orifice's square root is steep). One Rodas3 step was 1.3 kPa off, within a
    /// tolerance relative to the pressure (7 kPa) but 1.3e-3 of the flow's range on the
    /// 20 Hz squares; measured against 1 MPa the step is halved: 140 Pa.
    #[test]
    fn a_pressure_near_supply_is_held_to_the_absolute_tolerance() {
        let (params, p_supply) = paper_cylinder();
        let mut y = equilibrium(&params, p_supply, 0.0).to_array();
        (y[PA], y[PB], y[X], y[V]) = (6.8037e6, params.p_cavitation, 0.0399914, -0.3336);
        let (error, pressures, stats) =
            one_step_errors(&params, &y, (1.9012e-4, 0.0, 0.0), (p_supply, 0.0));
        let case = format!("{error:e} of the velocity, {pressures:e} Pa, {stats:?}");
        assert!(pressures < 300.0 && cut_in(2, &stats), "{case}");
    }

    /// The carry onto the stop's surface: over the time the closing speed takes to close
    /// the gap, every state at its rate, but never past the step's end (the piston then
    /// still put on the surface: the cut's estimate was early); and no carry at all for a
    /// part that ended inside the stop or moving away from it (time never runs back).
    #[test]
    fn the_carry_onto_the_stop_stays_inside_the_step_and_never_runs_back() {
        let (params, p_supply) = paper_cylinder();
        let spool = ([1e-4, 0.0], [1e-4, 0.0]);
        let step = InternalStep {
            params: &params,
            path: cubic_path(spool, STEP),
            h: STEP,
            loads: (p_supply, 0.0),
        };
        let surface = 0.5 * params.stroke * (1.0 + f64::EPSILON);
        let start = |gap: f64, v: f64| {
            let mut y = equilibrium(&params, p_supply, 0.0).to_array();
            (y[X], y[V]) = (0.5 * params.stroke - gap, v);
            y
        };
        let rates = |y: &Vec4| {
            let state = CylinderState::from_array(y);
            cylinder::derivatives(&params, &state, 1e-4, p_supply, 0.0)
        };
        // 3 nm at 0.3 m/s: 10 ns, from 10 us into the step.
        let mut y = start(3e-9, 0.3);
        let (y0, delay) = (y, (0.5 * params.stroke - y[X]) / y[V]);
        assert_eq!(step.onto_surface(&mut y, 10e-6, 1.0), 10e-6 + delay);
        let f = rates(&y0);
        for k in [PA, PB, V] {
            assert_eq!(y[k], y0[k] + delay * f[k], "state {k}");
        }
        assert_eq!(y[X], surface);
        // 3 nm at 0.3 m/s from 5 ns before the step's end: 5 ns at most.
        let mut y = start(3e-9, 0.3);
        assert_eq!(step.onto_surface(&mut y, STEP - 5e-9, 1.0), STEP);
        assert_eq!((y[V], y[X]), (y0[V] + (STEP - (STEP - 5e-9)) * f[V], surface));
        // Inside the stop already, and short of it moving away: the time stays.
        for (gap, v) in [(-3e-9, 0.3), (3e-9, -0.3)] {
            let mut y = start(gap, v);
            let y0 = y;
            assert_eq!(step.onto_surface(&mut y, 10e-6, 1.0), 10e-6, "gap {gap}, v {v}");
            assert_eq!([y[PA], y[PB], y[V]], [y0[PA], y0[PB], y0[V]], "gap {gap}, v {v}");
        }
    }
}
