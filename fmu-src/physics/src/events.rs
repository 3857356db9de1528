//! What a step reports beside the state: the mode changes in it ([`StepEvents`]) and the
//! integrators' work counters ([`Work`]).

use crate::numerics::rosenbrock;

/// Mode changes inside one step, for event logging.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepEvents {
    pub rail_entered: u32,
    pub rail_left: u32,
    /// Relief valves of chambers `[A, B]` open at the end of the step that were shut at its
    /// start (seen at communication points).
    pub relief_opened: [bool; 2],
}

/// Work the integrators have done since the instance was built or restored (cumulative
/// counters for benchmarks; not part of the state).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Work {
    /// Calls of the cylinder's Rosenbrock integrator (one per piece of spool path).
    pub cylinder_calls: u64,
    /// Its internal steps: accepted (Rodas3 ones included) and rejected.
    pub steps_accepted: u64,
    pub steps_rejected: u64,
    /// Analytic Jacobians, LU factorisations of the 4x4 iteration matrix, evaluations of
    /// the cylinder's right-hand side (a Jacobian counts as one).
    pub jacobians: u64,
    pub factorisations: u64,
    pub function_evaluations: u64,
    /// 9x9 matrix exponentials of the exact integrator (propagator cache misses).
    pub exponentials: u64,
    /// State-event searches (a guard may have crossed inside a sub-step).
    pub guard_locations: u64,
}

impl Work {
    /// The work done between `earlier` (a reading of the same instance) and `self`.
    pub fn since(&self, earlier: &Work) -> Work {
        Work {
            cylinder_calls: self.cylinder_calls - earlier.cylinder_calls,
            steps_accepted: self.steps_accepted - earlier.steps_accepted,
            steps_rejected: self.steps_rejected - earlier.steps_rejected,
            jacobians: self.jacobians - earlier.jacobians,
            factorisations: self.factorisations - earlier.factorisations,
            function_evaluations: self.function_evaluations - earlier.function_evaluations,
            exponentials: self.exponentials - earlier.exponentials,
            guard_locations: self.guard_locations - earlier.guard_locations,
        }
    }

    pub(crate) fn add(&mut self, stats: &rosenbrock::Stats) {
        self.cylinder_calls += 1;
        self.steps_accepted += stats.accepted as u64;
        self.steps_rejected += stats.rejected as u64;
        self.jacobians += stats.jacobian_evaluations as u64;
        self.factorisations += stats.factorisations as u64;
        self.function_evaluations += stats.function_evaluations as u64;
    }
}
