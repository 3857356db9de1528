//! Exact propagation of driver, coil and valve over any part of an internal step with no
//! matrix exponential inside the step, for the fixed-cost integrator ([`super::fixed_cost`]).
//!
//! A mode change placed inside an internal step leaves two parts of arbitrary length. Keyed
//! by length, their propagators would be built as they come: a 9x9 exponential (about a
//! microsecond) in whichever doStep first meets that length, the slowest doSteps. Instead
//! each (mode, stops) pair gets a ladder of [`LEVELS`] exponentials `exp(A T 2^-k)`, `T` the
//! power of two at or above `solver.h_internal`, built when the first step is prepared; a
//! part of length `tau` is the product of the rungs of the binary digits of `tau / T`
//! (matrix-vector products), finished by a Taylor series over what is left (below
//! `T 2^(1 - LEVELS)`, 60 ns at the default). The result is the same whether the ladder was
//! prepared or built when first needed, so a restored state continues bit for bit.

use crate::numerics::augmented_exp::exp_augmented;
use crate::numerics::augmented_state::{propagate, Mat, Vector};
use crate::numerics::mode_systems::{taylor_propagate, ModeSystem};

/// Rungs per ladder: the smallest is `T / 512`.
const LEVELS: usize = 10;
/// Ladders held; the least recently built is replaced (a driver uses a handful of modes).
const SLOTS: usize = 16;
const EMPTY: usize = usize::MAX;

/// The ladders of the (mode, stops) pairs met so far: a pure cache.
#[derive(Clone)]
pub(crate) struct DyadicLadders {
    /// The top rung's span `T` (s).
    top: f64,
    keys: [usize; SLOTS],
    /// On the heap, allocated with the integrator (104 kB): `rungs[slot][k] = exp(A T 2^-k)`.
    rungs: Box<[[Mat; LEVELS]]>,
    next: usize,
    /// Matrix exponentials computed so far (a work counter).
    pub(crate) exponentials: u64,
}

impl DyadicLadders {
    /// Empty ladders for parts of internal steps of at most `h_internal`.
    pub(crate) fn new(h_internal: f64) -> DyadicLadders {
        DyadicLadders {
            top: 2f64.powi(h_internal.log2().ceil() as i32),
            keys: [EMPTY; SLOTS],
            rungs: vec![[Mat::zeros(); LEVELS]; SLOTS].into_boxed_slice(),
            next: 0,
            exponentials: 0,
        }
    }

    /// Forgets every ladder (the systems they were built for changed).
    pub(crate) fn clear(&mut self) {
        self.keys = [EMPTY; SLOTS];
        self.next = 0;
    }

    /// The slot of `key`'s ladder (`key` names the (mode, stops) pair of `sys`), built if
    /// it is not held.
    pub(crate) fn slot(&mut self, key: usize, sys: &ModeSystem) -> Result<usize, String> {
        if let Some(slot) = self.keys.iter().position(|&k| k == key) {
            return Ok(slot);
        }
        let slot = self.next;
        let mut span = self.top;
        for rung in self.rungs[slot].iter_mut() {
            *rung = exp_augmented(&(sys.a * span)).ok_or_else(|| {
                format!(
                    "a sub-step of {} s with these parameters has no exact propagator; step \
                     refused",
                    crate::readable::readable(span)
                )
            })?;
            span *= 0.5;
        }
        self.exponentials += LEVELS as u64;
        self.keys[slot] = key;
        self.next = (slot + 1) % SLOTS;
        Ok(slot)
    }

    /// `exp(A tau) z` for the system `key` names, `0 <= tau <= T`.
    pub(crate) fn propagate(
        &mut self,
        key: usize,
        sys: &ModeSystem,
        tau: f64,
        z: &Vector,
    ) -> Result<Vector, String> {
        let slot = self.slot(key, sys)?;
        let (digits, rest) = self.digits(tau);
        let mut z = *z;
        for (rung, _) in self.rungs[slot].iter().zip(digits).filter(|(_, digit)| *digit) {
            z = propagate(rung, &z);
        }
        Ok(if rest > 0.0 { taylor_propagate(sys, &z, rest) } else { z })
    }

    /// The binary digits of `tau / T` (digit k: the rung of `T 2^-k` is taken) and what is
    /// left below the smallest rung.
    fn digits(&self, tau: f64) -> ([bool; LEVELS], f64) {
        let (mut digits, mut left, mut span) = ([false; LEVELS], tau, self.top);
        for digit in digits.iter_mut() {
            *digit = left >= span;
            if *digit {
                left -= span;
            }
            span *= 0.5;
        }
        (digits, left)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actuator::mode_system;
    use crate::components::coefficients::Coefficients;
    use crate::components::driver::MODES;
    use crate::params::Params;

    /// Over parts of every length up to the top rung, in every mode of the paper's drivers,
    /// the ladder gives `exp(A tau) z` to rounding (against the exponential of `A tau`
    /// itself, relative to the state's size), and a ladder built when first needed gives
    /// the same bits as one built ahead.
    #[test]
    fn the_ladder_propagates_as_the_exponential_of_the_whole_part() {
        let c = Coefficients::new(&Params::PAPER).unwrap();
        let z = Vector::from_fn(|k, _| [2e-3, 1.5, 3.0, 1e-6, 1e-3, 2e-5, 5e-3, 72.0, 1.0][k]);
        let (mut prepared, mut worst) = (DyadicLadders::new(25e-6), 0.0f64);
        for (key, mode) in MODES.into_iter().enumerate() {
            let sys = mode_system(&c, mode);
            if prepared.slot(key, &sys).is_err() {
                continue; // a mode with no propagator at this step (none of the paper's)
            }
            for tau in [0.0, 1e-9, 3.3e-8, 7.1e-7, 1.25e-5, 2.5e-5, 3.05e-5] {
                let ladder = prepared.propagate(key, &sys, tau, &z).unwrap();
                let direct = propagate(&exp_augmented(&(sys.a * tau)).unwrap(), &z);
                let scale = direct.abs().max().max(1.0);
                worst = worst.max((ladder - direct).abs().max() / scale);
                let mut lazy = DyadicLadders::new(25e-6);
                assert_eq!(lazy.propagate(key, &sys, tau, &z).unwrap(), ladder, "{mode:?}");
            }
        }
        println!("worst relative difference {worst:e}");
        assert!(worst < 1e-12, "{worst:e}");
    }

    /// A part's length in rungs: `T = 2^-15 s` for 25 us internal steps; 5/8 of it is the
    /// rungs 1/2 and 1/8 with nothing left; `T (1 - 2^-12)` every rung but the top and
    /// `T (2^-9 - 2^-12)` left for the series.
    #[test]
    fn a_part_is_cut_into_the_binary_digits_of_its_length() {
        let ladders = DyadicLadders::new(25e-6);
        let top = 2f64.powi(-15);
        assert_eq!(ladders.top, top);
        let (digits, rest) = ladders.digits(0.625 * top);
        assert_eq!(digits, [false, true, false, true, false, false, false, false, false, false]);
        assert_eq!(rest, 0.0);
        let (digits, rest) = ladders.digits(top * (1.0 - 2f64.powi(-12)));
        let mut below_top = [true; LEVELS];
        below_top[0] = false;
        assert_eq!(digits, below_top);
        assert_eq!(rest, top * (2f64.powi(-9) - 2f64.powi(-12)));
    }

    /// A ladder is built once per (mode, stops) pair and kept: ten exponentials each, none
    /// for a pair met again, until more pairs than slots push the oldest out.
    #[test]
    fn each_ladder_is_built_once_and_the_oldest_replaced() {
        let c = Coefficients::new(&Params::PAPER).unwrap();
        let sys = mode_system(&c, MODES[0]);
        let z = Vector::from_element(1.0);
        let mut ladders = DyadicLadders::new(25e-6);
        for round in 0..2 {
            for key in 0..SLOTS {
                ladders.propagate(key, &sys, 1e-5, &z).unwrap();
            }
            assert_eq!(ladders.exponentials, (SLOTS * LEVELS) as u64, "round {round}");
        }
        ladders.propagate(SLOTS, &sys, 1e-5, &z).unwrap();
        assert_eq!(ladders.keys[0], SLOTS, "the oldest slot takes the new pair");
        ladders.propagate(1, &sys, 1e-5, &z).unwrap();
        assert_eq!(ladders.exponentials, ((SLOTS + 1) * LEVELS) as u64);
        ladders.clear();
        ladders.propagate(1, &sys, 1e-5, &z).unwrap();
        assert_eq!(ladders.exponentials, ((SLOTS + 2) * LEVELS) as u64, "cleared: built again");
    }
}
