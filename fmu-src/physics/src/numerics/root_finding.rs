//! The root finders the cylinder's contact switches and the spool's null crossing share, and
//! the closed-form first root of a quadratic gap (a slew's end, a piston's contact).

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

/// When a gap of `gap` (positive) closes at the closing speed `v` and acceleration `a`
/// held: the first positive root of `a t^2 / 2 + v t = gap` (in the form that does not
/// cancel); `None` where it does not close.
pub(crate) fn time_to_close(gap: f64, v: f64, a: f64) -> Option<f64> {
    let discriminant = v * v + 2.0 * a * gap;
    let t = 2.0 * gap / (v + discriminant.sqrt());
    // `t * 0 == 0`: `t` is finite (an infinity times 0 is NaN). Not `is_finite`, nor
    // `t < inf`, which the compiler makes a test of the float's class in integer bits
    // together with `t > 0`, longer than the comparisons.
    (discriminant >= 0.0 && t > 0.0 && t * 0.0 == 0.0).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The time a gap closes at a held closing speed and acceleration: at a steady speed
    /// gap / v; accelerating, sooner, decelerating, later; from rest or moving away, only
    /// when accelerating towards it (the positive root); never where it stops short.
    #[test]
    fn a_gap_closes_at_the_first_root_of_its_quadratic() {
        let close = |gap: f64, v: f64, a: f64| time_to_close(gap, v, a);
        assert_eq!(close(3e-6, 0.3, 0.0), Some(1e-5));
        for (v, a) in [(0.3, 2e3), (0.3, -2e3), (0.0, 2e3), (-0.05, 2e3)] {
            let t = close(3e-6, v, a).unwrap();
            let gap_left = 3e-6 - v * t - 0.5 * a * t * t;
            assert!(gap_left.abs() < 1e-18 && t > 0.0, "v {v}, a {a}: {t:e} s, {gap_left:e}");
        }
        assert!(close(3e-6, 0.3, 2e3).unwrap() < 1e-5 && close(3e-6, 0.3, -2e3).unwrap() > 1e-5);
        // Stops 2.25 um in: never closes; nor moving away and slowing down.
        assert_eq!(close(3e-6, 0.3, -2e4), None);
        assert_eq!(close(3e-6, -0.3, -2e3), None);
        assert_eq!(close(3e-6, 0.0, 0.0), None);
    }
}
