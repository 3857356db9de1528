//! The propagators of whole internal steps, for the fixed-cost integrator
//! ([`super::fixed_cost`]): `exp(A h)` of each (mode, stops) pair for the internal step `h`,
//! one matrix per step (a 6x9 product propagates it), built when the first step is prepared.
//!
//! One matrix, not the exact integrator's sub-steps: those exist to look at the guards
//! between them, which the fixed-cost step does at its ends alone.

use crate::numerics::augmented_state::{propagate, Mat, Vector};
use crate::numerics::mode_systems::{checked_exponential, ModeSystem};

/// Propagators held: a driver uses a handful of modes, each for the communication step's
/// and the loop period's internal steps.
const SLOTS: usize = 16;
const EMPTY: (usize, u64) = (usize::MAX, 0);

/// `exp(A h)` by (mode, stops) pair and the bits of `h`: a pure cache.
#[derive(Clone)]
pub(crate) struct WholeSteps {
    keys: [(usize, u64); SLOTS],
    /// On the heap with the integrator: `matrices[slot] = exp(A h)` of `keys[slot]`.
    matrices: Box<[Mat; SLOTS]>,
    /// The slot of the last propagation: the next one is most often the same.
    last: usize,
    next: usize,
    /// Matrix exponentials computed so far (a work counter).
    pub(crate) exponentials: u64,
}

impl WholeSteps {
    pub(crate) fn new() -> WholeSteps {
        WholeSteps {
            keys: [EMPTY; SLOTS],
            matrices: Box::new([Mat::zeros(); SLOTS]),
            last: 0,
            next: 0,
            exponentials: 0,
        }
    }

    /// Forgets every propagator (the systems they were built for changed).
    pub(crate) fn clear(&mut self) {
        self.keys = [EMPTY; SLOTS];
        (self.last, self.next) = (0, 0);
    }

    /// The slot of the propagator of `sys` (named `system`) over `h`, built if not held.
    /// The last slot's check inline, the search and the build out of line: nearly every
    /// propagation hits the last slot, and the rest would give it their stack frame.
    #[inline]
    pub(crate) fn slot(
        &mut self,
        system: usize,
        sys: &ModeSystem,
        h: f64,
    ) -> Result<usize, String> {
        if self.keys[self.last] == (system, h.to_bits()) {
            return Ok(self.last);
        }
        self.find_or_build(system, sys, h)
    }

    #[inline(never)]
    fn find_or_build(&mut self, system: usize, sys: &ModeSystem, h: f64) -> Result<usize, String> {
        let key = (system, h.to_bits());
        let slot = match self.keys.iter().position(|&k| k == key) {
            Some(slot) => slot,
            None => {
                let matrix = checked_exponential(&sys.a, h, h)?;
                let slot = self.next;
                (self.keys[slot], self.matrices[slot]) = (key, matrix);
                self.exponentials += 1;
                self.next = (slot + 1) % SLOTS;
                slot
            }
        };
        self.last = slot;
        Ok(slot)
    }

    /// `exp(A h) z` for the system `system` names.
    #[inline]
    pub(crate) fn propagate(
        &mut self,
        system: usize,
        sys: &ModeSystem,
        h: f64,
        z: &Vector,
    ) -> Result<Vector, String> {
        let slot = self.slot(system, sys, h)?;
        Ok(propagate(&self.matrices[slot], z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actuator::mode_system;
    use crate::components::coefficients::Coefficients;
    use crate::components::driver::MODES;
    use crate::numerics::augmented_exp::exp_augmented;
    use crate::params::Params;

    /// A whole step goes by `exp(A h)` itself, bit for bit, in the paper's driver modes;
    /// each (mode, step) pair's exponential is built once while the pairs fit the slots.
    #[test]
    fn a_whole_step_is_its_exponential_built_once() {
        let c = Coefficients::new(&Params::PAPER).unwrap();
        let z = Vector::from_fn(|k, _| [2e-3, 1.5, 3.0, 1e-6, 1e-3, 2e-5, 5e-3, 72.0, 1.0][k]);
        const PAIRS: usize = 12;
        let mut whole = WholeSteps::new();
        for round in 0..2 {
            for (key, &mode) in MODES[..PAIRS / 2].iter().enumerate() {
                let sys = mode_system(&c, mode);
                for h in [5e-5, 2.5e-5] {
                    let Some(direct) = exp_augmented(&(sys.a * h)) else { continue };
                    let z1 = whole.propagate(key, &sys, h, &z).unwrap();
                    assert_eq!(z1, propagate(&direct, &z), "{mode:?} over {h}");
                }
            }
            assert_eq!(whole.exponentials, PAIRS as u64, "round {round}");
        }
        whole.clear();
        whole.propagate(0, &mode_system(&c, MODES[0]), 5e-5, &z).unwrap();
        assert_eq!(whole.exponentials, PAIRS as u64 + 1, "cleared: built again");
    }
}
