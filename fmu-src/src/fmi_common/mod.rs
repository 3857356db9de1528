//! What the FMI 2.0 and FMI 3.0 C APIs share; [`crate::fmi2`] and [`crate::fmi3`] are thin
//! shells over it.
//!
//! * `instance`: the instance (model + FMI state + logger) and the frame every call runs
//!   in: call-sequence check against the table of [`state_machine`], panic catching, the
//!   Error state.
//! * [`state_machine`]: the call-sequence table and the Error rules.
//! * `logging`: the log categories, the importer's logger, the [`Status`] of every call.
//! * `arguments`: the importer's pointer arguments, checked before they are read.
//! * `values`: the typed get/set paths.
//! * `lifecycle`: experiment setup, initialisation, reset, doStep and its log lines.
//! * `fmu_state`: the FMU states (snapshots) an instance owns, and their bytes.
//! * `macros`: the generators of the exported functions of both versions.
//!
//! Every `unsafe` operation here dereferences a pointer handed in by the importer; the
//! FMI standards make the importer responsible for its validity (an array of `n`
//! elements, a live instance from our own `Instantiate`). We check what can be checked
//! (NULL, alignment, size overflow, our magic numbers) and document the rest.

#![deny(unsafe_op_in_unsafe_fn)]

mod arguments;
mod fmu_state;
mod instance;
mod lifecycle;
mod logging;
mod macros;
pub mod state_machine;
mod values;

pub(crate) use arguments::opt_str;
pub(crate) use instance::{free_instance, guarded, instantiate, with_instance};
pub use logging::{Fmi2Logger, Fmi3Logger, Status, LOG_CATEGORIES};
pub(crate) use logging::{Logger, LOG_ERROR};
pub(crate) use macros::{fmi_functions, fmu_state_functions, not_supported};
pub(crate) use state_machine::{Call, Version};
pub(crate) use values::{
    Access, Boolean2, Boolean3, Float32, Float64, Int16, Int32, Int64, Int8, Integer2, Real2,
    UInt16, UInt32, UInt64, UInt8,
};
