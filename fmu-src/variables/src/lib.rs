//! The one table of the actuator's variables ([`variables`]) and their units ([`units`]):
//! names, causality, variability, ranges, start values, and the generated bindings between
//! a value array (indexed by value reference) and the physics' typed `Params`, `Inputs`
//! and `Outputs`. No FMI: the FMU (`ehsv-actuator`, which re-exports both modules) and the
//! MuJoCo plugin (`ehsv-mujoco`) read it alike.

pub use ehsv_physics as physics;
pub mod units;
pub mod variables;
