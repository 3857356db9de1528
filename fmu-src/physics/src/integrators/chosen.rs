//! The integrator [`Params::solver_method`] chose, behind the seam
//! ([`super::seam::Integrator`]): each call passed on by a `match`.

use crate::actuator::Actuator;
use crate::events::{StepEvents, Work};
use crate::held_inputs::HeldInputs;
use crate::integrators::exact::exact_integrator::ExactIntegrator;
use crate::integrators::fixed_cost::fixed_cost::FixedCostIntegrator;
use crate::integrators::seam::{Integrator, Segment};
use crate::params::{Params, SolverMethod};

/// The integrator [`SolverMethod`] chose (dispatched by `match`: no allocation, no
/// indirection on the hot path).
// Inline, not boxed: an instance holds one integrator for its life, and a box would be an
// indirection on the hot path (and an allocation at every change of method).
#[allow(clippy::large_enum_variant)]
#[derive(Clone)]
pub(crate) enum ChosenIntegrator {
    Exact(ExactIntegrator),
    FixedCost(FixedCostIntegrator),
}

impl ChosenIntegrator {
    /// The integrator of `method` for `actuator`.
    pub(crate) fn new(params: &Params, actuator: &Actuator) -> ChosenIntegrator {
        match params.solver_method {
            SolverMethod::Exact => ChosenIntegrator::Exact(ExactIntegrator::new(actuator)),
            SolverMethod::FixedCost => {
                let fixed = FixedCostIntegrator::new(params.solver_h_internal, actuator);
                ChosenIntegrator::FixedCost(fixed)
            }
        }
    }

    /// The method this integrator implements.
    pub(crate) fn method(&self) -> SolverMethod {
        match self {
            ChosenIntegrator::Exact(_) => SolverMethod::Exact,
            ChosenIntegrator::FixedCost(_) => SolverMethod::FixedCost,
        }
    }
}

impl Integrator for ChosenIntegrator {
    #[inline]
    fn evolve(
        &mut self,
        actuator: &mut Actuator,
        segment: Segment,
        inputs: &HeldInputs,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        match self {
            ChosenIntegrator::Exact(exact) => exact.evolve(actuator, segment, inputs, events),
            ChosenIntegrator::FixedCost(fixed) => fixed.evolve(actuator, segment, inputs, events),
        }
    }

    fn prepare(&mut self, actuator: &Actuator, step: f64) {
        match self {
            ChosenIntegrator::Exact(exact) => exact.prepare(actuator, step),
            ChosenIntegrator::FixedCost(fixed) => fixed.prepare(actuator, step),
        }
    }

    fn adopt_prepared(&mut self, probe: ChosenIntegrator) {
        match (self, probe) {
            (ChosenIntegrator::Exact(exact), ChosenIntegrator::Exact(probe)) => {
                exact.adopt_prepared(probe)
            }
            (ChosenIntegrator::FixedCost(fixed), ChosenIntegrator::FixedCost(probe)) => {
                fixed.adopt_prepared(probe)
            }
            // A probe of another method built nothing this one uses.
            _ => {}
        }
    }

    fn retuned(&mut self, actuator: &Actuator, systems_rebuilt: bool) {
        match self {
            ChosenIntegrator::Exact(exact) => exact.retuned(actuator, systems_rebuilt),
            ChosenIntegrator::FixedCost(fixed) => fixed.retuned(actuator, systems_rebuilt),
        }
    }

    fn count_work(&self, work: &mut Work) {
        match self {
            ChosenIntegrator::Exact(exact) => exact.count_work(work),
            ChosenIntegrator::FixedCost(fixed) => fixed.count_work(work),
        }
    }
}
