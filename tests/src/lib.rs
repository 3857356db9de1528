//! Test-only crate: see tests/*.rs and src/bin.
