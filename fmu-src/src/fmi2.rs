//! FMI 2.0 Co-Simulation C API: every function of fmi2Functions.h for a CS-only FMU.
//!
//! Each function is a thin shell: [`with_instance`] checks the instance pointer, the FMI
//! version and the call sequence, catches panics, and runs the body; the shared logic is
//! in [`crate::fmi_common`]. The functions are `unsafe extern "C"`: the caller (an FMI
//! importer) guarantees the pointer contracts of the standard (arrays of the announced
//! length, live instances and FMU states); NULL pointers are checked and refused.

#![allow(non_snake_case, non_camel_case_types, non_upper_case_globals)]
#![deny(unsafe_op_in_unsafe_fn)]

use std::ffi::{c_char, c_int, c_uint, c_void};

use crate::fmi_common::{
    free_instance, guarded, instantiate, unsupported, with_instance, Boolean2, Fmi2Logger,
    Integer2, Logger, Real2, State, Status, Version, ANY_STATE, GET_STATES, SET_STATES,
};

pub type fmi2Component = *mut c_void;
pub type fmi2ComponentEnvironment = *mut c_void;
pub type fmi2FMUstate = *mut c_void;
pub type fmi2ValueReference = c_uint;
pub type fmi2Real = f64;
pub type fmi2Integer = c_int;
pub type fmi2Boolean = c_int;
pub type fmi2Char = c_char;
pub type fmi2String = *const fmi2Char;
pub type fmi2Byte = c_char;
pub type fmi2Status = Status;

pub const fmi2True: fmi2Boolean = 1;
pub const fmi2False: fmi2Boolean = 0;

/// `fmi2Type` (a C enum, taken as int so any value from C is defined behaviour).
pub type fmi2Type = c_int;
pub const fmi2ModelExchange: fmi2Type = 0;
pub const fmi2CoSimulation: fmi2Type = 1;

/// `fmi2StatusKind`.
pub type fmi2StatusKind = c_int;
pub const fmi2DoStepStatus: fmi2StatusKind = 0;
pub const fmi2PendingStatus: fmi2StatusKind = 1;
pub const fmi2LastSuccessfulTime: fmi2StatusKind = 2;
pub const fmi2Terminated: fmi2StatusKind = 3;

pub type fmi2CallbackLogger = Option<Fmi2Logger>;
pub type fmi2CallbackAllocateMemory = Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>;
pub type fmi2CallbackFreeMemory = Option<unsafe extern "C" fn(*mut c_void)>;
pub type fmi2StepFinished = Option<unsafe extern "C" fn(fmi2ComponentEnvironment, fmi2Status)>;

/// `fmi2CallbackFunctions`. Only `logger` and `componentEnvironment` are used: memory
/// comes from the Rust allocator and steps are synchronous.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct fmi2CallbackFunctions {
    pub logger: fmi2CallbackLogger,
    pub allocateMemory: fmi2CallbackAllocateMemory,
    pub freeMemory: fmi2CallbackFreeMemory,
    pub stepFinished: fmi2StepFinished,
    pub componentEnvironment: fmi2ComponentEnvironment,
}

const V: Version = Version::Fmi2;

// ---------------------------------------------------------------- common functions

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// # Safety
/// `c` is NULL or a live instance; `categories` points to `nCategories` C strings.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: fmi2Component,
    loggingOn: fmi2Boolean,
    nCategories: usize,
    categories: *const fmi2String,
) -> fmi2Status {
    // SAFETY: pointer contracts forwarded from the caller.
    unsafe {
        with_instance(c, V, "fmi2SetDebugLogging", ANY_STATE, |inst| {
            inst.set_debug_logging(loggingOn != fmi2False, nCategories, categories)
        })
    }
}

/// Refuses (NULL + log) another fmuType, a wrong GUID or an empty name. `functions`
/// and its logger may be NULL (then nothing is logged); `fmuResourceLocation` is unused.
///
/// # Safety
/// String arguments are NULL or NUL-terminated; `functions` is NULL or valid.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instanceName: fmi2String,
    fmuType: fmi2Type,
    fmuGUID: fmi2String,
    _fmuResourceLocation: fmi2String,
    functions: *const fmi2CallbackFunctions,
    _visible: fmi2Boolean,
    loggingOn: fmi2Boolean,
) -> fmi2Component {
    guarded(
        || {
            // SAFETY: a non-NULL `functions` points to a valid struct (FMI contract).
            let logger = match unsafe { functions.as_ref() } {
                Some(fns) => {
                    fns.logger.map_or(Logger::None, |cb| Logger::Fmi2(cb, fns.componentEnvironment))
                }
                None => Logger::None,
            };
            let refusal = (fmuType != fmi2CoSimulation).then(|| {
                format!("fmuType {fmuType} is not supported: EhsvActuator is a Co-Simulation FMU only (fmi2CoSimulation = 1)")
            });
            // SAFETY: string contracts forwarded.
            unsafe {
                instantiate(
                    V,
                    "fmi2Instantiate",
                    instanceName,
                    fmuGUID,
                    logger,
                    loggingOn != fmi2False,
                    refusal,
                )
            }
        },
        |_| std::ptr::null_mut(),
    )
}

/// # Safety
/// `c` is NULL or a live instance, not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
    // SAFETY: forwarded contract.
    unsafe { free_instance(c, V, "fmi2FreeInstance") }
}

/// The tolerance is ignored (the integrator is exact); a defined stopTime bounds DoStep.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: fmi2Component,
    _toleranceDefined: fmi2Boolean,
    _tolerance: fmi2Real,
    startTime: fmi2Real,
    stopTimeDefined: fmi2Boolean,
    stopTime: fmi2Real,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        with_instance(c, V, "fmi2SetupExperiment", &[State::Instantiated], |inst| {
            inst.setup_experiment(startTime, (stopTimeDefined != fmi2False).then_some(stopTime))
        })
    }
}

/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        with_instance(c, V, "fmi2EnterInitializationMode", &[State::Instantiated], |inst| {
            inst.state = State::InitializationMode;
            Ok(Status::OK)
        })
    }
}

/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        with_instance(c, V, "fmi2ExitInitializationMode", &[State::InitializationMode], |inst| {
            inst.exit_initialization()
        })
    }
}

/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        with_instance(c, V, "fmi2Terminate", &[State::StepMode], |inst| {
            inst.state = State::Terminated;
            Ok(Status::OK)
        })
    }
}

/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe { with_instance(c, V, "fmi2Reset", ANY_STATE, |inst| inst.reset()) }
}

// ---------------------------------------------------------------- get / set

/// # Safety
/// `c` is NULL or a live instance; `vr` and `value` point to `nvr` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Real,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2GetReal", GET_STATES, |inst| {
            inst.get_values::<Real2>(vr, nvr, value, nvr)
        })
    }
}

/// Enumerations are read with fmi2GetInteger.
///
/// # Safety
/// As [`fmi2GetReal`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Integer,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2GetInteger", GET_STATES, |inst| {
            inst.get_values::<Integer2>(vr, nvr, value, nvr)
        })
    }
}

/// # Safety
/// As [`fmi2GetReal`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2GetBoolean", GET_STATES, |inst| {
            inst.get_values::<Boolean2>(vr, nvr, value, nvr)
        })
    }
}

/// There are no String variables: only `nvr = 0` succeeds.
///
/// # Safety
/// As [`fmi2GetReal`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *mut fmi2String,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2GetString", GET_STATES, |inst| {
            inst.no_values("String", vr, nvr, None)
        })
    }
}

/// # Safety
/// `c` is NULL or a live instance; `vr` and `value` point to `nvr` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Real,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2SetReal", SET_STATES, |inst| {
            inst.set_values::<Real2>(vr, nvr, value, nvr)
        })
    }
}

/// Enumerations are set with fmi2SetInteger.
///
/// # Safety
/// As [`fmi2SetReal`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Integer,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2SetInteger", SET_STATES, |inst| {
            inst.set_values::<Integer2>(vr, nvr, value, nvr)
        })
    }
}

/// # Safety
/// As [`fmi2SetReal`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Boolean,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2SetBoolean", SET_STATES, |inst| {
            inst.set_values::<Boolean2>(vr, nvr, value, nvr)
        })
    }
}

/// # Safety
/// As [`fmi2SetReal`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *const fmi2String,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2SetString", SET_STATES, |inst| {
            inst.no_values("String", vr, nvr, None)
        })
    }
}

// ---------------------------------------------------------------- FMU state

/// # Safety
/// `c` is NULL or a live instance; `FMUstate` is NULL or points to NULL or to a live state.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(
    c: fmi2Component,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2GetFMUstate", ANY_STATE, |inst| inst.get_fmu_state(FMUstate))
    }
}

/// # Safety
/// `c` is NULL or a live instance; `FMUstate` is NULL or a live state.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: fmi2Component, FMUstate: fmi2FMUstate) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2SetFMUstate", ANY_STATE, |inst| inst.set_fmu_state(FMUstate))
    }
}

/// # Safety
/// As [`fmi2GetFMUstate`].
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(
    c: fmi2Component,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2FreeFMUstate", ANY_STATE, |inst| inst.free_fmu_state(FMUstate))
    }
}

/// # Safety
/// `c` is NULL or a live instance; `FMUstate` NULL or live; `size` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2SerializedFMUstateSize", ANY_STATE, |inst| {
            inst.serialized_size(FMUstate, size)
        })
    }
}

/// # Safety
/// As above; `serializedState` points to `size` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    serializedState: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2SerializeFMUstate", ANY_STATE, |inst| {
            inst.serialize(FMUstate, serializedState.cast(), size)
        })
    }
}

/// # Safety
/// `serializedState` points to `size` bytes; `FMUstate` as in [`fmi2GetFMUstate`].
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: fmi2Component,
    serializedState: *const fmi2Byte,
    size: usize,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2DeSerializeFMUstate", ANY_STATE, |inst| {
            inst.deserialize(serializedState.cast(), size, FMUstate)
        })
    }
}

// ---------------------------------------------------------------- derivatives (not provided)

/// Not supported (providesDirectionalDerivative = false).
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: fmi2Component,
    _vUnknown_ref: *const fmi2ValueReference,
    _nUnknown: usize,
    _vKnown_ref: *const fmi2ValueReference,
    _nKnown: usize,
    _dvKnown: *const fmi2Real,
    _dvUnknown: *mut fmi2Real,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        unsupported(
            c,
            V,
            "fmi2GetDirectionalDerivative",
            " (providesDirectionalDerivative = false)",
        )
    }
}

/// Not supported (canInterpolateInputs = false).
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: fmi2Component,
    _vr: *const fmi2ValueReference,
    _nvr: usize,
    _order: *const fmi2Integer,
    _value: *const fmi2Real,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe { unsupported(c, V, "fmi2SetRealInputDerivatives", " (canInterpolateInputs = false)") }
}

/// Not supported (maxOutputDerivativeOrder = 0).
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: fmi2Component,
    _vr: *const fmi2ValueReference,
    _nvr: usize,
    _order: *const fmi2Integer,
    _value: *mut fmi2Real,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe { unsupported(c, V, "fmi2GetRealOutputDerivatives", " (maxOutputDerivativeOrder = 0)") }
}

// ---------------------------------------------------------------- stepping

/// Synchronous step. `noSetFMUStatePriorToCurrentPoint` is ignored (states are cheap).
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(
    c: fmi2Component,
    currentCommunicationPoint: fmi2Real,
    communicationStepSize: fmi2Real,
    _noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        with_instance(c, V, "fmi2DoStep", &[State::StepMode], |inst| {
            inst.do_step(currentCommunicationPoint, communicationStepSize)
        })
    }
}

/// fmi2DoStep never returns fmi2Pending, so there is never a step to cancel.
///
/// # Safety
/// `c` is NULL or a live instance.
#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
    // SAFETY: forwarded contract.
    unsafe {
        with_instance(c, V, "fmi2CancelStep", ANY_STATE, |inst| {
            inst.error("no asynchronous step is in progress (fmi2DoStep is synchronous, it never returns fmi2Pending)")
        })
    }
}

const STATUS_STATES: &[State] = &[State::StepMode, State::Terminated];

/// Status of an asynchronous step: never available (Discard, as the standard asks for
/// status kinds the slave cannot provide).
///
/// # Safety
/// `c` is NULL or a live instance; `value` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Status,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2GetStatus", STATUS_STATES, |inst| {
            inst.out("value", value)?;
            inst.discard(&format!("status kind {s} is not available (fmi2DoStep is synchronous)"))
        })
    }
}

/// fmi2LastSuccessfulTime → the model time; other kinds Discard.
///
/// # Safety
/// `c` is NULL or a live instance; `value` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Real,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2GetRealStatus", STATUS_STATES, |inst| {
            let value = inst.out("value", value)?;
            if s != fmi2LastSuccessfulTime {
                return inst.discard(&format!(
                    "status kind {s} has no Real value (only fmi2LastSuccessfulTime)"
                ));
            }
            *value = inst.model.time();
            Ok(Status::OK)
        })
    }
}

/// No Integer status kinds: Discard.
///
/// # Safety
/// `c` is NULL or a live instance; `value` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Integer,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2GetIntegerStatus", STATUS_STATES, |inst| {
            inst.out("value", value)?;
            inst.discard(&format!("status kind {s} has no Integer value"))
        })
    }
}

/// fmi2Terminated → false (the FMU never asks to stop); other kinds Discard.
///
/// # Safety
/// `c` is NULL or a live instance; `value` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2GetBooleanStatus", STATUS_STATES, |inst| {
            let value = inst.out("value", value)?;
            if s != fmi2Terminated {
                return inst.discard(&format!(
                    "status kind {s} has no Boolean value (only fmi2Terminated)"
                ));
            }
            *value = fmi2False;
            Ok(Status::OK)
        })
    }
}

/// No String status kinds (fmi2PendingStatus needs an asynchronous step): Discard.
///
/// # Safety
/// `c` is NULL or a live instance; `value` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2String,
) -> fmi2Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(c, V, "fmi2GetStringStatus", STATUS_STATES, |inst| {
            inst.out("value", value)?;
            inst.discard(&format!(
                "status kind {s} has no String value (fmi2DoStep is synchronous)"
            ))
        })
    }
}
