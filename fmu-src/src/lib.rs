//! EhsvActuator: an electro-hydraulic servo actuator as an FMI 2.0 / 3.0
//! Co-Simulation FMU.
//!
//! * [`variables`] and [`units`]: the one table of variables (drives XML, get/set, validation).
//! * [`model`]: a model instance as the FMI layer sees it (values by reference, step, state
//!   bytes); the typed boundary between value references and the physics.
//! * [`physics`]: plain-Rust model of driver, coil, Moog 30 valve, cylinder and load, with
//!   its exact piecewise-linear and Rosenbrock integrators. No FFI, no `unsafe`.
//! * `fmi2`, `fmi3`: the thin C API (the only `unsafe` code), generated alike over
//!   [`fmi_common`], which holds the call-sequence table and the Error rules
//!   ([`fmi_common::state_machine`]).

pub mod contract;
pub mod fmi2;
pub mod fmi3;
pub mod fmi_common;
pub mod model;
pub use ehsv_physics as physics;
pub use ehsv_variables::{units, variables};
