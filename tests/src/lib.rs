//! Test-only crate: see tests/*.rs and src/bin. The library holds what more than one binary
//! uses: the benchmark's workloads (the bench and `step_profile` run the same signals), and
//! the workloads stepped through the FMI 2 C API for counting instructions (`capi_steps`).

pub mod capi_steps;
pub mod workloads;
