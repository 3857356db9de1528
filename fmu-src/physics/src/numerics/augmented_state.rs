//! The augmented state of driver, coil and valve: six physical states and three
//! constants held over a step, so that every mode is `z' = A z`, linear and homogeneous.

use nalgebra::{SMatrix, SVector};

/// Augmented state size: 6 physical states + 3 constants.
pub(crate) const N: usize = 9;
pub(crate) type Mat = SMatrix<f64, N, N>;
pub(crate) type Vector = SVector<f64, N>;

/// Coil current, A.
pub(crate) const I: usize = 0;
/// PI integrator output Ki integral(e), V.
pub(crate) const UI: usize = 1;
/// Driver output voltage, V.
pub(crate) const U: usize = 2;
/// Flapper displacement, m.
pub(crate) const XF: usize = 3;
/// Flapper velocity, m/s.
pub(crate) const VF: usize = 4;
/// Spool displacement, m.
pub(crate) const XS: usize = 5;
/// Current command (constant over a step), A.
pub(crate) const I_CMD: usize = 6;
/// Rail voltage V_supply - V_drop (constant over a step), V.
pub(crate) const RAIL: usize = 7;
/// The constant 1, for affine terms.
pub(crate) const ONE: usize = 8;

/// Row vector e_k.
pub(crate) fn unit(k: usize) -> Vector {
    let mut r = Vector::zeros();
    r[k] = 1.0;
    r
}

/// States that evolve; the three after them are held constants (zero rows of every `A`).
pub(crate) const EVOLVING: usize = 6;

/// `a z` for a dynamics matrix, whose constants' rows are zero: only the evolving rows are
/// computed (two thirds of a full product; the event search and the Taylor series are made of these).
#[inline]
pub(crate) fn rate(a: &Mat, z: &Vector) -> Vector {
    product_of_columns(a, z, N)
}

/// `a d` for a derivative `d` of the state, whose constants' entries are zero (every Taylor
/// term after the first): their columns are skipped too, a third less work, same result.
#[inline]
pub(crate) fn rate_of_derivative(a: &Mat, d: &Vector) -> Vector {
    product_of_columns(a, d, EVOLVING)
}

/// The evolving rows of `a z` from the first `columns` columns of `a`.
#[inline]
fn product_of_columns(a: &Mat, z: &Vector, columns: usize) -> Vector {
    let entries = a.as_slice();
    let mut out = Vector::zeros();
    for (c, &zc) in z.iter().enumerate().take(columns) {
        let column = &entries[c * N..c * N + EVOLVING];
        for (o, &a_rc) in out.iter_mut().zip(column) {
            *o += a_rc * zc;
        }
    }
    out
}

/// `a . b`, summed in two independent lanes over the nine entries (a short dependency
/// chain, no generic iteration): guards, their rates and the spool's rows are dotted with
/// the state throughout the event search.
#[inline]
pub(crate) fn dot(a: &Vector, b: &Vector) -> f64 {
    let (a, b) = (a.as_slice(), b.as_slice());
    let mut lanes = [0.0; 2];
    for pair in 0..N / 2 {
        for (lane, sum) in lanes.iter_mut().enumerate() {
            *sum += a[2 * pair + lane] * b[2 * pair + lane];
        }
    }
    lanes[0] + lanes[1] + a[N - 1] * b[N - 1]
}

/// Every entry of `z` is finite: `z . 0` is then 0, and NaN where an entry is infinite or
/// NaN (its product with 0 is NaN). Straight-line in [`dot`]'s two lanes, where testing
/// each entry is a branch per entry.
#[inline]
pub(crate) fn all_finite(z: &Vector) -> bool {
    dot(z, &Vector::zeros()) == 0.0
}

/// Row `r` of `a` dotted with `z`, read down the column-major storage in two lanes (as
/// [`dot`]) without gathering the row first.
#[inline]
pub(crate) fn row_dot(a: &Mat, r: usize, z: &Vector) -> f64 {
    let (entries, z) = (a.as_slice(), z.as_slice());
    let mut lanes = [0.0; 2];
    for pair in 0..N / 2 {
        for (lane, sum) in lanes.iter_mut().enumerate() {
            let c = 2 * pair + lane;
            *sum += entries[c * N + r] * z[c];
        }
    }
    lanes[0] + lanes[1] + entries[(N - 1) * N + r] * z[N - 1]
}

/// `p z` for a propagator `exp(A t)` (constant rows those of the identity): the constants
/// are carried over exactly.
#[inline]
pub(crate) fn propagate(p: &Mat, z: &Vector) -> Vector {
    let mut out = rate(p, z);
    for r in EVOLVING..N {
        out[r] = z[r];
    }
    out
}

/// 2^63: from here on `as i64` saturates.
const TWO_TO_63: f64 = 9_223_372_036_854_775_808.0;

/// `x.ceil() as usize` (NaN and negatives give 0, `usize::MAX` from 2^63 on) without the
/// call: x86-64's baseline has no rounding instruction, so `ceil` is a libm call, and every
/// piece and sub-step count takes one. Through `i64`, whose conversions are one instruction
/// each way (`usize`'s are branchy sequences).
#[inline]
pub(crate) fn ceil_count(x: f64) -> usize {
    if x.is_nan() || x <= 0.0 {
        return 0;
    }
    if x >= TWO_TO_63 {
        return usize::MAX;
    }
    let whole = x as i64;
    (whole + ((whole as f64) < x) as i64) as usize
}
