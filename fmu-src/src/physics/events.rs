//! Locating state events: where a linear guard `c . z(t)` on the exact trajectory
//! `z(t) = exp(A t) z0` turns positive.

use super::{ModeSystem, Vector};

/// Event search windows keep |lambda|*h below this, where a Taylor polynomial is exact to rounding.
const THETA_FINE: f64 = 1.0;
pub(super) const TAYLOR_TERMS: usize = 24;
/// Samples of a guard polynomial per search window.
const GUARD_SAMPLES: usize = 16;

/// Could a guard (not in `passed`) have turned positive between `z0` and `z1` (`h`
/// apart)? True when it goes from <= 0 to > 0, or when the tangents at both ends meet
/// above zero (a bump).
pub(super) fn may_cross(sys: &ModeSystem, z0: &Vector, z1: &Vector, h: f64, passed: u8) -> bool {
    (0..sys.n_guards).any(|k| {
        if passed & 1 << k != 0 {
            return false;
        }
        let g0 = sys.guards[k].dot(z0);
        if g0 > 0.0 {
            return false;
        }
        if sys.guards[k].dot(z1) > 0.0 {
            return true;
        }
        // A bump needs a rising start steep enough to reach zero within h.
        let d0 = sys.guard_rates[k].dot(z0);
        if d0 <= 0.0 || g0 + d0 * h <= 0.0 {
            return false;
        }
        let d1 = sys.guard_rates[k].dot(z1);
        if d1 >= 0.0 {
            return false;
        }
        let g1 = sys.guards[k].dot(z1);
        let t = ((g1 - g0 - d1 * h) / (d0 - d1)).clamp(0.0, h);
        g0 + d0 * t > 0.0
    })
}

/// First instant in (0, h] where a guard (not in `passed`) turns positive: the time, the
/// guard and the state there. Searched in windows short enough for a Taylor polynomial
/// of the exact solution.
pub(super) fn locate_event(
    sys: &ModeSystem,
    z0: &Vector,
    h: f64,
    passed: u8,
) -> Option<(f64, usize, Vector)> {
    let windows = sys.substeps(h, THETA_FINE);
    let w = h / windows as f64;
    let mut start = *z0;
    for j in 0..windows {
        // Taylor terms of z(t) = exp(A t) z: terms[k] = A^k z / k!
        let mut terms = [Vector::zeros(); TAYLOR_TERMS];
        terms[0] = start;
        for k in 1..TAYLOR_TERMS {
            terms[k] = sys.a * terms[k - 1] / k as f64;
        }
        let mut first: Option<(f64, usize)> = None;
        for g in (0..sys.n_guards).filter(|g| passed & 1 << g == 0) {
            let mut coef = [0.0; TAYLOR_TERMS];
            for (c, t) in coef.iter_mut().zip(terms.iter()) {
                *c = sys.guards[g].dot(t);
            }
            if coef[0] > 0.0 {
                continue; // passed before this window (edge triggered)
            }
            if let Some(tau) = first_positive(&coef, w, first.map_or(w, |f| f.0)) {
                first = Some((tau, g));
            }
        }
        if let Some((mut tau, g)) = first {
            // The state handed on must be past the crossing as the mode logic evaluates it
            // (on the vector, not the polynomial), or the mode may not change and the guard
            // would be passed over: nudge forward past the rounding.
            let mut at = horner_vec(&terms, tau);
            let mut nudge = f64::EPSILON * w;
            while sys.guards[g].dot(&at) <= 0.0 && tau < w {
                tau = (tau + nudge).min(w);
                at = horner_vec(&terms, tau);
                nudge *= 2.0;
            }
            return Some((j as f64 * w + tau, g, at));
        }
        start = horner_vec(&terms, w);
    }
    None
}

fn horner(coef: &[f64; TAYLOR_TERMS], t: f64) -> f64 {
    coef.iter().rev().fold(0.0, |acc, c| acc * t + c)
}

pub(super) fn horner_vec(terms: &[Vector; TAYLOR_TERMS], t: f64) -> Vector {
    terms.iter().rev().fold(Vector::zeros(), |acc, c| acc * t + c)
}

/// First t in (0, limit] where the polynomial turns positive (sampled, then bisected to the
/// last representable instant at or before the crossing's far side).
fn first_positive(coef: &[f64; TAYLOR_TERMS], w: f64, limit: f64) -> Option<f64> {
    let mut lo = 0.0;
    for s in 1..=GUARD_SAMPLES {
        let t = (w * s as f64 / GUARD_SAMPLES as f64).min(limit);
        if horner(coef, t) > 0.0 {
            let mut hi = t;
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                if horner(coef, mid) > 0.0 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            return Some(hi);
        }
        lo = t;
        if t >= limit {
            break;
        }
    }
    None
}
