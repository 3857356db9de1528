//! [`Physics`], the whole physical state: the actuator and the integrator that advances
//! it. Its methods are written beside what they use: the public ones in the crate root
//! (`lib.rs`), advancing in `advance`, retuning in `retune`, bytes in `state::state_bytes`.

use crate::actuator::Actuator;
use crate::integrators::chosen::ChosenIntegrator;

/// The whole physical state and what is needed to advance it.
#[derive(Clone)]
pub struct Physics {
    /// Coefficients, mode systems and the state.
    pub(crate) actuator: Actuator,
    /// What advances the actuator between time events ([`Params::solver_method`](crate::Params::solver_method)).
    pub(crate) integrator: ChosenIntegrator,
    /// Inputs and step size (bits) of the last step if it left the state as it was, bit
    /// for bit, with no clock running: the same step again changes nothing (a pure cache).
    pub(crate) resting: Option<RestKey>,
    /// The force on the rod averaged over the last step (an output, carried across a saved
    /// state by the value array, so not part of the state bytes).
    pub(crate) rod_force_mean: f64,
    /// What the last step ended in, which the next one starts from (a pure cache: `None`
    /// where nothing is known, after a retune or a restore).
    pub(crate) step_end: Option<StepEnd>,
}

/// The state a step ended in as the next step's start reads it.
#[derive(Clone, Copy)]
pub(crate) struct StepEnd {
    /// The force on the rod (with the force port the next step's starting force; the
    /// motion port moves the rod first).
    pub(crate) rod_force: f64,
    /// Which relief valves were open (the rod's motion does not move them).
    pub(crate) relief_open: [bool; 2],
}

/// Inputs and step size as bits (see `Physics::resting`).
pub(crate) type RestKey = [u64; 10];
