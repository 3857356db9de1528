//! The fixed-cost integrator: fixed internal steps, its linearly implicit step of the
//! cylinder, and its ladders of exponentials for part-steps and its whole steps' propagators.

pub(crate) mod dyadic_ladder;
// The file keeps the name it has had since issue 30 (docs, mutation commands, history).
#[allow(clippy::module_inception)]
pub(crate) mod fixed_cost;
pub(crate) mod lean_cylinder;
pub(crate) mod whole_steps;
