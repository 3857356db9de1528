//! `exp(A t)` for the augmented systems' matrices, whose three constants' rows are zero.
//!
//! Such an `A = [[F, G], [0, 0]]` (`F` 6x6, `G` 6x3) keeps the shape through every step of
//! scaling and squaring with a Pade approximant (Higham 2005; the degree and the scaling chosen
//! from `||A^k||^(1/k)` as in Al-Mohy and Higham 2009): the matrices involved are
//! `[[X, Y], [0, c I]]`, and a product of two of them needs a 6x6 by 6x9 product, not a 9x9 by
//! 9x9 one. The norms of the powers are computed exactly from the powers the approximant needs
//! anyway (the general algorithm estimates them). Less arithmetic than a general 9x9
//! `exp()`, for the same result to rounding.

use crate::numerics::augmented_state::{Mat, EVOLVING, N};

/// The evolving rows `[X, Y]` of a matrix `[[X, Y], [0, c I]]`, column by column.
type Top = [[f64; EVOLVING]; N];

/// A matrix `[[X, Y], [0, c I]]`.
#[derive(Clone, Copy)]
struct Augmented {
    top: Top,
    c: f64,
}

impl Augmented {
    fn identity() -> Self {
        let mut top = [[0.0; EVOLVING]; N];
        for (k, column) in top.iter_mut().enumerate().take(EVOLVING) {
            column[k] = 1.0;
        }
        Augmented { top, c: 1.0 }
    }

    /// The evolving rows of `a` (its others are zero).
    fn of_dynamics(a: &Mat) -> Self {
        Augmented { top: std::array::from_fn(|k| std::array::from_fn(|r| a[(r, k)])), c: 0.0 }
    }

    /// `self * other`: `[[X1 X2, X1 Y2 + c2 Y1], [0, c1 c2 I]]`.
    fn times(&self, other: &Augmented) -> Augmented {
        let mut top = [[0.0; EVOLVING]; N];
        for (out, column) in top.iter_mut().zip(&other.top) {
            for (x_column, &weight) in self.top.iter().zip(column) {
                for (o, &x) in out.iter_mut().zip(x_column) {
                    *o += x * weight;
                }
            }
        }
        if other.c != 0.0 {
            for (out, y_column) in top.iter_mut().zip(&self.top).skip(EVOLVING) {
                for (o, &y) in out.iter_mut().zip(y_column) {
                    *o += y * other.c;
                }
            }
        }
        Augmented { top, c: self.c * other.c }
    }

    /// `sum of weights[k] * terms[k]`.
    fn combination(weights: &[f64], terms: &[&Augmented]) -> Augmented {
        let mut sum = Augmented { top: [[0.0; EVOLVING]; N], c: 0.0 };
        for (&w, term) in weights.iter().zip(terms) {
            for (out, column) in sum.top.iter_mut().zip(&term.top) {
                for (o, &x) in out.iter_mut().zip(column) {
                    *o += x * w;
                }
            }
            sum.c += term.c * w;
        }
        sum
    }

    fn scaled(&self, factor: f64) -> Augmented {
        Augmented { top: self.top.map(|column| column.map(|x| x * factor)), c: self.c }
    }

    /// The 1-norm (largest column sum of magnitudes).
    fn norm1(&self) -> f64 {
        let column_sum = |column: &[f64; EVOLVING]| column.iter().map(|x| x.abs()).sum::<f64>();
        let evolving = self.top[..EVOLVING].iter().map(column_sum);
        let constants = self.top[EVOLVING..].iter().map(|column| column_sum(column) + self.c.abs());
        evolving.chain(constants).fold(0.0, f64::max)
    }

    fn into_mat(self) -> Mat {
        let mut m = Mat::zeros();
        for (k, column) in self.top.iter().enumerate() {
            for (r, &x) in column.iter().enumerate() {
                m[(r, k)] = x;
            }
        }
        for r in EVOLVING..N {
            m[(r, r)] = self.c;
        }
        m
    }
}

/// Pade degrees and the largest `||A^k||^(1/k)` bound each is accurate to rounding for
/// (Al-Mohy and Higham 2009, table 3.1).
const THETA: [(usize, f64); 4] = [
    (3, 1.495585217958292e-2),
    (5, 2.53939833006323e-1),
    (7, 9.504178996162932e-1),
    (9, 2.097847961257068e0),
];
const THETA_13: f64 = 4.25;

/// Coefficients `b_0 .. b_m` of the degree-`m` diagonal Pade approximant of `exp`.
fn pade_coefficients(m: usize) -> &'static [f64] {
    match m {
        3 => &[120.0, 60.0, 12.0, 1.0],
        5 => &[30240.0, 15120.0, 3360.0, 420.0, 30.0, 1.0],
        7 => &[17297280.0, 8648640.0, 1995840.0, 277200.0, 25200.0, 1512.0, 56.0, 1.0],
        9 => &[
            17643225600.0,
            8821612800.0,
            2075673600.0,
            302702400.0,
            30270240.0,
            2162160.0,
            110880.0,
            3960.0,
            90.0,
            1.0,
        ],
        _ => &[
            64764752532480000.0,
            32382376266240000.0,
            7771770303897600.0,
            1187353796428800.0,
            129060195264000.0,
            10559470521600.0,
            670442572800.0,
            33522128640.0,
            1323241920.0,
            40840800.0,
            960960.0,
            16380.0,
            182.0,
            1.0,
        ],
    }
}

/// `exp(a)` for a matrix whose rows from [`EVOLVING`] on are zero (the identity's there).
/// `None` if the evolving block of the approximant's denominator is singular (only for
/// non-finite or absurdly scaled input).
pub(crate) fn exp_augmented(a: &Mat) -> Option<Mat> {
    let mut result = exp_of(Augmented::of_dynamics(a))?;
    // A part held at a travel stop (a zero row) stays exactly where it is: the solve's
    // pivoting could leave its row of the result within rounding of the unit row, and a
    // spool 2e-18 m off its stop is no longer at it.
    for r in (0..EVOLVING).filter(|&r| a.row(r).iter().all(|&x| x == 0.0)) {
        result.row_mut(r).fill(0.0);
        result[(r, r)] = 1.0;
    }
    Some(result)
}

/// `exp(a)` by scaling and squaring a Pade approximant, degree and scaling from [`plan`].
fn exp_of(a: Augmented) -> Option<Mat> {
    let [a2, a4, a6] = even_powers(&a);
    let identity = Augmented::identity();
    match plan(a4.norm1(), a6.norm1())? {
        (13, squarings) => {
            let scale = 2f64.powi(-squarings);
            let (a2, a4, a6) =
                (a2.scaled(scale.powi(2)), a4.scaled(scale.powi(4)), a6.scaled(scale.powi(6)));
            solve_pade(
                &a.scaled(scale),
                [&identity, &a2, &a4, &a6, &identity],
                pade_coefficients(13),
                squarings,
            )
        }
        (degree, _) => {
            let a8 = if degree == 9 { a4.times(&a4) } else { identity };
            solve_pade(&a, [&identity, &a2, &a4, &a6, &a8], pade_coefficients(degree), 0)
        }
    }
}

/// `[a^2, a^4, a^6]`: every approximant's, and the norms that choose it.
fn even_powers(a: &Augmented) -> [Augmented; 3] {
    let a2 = a.times(a);
    let a4 = a2.times(&a2);
    let a6 = a4.times(&a2);
    [a2, a4, a6]
}

/// The Pade degree and the number of squarings for a matrix with `||A^4|| = n4` and
/// `||A^6|| = n6`. `||A^8|| <= n4^2` and `||A^10|| <= n4 n6` stand in for the norms the
/// algorithm would estimate: upper bounds, so never too little scaling.
fn plan(n4: f64, n6: f64) -> Option<(usize, i32)> {
    let eta = n4.powf(0.25).max(n6.powf(1.0 / 6.0));
    if let Some(&(degree, _)) = THETA.iter().find(|&&(_, theta)| eta <= theta) {
        return Some((degree, 0));
    }
    let eta_13 = n4.powf(0.25).max((n4 * n6).powf(0.1));
    let squarings = if eta_13 > THETA_13 { (eta_13 / THETA_13).log2().ceil() } else { 0.0 };
    // Past f64's range (a parameter far beyond physics, a slew rate of 1e300 V/s) the count
    // is infinite, 2^31 squarings as an integer: no exponential, the step is refused.
    (squarings <= MAX_SQUARINGS).then_some((13, squarings as i32))
}

/// More squarings than any finite norm asks for (f64's largest is 2^1024).
const MAX_SQUARINGS: f64 = 1100.0;

/// `r_m(a) = (V - U)^-1 (V + U)` from the even powers `[I, a^2, a^4, a^6, a^8]` (`a^8` only
/// for degree 9), squared `squarings` times.
fn solve_pade(a: &Augmented, powers: [&Augmented; 5], b: &[f64], squarings: i32) -> Option<Mat> {
    let (odd, even) = if b.len() == 14 {
        // Degree 13: the powers past a^6 as a^6 times a combination (Higham 2005).
        let [identity, a2, a4, a6, _] = powers;
        let high = |w: [f64; 3]| a6.times(&Augmented::combination(&w, &[a6, a4, a2]));
        let (high_odd, high_even) = (high([b[13], b[11], b[9]]), high([b[12], b[10], b[8]]));
        let lower = [&high_odd, a6, a4, a2, identity];
        let odd = Augmented::combination(&[1.0, b[7], b[5], b[3], b[1]], &lower);
        let lower = [&high_even, a6, a4, a2, identity];
        let even = Augmented::combination(&[1.0, b[6], b[4], b[2], b[0]], &lower);
        (odd, even)
    } else {
        let terms = b.len() / 2;
        let mut odd_weights = [0.0; 5];
        let mut even_weights = [0.0; 5];
        for k in 0..terms {
            odd_weights[k] = b[2 * k + 1];
            even_weights[k] = b[2 * k];
        }
        (
            Augmented::combination(&odd_weights[..terms], &powers),
            Augmented::combination(&even_weights[..terms], &powers),
        )
    };
    let u = a.times(&odd);
    // (V - U) X = V + U is block upper triangular, V's `c I` below U's zeros: for
    // V - U = [[Q, Q2], [0, c I]] and V + U = [[R1, R2], [0, c I]],
    // X = [[Q^-1 R1, Q^-1 (R2 - Q2)], [0, I]].
    let mut q = [[0.0; EVOLVING]; EVOLVING];
    let mut rhs = [[0.0; EVOLVING]; N];
    for k in 0..N {
        for r in 0..EVOLVING {
            let (v, u) = (even.top[k][r], u.top[k][r]);
            if k < EVOLVING {
                q[k][r] = v - u;
                rhs[k][r] = v + u;
            } else {
                rhs[k][r] = 2.0 * u;
            }
        }
    }
    let mut x = Augmented { top: solve(q, rhs)?, c: 1.0 };
    for _ in 0..squarings {
        x = x.times(&x);
    }
    Some(x.into_mat())
}

/// `q^-1 rhs` by Gaussian elimination with partial pivoting (column by column, so the
/// row operations run along contiguous columns); `None` for a singular `q`.
fn solve(mut q: [[f64; EVOLVING]; EVOLVING], mut rhs: Top) -> Option<Top> {
    let mut inverse_pivots = [0.0; EVOLVING];
    for k in 0..EVOLVING {
        let mut pivot = k;
        for i in k + 1..EVOLVING {
            if q[k][i].abs() > q[k][pivot].abs() {
                pivot = i;
            }
        }
        let inverse = 1.0 / q[k][pivot];
        if !inverse.is_finite() || inverse == 0.0 {
            return None;
        }
        inverse_pivots[k] = inverse;
        // Full-length column updates (zero multipliers above the pivot): they vectorise.
        let mut multipliers = [0.0; EVOLVING];
        q[k].swap(k, pivot);
        for i in k + 1..EVOLVING {
            multipliers[i] = q[k][i] * inverse;
        }
        // The pivot column below its upper part is done with: zeroed, back substitution
        // also runs full length.
        q[k][k..].fill(0.0);
        for column in q[k + 1..].iter_mut().chain(rhs.iter_mut()) {
            column.swap(k, pivot);
            let at_pivot = column[k];
            for (x, m) in column.iter_mut().zip(multipliers) {
                *x -= m * at_pivot;
            }
        }
    }
    for column in rhs.iter_mut() {
        for k in (0..EVOLVING).rev() {
            let solved = column[k] * inverse_pivots[k];
            for (x, &u) in column.iter_mut().zip(&q[k]) {
                *x -= u * solved;
            }
            column[k] = solved;
        }
    }
    Some(rhs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actuator::mode_system;
    use crate::components::coefficients::Coefficients;
    use crate::components::driver::MODES;
    use crate::components::valve::Stops;

    /// Every mode, free and at every combination of stops, over the spans the propagator
    /// cache asks for (|lambda| h up to 6): the general exponential's result to rounding, and
    /// exactly the unit row for a part held at its stop. Each Pade degree and the scaling
    /// are taken.
    #[test]
    fn matches_the_general_exponential_for_every_mode_and_span() {
        let mut params = crate::params::Params::PAPER;
        params.valve.x_flapper_max = 30e-6;
        params.valve.x_spool_max = 0.2e-3;
        let c = Coefficients::new(&params).unwrap();
        let typical =
            Mat::from_diagonal(&[2e-3, 1.5, 3.0, 1e-6, 1e-3, 2e-5, 5e-3, 72.0, 1.0].into());
        let mut plans = std::collections::BTreeSet::new();
        for mode in MODES {
            let free = mode_system(&c, mode);
            for code in 0..9 {
                let sys = free.with_stops(&c, Stops::from_code(code).unwrap());
                // The cache's sub-steps keep |lambda| h <= 6.
                for fraction in [1e-9, 1e-7, 1e-5, 1e-3, 0.01, 0.1, 0.3, 1.0, 3.0, 6.0] {
                    let span = fraction / sys.radius;
                    let scaled = sys.a * span;
                    let general = scaled.exp();
                    let ours = exp_augmented(&scaled).unwrap();
                    for held in (0..N).filter(|&r| scaled.row(r).iter().all(|&x| x == 0.0)) {
                        assert_eq!(
                            ours.row(held),
                            Mat::identity().row(held),
                            "{mode:?} stops {code}: held row {held}"
                        );
                    }
                    // Row by row on a state of typical magnitudes (rows and columns carry
                    // different units), against the size of the terms each row sums, or the
                    // row's typical magnitude where they cancel (a flapper back at null).
                    let (general, ours) = (general * typical, ours * typical);
                    for row in 0..N {
                        let error = (general.row(row) - ours.row(row)).abs().max();
                        let terms = general.row(row).abs().sum().max(typical[(row, row)]);
                        assert!(
                            error <= 1e-12 * terms,
                            "{mode:?} stops {code} span {span}: row {row} off by {error:e} of {terms:e}"
                        );
                    }
                    let [_, a4, a6] = even_powers(&Augmented::of_dynamics(&scaled));
                    let (degree, squarings) = plan(a4.norm1(), a6.norm1()).unwrap();
                    plans.insert((degree, squarings > 0));
                }
            }
        }
        let expected = [(3, false), (5, false), (7, false), (9, false), (13, false), (13, true)];
        assert_eq!(plans, expected.into_iter().collect());
    }
}
