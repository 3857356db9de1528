//! LU factorisation of a 4x4 matrix with partial pivoting, on the stack (the Rosenbrock
//! integrator solves one such system per stage).

use super::cylinder::{Mat4, Vec4, N_STATES};

/// LU factors of a 4x4 matrix with partial pivoting.
pub(crate) struct Lu4 {
    lu: Mat4,
    pivot: [usize; N_STATES],
}

impl Lu4 {
    pub(crate) fn factor(mut a: Mat4) -> Option<Lu4> {
        let mut pivot = [0; N_STATES];
        for col in 0..N_STATES {
            let mut best = col;
            let mut best_abs = a[col][col].abs();
            for (row, values) in a.iter().enumerate().skip(col + 1) {
                if values[col].abs() > best_abs {
                    best = row;
                    best_abs = values[col].abs();
                }
            }
            let p = a[best][col];
            if p == 0.0 || !p.is_finite() {
                return None;
            }
            if best != col {
                a.swap(col, best);
            }
            pivot[col] = best;
            let pivot_row = a[col];
            for row in a.iter_mut().skip(col + 1) {
                let m = row[col] / p;
                row[col] = m;
                for c in col + 1..N_STATES {
                    row[c] -= m * pivot_row[c];
                }
            }
        }
        Some(Lu4 { lu: a, pivot })
    }

    pub(crate) fn solve(&self, mut b: Vec4) -> Vec4 {
        for col in 0..N_STATES {
            b.swap(col, self.pivot[col]);
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
            b[row] /= self.lu[row][row];
        }
        b
    }
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
