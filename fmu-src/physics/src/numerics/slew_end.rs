//! The mode after a slew that a command step started: run from the segment's start.
//!
//! A new current command starts a slew at the segment's start that ends within a
//! microsecond; the mode after it (usually the linear one) then runs to the segment's end,
//! `z(S) = exp(A (S - tau)) z(tau)`. That span never repeats, so its propagator is a cached
//! one of its leading bits and a Taylor series of 7-9 products for the rest, on every step
//! that changes the command. The same end is `exp(A S) (z0 + c)`: the propagator of the whole
//! segment (a span that repeats, cached exactly) applied to the segment's start moved by a
//! short series `c` of known vectors.
//!
//! Why it holds: the slew's dynamics `A_s` differ from the next mode's `A` only in the
//! driver output's row, `A_s = A + e_U d`. Variation of constants gives
//! `exp(-A tau) z_s(tau) = z0 + int_0^tau exp(-A s) e_U w(s) ds` with `w(s) = d z_s(s)`. Where
//! `d A_s^2 = 0` (the PI law's value moves as a parabola while slewing: the paper's tuning,
//! where the PI zero cancels the coil's pole), `w(s) = w0 + w1 s` exactly, with `w0 = d z0`
//! and `w1 = (d A_s) z0`, and
//! `c = sum_k (-A)^k e_U / k! int_0^tau s^k (w0 + w1 s) ds`.

use crate::components::coefficients::Coefficients;
use crate::components::driver::{u_lin, Mode, MODES};
use crate::numerics::augmented_state::{dot, Mat, Vector, EVOLVING, U};
use crate::numerics::mode_systems::{ModeSystem, NEGLECTED_TERM, RECIPROCALS};
use crate::numerics::root_finding::time_to_close;

/// For each slew (up, down) and each mode after it: `[d, d A_s]` where the two modes
/// differ only in the output row and `w` is linear in time, else `None`.
pub(crate) type SlewExits = [[Option<[Vector; 2]>; MODES.len()]; 2];

const SLEWS: [Mode; 2] = [Mode::SlewUp, Mode::SlewDown];

/// The exits of both slews among `systems` (one per mode, in [`MODES`] order).
pub(crate) fn slew_exits(systems: &[ModeSystem; MODES.len()]) -> SlewExits {
    SLEWS.map(|slew| {
        let a_s = &systems[slew.index()].a;
        MODES.map(|to| {
            let mut difference: Mat = a_s - systems[to.index()].a;
            let d = difference.row(U).transpose();
            difference.row_mut(U).fill(0.0);
            let d_rate = a_s.transpose() * d;
            let linear = (a_s.transpose() * d_rate).iter().all(|&x| x == 0.0);
            (to != slew && difference.iter().all(|&x| x == 0.0) && linear).then_some([d, d_rate])
        })
    })
}

/// `[d, d A_s]` for a slew `from` that ended in mode `to`, if the pair qualifies.
pub(crate) fn exit(exits: &SlewExits, from: Mode, to: Mode) -> Option<&[Vector; 2]> {
    let slew = SLEWS.iter().position(|&s| s == from)?;
    exits[slew][to.index()].as_ref()
}

/// `exp(-A tau) z_s(tau)`, `A` that of `sys`, for a slew from `z0` that lasted `tau` and left
/// through `exit` (see the module): `z0 + c`, summed until `(|lambda| tau)^k / k!` is below
/// [`NEGLECTED_TERM`] as in every Taylor series here. `None` where that needs more than [`BACK_TERMS`].
pub(crate) fn pulled_back(
    sys: &ModeSystem,
    [d, d_rate]: &[Vector; 2],
    z0: &Vector,
    tau: f64,
) -> Option<Vector> {
    let (w0, w1) = (dot(d, z0), dot(d_rate, z0));
    let mut start = *z0;
    let scale = sys.radius * tau;
    let mut bound = 1.0;
    // tau^(k+1); int_0^tau s^k (w0 + w1 s) ds = tau^(k+1) (w0 / (k+1) + w1 tau / (k+2)).
    let mut power = tau;
    for (k, column) in sys.back.iter().enumerate() {
        let moment = power * (w0 * RECIPROCALS[k + 1] + w1 * tau * RECIPROCALS[k + 2]);
        // The constants' entries of every column are zero.
        let evolving = &mut start.as_mut_slice()[..EVOLVING];
        for (s, c) in evolving.iter_mut().zip(&column.as_slice()[..EVOLVING]) {
            *s += c * moment;
        }
        power *= tau;
        bound *= scale * RECIPROCALS[k + 1];
        if bound <= NEGLECTED_TERM {
            return Some(start);
        }
    }
    None
}

/// When a slew from `z0` that leaves through `exit` (to the linear mode) brings the output
/// to the PI law's value: the gap `u_lin - U` falls at the rate `w` (the slew's rate less
/// the law's, linear in time: see the module), so it is `gap0 - w0 s - w1 s^2 / 2`, a
/// quadratic solved in closed form (its root nearer zero, in the form that does not
/// cancel). `None` where the gap does not close.
pub(crate) fn end_time(c: &Coefficients, [d, d_rate]: &[Vector; 2], z0: &Vector) -> Option<f64> {
    let gap = u_lin(c, z0) - z0[U];
    let (w0, w1) = (dot(d, z0), dot(d_rate, z0));
    if gap * w0 <= 0.0 {
        // The gap opens (or holds) at the slew's start: no end here, even where the law's
        // slowing would turn it back later.
        return None;
    }
    // The same root with every sign turned where the gap is negative (exact: bit for bit).
    // A NaN gap has no root either way.
    if gap < 0.0 {
        time_to_close(-gap, -w0, -w1)
    } else {
        time_to_close(gap, w0, w1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actuator::mode_system;
    use crate::components::coefficients::Coefficients;
    use crate::components::driver::u_lin_row;
    use crate::numerics::augmented_state::{I_CMD, ONE, RAIL};

    fn systems() -> [ModeSystem; MODES.len()] {
        let c = Coefficients::new(&crate::params::Params::PAPER).unwrap();
        MODES.map(|m| mode_system(&c, m))
    }

    #[test]
    fn slews_end_in_the_modes_that_differ_from_them_in_the_output_row_only() {
        let exits = slew_exits(&systems());
        // The frozen rails stop the integrator too; the linear mode is no slew.
        for (from, to, qualifies) in [
            (Mode::SlewUp, Mode::Linear, true),
            (Mode::SlewDown, Mode::Linear, true),
            (Mode::SlewUp, Mode::HighIntegrating, true),
            (Mode::SlewDown, Mode::LowIntegrating, true),
            (Mode::SlewUp, Mode::HighFrozen, false),
            (Mode::SlewDown, Mode::LowFrozen, false),
            (Mode::SlewUp, Mode::SlewUp, false),
            (Mode::Linear, Mode::SlewUp, false),
        ] {
            assert_eq!(exit(&exits, from, to).is_some(), qualifies, "{from:?} -> {to:?}");
        }
    }

    /// The pulled-back start against matrix exponentials: `exp(-A tau) exp(A_s tau) z0`,
    /// and the segment's end from it against `exp(A (S - tau)) exp(A_s tau) z0`.
    #[test]
    fn the_pulled_back_start_is_where_the_slews_end_goes_back_to() {
        let systems = systems();
        let exits = slew_exits(&systems);
        let segment = 5e-5;
        for (from, to, i_ref) in [
            (Mode::SlewUp, Mode::Linear, 2e-3),
            (Mode::SlewDown, Mode::Linear, -2e-3),
            (Mode::SlewUp, Mode::HighIntegrating, 2e-3),
        ] {
            let (slew, after) = (&systems[from.index()], &systems[to.index()]);
            let mut z0 =
                Vector::from_fn(|k, _| [1e-4, 0.3, 0.3, 1e-6, 0.0, 2e-5, 0.0, 72.0, 1.0][k]);
            z0[I_CMD] = i_ref;
            for tau in [1e-9, 3e-8, 1e-7] {
                let at_end = (slew.a * tau).exp() * z0;
                let reference = (after.a * -tau).exp() * at_end;
                let exit = exit(&exits, from, to).unwrap();
                let start = pulled_back(after, exit, &z0, tau).unwrap();
                let scale = z0.amax();
                assert!(
                    (start - reference).amax() <= 1e-13 * scale,
                    "{from:?} -> {to:?}, {tau:e} s: {start:?} vs {reference:?}"
                );
                // The slew moved the output: the start is not the segment's.
                assert!((start - z0).amax() > 1e-6 * scale, "{from:?} -> {to:?}, {tau:e} s");
                let end = (after.a * segment).exp() * start;
                let direct = (after.a * (segment - tau)).exp() * at_end;
                assert!((end - direct).amax() <= 1e-12 * direct.amax(), "{from:?} -> {to:?}");
            }
        }
    }

    /// The closed-form end of a slew against the first zero of `u_lin - U` along the slew's
    /// own exponential, found by bisection: the same time to 1e-9 of it, for command steps
    /// of 0.02 to 2 mA from rest, both ways.
    #[test]
    fn the_slews_end_is_the_root_of_a_quadratic() {
        let c = Coefficients::new(&crate::params::Params::PAPER).unwrap();
        let systems = systems();
        let exits = slew_exits(&systems);
        for (from, i_ref) in [(Mode::SlewUp, 1.0), (Mode::SlewDown, -1.0)] {
            for size in [2e-5, 2e-4, 2e-3] {
                let mut z0 = Vector::zeros();
                (z0[I_CMD], z0[RAIL], z0[ONE]) = (i_ref * size, 72.0, 1.0);
                let exit = exit(&exits, from, Mode::Linear).unwrap();
                let tau = end_time(&c, exit, &z0).unwrap();
                let a = systems[from.index()].a;
                let gap = |t: f64| {
                    let z = (a * t).exp() * z0;
                    i_ref * (dot(&u_lin_row(&c), &z) - z[U])
                };
                let (mut lo, mut hi) = (0.0, 1e-4);
                assert!(gap(lo) > 0.0 && gap(hi) < 0.0, "{from:?} {size}");
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    *(if gap(mid) > 0.0 { &mut lo } else { &mut hi }) = mid;
                }
                println!("{from:?} {size}: {tau:e} s, bisection {lo:e} s");
                assert!((tau - lo).abs() <= 1e-9 * lo, "{from:?} {size}: {tau:e} vs {lo:e}");
            }
        }
    }

    /// The quadratic's cases, on a made-up slew whose gap closes at `w0 + w1 t` (rates read
    /// off the constant 1): a steady close takes gap / w0, either way; a gap that opens, or
    /// one the slew's slowing stops short of closing, has no end.
    #[test]
    fn a_slew_whose_gap_does_not_close_has_no_end() {
        let c = Coefficients::new(&crate::params::Params::PAPER).unwrap();
        let mut z0 = Vector::zeros();
        (z0[I_CMD], z0[ONE]) = (1e-4, 1.0);
        let gap = c.kp * 1e-4;
        let rates = |w0: f64, w1: f64| {
            let (mut d, mut d_rate) = (Vector::zeros(), Vector::zeros());
            (d[ONE], d_rate[ONE]) = (w0, w1);
            [d, d_rate]
        };
        let steady = end_time(&c, &rates(2e7, 0.0), &z0).unwrap();
        assert!((steady - gap / 2e7).abs() < 1e-15 * steady, "{steady:e}");
        assert_eq!(end_time(&c, &rates(-2e7, 0.0), &z0), None, "opening");
        // w0^2 + 2 w1 gap < 0: the gap's fall stops before it closes.
        let stopping = -1.01 * 2e7 * 2e7 / (2.0 * gap);
        assert_eq!(end_time(&c, &rates(2e7, stopping), &z0), None, "stopping short");
        let just = -0.99 * 2e7 * 2e7 / (2.0 * gap);
        assert!(end_time(&c, &rates(2e7, just), &z0).unwrap() > steady, "slowed");
        z0[I_CMD] = -1e-4;
        let down = end_time(&c, &rates(-2e7, 0.0), &z0).unwrap();
        assert!((down - steady).abs() < 1e-15 * steady, "down {down:e}");
    }
}
