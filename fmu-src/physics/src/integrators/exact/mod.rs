//! The exact integrator (the default): driver, coil and valve propagated exactly, the
//! cylinder driven along the spool's exact path.

pub(crate) mod driven_cylinder;
pub(crate) mod exact_integrator;
