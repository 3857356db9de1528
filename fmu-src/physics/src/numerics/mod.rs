//! The numerics both integrators use: the augmented state of driver, coil and valve and its
//! exponentials, the mode systems (propagators, event location), the slews' ends in closed
//! form, the cylinder's Rosenbrock steps, the 4x4 LU and root finding.

pub(crate) mod augmented_exp;
pub(crate) mod augmented_state;
pub(crate) mod lu4;
pub(crate) mod mode_systems;
pub(crate) mod root_finding;
pub(crate) mod rosenbrock;
pub(crate) mod slew_end;
