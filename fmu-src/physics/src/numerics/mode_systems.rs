//! The mode systems of driver, coil and valve ([`ModeSystem`]: dynamics and exit guards),
//! their exact propagators ([`PropagatorCache`]) and the location of their state events
//! ([`locate_event`]): what [`crate::integrators::exact::exact_integrator`] drives over a segment.
//!
//! Between communication points the inputs are constant and, within one driver *mode*
//! (linear, at a rail, slewing, ...), the whole system is linear and time-invariant:
//! `z' = A_mode z` on an augmented state `z` that carries the constant inputs too. Its
//! exact solution is `z(t) = exp(A t) z(0)`, so we propagate with matrix exponentials:
//! no stability limit (the driver loop's 20 us pole costs nothing), no truncation error,
//! the same result at any communication step. Mode changes happen where a linear *guard*
//! `c . z` crosses zero (the output reaches a rail, leaves it, the error changes sign,
//! the slew limit binds); they are located to machine precision on the exact trajectory
//! (a Taylor polynomial of the guard inside a short window, then safeguarded Newton).
//! The cost of a step without events is one 9x9 matrix-vector product per sub-step, with
//! propagators cached per (mode, sub-step); no heap allocation while stepping.
//!
//! The H-bridge driver adds *time events* on an absolute clock (PWM edges, samples of its
//! digital PI loop, see [`crate::components::hbridge`]); the step is cut at each, so switching instants are
//! exact and do not depend on the communication step.

use crate::components::coefficients::Coefficients;
use crate::components::valve::{self, Stops};
use crate::numerics::augmented_exp::exp_augmented;
use crate::numerics::augmented_state::{
    ceil_count, dot, propagate, rate, rate_of_derivative, Mat, Vector, U, VF, XS,
};
use crate::readable::readable;

/// Coarse sub-steps keep |lambda|*h below this; guards are checked at their ends.
const THETA_COARSE: f64 = 6.0;
/// Largest |A h|_1 handed to the exponential (see `PropagatorCache::get`).
const MAX_SCALED_NORM: f64 = 1e25;
/// Sub-steps per propagation at most (a 1e6 s step stays well under a second).
const MAX_SUBSTEPS: usize = 1 << 14;
/// Driver guards (4) + flapper stop guards (2) + spool stop guards (2).
pub(crate) const MAX_GUARDS: usize = 8;
const CACHE_SLOTS: usize = 32;

/// One number per guard.
type PerGuard = [f64; MAX_GUARDS];

/// The linear system of one mode: dynamics, exit guards (leave when `guard . z > 0`),
/// and the sub-step lengths that keep |lambda|*h bounded.
#[derive(Clone, Copy)]
pub(crate) struct ModeSystem {
    pub(crate) a: Mat,
    guards: [Vector; MAX_GUARDS],
    /// d(guard)/dt = (A^T guard) . z
    guard_rates: [Vector; MAX_GUARDS],
    /// How many Taylor coefficients of each guard along a trajectory can be nonzero
    /// ([`nonzero_terms`]).
    guard_terms: [usize; MAX_GUARDS],
    /// Bit g: guard g is no line or parabola in time (more than [`CLOSED_FORM_TERMS`]).
    beyond_closed_form: u8,
    pub(crate) n_guards: usize,
    /// Spectral radius of `a` (1/s).
    pub(crate) radius: f64,
    /// Rows of `A` and `A^2` that give the spool's velocity and acceleration from `z`.
    spool_rows: [Vector; 2],
    /// `(-A)^k e_U / k!` ([`super::slew_end`]); [`ModeSystem::with_stops`] keeps the free
    /// system's (unused with travel stops).
    pub(crate) back: [Vector; BACK_TERMS],
}

/// Terms of [`ModeSystem::back`]: they cover slews up to about 0.07 / |lambda| (1.4 us in
/// the paper's linear mode; longer ones go the usual way).
pub(crate) const BACK_TERMS: usize = 10;

/// `(-A)^k e_U / k!` for `k < BACK_TERMS`: the series of [`slew_end::pulled_back`](super::slew_end::pulled_back), per mode.
pub(crate) fn back_series(a: &Mat) -> [Vector; BACK_TERMS] {
    let mut series = [Vector::zeros(); BACK_TERMS];
    series[0][U] = 1.0;
    for k in 1..BACK_TERMS {
        series[k] = -(a * series[k - 1]) * RECIPROCALS[k];
    }
    series
}

/// The rows of `a` and `a^2` for the spool: its velocity and acceleration at any state in
/// two dot products (the cylinder reads them at both ends of every piece).
fn spool_rows(a: &Mat) -> [Vector; 2] {
    let velocity = a.row(XS).transpose();
    [velocity, a.transpose() * velocity]
}

/// Powers of `A^T` looked at by [`nonzero_terms`].
const SHORT_GUARD: usize = 4;

/// How many Taylor coefficients of `guard . z(t)` can be nonzero: the first `k` >= 1 with
/// `(A^T)^k guard` exactly zero, up to [`SHORT_GUARD`] (a rail guard while slewing is a
/// straight line: 2), else all of them. The event search computes no more. `rate` is
/// `A^T guard`, the guard's rate row.
fn nonzero_terms(a: &Mat, rate: Vector) -> usize {
    std::iter::successors(Some(rate), |row| Some(a.transpose() * row))
        .take(SHORT_GUARD)
        .position(|row| row.iter().all(|&x| x == 0.0))
        .map_or(TAYLOR_TERMS, |k| k + 1)
}

impl ModeSystem {
    /// The system `z' = a z` with exit guards `guards`.
    pub(crate) fn new(a: Mat, guards: &[Vector]) -> ModeSystem {
        let radius = spectral_radius(&a);
        let mut sys = ModeSystem {
            a,
            guards: [Vector::zeros(); MAX_GUARDS],
            guard_rates: [Vector::zeros(); MAX_GUARDS],
            guard_terms: [TAYLOR_TERMS; MAX_GUARDS],
            beyond_closed_form: 0,
            n_guards: 0,
            radius,
            spool_rows: spool_rows(&a),
            back: back_series(&a),
        };
        for &g in guards {
            sys.push_guard(g);
        }
        sys
    }

    fn push_guard(&mut self, guard: Vector) {
        let rate = self.a.transpose() * guard;
        self.guards[self.n_guards] = guard;
        self.guard_rates[self.n_guards] = rate;
        self.guard_terms[self.n_guards] = nonzero_terms(&self.a, rate);
        if self.guard_terms[self.n_guards] > CLOSED_FORM_TERMS {
            self.beyond_closed_form |= 1 << self.n_guards;
        }
        self.n_guards += 1;
    }

    /// Whether every guard not in `passed_guards` is a line or a parabola in time, so that its
    /// crossing is found in closed form ([`locate_closed_form`]).
    pub(crate) fn closed_form_search(&self, passed_guards: u8) -> bool {
        self.beyond_closed_form & !passed_guards == 0
    }

    /// Guard `g`'s value at `z`.
    pub(crate) fn guard_value(&self, g: usize, z: &Vector) -> f64 {
        dot(&self.guards[g], z)
    }

    /// The size of guard `g`'s terms at `z` (`sum |guard_i z_i|`): its rounding is a few ulp of it.
    fn guard_scale(&self, g: usize, z: &Vector) -> f64 {
        self.guards[g].iter().zip(z.iter()).map(|(a, b)| (a * b).abs()).sum()
    }

    /// Guard `g`'s rate of change at `z`.
    fn guard_rate(&self, g: usize, z: &Vector) -> f64 {
        dot(&self.guard_rates[g], z)
    }

    /// This driver mode with the valve's travel stops: a part at a stop is held there
    /// (inelastic), a free part gets guards for reaching its stops. No allocation.
    pub(crate) fn with_stops(&self, c: &Coefficients, stops: Stops) -> ModeSystem {
        if !valve::has_stops(c) {
            return *self;
        }
        let mut sys = *self;
        let flapper_accel = self.a.row(VF).transpose();
        valve::hold_at_stops(stops, &mut sys.a);
        sys.spool_rows = spool_rows(&sys.a);
        // The free system's spectral radius bounds the held one's well enough for sub-steps.
        sys.n_guards = 0;
        sys.beyond_closed_form = 0;
        for k in 0..self.n_guards {
            sys.push_guard(self.guards[k]);
        }
        valve::stop_guards(c, stops, flapper_accel, |g| sys.push_guard(g));
        sys
    }

    /// The spool's position, velocity and acceleration at `z`.
    pub(crate) fn spool_motion(&self, z: &Vector) -> [f64; 3] {
        [z[XS], dot(&self.spool_rows[0], z), dot(&self.spool_rows[1], z)]
    }

    /// Sub-steps keeping |lambda|*h below `theta`; capped so that a huge step stays bounded
    /// in time (the propagation itself is exact at any length, only event search coarsens).
    pub(crate) fn substeps(&self, span: f64, theta: f64) -> usize {
        ceil_count(span * self.radius / theta).clamp(1, MAX_SUBSTEPS)
    }
}

/// Mantissa bits of a sub-step that select its cached propagator; the rest of the
/// sub-step (below `2^-KEY_BITS` of it) is propagated by a short Taylor series.
const KEY_BITS: u32 = 8;
/// Spans with |lambda| span below this go by Taylor series alone (a handful of terms,
/// cheaper than a matrix exponential of a span that will not come again).
const TAYLOR_ONLY: f64 = 0.05;

/// `h` with all but the top [`KEY_BITS`] bits of its mantissa cleared (`h >= 0`).
fn key_span(h: f64) -> f64 {
    f64::from_bits(h.to_bits() & !((1u64 << (52 - KEY_BITS)) - 1))
}

/// How a span is cut into equal sub-steps of `h`, and how one sub-step propagates:
/// `z(h) = taylor(rest) exp(A key) z` with `h = key + rest` (no matrix: Taylor series alone).
/// The split depends on the span only, never on what the cache holds, so a propagation
/// gives the same bits whether its matrix was cached or not (restored states continue bit
/// for bit).
pub(crate) struct Propagator<'a> {
    pub(crate) substeps: usize,
    pub(crate) h: f64,
    matrix: Option<&'a Mat>,
    rest: f64,
}

impl Propagator<'_> {
    /// Sub-steps by Taylor series alone (the H-bridge's switched spans: short and
    /// irregular, where a series beats exp()), at least `min_substeps`. A span longer than
    /// the series covers in [`MAX_SUBSTEPS`] pieces of its own (an absurdly slow PWM) stays
    /// one sub-step, or the work would grow without bound.
    pub(crate) fn taylor_only(sys: &ModeSystem, span: f64, min_substeps: usize) -> Self {
        let substeps = if sys.substeps(span, 1.0) < MAX_SUBSTEPS {
            min_substeps.clamp(1, MAX_SUBSTEPS)
        } else {
            1
        };
        Propagator { substeps, h: span / substeps as f64, matrix: None, rest: 0.0 }
    }

    /// One sub-step from `z`.
    pub(crate) fn apply(&self, sys: &ModeSystem, z: &Vector) -> Vector {
        match self.matrix {
            Some(matrix) if self.rest > 0.0 => {
                taylor_propagate(sys, &propagate(matrix, z), self.rest)
            }
            Some(matrix) => propagate(matrix, z),
            None => taylor_propagate(sys, z, self.h),
        }
    }

    /// From `z` over all its sub-steps.
    pub(crate) fn apply_all(&self, sys: &ModeSystem, z: &Vector) -> Vector {
        (0..self.substeps).fold(*z, |z, _| self.apply(sys, &z))
    }

    /// Whether a sub-step goes through a cached matrix (the fixed-point shortcut needs one).
    pub(crate) fn has_matrix(&self) -> bool {
        self.matrix.is_some()
    }
}

/// Recently used sub-step propagators exp(A key), keyed by system and the key span's bits.
#[derive(Clone, Copy)]
pub(crate) struct PropagatorCache {
    keys: [(usize, u64); CACHE_SLOTS],
    values: [Mat; CACHE_SLOTS],
    next: usize,
    /// Matrix exponentials computed so far (a work counter).
    pub(crate) exponentials: u64,
}

impl PropagatorCache {
    pub(crate) fn new() -> Self {
        PropagatorCache {
            keys: [(usize::MAX, 0); CACHE_SLOTS],
            values: [Mat::zeros(); CACHE_SLOTS],
            next: 0,
            exponentials: 0,
        }
    }

    /// Forgets every propagator (the systems they were built for changed); the count of
    /// exponentials stays.
    pub(crate) fn clear(&mut self) {
        self.keys = [(usize::MAX, 0); CACHE_SLOTS];
        self.next = 0;
    }

    /// `system` names the (mode, stops) pair of `sys`. `exact`: key the sub-step by all
    /// its bits (whole communication steps: they repeat exactly, and a settled state then
    /// maps onto itself bit for bit, which lets `evolve` skip it). At least `min_substeps`
    /// sub-steps (as far as [`MAX_SUBSTEPS`]).
    pub(crate) fn get(
        &mut self,
        system: usize,
        sys: &ModeSystem,
        span: f64,
        exact: bool,
        min_substeps: usize,
    ) -> Result<Propagator<'_>, String> {
        let substeps = sys.substeps(span, THETA_COARSE).max(min_substeps.min(MAX_SUBSTEPS));
        let h = span / substeps as f64;
        if h * sys.radius <= TAYLOR_ONLY {
            return Ok(Propagator { substeps, h, matrix: None, rest: 0.0 });
        }
        let key_h = if exact { h } else { key_span(h) };
        let key = (system, key_h.to_bits());
        let slot = match self.keys.iter().position(|&k| k == key) {
            Some(slot) => slot,
            None => {
                let propagator = checked_exponential(&sys.a, key_h, h)?;
                let slot = self.next;
                self.keys[slot] = key;
                self.values[slot] = propagator;
                self.exponentials += 1;
                self.next = (slot + 1) % CACHE_SLOTS;
                slot
            }
        };
        Ok(Propagator { substeps, h, matrix: Some(&self.values[slot]), rest: h - key_h })
    }
}

/// `exp(A span)`, refused (naming `step`, the step it serves) where `A span` is beyond
/// exact propagation: the squarings grow with log2 of its norm, and past ~1e30 the powers'
/// norms overflow. Physical cases stay decades below [`MAX_SCALED_NORM`] (a 1e20 s step
/// gives ~3e23).
pub(crate) fn checked_exponential(a: &Mat, span: f64, step: f64) -> Result<Mat, String> {
    let scaled = a * span;
    let norm =
        scaled.column_iter().map(|c| c.iter().map(|x| x.abs()).sum::<f64>()).fold(0.0, f64::max);
    if norm.is_nan() || norm > MAX_SCALED_NORM {
        return Err(format!(
            "a sub-step of {} s with these parameters is beyond exact propagation (|A h| = {}); \
             step refused",
            readable(step),
            readable(norm)
        ));
    }
    exp_augmented(&scaled).ok_or_else(|| {
        format!(
            "a sub-step of {} s with these parameters has no exact propagator (|A h| = {}); step \
             refused",
            readable(step),
            readable(norm)
        )
    })
}

/// exp(A t) z by its Taylor series, in pieces with |lambda| h <= 1, each summed until
/// (|lambda| h)^k / k! is below rounding.
pub(crate) fn taylor_propagate(sys: &ModeSystem, z0: &Vector, span: f64) -> Vector {
    let pieces = sys.substeps(span, 1.0);
    let h = span / pieces as f64;
    let terms = taylor_terms(sys.radius * h);
    let mut z = *z0;
    for _ in 0..pieces {
        // `terms` >= 2; past the first term the constants' entries are zero.
        let mut term = rate(&sys.a, &z) * h;
        let mut sum = z + term;
        for reciprocal in &RECIPROCALS[2..terms] {
            term = rate_of_derivative(&sys.a, &term) * (h * reciprocal);
            sum += term;
        }
        z = sum;
    }
    z
}

/// Every Taylor series here is summed until the bound `(|lambda| t)^n / n!` of its first
/// neglected term is below this: rounding, with room for the bound's use of the spectral
/// radius.
pub(crate) const NEGLECTED_TERM: f64 = 1e-18;

/// Terms of the Taylor series of exp(A t) with |lambda| t = `scale` <= 1 that reach
/// rounding: the first neglected one, `scale^n / n!`, is below [`NEGLECTED_TERM`]. At least 2.
fn taylor_terms(scale: f64) -> usize {
    let mut terms = 1;
    let mut bound = 1.0;
    while terms < TAYLOR_TERMS && bound > NEGLECTED_TERM {
        bound *= scale * RECIPROCALS[terms];
        terms += 1;
    }
    terms
}

/// Largest |eigenvalue| of `a`, from a Schur decomposition with bounded iterations; a
/// matrix it cannot decompose (absurdly scaled parameters) gets its infinity norm, an
/// upper bound. Never loops unbounded.
fn spectral_radius(a: &Mat) -> f64 {
    if !a.iter().all(|x| x.is_finite()) {
        return f64::INFINITY;
    }
    match nalgebra::linalg::Schur::try_new(*a, f64::EPSILON, 500) {
        Some(schur) => schur.complex_eigenvalues().iter().map(|l| l.norm()).fold(0.0, f64::max),
        None => a.row_iter().map(|r| r.iter().map(|x| x.abs()).sum::<f64>()).fold(0.0, f64::max),
    }
}

/// Event search windows keep |lambda|*h below this, where a Taylor polynomial is exact to rounding.
const THETA_FINE: f64 = 1.0;
const TAYLOR_TERMS: usize = 24;
/// 1/k for the Taylor terms: a multiplication instead of a division, in the inner loop of
/// every series and of the event search.
pub(crate) const RECIPROCALS: [f64; TAYLOR_TERMS] = {
    let mut r = [0.0; TAYLOR_TERMS];
    let mut k = 1;
    while k < TAYLOR_TERMS {
        r[k] = 1.0 / k as f64;
        k += 1;
    }
    r
};
/// Samples of a guard polynomial per search window.
const GUARD_SAMPLES: usize = 16;

/// Could a guard (not in `passed_guards`) have turned positive between `z0` and `z1` (`h`
/// apart)? True when it goes from <= 0 to > 0, or when the tangents at both ends meet
/// above zero (a bump). `at_start`: the guards at `z0` ([`GuardsAt::new`]), whose
/// `passed_guards` ones are left out.
pub(crate) fn may_cross(sys: &ModeSystem, at_start: &GuardsAt, z1: &Vector, h: f64) -> bool {
    (0..sys.n_guards).any(|k| {
        if at_start.passed_guards & 1 << k != 0 {
            return false;
        }
        let g0 = at_start.values[k];
        if g0 > 0.0 {
            return false;
        }
        let g1 = sys.guard_value(k, z1);
        if g1 > 0.0 {
            return true;
        }
        // A bump needs a rising start steep enough to reach zero within h.
        let d0 = at_start.rates[k];
        if d0 <= 0.0 || g0 + d0 * h <= 0.0 {
            return false;
        }
        let d1 = sys.guard_rate(k, z1);
        if d1 >= 0.0 {
            return false;
        }
        let t = ((g1 - g0 - d1 * h) / (d0 - d1)).clamp(0.0, h);
        g0 + d0 * t > 0.0
    })
}

/// First instant in (0, h] where a guard (not passed) turns positive: the time, the guard
/// and the state there; `at_start` holds the guards at `z0`. In closed form where every open
/// guard is a line or a parabola in time ([`locate_closed_form`]: the slews), else searched
/// in windows short enough for a Taylor polynomial of the exact solution
/// ([`locate_sampled`]). The first window ends a few times past `predicted`, the earliest
/// crossing the guards' slopes predict ([`GuardsAt::predicted_crossing`]): a command step's
/// slewing ends within nanoseconds, and a window that short needs a few Taylor terms, not
/// two dozen.
pub(crate) fn locate_event(
    sys: &ModeSystem,
    z0: &Vector,
    h: f64,
    at_start: &GuardsAt,
    predicted: f64,
) -> Option<(f64, usize, Vector)> {
    locate_closed_form(sys, z0, h, at_start)
        .unwrap_or_else(|| locate_sampled(sys, z0, h, at_start.passed_guards, predicted))
}

/// [`locate_event`] for any guards: each guard's Taylor polynomial sampled per window.
/// Kept out of line: most events take the closed form, and this search inlined would make
/// the exact integrator's evolution too large to inline into its caller.
#[inline(never)]
fn locate_sampled(
    sys: &ModeSystem,
    z0: &Vector,
    h: f64,
    passed_guards: u8,
    predicted: f64,
) -> Option<(f64, usize, Vector)> {
    let longest = h / sys.substeps(h, THETA_FINE) as f64;
    let mut w = (PREDICTION_MARGIN * predicted).clamp(longest / 4096.0, longest);
    let mut start = *z0;
    let mut offset = 0.0;
    while offset < h {
        w = w.min(h - offset);
        let n = taylor_terms(sys.radius * w);
        // Taylor terms of z(t) = exp(A t) z: terms[k] = A^k z / k!
        let mut terms = [Vector::zeros(); TAYLOR_TERMS];
        terms[0] = start;
        // `n` >= 2; past the first term the constants' entries are zero.
        terms[1] = rate(&sys.a, &start);
        for k in 2..n {
            terms[k] = rate_of_derivative(&sys.a, &terms[k - 1]) * RECIPROCALS[k];
        }
        let terms = &terms[..n];
        let mut first: Option<(f64, usize)> = None;
        for g in (0..sys.n_guards).filter(|g| passed_guards & 1 << g == 0) {
            let mut coef = [0.0; TAYLOR_TERMS];
            coef[0] = sys.guard_value(g, &terms[0]);
            if coef[0] > 0.0 {
                continue; // passed before this window (edge triggered)
            }
            let used = n.min(sys.guard_terms[g]);
            for (c, t) in coef[1..used].iter_mut().zip(&terms[1..]) {
                *c = sys.guard_value(g, t);
            }
            if let Some(tau) = first_positive(&coef[..used], w, first.map_or(w, |f| f.0)) {
                first = Some((tau, g));
            }
        }
        if let Some((tau, g)) = first {
            let (tau, at) = past_crossing(sys, g, terms, tau, (w, w));
            return Some((offset + tau, g, at));
        }
        start = horner_vec(terms, w);
        offset += w;
        w = longest;
    }
    None
}

/// The state at a crossing `tau` of guard `g` inside a window `w` whose Taylor terms are
/// `terms`, and the instant: the state handed on must be past the crossing as the mode
/// logic evaluates it (on the vector, not the polynomial), or the mode may not change and
/// the guard would be passed over. So it is nudged forward past the rounding: by 64 ulp of
/// the window (from the crossing itself, the state often still reads the guard on the near
/// side, and each retry costs an evaluation of the state), or by the time the guard takes
/// to rise through its own rounding where that is longer (a slew of nanoseconds whose guard
/// has terms of hundreds of volts rises through its rounding only after many doublings of
/// 64 ulp).
fn past_crossing(
    sys: &ModeSystem,
    g: usize,
    terms: &[Vector],
    tau: f64,
    (w, end): (f64, f64),
) -> (f64, Vector) {
    let mut nudge = 64.0 * f64::EPSILON * w;
    let mut tau = (tau + nudge).min(end);
    let mut at = horner_vec(terms, tau);
    if sys.guard_value(g, &at) <= 0.0 && tau < end {
        let rate = sys.guard_rate(g, &at);
        if rate > 0.0 {
            nudge = nudge.max(4.0 * f64::EPSILON * sys.guard_scale(g, &at) / rate);
        }
        while sys.guard_value(g, &at) <= 0.0 && tau < end {
            tau = (tau + nudge).min(end);
            at = horner_vec(terms, tau);
            nudge *= 2.0;
        }
    }
    (tau, at)
}

/// The closed form hands on the state from one Taylor window of at most this |lambda| w
/// (a slew of microseconds); [`CLOSED_FORM_WINDOW_TERMS`] terms cover it.
const CLOSED_FORM_WINDOW: f64 = 0.1;
const CLOSED_FORM_WINDOW_TERMS: usize = 12;

/// Guards with at most this many Taylor coefficients along the trajectory (a line or a
/// parabola: the slew's ends with the paper's tuning) have their crossings in closed form.
const CLOSED_FORM_TERMS: usize = 3;

/// [`locate_event`] where every guard (not in `passed_guards`) is a line or a parabola in time:
/// each crossing in closed form over the whole of `h`, then the state there from the Taylor
/// polynomial of the trajectory up to just past it, without the sampling and refining of
/// the polynomials that the sampled search needs. `None` where this does not apply (other
/// guards, or a crossing too far for one Taylor window): the sampled search decides.
fn locate_closed_form(
    sys: &ModeSystem,
    z0: &Vector,
    h: f64,
    at_start: &GuardsAt,
) -> Option<Option<(f64, usize, Vector)>> {
    if !sys.closed_form_search(at_start.passed_guards) {
        return None;
    }
    let open = || (0..sys.n_guards).filter(|g| at_start.passed_guards & 1 << g == 0);
    let mut terms = [Vector::zeros(); CLOSED_FORM_WINDOW_TERMS];
    terms[0] = *z0;
    terms[1] = rate(&sys.a, z0);
    terms[2] = rate_of_derivative(&sys.a, &terms[1]) * RECIPROCALS[2];
    let mut first: Option<(f64, usize)> = None;
    for g in open() {
        // The guard's value and rate at the start are `guard . z0` and `guard . A z0`.
        let (c0, c1) = (at_start.values[g], at_start.rates[g]);
        if c0 > 0.0 {
            continue; // passed before (edge triggered)
        }
        let c2 = if sys.guard_terms[g] > 2 { sys.guard_value(g, &terms[2]) } else { 0.0 };
        let limit = first.map_or(h, |f| f.0);
        if let Some(tau) = first_positive_quadratic([c0, c1, c2], limit) {
            first = Some((tau, g));
        }
    }
    let Some((tau, g)) = first else {
        return Some(None);
    };
    // Nudged as in a window of PREDICTION_MARGIN times the crossing's time, the polynomial
    // only taken a sixteenth past it: the nudges are 1e-14 of that, and it needs a term less.
    let w = (PREDICTION_MARGIN * tau).clamp(f64::EPSILON * h, h);
    let end = (tau + tau / 16.0).clamp(f64::EPSILON * h, h);
    if sys.radius * end > CLOSED_FORM_WINDOW {
        return None;
    }
    let n = taylor_terms(sys.radius * end);
    for k in 3..n {
        terms[k] = rate_of_derivative(&sys.a, &terms[k - 1]) * RECIPROCALS[k];
    }
    let (tau, at) = past_crossing(sys, g, &terms[..n.max(3)], tau, (w, end));
    Some(Some((tau, g, at)))
}

/// First `t` in `[0, limit]` where `c0 + c1 t + c2 t^2` (`c0 <= 0`) turns positive, within
/// rounding of the root (the caller steps past it).
fn first_positive_quadratic([c0, c1, c2]: [f64; 3], limit: f64) -> Option<f64> {
    let root = if c0 == 0.0 {
        // Rising at once, or after a dip to the other root `-c1/c2`.
        if c1 > 0.0 || (c1 == 0.0 && c2 > 0.0) {
            Some(0.0)
        } else if c2 > 0.0 {
            Some(-c1 / c2)
        } else {
            None
        }
    } else if c2 == 0.0 {
        (c1 > 0.0).then(|| -c0 / c1)
    } else {
        let discriminant = c1 * c1 - 4.0 * c2 * c0;
        if discriminant.is_nan() || discriminant < 0.0 {
            return None;
        }
        // The roots without cancellation: q / c2 and c0 / q (q != 0 as c0 != 0).
        let q = -0.5 * (c1 + discriminant.sqrt().copysign(c1));
        let (r1, r2) = (q / c2, c0 / q);
        if c2 > 0.0 {
            // Opening upwards from c0 < 0: the roots straddle zero, the crossing is the later.
            Some(r1.max(r2))
        } else if c1 > 0.0 {
            // Opening downwards: above zero between two positive roots.
            Some(r1.min(r2))
        } else {
            None
        }
    };
    root.filter(|&t| t >= 0.0 && t <= limit)
}

/// The guards' values and rates at the start of a sub-step, shared by the crossing's
/// prediction and the check after the sub-step. Guards in `passed_guards` are not evaluated.
pub(crate) struct GuardsAt {
    values: PerGuard,
    rates: PerGuard,
    passed_guards: u8,
    /// See [`GuardsAt::predicted_crossing`]: found in the loop that evaluates the guards.
    predicted: f64,
}

impl GuardsAt {
    pub(crate) fn new(sys: &ModeSystem, z: &Vector, passed_guards: u8) -> GuardsAt {
        let mut at = GuardsAt {
            values: [0.0; MAX_GUARDS],
            rates: [0.0; MAX_GUARDS],
            passed_guards,
            predicted: f64::INFINITY,
        };
        for g in (0..sys.n_guards).filter(|g| passed_guards & 1 << g == 0) {
            let value = sys.guard_value(g, z);
            at.values[g] = value;
            // A guard above zero has been passed: its rate matters to no one.
            if value <= 0.0 {
                let rate = sys.guard_rate(g, z);
                at.rates[g] = rate;
                if rate > 0.0 {
                    at.predicted = at.predicted.min(-value / rate);
                }
            }
        }
        at
    }

    /// The earliest time at which a guard (not in `passed_guards`) reaches zero if it kept its
    /// present slope; infinite if none is rising towards zero.
    pub(crate) fn predicted_crossing(&self) -> f64 {
        self.predicted
    }

    /// Whether a guard whose slope reaches zero within `h` (the predicted crossing is before
    /// `h`) still does with its curvature at `z` (its Taylor parabola up to `h`). A guard
    /// rising fast but bending away (the linear mode's output nearing its value after a
    /// slew, the rail far off) does not: the sub-step then goes the usual way (propagated,
    /// then [`may_cross`]) instead of a search. Out of line: only the sub-steps with a
    /// predicted crossing whose guards are not all searched in closed form ask (lines and
    /// parabolas, the slews': cheaper to search).
    #[inline(never)]
    pub(crate) fn crossing_imminent(&self, sys: &ModeSystem, z: &Vector, h: f64) -> bool {
        let open = || (0..sys.n_guards).filter(|g| self.passed_guards & 1 << g == 0);
        let acceleration = rate_of_derivative(&sys.a, &rate(&sys.a, z));
        open().any(|g| {
            let (value, slope) = (self.values[g], self.rates[g]);
            if value > 0.0 || slope <= 0.0 || -value / slope >= h {
                return false;
            }
            let half_curvature = 0.5 * sys.guard_value(g, &acceleration);
            let peak =
                if half_curvature < 0.0 { (-slope / (2.0 * half_curvature)).min(h) } else { h };
            value + peak * (slope + peak * half_curvature) > 0.0
        })
    }
}

/// The first search window ends this many times past the earliest predicted crossing.
const PREDICTION_MARGIN: f64 = 4.0;

fn horner(coef: &[f64], t: f64) -> f64 {
    coef.iter().rev().fold(0.0, |acc, c| acc * t + c)
}

fn horner_vec(terms: &[Vector], t: f64) -> Vector {
    terms.iter().rev().fold(Vector::zeros(), |acc, c| acc * t + c)
}

/// First t in (0, limit] where the polynomial turns positive: sampled, then the crossing
/// inside the first sample interval that changes sign is refined to rounding.
fn first_positive(coef: &[f64], w: f64, limit: f64) -> Option<f64> {
    // A guard that cannot climb to zero by `limit` even with every term pushing up (the
    // other exit guards of a mode, far from their thresholds) needs no samples.
    let reach = limit.min(w);
    let rise = coef[1..].iter().rev().fold(0.0, |acc, c| (acc + c.abs()) * reach);
    if coef[0] + rise < 0.0 {
        return None;
    }
    let mut lo = (0.0, coef[0]);
    for s in 1..=GUARD_SAMPLES {
        let t = (w * s as f64 / GUARD_SAMPLES as f64).min(limit);
        let p_t = horner(coef, t);
        if p_t > 0.0 {
            return Some(refine_crossing(coef, lo, (t, p_t)));
        }
        lo = (t, p_t);
        if t >= limit {
            break;
        }
    }
    None
}

/// The crossing of a polynomial inside `[lo, hi]` (p(lo) <= 0 < p(hi)), as the earliest
/// instant found where p > 0, within a few roundings of the root. Safeguarded Newton from
/// the secant point: a guard is nearly linear across one sample interval, so two or three
/// iterations reach rounding (bisection to adjacent numbers took ~40 evaluations). Unlike
/// `root_finding::newton_in_bracket` it also stops once Newton's step is below rounding,
/// where the bracket may still be wide on one side, and then steps just past the root.
fn refine_crossing(coef: &[f64], (mut lo, p_lo): (f64, f64), (mut hi, p_hi): (f64, f64)) -> f64 {
    let mut t = lo + (hi - lo) * (p_lo / (p_lo - p_hi));
    for _ in 0..REFINE_ITERATIONS {
        if !(t > lo && t < hi) {
            t = 0.5 * (lo + hi);
        }
        let (p, slope) = horner_with_slope(coef, t);
        if p > 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        let next = if slope > 0.0 { t - p / slope } else { 0.5 * (lo + hi) };
        if hi - lo <= 4.0 * f64::EPSILON * hi || (next - t).abs() <= 2.0 * f64::EPSILON * t {
            break;
        }
        t = next;
    }
    if t == hi {
        return hi;
    }
    // The last iterate is at or below zero, within rounding of the root: step past it.
    let mut nudge = f64::EPSILON * hi;
    while lo + nudge < hi {
        if horner(coef, lo + nudge) > 0.0 {
            return lo + nudge;
        }
        nudge *= 2.0;
    }
    hi
}

/// Newton iterations at most before the crossing's bracket is taken as it is.
const REFINE_ITERATIONS: usize = 12;

/// The polynomial and its derivative at `t` (one Horner pass).
fn horner_with_slope(coef: &[f64], t: f64) -> (f64, f64) {
    coef.iter().rev().fold((0.0, 0.0), |(p, dp), c| (p * t + c, dp * t + p))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actuator::mode_system;
    use crate::components::driver::Mode;
    use crate::components::driver::MODES;
    use crate::numerics::augmented_state::{RAIL, U};

    #[test]
    fn a_line_or_parabola_crosses_where_its_roots_say() {
        let cross = |c: [f64; 3]| first_positive_quadratic(c, 10.0);
        assert_eq!(cross([-2.0, 1.0, 0.0]), Some(2.0), "a rising line");
        assert_eq!(cross([-2.0, -1.0, 0.0]), None, "a falling line");
        assert_eq!(cross([-6.0, 1.0, 1.0]), Some(2.0), "upwards: the later root (-3 and 2)");
        assert_eq!(cross([-3.0, 4.0, -1.0]), Some(1.0), "downwards: the earlier of 1 and 3");
        assert_eq!(cross([-3.0, -4.0, -1.0]), None, "downwards, roots -1 and -3");
        assert_eq!(cross([-1.0, 1.0, -1.0]), None, "downwards, never reaching zero");
        assert_eq!(cross([0.0, 1.0, -1.0]), Some(0.0), "on zero and rising");
        assert_eq!(cross([0.0, -1.0, 1.0]), Some(1.0), "on zero, dipping first");
        assert_eq!(cross([0.0, -1.0, -1.0]), None);
        assert_eq!(cross([-200.0, 1.0, 0.0]), None, "beyond the limit");
        // No cancellation where c2 t^2 is tiny against c1 t (the slew's end: a near line).
        let root = cross([-1e-7, 2e7, 1e3]).unwrap();
        assert!((root - 5e-15).abs() <= 4.0 * f64::EPSILON * 5e-15, "{root:e}");
    }

    /// The crossings in closed form are those the sampled search finds, to rounding, and
    /// so are the states there: slews up and down of various lengths, towards the PI law's
    /// value or a rail.
    #[test]
    fn closed_form_crossings_match_the_sampled_search() {
        assert!(taylor_terms(CLOSED_FORM_WINDOW) <= CLOSED_FORM_WINDOW_TERMS);
        let c = Coefficients::new(&crate::params::Params::PAPER).unwrap();
        let mut searched = 0;
        for mode in [Mode::SlewUp, Mode::SlewDown] {
            let sys = mode_system(&c, mode);
            let sign = if mode == Mode::SlewUp { 1.0 } else { -1.0 };
            for (u0, i_ref) in [(0.0, 1e-6), (0.0, 5e-3), (-60.0, 1e-3), (65.0, -3e-4), (0.0, 1e-3)]
            {
                let mut z =
                    Vector::from_fn(|k, _| [0.0, 0.0, 0.0, 1e-6, 0.0, 2e-5, 0.0, 72.0, 1.0][k]);
                z[U] = sign * u0;
                z[crate::numerics::augmented_state::I_CMD] = sign * i_ref;
                let h = 5e-5;
                let at_start = GuardsAt::new(&sys, &z, 0);
                // A slew of microseconds (to a rail) goes to the sampled search.
                let Some(closed) = locate_closed_form(&sys, &z, h, &at_start) else {
                    continue;
                };
                let predicted = at_start.predicted_crossing();
                let sampled = locate_sampled(&sys, &z, h, 0, predicted);
                match (closed, sampled) {
                    (Some((t1, g1, z1)), Some((t2, g2, z2))) => {
                        searched += 1;
                        assert_eq!(g1, g2, "{mode:?} {u0} {i_ref}");
                        assert!(
                            (t1 - t2).abs() <= 1e-12 * t2,
                            "{mode:?} {u0} {i_ref}: {t1:e} {t2:e}"
                        );
                        let scale = z1.amax();
                        assert!((z1 - z2).amax() <= 1e-12 * scale, "{mode:?} {u0} {i_ref}");
                    }
                    (None, None) => {}
                    other => panic!("{mode:?} {u0} {i_ref}: {other:?}"),
                }
            }
        }
        assert!(searched >= 6, "most of these slews are in closed form: {searched}");
    }

    /// The Taylor coefficients that the event search leaves out are zero along an exact
    /// trajectory. While slewing the output moves at the slew rate exactly, so its distance
    /// to either rail is a straight line (2 coefficients); with the paper's tuning the PI
    /// zero sits on the coil's pole (Ki = Kp R / L) and the slew's end is a parabola (3);
    /// detuned, it takes all of them.
    #[test]
    fn guards_the_search_shortens_are_polynomials_along_the_trajectory() {
        let tuned = crate::params::Params::PAPER;
        let mut detuned = tuned;
        detuned.opamp.ki *= 1.5;
        let z = Vector::from_fn(|k, _| [2e-3, 1.5, 3.0, 1e-6, 1e-3, 2e-5, 5e-3, 72.0, 1.0][k]);
        let t = 2e-4;
        for (params, slew_end_terms) in [(tuned, 3), (detuned, TAYLOR_TERMS)] {
            let c = Coefficients::new(&params).unwrap();
            for mode in MODES {
                let sys = mode_system(&c, mode);
                let end = (sys.a * t).exp() * z;
                for g in (0..sys.n_guards).filter(|&g| sys.guard_terms[g] < TAYLOR_TERMS) {
                    // guard . z(t) from the coefficients the search takes.
                    let (mut row, mut power) = (sys.guards[g], 1.0);
                    let (mut polynomial, mut scale) = (0.0, 0.0);
                    for k in 0..sys.guard_terms[g] {
                        polynomial += dot(&row, &z) * power;
                        scale += (dot(&row, &z) * power).abs();
                        row = sys.a.transpose() * row;
                        power *= t / (k + 1) as f64;
                    }
                    let exact = sys.guard_value(g, &end);
                    assert!((exact - polynomial).abs() <= 1e-12 * scale, "{mode:?} guard {g}");
                }
            }
            for mode in [Mode::SlewUp, Mode::SlewDown] {
                let sys = mode_system(&c, mode);
                for g in 0..sys.n_guards {
                    let rail = sys.guards[g][U].abs() == 1.0 && sys.guards[g][RAIL].abs() == 1.0;
                    let expected = if rail { 2 } else { slew_end_terms };
                    assert_eq!(sys.guard_terms[g], expected, "{mode:?} guard {g}");
                }
            }
        }
    }
}
