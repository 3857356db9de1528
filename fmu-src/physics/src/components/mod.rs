//! The components' equations: the coil drivers (op-amp and industrial PI, H-bridge), the
//! torque-motor coil, the two-stage valve and its metering ports, the cylinder (its
//! parameters and state, its terms with their slopes, its right-hand side and Jacobian),
//! the outer flow and position loops and the rod's port, with the coefficients they read.

pub(crate) mod coefficients;
pub(crate) mod coil;
pub(crate) mod cylinder;
pub(crate) mod cylinder_jacobian;
pub(crate) mod cylinder_params;
pub(crate) mod cylinder_terms;
pub(crate) mod driver;
pub(crate) mod hbridge;
pub(crate) mod metering_ports;
pub(crate) mod outer_loop;
pub(crate) mod rod_port;
pub(crate) mod valve;
pub(crate) mod valve_datasheet;
