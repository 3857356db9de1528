//! FMI 3.0 C API: every function of fmi3Functions.h. Only Co-Simulation without event
//! mode is provided; Model Exchange and Scheduled Execution instantiation return NULL, and
//! functions of capabilities the modelDescription declares false return Error with a log
//! line "fmi3X is not supported by EhsvActuator".
//!
//! As in [`crate::fmi2`], each function is a thin shell over [`crate::fmi_common`]; the
//! functions are `unsafe extern "C"` (the importer guarantees the pointer contracts of the
//! standard; NULL pointers are checked and refused).

#![allow(non_snake_case, non_camel_case_types, non_upper_case_globals)]
#![deny(unsafe_op_in_unsafe_fn)]

use std::ffi::{c_char, c_int, c_void};

use crate::fmi_common::{
    self as common, free_instance, guarded, instantiate, unsupported, with_instance, Access,
    Boolean3, Float64, Fmi3Logger, Logger, State, Status, Version, ANY_STATE, GET_STATES,
    SET_STATES,
};

pub type fmi3Instance = *mut c_void;
pub type fmi3InstanceEnvironment = *mut c_void;
pub type fmi3FMUState = *mut c_void;
pub type fmi3ValueReference = u32;
pub type fmi3Float32 = f32;
pub type fmi3Float64 = f64;
pub type fmi3Int8 = i8;
pub type fmi3UInt8 = u8;
pub type fmi3Int16 = i16;
pub type fmi3UInt16 = u16;
pub type fmi3Int32 = i32;
pub type fmi3UInt32 = u32;
pub type fmi3Int64 = i64;
pub type fmi3UInt64 = u64;
pub type fmi3Boolean = bool;
pub type fmi3Char = c_char;
pub type fmi3String = *const fmi3Char;
pub type fmi3Byte = u8;
pub type fmi3Binary = *const fmi3Byte;
pub type fmi3Clock = bool;
pub type fmi3Status = Status;
/// `fmi3IntervalQualifier` and `fmi3DependencyKind` (C enums, taken as int).
pub type fmi3IntervalQualifier = c_int;
pub type fmi3DependencyKind = c_int;

pub type fmi3LogMessageCallback = Option<Fmi3Logger>;
pub type fmi3ClockUpdateCallback = Option<unsafe extern "C" fn(fmi3InstanceEnvironment)>;
pub type fmi3IntermediateUpdateCallback = Option<
    unsafe extern "C" fn(
        fmi3InstanceEnvironment,
        fmi3Float64,
        fmi3Boolean,
        fmi3Boolean,
        fmi3Boolean,
        fmi3Boolean,
        *mut fmi3Boolean,
        *mut fmi3Float64,
    ),
>;
pub type fmi3LockPreemptionCallback = Option<unsafe extern "C" fn()>;
pub type fmi3UnlockPreemptionCallback = Option<unsafe extern "C" fn()>;

const V: Version = Version::Fmi3;

/// Logs a refused instantiation of an interface this FMU does not provide.
///
/// # Safety
/// `name` is NULL or a C string.
unsafe fn refuse_interface(
    func: &'static str,
    name: fmi3String,
    env: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
) -> fmi3Instance {
    guarded(
        || {
            let logger = logMessage.map_or(Logger::None, |cb| Logger::Fmi3(cb, env));
            // SAFETY: forwarded contract.
            let label = unsafe { common::opt_str(name) }.unwrap_or(c"");
            logger.emit(
                label,
                Status::Error,
                common::LOG_CATEGORIES[common::LOG_ERROR].0,
                &format!("{func} is not supported by EhsvActuator (Co-Simulation only)"),
            );
            std::ptr::null_mut()
        },
        |_| std::ptr::null_mut(),
    )
}

// ---------------------------------------------------------------- common functions

#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

/// # Safety
/// `instance` is NULL or live; `categories` points to `nCategories` C strings.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: fmi3Instance,
    loggingOn: fmi3Boolean,
    nCategories: usize,
    categories: *const fmi3String,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3SetDebugLogging", ANY_STATE, |inst| {
            inst.set_debug_logging(loggingOn, nCategories, categories)
        })
    }
}

/// Not provided: NULL + log.
///
/// # Safety
/// `instanceName` is NULL or a C string.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    instanceName: fmi3String,
    _instantiationToken: fmi3String,
    _resourcePath: fmi3String,
    _visible: fmi3Boolean,
    _loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
) -> fmi3Instance {
    // SAFETY: forwarded contract.
    unsafe {
        refuse_interface(
            "fmi3InstantiateModelExchange",
            instanceName,
            instanceEnvironment,
            logMessage,
        )
    }
}

/// Refuses (NULL + log) a wrong token, an empty name and `eventModeUsed` (no event
/// mode). `resourcePath`, `visible`, `earlyReturnAllowed` (never used: steps do not
/// return early) and the intermediate-update arguments are not needed.
///
/// # Safety
/// String arguments are NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    _resourcePath: fmi3String,
    _visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    eventModeUsed: fmi3Boolean,
    _earlyReturnAllowed: fmi3Boolean,
    _requiredIntermediateVariables: *const fmi3ValueReference,
    _nRequiredIntermediateVariables: usize,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    _intermediateUpdate: fmi3IntermediateUpdateCallback,
) -> fmi3Instance {
    guarded(
        || {
            let logger =
                logMessage.map_or(Logger::None, |cb| Logger::Fmi3(cb, instanceEnvironment));
            let refusal = eventModeUsed
                .then(|| "eventModeUsed = true is not supported: EhsvActuator has no event mode (hasEventMode = false)".to_string());
            // SAFETY: string contracts forwarded.
            unsafe {
                instantiate(
                    V,
                    "fmi3InstantiateCoSimulation",
                    instanceName,
                    instantiationToken,
                    logger,
                    loggingOn,
                    refusal,
                )
            }
        },
        |_| std::ptr::null_mut(),
    )
}

/// Not provided: NULL + log.
///
/// # Safety
/// `instanceName` is NULL or a C string.
#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    instanceName: fmi3String,
    _instantiationToken: fmi3String,
    _resourcePath: fmi3String,
    _visible: fmi3Boolean,
    _loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    _clockUpdate: fmi3ClockUpdateCallback,
    _lockPreemption: fmi3LockPreemptionCallback,
    _unlockPreemption: fmi3UnlockPreemptionCallback,
) -> fmi3Instance {
    // SAFETY: forwarded contract.
    unsafe {
        refuse_interface(
            "fmi3InstantiateScheduledExecution",
            instanceName,
            instanceEnvironment,
            logMessage,
        )
    }
}

/// # Safety
/// `instance` is NULL or live, not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(instance: fmi3Instance) {
    // SAFETY: forwarded contract.
    unsafe { free_instance(instance, V, "fmi3FreeInstance") }
}

/// The tolerance is ignored (the integrator is exact); a defined stopTime bounds DoStep.
///
/// # Safety
/// `instance` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    instance: fmi3Instance,
    _toleranceDefined: fmi3Boolean,
    _tolerance: fmi3Float64,
    startTime: fmi3Float64,
    stopTimeDefined: fmi3Boolean,
    stopTime: fmi3Float64,
) -> fmi3Status {
    // SAFETY: forwarded contract.
    unsafe {
        with_instance(instance, V, "fmi3EnterInitializationMode", &[State::Instantiated], |inst| {
            inst.setup_experiment(startTime, stopTimeDefined.then_some(stopTime))?;
            inst.state = State::InitializationMode;
            Ok(Status::OK)
        })
    }
}

/// Without event mode the instance goes straight to Step Mode.
///
/// # Safety
/// `instance` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn fmi3ExitInitializationMode(instance: fmi3Instance) -> fmi3Status {
    // SAFETY: forwarded contract.
    unsafe {
        with_instance(
            instance,
            V,
            "fmi3ExitInitializationMode",
            &[State::InitializationMode],
            |inst| inst.exit_initialization(),
        )
    }
}

/// # Safety
/// `instance` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn fmi3EnterEventMode(instance: fmi3Instance) -> fmi3Status {
    // SAFETY: forwarded contract.
    unsafe { unsupported(instance, V, "fmi3EnterEventMode", " (no event mode)") }
}

/// # Safety
/// `instance` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn fmi3Terminate(instance: fmi3Instance) -> fmi3Status {
    // SAFETY: forwarded contract.
    unsafe {
        with_instance(instance, V, "fmi3Terminate", &[State::StepMode], |inst| {
            inst.state = State::Terminated;
            Ok(Status::OK)
        })
    }
}

/// # Safety
/// `instance` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn fmi3Reset(instance: fmi3Instance) -> fmi3Status {
    // SAFETY: forwarded contract.
    unsafe { with_instance(instance, V, "fmi3Reset", ANY_STATE, |inst| inst.reset()) }
}

// ---------------------------------------------------------------- get / set

/// One `fmi3Get<T>`/`fmi3Set<T>` pair over an [`Access`] type. `$c` is the C element
/// type of the signature; it has the layout of the accessor's element type.
macro_rules! get_set {
    ($get:ident, $set:ident, $acc:ty, $c:ty) => {
        /// # Safety
        /// `instance` is NULL or live; `valueReferences` has `nValueReferences` elements,
        /// `values` has `nValues`.
        #[no_mangle]
        pub unsafe extern "C" fn $get(
            instance: fmi3Instance,
            valueReferences: *const fmi3ValueReference,
            nValueReferences: usize,
            values: *mut $c,
            nValues: usize,
        ) -> fmi3Status {
            // SAFETY: forwarded contracts; `$c` and `<$acc as Access>::C` have the same
            // size and alignment (bool is read/written as a 0/1 byte).
            unsafe {
                with_instance(instance, V, stringify!($get), GET_STATES, |inst| {
                    inst.get_values::<$acc>(
                        valueReferences,
                        nValueReferences,
                        values.cast::<<$acc as Access>::C>(),
                        nValues,
                    )
                })
            }
        }

        /// # Safety
        /// As the getter.
        #[no_mangle]
        pub unsafe extern "C" fn $set(
            instance: fmi3Instance,
            valueReferences: *const fmi3ValueReference,
            nValueReferences: usize,
            values: *const $c,
            nValues: usize,
        ) -> fmi3Status {
            // SAFETY: as the getter.
            unsafe {
                with_instance(instance, V, stringify!($set), SET_STATES, |inst| {
                    inst.set_values::<$acc>(
                        valueReferences,
                        nValueReferences,
                        values.cast::<<$acc as Access>::C>(),
                        nValues,
                    )
                })
            }
        }
    };
}

get_set!(fmi3GetFloat32, fmi3SetFloat32, common::Float32, fmi3Float32);
get_set!(fmi3GetFloat64, fmi3SetFloat64, Float64, fmi3Float64);
get_set!(fmi3GetInt8, fmi3SetInt8, common::Int8, fmi3Int8);
get_set!(fmi3GetUInt8, fmi3SetUInt8, common::UInt8, fmi3UInt8);
get_set!(fmi3GetInt16, fmi3SetInt16, common::Int16, fmi3Int16);
get_set!(fmi3GetUInt16, fmi3SetUInt16, common::UInt16, fmi3UInt16);
get_set!(fmi3GetInt32, fmi3SetInt32, common::Int32, fmi3Int32);
get_set!(fmi3GetUInt32, fmi3SetUInt32, common::UInt32, fmi3UInt32);
get_set!(fmi3GetInt64, fmi3SetInt64, common::Int64, fmi3Int64);
get_set!(fmi3GetUInt64, fmi3SetUInt64, common::UInt64, fmi3UInt64);
get_set!(fmi3GetBoolean, fmi3SetBoolean, Boolean3, fmi3Boolean);

/// No String variables: only `nValueReferences = 0` succeeds.
///
/// # Safety
/// `instance` is NULL or live; `valueReferences` has `nValueReferences` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetString(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    _values: *mut fmi3String,
    nValues: usize,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3GetString", GET_STATES, |inst| {
            inst.no_values("String", valueReferences, nValueReferences, Some(nValues))
        })
    }
}

/// # Safety
/// As [`fmi3GetString`].
#[no_mangle]
pub unsafe extern "C" fn fmi3SetString(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    _values: *const fmi3String,
    nValues: usize,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3SetString", SET_STATES, |inst| {
            inst.no_values("String", valueReferences, nValueReferences, Some(nValues))
        })
    }
}

/// No Binary variables: only `nValueReferences = 0` succeeds.
///
/// # Safety
/// As [`fmi3GetString`].
#[no_mangle]
pub unsafe extern "C" fn fmi3GetBinary(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    _valueSizes: *mut usize,
    _values: *mut fmi3Binary,
    nValues: usize,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3GetBinary", GET_STATES, |inst| {
            inst.no_values("Binary", valueReferences, nValueReferences, Some(nValues))
        })
    }
}

/// # Safety
/// As [`fmi3GetString`].
#[no_mangle]
pub unsafe extern "C" fn fmi3SetBinary(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    _valueSizes: *const usize,
    _values: *const fmi3Binary,
    nValues: usize,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3SetBinary", SET_STATES, |inst| {
            inst.no_values("Binary", valueReferences, nValueReferences, Some(nValues))
        })
    }
}

/// No clocks: only `nValueReferences = 0` succeeds.
///
/// # Safety
/// As [`fmi3GetString`].
#[no_mangle]
pub unsafe extern "C" fn fmi3GetClock(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    _values: *mut fmi3Clock,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3GetClock", ANY_STATE, |inst| {
            inst.no_values("Clock", valueReferences, nValueReferences, None)
        })
    }
}

/// # Safety
/// As [`fmi3GetString`].
#[no_mangle]
pub unsafe extern "C" fn fmi3SetClock(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: usize,
    _values: *const fmi3Clock,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3SetClock", ANY_STATE, |inst| {
            inst.no_values("Clock", valueReferences, nValueReferences, None)
        })
    }
}

// ---------------------------------------------------------------- dependencies (not provided)

/// Not supported (providesPerElementDependencies = false; the dependencies are in the XML).
///
/// # Safety
/// `instance` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetNumberOfVariableDependencies(
    instance: fmi3Instance,
    _valueReference: fmi3ValueReference,
    _nDependencies: *mut usize,
) -> fmi3Status {
    // SAFETY: forwarded contract.
    unsafe {
        unsupported(
            instance,
            V,
            "fmi3GetNumberOfVariableDependencies",
            " (providesPerElementDependencies = false)",
        )
    }
}

/// Not supported (providesPerElementDependencies = false).
///
/// # Safety
/// `instance` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetVariableDependencies(
    instance: fmi3Instance,
    _dependent: fmi3ValueReference,
    _elementIndicesOfDependent: *mut usize,
    _independents: *mut fmi3ValueReference,
    _elementIndicesOfIndependents: *mut usize,
    _dependencyKinds: *mut fmi3DependencyKind,
    _nDependencies: usize,
) -> fmi3Status {
    // SAFETY: forwarded contract.
    unsafe {
        unsupported(
            instance,
            V,
            "fmi3GetVariableDependencies",
            " (providesPerElementDependencies = false)",
        )
    }
}

// ---------------------------------------------------------------- FMU state

/// # Safety
/// `instance` is NULL or live; `FMUState` is NULL or points to NULL or to a live state.
#[no_mangle]
pub unsafe extern "C" fn fmi3GetFMUState(
    instance: fmi3Instance,
    FMUState: *mut fmi3FMUState,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3GetFMUState", ANY_STATE, |inst| {
            inst.get_fmu_state(FMUState)
        })
    }
}

/// # Safety
/// `instance` is NULL or live; `FMUState` is NULL or a live state.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetFMUState(
    instance: fmi3Instance,
    FMUState: fmi3FMUState,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3SetFMUState", ANY_STATE, |inst| {
            inst.set_fmu_state(FMUState)
        })
    }
}

/// # Safety
/// As [`fmi3GetFMUState`].
#[no_mangle]
pub unsafe extern "C" fn fmi3FreeFMUState(
    instance: fmi3Instance,
    FMUState: *mut fmi3FMUState,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3FreeFMUState", ANY_STATE, |inst| {
            inst.free_fmu_state(FMUState)
        })
    }
}

/// # Safety
/// `instance` NULL or live; `FMUState` NULL or live; `size` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
    instance: fmi3Instance,
    FMUState: fmi3FMUState,
    size: *mut usize,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3SerializedFMUStateSize", ANY_STATE, |inst| {
            inst.serialized_size(FMUState, size)
        })
    }
}

/// # Safety
/// As above; `serializedState` points to `size` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn fmi3SerializeFMUState(
    instance: fmi3Instance,
    FMUState: fmi3FMUState,
    serializedState: *mut fmi3Byte,
    size: usize,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3SerializeFMUState", ANY_STATE, |inst| {
            inst.serialize(FMUState, serializedState, size)
        })
    }
}

/// # Safety
/// `serializedState` points to `size` bytes; `FMUState` as in [`fmi3GetFMUState`].
#[no_mangle]
pub unsafe extern "C" fn fmi3DeserializeFMUState(
    instance: fmi3Instance,
    serializedState: *const fmi3Byte,
    size: usize,
    FMUState: *mut fmi3FMUState,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3DeserializeFMUState", ANY_STATE, |inst| {
            inst.deserialize(serializedState, size, FMUState)
        })
    }
}

// ---------------------------------------------------------------- not provided

/// Generates exported functions that only report "not supported".
macro_rules! not_supported {
    ($($(#[$doc:meta])* $name:ident($($arg:ident: $ty:ty),*) $why:literal;)*) => {$(
        $(#[$doc])*
        ///
        /// # Safety
        /// `instance` is NULL or live (no other argument is read).
        #[no_mangle]
        pub unsafe extern "C" fn $name(instance: fmi3Instance, $($arg: $ty),*) -> fmi3Status {
            $(let _ = $arg;)*
            // SAFETY: forwarded contract.
            unsafe { unsupported(instance, V, stringify!($name), $why) }
        }
    )*};
}

not_supported! {
    /// Not supported (providesDirectionalDerivative = false).
    fmi3GetDirectionalDerivative(unknowns: *const fmi3ValueReference, nUnknowns: usize,
        knowns: *const fmi3ValueReference, nKnowns: usize, seed: *const fmi3Float64, nSeed: usize,
        sensitivity: *mut fmi3Float64, nSensitivity: usize) " (providesDirectionalDerivative = false)";
    /// Not supported (providesAdjointDerivatives = false).
    fmi3GetAdjointDerivative(unknowns: *const fmi3ValueReference, nUnknowns: usize,
        knowns: *const fmi3ValueReference, nKnowns: usize, seed: *const fmi3Float64, nSeed: usize,
        sensitivity: *mut fmi3Float64, nSensitivity: usize) " (providesAdjointDerivatives = false)";
    /// Not supported (no structural parameters).
    fmi3EnterConfigurationMode() " (no structural parameters)";
    /// Not supported (no structural parameters).
    fmi3ExitConfigurationMode() " (no structural parameters)";
    /// Not supported (no clocks).
    fmi3GetIntervalDecimal(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        intervals: *mut fmi3Float64, qualifiers: *mut fmi3IntervalQualifier) " (no clocks)";
    /// Not supported (no clocks).
    fmi3GetIntervalFraction(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        counters: *mut fmi3UInt64, resolutions: *mut fmi3UInt64,
        qualifiers: *mut fmi3IntervalQualifier) " (no clocks)";
    /// Not supported (no clocks).
    fmi3GetShiftDecimal(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        shifts: *mut fmi3Float64) " (no clocks)";
    /// Not supported (no clocks).
    fmi3GetShiftFraction(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        counters: *mut fmi3UInt64, resolutions: *mut fmi3UInt64) " (no clocks)";
    /// Not supported (no clocks).
    fmi3SetIntervalDecimal(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        intervals: *const fmi3Float64) " (no clocks)";
    /// Not supported (no clocks).
    fmi3SetIntervalFraction(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        counters: *const fmi3UInt64, resolutions: *const fmi3UInt64) " (no clocks)";
    /// Not supported (no clocks).
    fmi3SetShiftDecimal(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        shifts: *const fmi3Float64) " (no clocks)";
    /// Not supported (no clocks).
    fmi3SetShiftFraction(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        counters: *const fmi3UInt64, resolutions: *const fmi3UInt64) " (no clocks)";
    /// Not supported (no event mode).
    fmi3EvaluateDiscreteStates() " (no event mode)";
    /// Not supported (no event mode).
    fmi3UpdateDiscreteStates(discreteStatesNeedUpdate: *mut fmi3Boolean, terminateSimulation: *mut fmi3Boolean,
        nominalsOfContinuousStatesChanged: *mut fmi3Boolean, valuesOfContinuousStatesChanged: *mut fmi3Boolean,
        nextEventTimeDefined: *mut fmi3Boolean, nextEventTime: *mut fmi3Float64) " (no event mode)";
    /// Model Exchange: not provided.
    fmi3EnterContinuousTimeMode() " (Co-Simulation only)";
    /// Model Exchange: not provided.
    fmi3CompletedIntegratorStep(noSetFMUStatePriorToCurrentPoint: fmi3Boolean, enterEventMode: *mut fmi3Boolean,
        terminateSimulation: *mut fmi3Boolean) " (Co-Simulation only)";
    /// Model Exchange: not provided.
    fmi3SetTime(time: fmi3Float64) " (Co-Simulation only)";
    /// Model Exchange: not provided.
    fmi3SetContinuousStates(continuousStates: *const fmi3Float64, nContinuousStates: usize) " (Co-Simulation only)";
    /// Model Exchange: not provided.
    fmi3GetContinuousStateDerivatives(derivatives: *mut fmi3Float64, nContinuousStates: usize) " (Co-Simulation only)";
    /// Model Exchange: not provided.
    fmi3GetEventIndicators(eventIndicators: *mut fmi3Float64, nEventIndicators: usize) " (Co-Simulation only)";
    /// Model Exchange: not provided.
    fmi3GetContinuousStates(continuousStates: *mut fmi3Float64, nContinuousStates: usize) " (Co-Simulation only)";
    /// Model Exchange: not provided.
    fmi3GetNominalsOfContinuousStates(nominals: *mut fmi3Float64, nContinuousStates: usize) " (Co-Simulation only)";
    /// Model Exchange: not provided.
    fmi3GetNumberOfEventIndicators(nEventIndicators: *mut usize) " (Co-Simulation only)";
    /// Model Exchange: not provided.
    fmi3GetNumberOfContinuousStates(nContinuousStates: *mut usize) " (Co-Simulation only)";
    /// Not supported: without event mode the instance is in Step Mode after initialisation.
    fmi3EnterStepMode() " (no event mode: the instance is in Step Mode after fmi3ExitInitializationMode)";
    /// Not supported (maxOutputDerivativeOrder = 0).
    fmi3GetOutputDerivatives(valueReferences: *const fmi3ValueReference, nValueReferences: usize,
        orders: *const fmi3Int32, values: *mut fmi3Float64, nValues: usize) " (maxOutputDerivativeOrder = 0)";
    /// Scheduled Execution: not provided.
    fmi3ActivateModelPartition(clockReference: fmi3ValueReference, activationTime: fmi3Float64) " (Co-Simulation only)";
}

// ---------------------------------------------------------------- stepping

/// Synchronous step without events or early return: the out-flags are always false and
/// `*lastSuccessfulTime` is the model time (unchanged on error).
///
/// # Safety
/// `instance` is NULL or live; the out-pointers are NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn fmi3DoStep(
    instance: fmi3Instance,
    currentCommunicationPoint: fmi3Float64,
    communicationStepSize: fmi3Float64,
    _noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
    eventHandlingNeeded: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
    earlyReturn: *mut fmi3Boolean,
    lastSuccessfulTime: *mut fmi3Float64,
) -> fmi3Status {
    // SAFETY: forwarded contracts.
    unsafe {
        with_instance(instance, V, "fmi3DoStep", &[State::StepMode], |inst| {
            let event = inst.out("eventHandlingNeeded", eventHandlingNeeded)?;
            let terminate = inst.out("terminateSimulation", terminateSimulation)?;
            let early = inst.out("earlyReturn", earlyReturn)?;
            let last = inst.out("lastSuccessfulTime", lastSuccessfulTime)?;
            let result = inst.do_step(currentCommunicationPoint, communicationStepSize);
            *event = false;
            *terminate = false;
            *early = false;
            *last = inst.model.time();
            result
        })
    }
}
