//! LU factorisation of a 4x4 matrix with partial pivoting, on the stack (the Rosenbrock
//! integrator solves one such system per stage).

use crate::components::cylinder::{Mat4, Vec4, N_STATES};

/// LU factors of a 4x4 matrix with partial pivoting.
pub(crate) struct Lu4 {
    lu: Mat4,
    pivot: [usize; N_STATES],
    /// `1 / U_ii`: the back substitution multiplies by these. Its four dividing steps
    /// depend on each other, six solves per Rosenbrock step, and a division's latency is
    /// several multiplications'; the result differs from dividing by a rounding at most.
    inv_diagonal: Vec4,
}

impl Lu4 {
    pub(crate) fn factor(mut a: Mat4) -> Option<Lu4> {
        let mut pivot = [0; N_STATES];
        // One call per column with the column a constant: the loops below it unroll.
        eliminate::<0>(&mut a, &mut pivot)?;
        eliminate::<1>(&mut a, &mut pivot)?;
        eliminate::<2>(&mut a, &mut pivot)?;
        eliminate::<3>(&mut a, &mut pivot)?;
        let inv_diagonal = std::array::from_fn(|i| 1.0 / a[i][i]);
        Some(Lu4 { lu: a, pivot, inv_diagonal })
    }

    #[inline(always)]
    pub(crate) fn solve(&self, mut b: Vec4) -> Vec4 {
        // Usually no row was swapped: b then stays in registers.
        for col in 0..N_STATES {
            if self.pivot[col] != col {
                b.swap(col, self.pivot[col]);
            }
        }
        for row in 1..N_STATES {
            for c in 0..row {
                b[row] -= self.lu[row][c] * b[c];
            }
        }
        for row in (0..N_STATES).rev() {
            for c in row + 1..N_STATES {
                b[row] -= self.lu[row][c] * b[c];
            }
            b[row] *= self.inv_diagonal[row];
        }
        b
    }
}

/// Column `COL` of the elimination: the largest remaining entry of the column as the pivot
/// (`None` if it is 0 or not finite), its row swapped up, the multipliers stored below it.
#[inline(always)]
fn eliminate<const COL: usize>(a: &mut Mat4, pivot: &mut [usize; N_STATES]) -> Option<()> {
    let mut best = COL;
    let mut best_abs = a[COL][COL].abs();
    for (row, values) in a.iter().enumerate().skip(COL + 1) {
        if values[COL].abs() > best_abs {
            best = row;
            best_abs = values[COL].abs();
        }
    }
    let p = a[best][COL];
    if p == 0.0 || !p.is_finite() {
        return None;
    }
    if best != COL {
        a.swap(COL, best);
    }
    pivot[COL] = best;
    let pivot_row = a[COL];
    for row in a.iter_mut().skip(COL + 1) {
        let m = row[COL] / p;
        row[COL] = m;
        for c in COL + 1..N_STATES {
            row[c] -= m * pivot_row[c];
        }
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_system_that_needs_pivoting() {
        let a = [
            [0.0, 2.0, 0.0, 1.0],
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 3.0, 0.0],
            [0.0, 1.0, 0.0, 4.0],
        ];
        let x = [1.0, -2.0, 0.5, 3.0];
        let mut b = [0.0; N_STATES];
        for (row, bi) in a.iter().zip(b.iter_mut()) {
            *bi = row.iter().zip(x).map(|(aij, xj)| aij * xj).sum();
        }
        let solved = Lu4::factor(a).unwrap().solve(b);
        for (s, x) in solved.iter().zip(x) {
            assert!((s - x).abs() < 1e-15, "{solved:?}");
        }
        assert!(Lu4::factor([[0.0; N_STATES]; N_STATES]).is_none());
    }
}
