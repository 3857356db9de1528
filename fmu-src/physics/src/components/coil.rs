//! Torque-motor coil: `L di/dt = u - (R + R_sense) i - K_b dx_f/dt`, driven by the driver
//! voltage `u` (the ideal current source instead holds `i` at the command).

use crate::components::coefficients::Coefficients;
use crate::components::driver::Mode;
use crate::numerics::augmented_state::{Mat, I, U, VF};

/// Writes the coil row of `z' = A z` for a driver mode.
pub(crate) fn coil_rows(c: &Coefficients, mode: Mode, a: &mut Mat) {
    if mode != Mode::Ideal {
        a[(I, I)] = -c.r_total / c.inductance;
        a[(I, U)] = 1.0 / c.inductance;
        a[(I, VF)] = -c.k_backemf / c.inductance;
    }
}

/// Steady coil current under a constant voltage `u`.
pub(crate) fn steady_current(c: &Coefficients, u: f64) -> f64 {
    u / c.r_total
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::components::coefficients::Coefficients;

    #[test]
    fn coil_row_is_the_rl_circuit_and_ideal_source_has_none() {
        let c = Coefficients::new(&crate::params::Params::PAPER).unwrap();
        let mut a = Mat::zeros();
        coil_rows(&c, Mode::Linear, &mut a);
        assert_eq!(a[(I, I)], -1000.0 / 3.2);
        assert_eq!(a[(I, U)], 1.0 / 3.2);
        let mut ideal = Mat::zeros();
        coil_rows(&c, Mode::Ideal, &mut ideal);
        assert_eq!(ideal, Mat::zeros());
        assert_eq!(steady_current(&c, 10.0), 0.01);
    }
}
