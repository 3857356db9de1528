//! Test-only crate: see tests/*.rs and src/bin. The library holds what more than one binary
//! uses: the benchmark's workloads (the bench and `step_profile` run the same signals).

pub mod workloads;
