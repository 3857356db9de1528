//! Macros that generate the exported C functions of both FMI versions alike: each
//! function on an instance is its C signature, its row of the call-sequence table
//! ([`super::Call`]) and a body run inside [`super::with_instance`].

/// Exported functions on an instance. The first argument is the instance; `$call` names
/// the row of the call-sequence table; `$body` runs with the instance as `$inst` and
/// returns `Result<Status, Status>`. The invoking module defines `V`, its FMI version.
macro_rules! fmi_functions {
    ($(
        $(#[$doc:meta])*
        fn $name:ident($instance:ident: $ity:ty $(, $arg:ident: $aty:ty)* $(,)?)
            $call:ident => |$inst:ident| $body:expr;
    )*) => {$(
        $(#[$doc])*
        ///
        /// # Safety
        /// The instance is NULL or live (from this FMU's Instantiate, not yet freed) and
        /// used by one thread at a time; pointer arguments are NULL or follow the FMI
        /// contract (arrays of the announced length, writable out-parameters).
        #[no_mangle]
        pub unsafe extern "C" fn $name($instance: $ity $(, $arg: $aty)*) -> Status {
            // SAFETY: the caller's contract, forwarded; `with_instance` checks the instance
            // pointer, the body checks every other pointer it reads.
            unsafe {
                $crate::fmi_common::with_instance::<Actuator>(
                    $instance,
                    V,
                    stringify!($name),
                    $crate::fmi_common::Call::$call,
                    |$inst| $body,
                )
            }
        }
    )*};
}

/// Exported functions of capabilities this FMU does not have: Error +
/// `"fmiX is not supported by EhsvActuator<why>"` (allowed in every state; no argument is read).
macro_rules! not_supported {
    ($(
        $(#[$doc:meta])*
        fn $name:ident($instance:ident: $ity:ty $(, $arg:ident: $aty:ty)* $(,)?) $why:literal;
    )*) => {
        $crate::fmi_common::fmi_functions! {$(
            $(#[$doc])*
            fn $name($instance: $ity $(, $arg: $aty)*) Unsupported => |inst| {
                $(let _ = $arg;)*
                inst.unsupported($why)
            };
        )*}
    };
}

/// The six FMU-state functions (get, set, free, size, serialize, deserialize), the same
/// in both versions but for names and types.
macro_rules! fmu_state_functions {
    (
        instance: $ity:ty, state: $sty:ty, byte: $bty:ty,
        $get:ident, $set:ident, $free:ident, $size:ident, $serialize:ident, $deserialize:ident
    ) => {
        $crate::fmi_common::fmi_functions! {
            /// Stores the instance's state (model, FMI mode, stop time) into `*state`: a new
            /// FMU state for NULL, else the given one is overwritten.
            fn $get(instance: $ity,
                state: *mut $sty) GetFMUState => |inst| inst.get_fmu_state(state);
            /// Restores an FMU state this instance made, FMI mode and stop time included.
            fn $set(instance: $ity, state: $sty) SetFMUState => |inst| inst.set_fmu_state(state);
            /// Frees `*state` and sets it to NULL (NULL is fine).
            fn $free(instance: $ity,
                state: *mut $sty) StoredFMUState => |inst| inst.free_fmu_state(state);
            /// The size of the serialized FMU state.
            fn $size(instance: $ity, state: $sty, size: *mut usize)
                StoredFMUState => |inst| inst.serialized_size(state, size);
            /// Writes the FMU state into `serializedState` (`size` bytes at least).
            fn $serialize(instance: $ity, state: $sty, serializedState: *mut $bty, size: usize)
                StoredFMUState => |inst| inst.serialize(state, serializedState.cast(), size);
            /// A new (or the given) FMU state from bytes, checked: mode byte, stop time,
            /// model bytes, checksum.
            fn $deserialize(instance: $ity, serializedState: *const $bty, size: usize,
                state: *mut $sty)
                StoredFMUState => |inst| inst.deserialize(serializedState.cast(), size, state);
        }
    };
}

pub(crate) use {fmi_functions, fmu_state_functions, not_supported};
