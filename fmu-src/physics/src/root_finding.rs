//! The root finder the cylinder's contact switches and the spool's null crossing share.

/// Newton's method kept inside a bracket `[lo, hi]` across which a function changes sign:
/// `f(t)` gives its value and slope, `beyond(value)` whether `t` lies past the root. Each
/// evaluation shrinks the bracket; a Newton step that would leave it is replaced by
/// bisection. Stops when the bracket is narrower than `rel_tol` of its far end (or after
/// 60 evaluations) and returns it.
pub(crate) fn newton_in_bracket(
    f: impl Fn(f64) -> (f64, f64),
    beyond: impl Fn(f64) -> bool,
    (mut lo, mut hi): (f64, f64),
    start: f64,
    rel_tol: f64,
) -> (f64, f64) {
    let mut t = start;
    for _ in 0..60 {
        if !(t > lo && t < hi) {
            t = 0.5 * (lo + hi);
        }
        let (value, slope) = f(t);
        if beyond(value) {
            hi = t;
        } else {
            lo = t;
        }
        if hi - lo <= rel_tol * hi {
            break;
        }
        t = if slope != 0.0 { t - value / slope } else { 0.5 * (lo + hi) };
    }
    (lo, hi)
}
