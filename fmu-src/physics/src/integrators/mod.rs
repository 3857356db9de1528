//! The integrators of the actuator's continuous part: the seam they implement (`seam`), the
//! dispatch to the chosen one (`chosen`), and each in a folder of its own.

pub(crate) mod chosen;
pub(crate) mod exact;
pub(crate) mod fixed_cost;
pub(crate) mod seam;
