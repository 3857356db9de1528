//! Rosenbrock integrator of the cylinder ([`crate::components::cylinder`]).
//!
//! Rodas4 (Hairer & Wanner, *Solving ODEs II*, IV.7; coefficients of `rodas.f`, METH = 1):
//! a 6-stage Rosenbrock method of order 4, stiffly accurate and L-stable, with an embedded
//! order-3 solution for error control. Why implicit: the Jacobian's stiff modes are not rare
//! corners but ordinary operating states (eigenvalues computed in `tests::jacobian_eigenvalues`):
//! at rest the friction tanh gives `-6.0e4 1/s` (`~ -Fs/(m v_smooth)`); pressed on the end stop
//! `-1.4e5, -6.2e4, -1.6e4` (laminar port near supply, friction); a port in its laminar region
//! `-6e4`; during an impact the contact mode `-1.07e3 +- 4.4e3i` plus `-2.7e4`; moving at rated
//! flow only `-1.3e4, -1.9e3, -4.0e2`. An explicit method would sit on its stability boundary
//! (`|lambda h| < 3.3`: steps of 2..50 us) in most of these; Rodas4 takes steps set by accuracy
//! only: one step per 0.1 ms call at rest, in steady motion and pressed on a stop. Order 4
//! keeps the step count low at the 1e-7 tolerance.
//! The 4x4 Jacobian and `df/dt = df/dx_s x_s'` are analytic (`linearise`, checked against
//! differences in `tests::analytic_jacobian_matches_finite_differences`); the linear systems
//! use a hand-written 4x4 LU with partial pivoting. A step that the call boundary cuts to at
//! most half the controller's size first tries Rodas3 (Sandu et al. 1997; 4 stages, 2 model
//! evaluations after the linearisation) and keeps it only if its own embedded estimate passes
//! the same tolerance; after a failure it sits out a few such steps (its failures come in
//! runs, [`MAX_RODAS3_BACKOFF`]). Steps are cut to land on the end-stop contact switches (x reaching
//! `+-S/2`, the contact force crossing zero), predicted from the Taylor polynomial that the
//! linearisation gives, instead of rejecting their way across the jump in `v'`; and on a
//! cavitation kink (a chamber in the band turning from filling to emptying) once an attempt
//! across it failed.
//! Everything lives on the stack: no allocation in [`advance_with_rate`].

use crate::components::cylinder::{
    derivatives, next_cavitation_switch, next_contact_switch, CylinderParams, CylinderState, Mat4,
    Vec4, N_STATES, PA, PB,
};
use crate::components::cylinder_jacobian::linearise;
use crate::components::metering_ports::PortLaw;
use crate::numerics::lu4::Lu4;
use crate::readable::readable;
use std::marker::PhantomData;

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
/// First step when nothing is known yet (s).
const INITIAL_STEP: f64 = 1e-6;
/// Refuse a call that needs more internal steps than this (rejected ones included).
const MAX_STEPS_PER_CALL: u32 = 100_000;

/// Error weights: the error of state i is measured against `rtol * max(|y_i|, STATE_SCALE[i])`.
pub(crate) const STATE_SCALE: [f64; N_STATES] = [1.0e6, 1.0e6, 1.0e-2, 1.0e-1];

/// Numbers in [`RosenbrockMemory::to_array`].
pub(crate) const MEMORY_VALUES: usize = 6;

/// What the integrator carries from one call to the next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RosenbrockMemory {
    /// Relative tolerance on the scaled states.
    pub rtol: f64,
    /// Step size to try next (s); 0 = not known yet.
    pub h_next: f64,
    /// Last accepted step and its error, for Gustafsson's predictive controller.
    h_accepted: f64,
    err_accepted: f64,
    /// Steps that could try Rodas3 that will not, after it failed ([`MAX_RODAS3_BACKOFF`]),
    /// and how many the last failure set.
    rodas3_skip: u32,
    rodas3_backoff: u32,
}

/// After a Rodas3 attempt fails its error test, the next 1, 2, 4, ... (doubling while it
/// keeps failing, back to 1 once it passes) steps that could try it go to Rodas4 at once,
/// up to this many: its failures come in runs (a step on which it fails is mostly followed
/// by another), and each costs an LU and two model evaluations.
const MAX_RODAS3_BACKOFF: u32 = 64;

/// At the default `Params::solver_rtol` (an instance starts at its parameter's value).
#[cfg(test)]
impl Default for RosenbrockMemory {
    fn default() -> Self {
        RosenbrockMemory::new(crate::params::Params::PAPER.solver_rtol)
    }
}

impl RosenbrockMemory {
    pub(crate) fn new(rtol: f64) -> RosenbrockMemory {
        RosenbrockMemory {
            rtol,
            h_next: 0.0,
            h_accepted: 0.0,
            err_accepted: 1.0,
            rodas3_skip: 0,
            rodas3_backoff: 0,
        }
    }
    /// Whether a step that could try Rodas3 may: not while sitting out a backoff (the turn
    /// is counted).
    fn takes_rodas3_turn(&mut self) -> bool {
        if self.rodas3_skip > 0 {
            self.rodas3_skip -= 1;
            false
        } else {
            true
        }
    }

    /// `[rtol, h_next, h_accepted, err_accepted, rodas3_skip, rodas3_backoff]`, for
    /// serialising the instance state.
    pub(crate) fn to_array(self) -> [f64; MEMORY_VALUES] {
        let (skip, backoff) = (self.rodas3_skip as f64, self.rodas3_backoff as f64);
        [self.rtol, self.h_next, self.h_accepted, self.err_accepted, skip, backoff]
    }
    /// Inverse of [`RosenbrockMemory::to_array`]; counts out of range are clamped.
    pub(crate) fn from_array(a: &[f64; MEMORY_VALUES]) -> RosenbrockMemory {
        let count = |x: f64| x.clamp(0.0, MAX_RODAS3_BACKOFF as f64) as u32;
        RosenbrockMemory {
            rtol: a[0],
            h_next: a[1],
            h_accepted: a[2],
            err_accepted: a[3],
            rodas3_skip: count(a[4]),
            rodas3_backoff: count(a[5]),
        }
    }
}

/// Work done in one call of [`advance_with_rate`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Stats {
    pub accepted: u32,
    pub rejected: u32,
    /// Model evaluations (an analytic linearisation counts as one, and in `jacobian_evaluations`).
    pub function_evaluations: u32,
    pub jacobian_evaluations: u32,
    /// LU factorisations of the iteration matrix (one per attempted step, Rodas3 included).
    pub factorisations: u32,
    /// Accepted steps taken with Rodas3 (included in `accepted`), and Rodas3 attempts whose
    /// error estimate failed (followed by Rodas4 on the same step; not in `rejected`).
    pub rodas3_accepted: u32,
    pub rodas3_failed: u32,
    /// Accepted steps cut short to land on an end-stop contact switch (included in `accepted`).
    pub landings: u32,
    /// Largest amount a pressure was lifted back to the cavitation floor after a step (Pa).
    pub floor_clamp: f64,
}

/// Advances the state by `h` seconds; `x_s(tau)` is the spool position at `tau` in `[0, h]`.
/// Its rate (for `df/dt`) is taken by differencing `x_s` alone (no extra model evaluation);
/// the physics core uses [`advance_with_rate`] with the exact rate, the tests this form
/// for arbitrary spool paths. On error the state is left as it was.
#[cfg(test)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn advance(
    params: &CylinderParams,
    state: &mut CylinderState,
    h: f64,
    p_supply: f64,
    load: f64,
    x_s: impl Fn(f64) -> f64,
    memory: &mut RosenbrockMemory,
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
    advance_with_rate::<crate::components::metering_ports::AnyLap>(
        params, state, h, p_supply, load, spool, memory,
    )
}

/// Why [`hydraulics_refusal`] refuses a step of the cylinder's integrator.
#[derive(Clone, Copy)]
enum Refusal {
    NotFinite,
    TooManySteps,
    Underflow,
}

/// The message of a refused step of `h` (at `tau` into it). Cold and out of line: the
/// integrator's loop tests for each on every internal step.
#[cold]
#[inline(never)]
fn hydraulics_refusal(why: Refusal, h: f64, tau: f64) -> String {
    match why {
        Refusal::NotFinite => {
            format!("hydraulics: step {} s is not a positive finite number", readable(h))
        }
        Refusal::TooManySteps => format!(
            "hydraulics: more than {MAX_STEPS_PER_CALL} internal steps in one step of {} s",
            readable(h)
        ),
        Refusal::Underflow => format!(
            "hydraulics: step size underflow at {} s into a step of {} s",
            readable(tau),
            readable(h)
        ),
    }
}

/// As `advance` (the tests' form, spool rate by differences), with `spool(tau) = (x_s, dx_s/dtau)` at `tau` in `[0, h]`,
/// the ports by the law `L`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn advance_with_rate<L: PortLaw>(
    params: &CylinderParams,
    state: &mut CylinderState,
    h: f64,
    p_supply: f64,
    load: f64,
    spool: impl Fn(f64) -> (f64, f64),
    memory: &mut RosenbrockMemory,
) -> Result<Stats, String> {
    let mut stats = Stats::default();
    if h == 0.0 {
        return Ok(stats);
    }
    if !(h.is_finite() && h > 0.0) {
        return Err(hydraulics_refusal(Refusal::NotFinite, h, 0.0));
    }
    let model = Rhs::<L, _> { params, p_supply, load, spool: &spool, law: PhantomData };
    let mut call = Call {
        h,
        y: state.to_array(),
        tau: 0.0,
        step: if memory.h_next > 0.0 { memory.h_next } else { INITIAL_STEP },
        rejected_last: false,
        rejection: None,
        landings: 0,
        cavitation_watch_end: 0.0,
    };
    // The linearisation at (tau, y), kept across rejected attempts from the same point.
    let mut lin: Option<Linearisation> = None;
    loop {
        if stats.accepted + stats.rejected >= MAX_STEPS_PER_CALL {
            return Err(hydraulics_refusal(Refusal::TooManySteps, h, 0.0));
        }
        // The last step lands exactly on h; remember the untruncated size for the next call.
        let wanted = call.step;
        let mut last = call.tau + call.step * 1.0001 >= h;
        if last {
            call.step = h - call.tau;
        }
        let here = match lin {
            Some(ref l) => l,
            None => lin.insert(model.linearise(call.tau, &call.y, &mut stats)),
        };
        // Step onto the next end-stop contact switch (or a watched cavitation kink) instead of
        // across it.
        let mut landing = false;
        if call.landings < MAX_LANDINGS {
            if let Some(t_land) = call.switch_ahead(params, here, wanted) {
                call.step = t_land;
                last = false;
                landing = true;
            }
        }
        if call.step <= 1e-14 * h.max(1e-6) {
            return Err(hydraulics_refusal(Refusal::Underflow, h, call.tau));
        }
        // A step the call boundary cut to at most half of what Rodas4's controller wants is
        // smooth at this size: try the cheaper Rodas3 under the same tolerance first and keep
        // its result only if its own error estimate passes; else Rodas4 from the same
        // linearisation. The controller only ever learns from Rodas4 steps.
        if last && call.step * 2.0 <= wanted && memory.takes_rodas3_turn() {
            if let Some(y3) = rodas3_step(&model, here, &call, memory, &mut stats)? {
                call.y = y3;
                memory.h_next = wanted;
                break;
            }
        }
        let (y_new, err) = rosenbrock_step::<6, _, _>(
            &RODAS4,
            &model,
            here,
            (call.tau, &call.y, call.step),
            memory.rtol,
            &mut stats,
        )?;
        if err <= 1.0 {
            lin = None;
            let attempt = Attempt { wanted, last, landing };
            if call.accept(params, y_new, err, attempt, memory, &mut stats) {
                break;
            }
        } else {
            call.reject(err, &mut stats);
        }
    }
    if !call.y.iter().all(|v| v.is_finite()) {
        return Err("hydraulics: the state became non-finite; step refused".into());
    }
    *state = CylinderState::from_array(&call.y);
    Ok(stats)
}

/// Where a call of [`advance_with_rate`] stands between its internal steps.
struct Call {
    /// The call's length (s).
    h: f64,
    /// The state reached, `tau` into the call.
    y: Vec4,
    tau: f64,
    /// Size of the next attempt (s).
    step: f64,
    /// The attempt before the last accepted step was rejected.
    rejected_last: bool,
    /// The last rejected attempt from the current point: (step, error).
    rejection: Option<(f64, f64)>,
    /// Consecutive steps cut to a contact switch; bounded so a switch the state cannot be
    /// moved across (rounding) falls back to plain error control.
    landings: u32,
    /// Where the watch for a cavitation kink that a rejected attempt held ends (0: none).
    cavitation_watch_end: f64,
}

/// An attempted step: the controller's size before the call boundary or a switch cut it,
/// whether it ends the call, whether a switch cut it.
#[derive(Clone, Copy)]
struct Attempt {
    wanted: f64,
    last: bool,
    landing: bool,
}

impl Call {
    /// Where the step from here should end instead of `self.step` (`wanted`: the
    /// controller's size): just short of or on the next end-stop contact switch, or just
    /// past a watched cavitation kink, whichever comes first inside the step (`None`: the
    /// step stands). Updates the kink's watch. Inlined in each law's copy of the call.
    #[inline(always)]
    fn switch_ahead(
        &mut self,
        params: &CylinderParams,
        here: &Linearisation,
        wanted: f64,
    ) -> Option<f64> {
        let linear = (&here.f0, &here.jac, &here.f_t);
        let contact = next_contact_switch(params, &self.y, linear, self.step).map(|t_switch| {
            if t_switch <= 1e-3 * wanted {
                // Close: the Taylor prediction is exact to far below this margin.
                t_switch * (1.0 + 1e-6)
            } else {
                // Far: land just short; the next step, from very close, lands on it.
                t_switch * (1.0 - 1e-4)
            }
        });
        // Most kinks of the cavitation fade are crossed at no cost. One inside a rejected
        // attempt is watched until that attempt's end, and a step that reaches it ends
        // just past it: a kink (not a jump) a hair before a step's end costs nothing.
        let rejected = self.rejection.map_or(0.0, |(rejected, _)| rejected);
        let mut kink = None;
        if rejected > 0.0 || self.cavitation_watch_end > self.tau {
            let horizon = rejected.max(self.cavitation_watch_end - self.tau);
            kink = next_cavitation_switch(params, &self.y, linear, horizon);
            self.cavitation_watch_end = kink.map_or(0.0, |_| self.tau + horizon);
        }
        let kink = kink.map(|t_switch| t_switch * (1.0 + 1e-3));
        let t_land = contact.into_iter().chain(kink).reduce(f64::min)?;
        let t_land = t_land.max(1e-12 * self.h);
        (t_land < self.step).then_some(t_land)
    }

    /// Takes an accepted Rodas4 step to `y_new` (error `err`) and chooses the next step's
    /// size: the predictive controller, not after a landing on a switch. Returns whether
    /// the call is done.
    fn accept(
        &mut self,
        params: &CylinderParams,
        y_new: Vec4,
        err: f64,
        attempt: Attempt,
        memory: &mut RosenbrockMemory,
        stats: &mut Stats,
    ) -> bool {
        stats.accepted += 1;
        self.rejection = None;
        self.y = y_new;
        clamp_to_floor(params, &mut self.y, stats);
        self.tau += self.step;
        if attempt.landing {
            // A step cut short by a switch says nothing about the step size past it:
            // continue with what the controller wanted before.
            stats.landings += 1;
            self.landings += 1;
            self.step = attempt.wanted.min(self.h);
            return false;
        }
        self.landings = 0;
        let step = self.step;
        let mut factor = (fourth_root(err) / SAFETY).clamp(1.0 / MAX_FACTOR, 1.0 / MIN_FACTOR);
        // Gustafsson: also use the trend of the error between accepted steps.
        if memory.h_accepted > 0.0 {
            let predictive =
                (memory.h_accepted / step) * fourth_root(err * err / memory.err_accepted) / SAFETY;
            factor = factor.max(predictive.clamp(1.0 / MAX_FACTOR, 1.0 / MIN_FACTOR));
        }
        memory.h_accepted = step;
        memory.err_accepted = err.max(1e-2);
        let mut next = step / factor;
        if self.rejected_last {
            next = next.min(step);
        }
        self.rejected_last = false;
        if attempt.last {
            memory.h_next = if next >= step { next.max(attempt.wanted) } else { next };
            return true;
        }
        self.step = next.min(self.h);
        false
    }

    /// Shrinks the step after a rejected attempt with error `err`.
    fn reject(&mut self, err: f64, stats: &mut Stats) {
        stats.rejected += 1;
        self.rejected_last = true;
        // Order 4 is what the error should follow; where a second rejection from the
        // same point shows it falling slower (a kink inside the step), use the order seen.
        let root = match self.rejection {
            Some((h0, e0)) if e0 > err && h0 > self.step => {
                let order = ((e0 / err).ln() / (h0 / self.step).ln()).clamp(1.0, 4.0);
                err.powf(1.0 / order)
            }
            _ => fourth_root(err),
        };
        self.rejection = Some((self.step, err));
        let factor = (root / SAFETY).min(1.0 / MIN_FACTOR);
        self.step /= factor;
    }
}

/// A Rodas3 attempt at the step from `call`'s point: its state (lifted to the cavitation
/// floor) if its own error estimate passes, else `None` after backing off further attempts.
fn rodas3_step<L: PortLaw, F: Fn(f64) -> (f64, f64)>(
    model: &Rhs<'_, L, F>,
    here: &Linearisation,
    call: &Call,
    memory: &mut RosenbrockMemory,
    stats: &mut Stats,
) -> Result<Option<Vec4>, String> {
    let (mut y3, err3) = rosenbrock_step::<4, _, _>(
        &RODAS3,
        model,
        here,
        (call.tau, &call.y, call.step),
        memory.rtol,
        stats,
    )?;
    if err3 <= 1.0 {
        memory.rodas3_backoff = 0;
        stats.accepted += 1;
        stats.rodas3_accepted += 1;
        clamp_to_floor(model.params, &mut y3, stats);
        return Ok(Some(y3));
    }
    stats.rodas3_failed += 1;
    memory.rodas3_backoff = (2 * memory.rodas3_backoff).clamp(1, MAX_RODAS3_BACKOFF);
    memory.rodas3_skip = memory.rodas3_backoff;
    Ok(None)
}

/// x^(1/4) by two square roots (exact to rounding, a fraction of `powf`'s cost).
fn fourth_root(x: f64) -> f64 {
    x.sqrt().sqrt()
}

/// Consecutive steps [`advance_with_rate`] cuts to a contact switch before it gives up on it.
const MAX_LANDINGS: u32 = 4;

/// Lifts rounding-size undershoot of the cavitation floor back to it (recorded in `stats`).
fn clamp_to_floor(params: &CylinderParams, y: &mut Vec4, stats: &mut Stats) {
    for k in [PA, PB] {
        if y[k] < params.p_cavitation {
            stats.floor_clamp = stats.floor_clamp.max(params.p_cavitation - y[k]);
            y[k] = params.p_cavitation;
        }
    }
}

/// The right-hand side over one call: parameters, inputs and the spool path, the ports by
/// the law `L`.
struct Rhs<'a, L: PortLaw, S: Fn(f64) -> (f64, f64)> {
    params: &'a CylinderParams,
    p_supply: f64,
    load: f64,
    spool: &'a S,
    law: PhantomData<L>,
}

impl<L: PortLaw, S: Fn(f64) -> (f64, f64)> Rhs<'_, L, S> {
    /// `f` at `(tau, y)`. Inlined where the stages are, [`derivatives`] called out of line.
    #[inline(always)]
    fn f(&self, tau: f64, y: &Vec4, stats: &mut Stats) -> Vec4 {
        stats.function_evaluations += 1;
        derivatives::<L>(
            self.params,
            &CylinderState::from_array(y),
            (self.spool)(tau).0,
            self.p_supply,
            self.load,
        )
    }

    /// `f`, `df/dy` and `df/dt` at `(tau, y)`, analytic.
    fn linearise(&self, tau: f64, y: &Vec4, stats: &mut Stats) -> Linearisation {
        stats.function_evaluations += 1;
        stats.jacobian_evaluations += 1;
        let (x_s, rate) = (self.spool)(tau);
        let (f0, jac, f_xs) = linearise::<L>(self.params, y, x_s, self.p_supply, self.load);
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
/// Inlined at both call sites and unrolled stage by stage ([`stage`]) so that the method's
/// coefficients are constants there: the loops unroll and the terms with a zero coefficient
/// fold away. Every remaining operation is the one of the method's formulas, in the same order.
#[inline(always)]
fn rosenbrock_step<const S: usize, L: PortLaw, F: Fn(f64) -> (f64, f64)>(
    method: &Rosenbrock<S>,
    model: &Rhs<'_, L, F>,
    lin: &Linearisation,
    (tau, y, h): (f64, &Vec4, f64),
    rtol: f64,
    stats: &mut Stats,
) -> Result<(Vec4, f64), String> {
    // W = I/(h gamma) - J
    let diagonal = 1.0 / (h * method.gamma);
    let mut w = lin.jac;
    for (i, row) in w.iter_mut().enumerate() {
        for value in row.iter_mut() {
            *value = -*value;
        }
        row[i] += diagonal;
    }
    stats.factorisations += 1;
    let lu = Lu4::factor(w).ok_or_else(|| "hydraulics: singular iteration matrix".to_string())?;
    let mut st = Stages { k: [[0.0; N_STATES]; S], f: lin.f0, point: *y };
    macro_rules! stages {
        ($($i:literal)*) => { $( stage::<$i, S, L, F>(method, model, lin, &lu, (tau, y, h), &mut st, stats); )* };
    }
    const { assert!(S <= 6, "stages! below unrolls at most 6 stages") };
    stages!(0 1 2 3 4 5);
    let k = &st.k;
    // Stiffly accurate (the last row of `a` is `m` without its last entry, which is 1):
    // `y_new` is the last stage's point plus the last stage, the same sum in the same order.
    let stiffly_accurate = method.m[S - 1] == 1.0
        && method.new_f[S - 1]
        && (0..S - 1).all(|j| method.m[j] == method.a[S - 1][j]);
    let mut y_new = *y;
    let mut sum = 0.0;
    for n in 0..N_STATES {
        if stiffly_accurate {
            y_new[n] = st.point[n] + k[S - 1][n];
        } else {
            for (m, k) in method.m.iter().zip(k) {
                y_new[n] += m * k[n];
            }
        }
        let mut error = 0.0;
        for (e, k) in method.e.iter().zip(k) {
            if *e != 0.0 {
                error += e * k[n];
            }
        }
        let scale = rtol * y[n].abs().max(y_new[n].abs()).max(STATE_SCALE[n]);
        sum += (error / scale).powi(2);
    }
    let err = (sum / N_STATES as f64).sqrt();
    // A non-finite stage is an error estimate of infinity: the step is rejected and shrunk
    // (the stages the estimate leaves out all enter `y_new`).
    let finite = err.is_finite() && y_new.iter().all(|v| v.is_finite());
    Ok((y_new, if finite { err } else { f64::INFINITY }))
}

/// The stages of one Rosenbrock step so far: `k_i`, and the latest model evaluation and
/// the point it was taken at.
struct Stages<const S: usize> {
    k: [Vec4; S],
    f: Vec4,
    point: Vec4,
}

/// Stage `I` of `method` (nothing if it has fewer stages): its point and model evaluation
/// if it has one, its right-hand side, and `k_I`. `I` is a constant, so the sums over the
/// earlier stages unroll.
#[inline(always)]
#[allow(clippy::needless_range_loop)]
fn stage<const I: usize, const S: usize, L: PortLaw, F: Fn(f64) -> (f64, f64)>(
    method: &Rosenbrock<S>,
    model: &Rhs<'_, L, F>,
    lin: &Linearisation,
    lu: &Lu4,
    (tau, y, h): (f64, &Vec4, f64),
    st: &mut Stages<S>,
    stats: &mut Stats,
) {
    if I >= S {
        return;
    }
    if I > 0 && method.new_f[I] {
        st.point = *y;
        for j in 0..I {
            for n in 0..N_STATES {
                st.point[n] += method.a[I][j] * st.k[j][n];
            }
        }
        st.f = model.f(tau + method.nodes[I] * h, &st.point, stats);
    }
    let mut rhs = st.f;
    if method.d[I] != 0.0 {
        let hd = h * method.d[I];
        for n in 0..N_STATES {
            rhs[n] += hd * lin.f_t[n];
        }
    }
    for j in 0..I {
        let c = method.c[I][j] / h;
        for n in 0..N_STATES {
            rhs[n] += c * st.k[j][n];
        }
    }
    st.k[I] = lu.solve(rhs);
}

#[cfg(test)]
#[path = "rosenbrock_tests.rs"]
pub(crate) mod tests;
