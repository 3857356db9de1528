//! The seam between the physics and its integrators. [`Physics`](crate::physics::Physics) cuts each
//! communication step at the time events of the digital loops (PWM edges, samples of the
//! H-bridge's and the outer loops); between two of them the inputs are held and the
//! actuator's continuous part (driver, coil, valve, cylinder) evolves: that is an
//! integrator's work. [`Params::solver_method`](crate::params::Params::solver_method) chooses the
//! integrator ([`SolverMethod`]) and [`ChosenIntegrator`] passes each call to it.
//!
//! # What an integrator receives and must return
//! [`Integrator::evolve`] receives
//! * the [`Actuator`]: its coefficients, the mode systems of driver, coil and valve, and the
//!   state at the segment's start, consistent with its driver mode and valve stops (as
//!   [`Actuator::settle`] leaves it);
//! * the [`Segment`]: its length and whether it is a whole communication step;
//! * the inputs held over it ([`HeldInputs`]: current command input, rail, supply, load, the
//!   outer loop's reference) and the step's [`StepEvents`].
//!
//! On `Ok` it must leave the actuator at the segment's end:
//! * `z` and the cylinder's state (with its Rosenbrock memory, part of the instance state)
//!   at that time, `z` on its mode's manifold (`driver::project_onto`);
//! * the driver mode and valve stops consistent with that state, changed only through
//!   [`Actuator::settle`] (which keeps the active system with them), each switch counted in
//!   the events (`driver::count_switch`);
//! * its work added to `actuator.work` (and its own counters reported by
//!   [`Integrator::count_work`]).
//!
//! It must not touch the digital loops, whose time events are the caller's, nor allocate.
//! Its results may depend on the state, the inputs and the parameters only, never on what
//! its caches hold, so that a restored state continues bit for bit. On `Err` (a message
//! saying why) it may leave the actuator anywhere: the caller restores the step's start.
//!
//! Adding an integrator: a module with a type that implements [`Integrator`], a variant of
//! [`SolverMethod`] and of [`ChosenIntegrator`] for it, and its arm in the matches below;
//! the others stay as they are.

use crate::actuator::Actuator;
use crate::events::{StepEvents, Work};
use crate::held_inputs::HeldInputs;

/// A stretch of a communication step without time events.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Segment {
    /// Its length (s): the communication step or the outer loop's sample period where it is
    /// one of those to the rounding of the instants that bound it, else its own.
    pub span: f64,
    /// It is a whole communication step (no time event cut it).
    pub whole: bool,
}

/// An integrator of the actuator's continuous part, one segment at a time (see the module
/// documentation for the contract).
pub(crate) trait Integrator {
    /// Advances `actuator` over `segment` with `inputs` held.
    fn evolve(
        &mut self,
        actuator: &mut Actuator,
        segment: Segment,
        inputs: &HeldInputs,
        events: &mut StepEvents,
    ) -> Result<(), String>;

    /// Builds ahead what steps of `step` seconds from the actuator's state will need
    /// (caches only: nothing a result depends on).
    fn prepare(&mut self, _actuator: &Actuator, _step: f64) {}

    /// Keeps what `probe` (a copy of this integrator that took a step and was prepared)
    /// built ahead; the rest of it is dropped.
    fn adopt_prepared(&mut self, _probe: Self)
    where
        Self: Sized,
    {
    }

    /// The actuator's coefficients changed (a retune); `systems_rebuilt`: so did its mode
    /// systems. What the integrator derived from them goes; its work counters stay.
    fn retuned(&mut self, actuator: &Actuator, systems_rebuilt: bool);

    /// Adds the work this integrator counts itself to `work`.
    fn count_work(&self, _work: &mut Work) {}
}
