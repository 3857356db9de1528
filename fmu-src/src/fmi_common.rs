//! What the FMI 2.0 and FMI 3.0 C APIs share: the instance (model + FMI state + logger),
//! the frame every call runs in (call-sequence check against the table of
//! [`crate::fmi_state_machine`], panic catching, the Error state), logging, the typed
//! get/set paths and the FMU states (snapshots) an instance owns. [`crate::fmi2`] and
//! [`crate::fmi3`] are thin shells over it.
//!
//! Every `unsafe` operation here dereferences a pointer handed in by the importer; the
//! FMI standards make the importer responsible for its validity (an array of `n`
//! elements, a live instance from our own `Instantiate`). We check what can be checked
//! (NULL, alignment, size overflow, our magic numbers) and document the rest.

#![deny(unsafe_op_in_unsafe_fn)]

use std::collections::HashMap;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use crate::fmi_state_machine::settable_in;
pub(crate) use crate::fmi_state_machine::{Call, State, Version};
use crate::model::{communication_point_tolerance, InputWarning, Model};
use crate::physics::StepEvents;
use crate::variables::{Causality, VarType, Variability, VARIABLES};

/// Log categories, `(name, description)`: the one list the C API accepts in
/// `SetDebugLogging` and both modelDescription.xml files declare.
pub const LOG_CATEGORIES: &[(&str, &str)] = &[
    (
        "logEvents",
        "Events inside a communication step: the driver output reaching or leaving a supply rail",
    ),
    (
        "logStatusWarning",
        "Calls that return Warning or Discard: a doStep where i_ref rises above the valve's \
         rated current, or a supply (V_supply, p_supply) is 0 while a command asks for motion \
         (once when the condition begins)",
    ),
    ("logStatusError", "Calls that return Error (always logged when a logger callback is given)"),
    ("logAll", "Everything, including one line per call into the FMU"),
];
pub(crate) const LOG_EVENTS: usize = 0;
pub(crate) const LOG_WARNING: usize = 1;
pub(crate) const LOG_ERROR: usize = 2;
pub(crate) const LOG_ALL: usize = 3;
const N_CATEGORIES: usize = LOG_CATEGORIES.len();

/// `fmi2Status` / `fmi3Status`: same numbering in both standards (FMI 2's `fmi2Pending`
/// is never returned: this FMU steps synchronously).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    OK = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
}

use State::{InitializationMode, Instantiated, StepMode, Terminated};

/// FMI 2 `fmi2CallbackLogger` (C-variadic: the message is a printf format string).
pub type Fmi2Logger =
    unsafe extern "C" fn(*mut c_void, *const c_char, c_int, *const c_char, *const c_char, ...);
/// FMI 3 `fmi3LogMessageCallback`.
pub type Fmi3Logger = unsafe extern "C" fn(*mut c_void, c_int, *const c_char, *const c_char);

#[derive(Clone, Copy)]
pub(crate) enum Logger {
    None,
    Fmi2(Fmi2Logger, *mut c_void),
    Fmi3(Fmi3Logger, *mut c_void),
}

/// A C string from Rust text; interior NULs (never expected) are made visible, not fatal.
fn c_text(s: &str) -> CString {
    CString::new(s.replace('\0', "\\0")).unwrap_or_default()
}

impl Logger {
    /// Sends one message. FMI 2 treats `message` as a printf format, so every '%' is doubled.
    pub(crate) fn emit(&self, instance_name: &CStr, status: Status, category: &str, message: &str) {
        match *self {
            Logger::None => {}
            Logger::Fmi2(cb, env) => {
                let msg = c_text(&message.replace('%', "%%"));
                let cat = c_text(category);
                // SAFETY: `cb` is the importer's logger from fmi2CallbackFunctions; every
                // string argument is a live NUL-terminated C string, and `msg` has no
                // unescaped conversion so no variadic argument is read.
                unsafe {
                    cb(env, instance_name.as_ptr(), status as c_int, cat.as_ptr(), msg.as_ptr())
                }
            }
            Logger::Fmi3(cb, env) => {
                let msg = c_text(message);
                let cat = c_text(category);
                // SAFETY: `cb` is the importer's logMessage callback; arguments are live C strings.
                unsafe { cb(env, status as c_int, cat.as_ptr(), msg.as_ptr()) }
            }
        }
    }
}

const INSTANCE_MAGIC: u64 = 0x4548_5356_494e_5354; // "EHSVINST"

/// One FMU instance, behind the `fmi2Component` / `fmi3Instance` pointer.
#[repr(C)]
pub(crate) struct Instance {
    /// First field, so a foreign or freed pointer is likely to be recognised.
    magic: u64,
    version: Version,
    name: CString,
    logger: Logger,
    categories: [bool; N_CATEGORIES],
    /// The exported function being executed (prefix of error messages).
    func: &'static str,
    pub(crate) model: Model,
    pub(crate) state: State,
    pub(crate) stop_time: Option<f64>,
    /// The FMU states this instance handed out and the importer has not freed, by the
    /// address the importer holds: FreeInstance frees what is left, and a pointer that is
    /// not in here (freed, foreign, garbage) is refused without being read.
    fmu_states: HashMap<usize, Box<SavedState>>,
    /// Which [`InputWarning`]s held at the last doStep: each is reported when it begins.
    warned: [bool; InputWarning::ALL.len()],
}

/// An FMU state behind `fmi2FMUstate` / `fmi3FMUState`: everything needed to continue
/// (FMI 2.0.4 2.1.8, FMI 3.0): the model, the FMI state it was taken in, the stop time.
struct SavedState {
    model: Model,
    mode: State,
    stop_time: Option<f64>,
}

/// Format and version of the serialized FMU state (the model's own bytes are inside).
const FMU_STATE_MAGIC: &[u8; 8] = b"EHSVFS01";

impl SavedState {
    /// mode | stop time defined (0/1) | stop time (0 if undefined) | model bytes, framed
    /// and checksummed as the model's bytes are.
    fn to_bytes(&self) -> Vec<u8> {
        let mut body = vec![self.mode.code(), self.stop_time.is_some() as u8];
        body.extend_from_slice(&self.stop_time.unwrap_or(0.0).to_le_bytes());
        body.extend_from_slice(&self.model.to_bytes());
        crate::model::frame(FMU_STATE_MAGIC, &body)
    }

    /// Inverse of [`SavedState::to_bytes`]; refuses what the FMU would never have written.
    fn from_bytes(bytes: &[u8]) -> Result<SavedState, String> {
        let body = crate::model::unframe(FMU_STATE_MAGIC, bytes)?;
        let (head, model) = body.split_at_checked(10).ok_or("state is truncated")?;
        let mode = State::from_code(head[0])
            .ok_or_else(|| format!("state has an unknown FMI mode code {}", head[0]))?;
        let stop = f64::from_le_bytes(head[2..10].try_into().expect("8 bytes"));
        let stop_time = match head[1] {
            0 if stop.to_bits() == 0 => None,
            1 if stop.is_finite() => Some(stop),
            flag => return Err(format!("state has an invalid stop time ({flag}, {stop})")),
        };
        let model = Model::from_bytes(model)?;
        check_restored(&model)?;
        if model.is_initialized() != matches!(mode, StepMode | Terminated) {
            return Err(format!(
                "state's FMI mode code {} does not match its model (initialised: {})",
                head[0],
                model.is_initialized()
            ));
        }
        Ok(SavedState { model, mode, stop_time })
    }
}

fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic".to_string()
    }
}

/// Runs `f`, turning a panic into `on_panic(message)`: no panic crosses the C boundary.
pub(crate) fn guarded<R>(f: impl FnOnce() -> R, on_panic: impl FnOnce(String) -> R) -> R {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => on_panic(panic_text(&*payload)),
    }
}

/// Reads a C string argument; `None` for NULL.
///
/// # Safety
/// `p` is NULL or a NUL-terminated string (FMI contract).
pub(crate) unsafe fn opt_str<'a>(p: *const c_char) -> Option<&'a CStr> {
    // SAFETY: see function contract.
    (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) })
}

/// Creates an instance after checking name and token; on refusal logs through `logger`
/// (errors are always logged) and returns NULL.
///
/// # Safety
/// `name` and `token` are NULL or NUL-terminated strings.
pub(crate) unsafe fn instantiate(
    version: Version,
    func: &'static str,
    name: *const c_char,
    token: *const c_char,
    logger: Logger,
    logging_on: bool,
    refusal: Option<String>,
) -> *mut c_void {
    // SAFETY: forwarded contract.
    let (name, token) = unsafe { (opt_str(name), opt_str(token)) };
    let shown = name.map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let refuse = |why: String| {
        let label = name.unwrap_or(c"");
        logger.emit(label, Status::Error, LOG_CATEGORIES[LOG_ERROR].0, &format!("{func}: {why}"));
        std::ptr::null_mut()
    };
    let name = match name {
        Some(n) if !n.is_empty() => n,
        _ => return refuse("instanceName must be a non-empty string".into()),
    };
    let expected = crate::variables::interface_token();
    let what = if version == Version::Fmi2 { "fmuGUID" } else { "instantiationToken" };
    match token.map(|t| t.to_string_lossy()) {
        None => return refuse(format!("instance '{shown}': {what} is NULL (expected {expected})")),
        Some(t) if t != expected => {
            return refuse(format!(
                "instance '{shown}': {what} {t} does not match this FMU ({expected}); \
                 the modelDescription.xml belongs to another build"
            ))
        }
        Some(_) => {}
    }
    if let Some(why) = refusal {
        return refuse(format!("instance '{shown}': {why}"));
    }
    let inst = Box::new(Instance {
        magic: INSTANCE_MAGIC,
        version,
        name: name.to_owned(),
        logger,
        categories: [logging_on; N_CATEGORIES],
        func,
        model: Model::new(),
        state: Instantiated,
        stop_time: None,
        fmu_states: HashMap::new(),
        warned: [false; InputWarning::ALL.len()],
    });
    inst.trace(|| format!("{func}: instance '{shown}' created"));
    Box::into_raw(inst).cast()
}

/// The instance behind `ptr` if it is one of ours; NULL or foreign → `None`.
///
/// # Safety
/// `ptr` is NULL or was returned by our `Instantiate` and not yet freed.
unsafe fn instance_ptr(ptr: *mut c_void) -> Option<*mut Instance> {
    let p = ptr.cast::<Instance>();
    // SAFETY: non-NULL `p` points to an Instance (contract); `magic` is its first field.
    (!p.is_null() && p.is_aligned() && unsafe { (*p).magic } == INSTANCE_MAGIC).then_some(p)
}

/// The frame of every exported function taking an instance: NULL/foreign instance →
/// Error (no logger to tell); wrong FMI version, or `call` not allowed in the instance's
/// state by the table → Error + log, nothing changed; then `f`, with panics caught,
/// logged as "internal error" and the instance put in the Error state. `Err` and `Ok`
/// both carry the status to return (`Err` for early exits through `?`).
///
/// # Safety
/// `ptr` is NULL or a live instance from our `Instantiate`; nothing else may use the
/// instance during the call (FMI: one instance is called from one thread at a time).
pub(crate) unsafe fn with_instance(
    ptr: *mut c_void,
    version: Version,
    func: &'static str,
    call: Call,
    f: impl FnOnce(&mut Instance) -> Result<Status, Status>,
) -> Status {
    // SAFETY: forwarded contract.
    let Some(p) = (unsafe { instance_ptr(ptr) }) else { return Status::Error };
    guarded(
        || {
            // SAFETY: `p` is a live instance, exclusively ours for this call.
            let inst = unsafe { &mut *p };
            inst.func = func;
            if inst.version != version {
                return inst.fail("called with an instance of the other FMI version");
            }
            inst.trace(|| format!("{func} (state {})", inst.state.name(version)));
            let allowed = call.allowed();
            if !allowed.contains(inst.state) {
                let after_error = if inst.state == State::Error {
                    "; after a failed call only SetFMUState, Reset and FreeInstance go on"
                } else {
                    ""
                };
                return inst.fail(&format!(
                    "illegal call sequence: {func} is not allowed in state {} (only in {}){after_error}",
                    inst.state.name(version),
                    allowed.names(version)
                ));
            }
            match f(inst) {
                Ok(s) | Err(s) => s,
            }
        },
        |msg| {
            // SAFETY: as above; the closure that panicked no longer borrows the instance.
            let inst = unsafe { &mut *p };
            inst.state = State::Error;
            guarded(
                || inst.fail(&format!("internal error: {msg}; the instance is in the Error state")),
                |_| Status::Error,
            )
        },
    )
}

/// Frees an instance (NULL or foreign: nothing happens).
///
/// # Safety
/// As [`with_instance`]; `ptr` is not used afterwards.
pub(crate) unsafe fn free_instance(ptr: *mut c_void, version: Version, func: &'static str) {
    // SAFETY: forwarded contract.
    let Some(p) = (unsafe { instance_ptr(ptr) }) else { return };
    guarded(
        || {
            // SAFETY: `p` came from Box::into_raw in `instantiate` and is freed once.
            let mut inst = unsafe { Box::from_raw(p) };
            if inst.version != version {
                inst.func = func;
                inst.fail("called with an instance of the other FMI version");
                std::mem::forget(inst); // not ours to free through this API
                return;
            }
            inst.trace(|| format!("{func} (and {} FMU state(s) not freed)", inst.fmu_states.len()));
            inst.magic = 0; // dropping `inst` frees the instance and its FMU states
        },
        |_| (),
    )
}

/// Conversions between a C value type and the model's `f64`, and which variable
/// types the accessor serves. One zero-sized type per FMI getter/setter family.
pub(crate) trait Access {
    type C: Copy;
    /// The FMI type name in messages ("Real", "Float64", ...).
    const NAME: &'static str;
    fn accepts(ty: VarType) -> bool;
    fn to_c(v: f64) -> Self::C;
    fn from_c(c: Self::C) -> f64;
}

macro_rules! access {
    ($(#[$doc:meta])* $name:ident, $c:ty, $label:literal, $accepts:expr, $to:expr, $from:expr) => {
        $(#[$doc])*
        pub(crate) struct $name;
        impl Access for $name {
            type C = $c;
            const NAME: &'static str = $label;
            fn accepts(ty: VarType) -> bool {
                ($accepts)(ty)
            }
            fn to_c(v: f64) -> $c {
                ($to)(v)
            }
            fn from_c(c: $c) -> f64 {
                ($from)(c)
            }
        }
    };
}

// Values are exact: enumeration values and Booleans are small integers stored in f64.
access!(Real2, f64, "Real", |t| t == VarType::Real, |v| v, |c| c);
access!(
    /// fmi2Integer serves enumerations (FMI 2 has no separate enumeration accessor).
    Integer2, c_int, "Integer", |t| matches!(t, VarType::Enumeration(_)), |v: f64| v as c_int, |c: c_int| c as f64
);
access!(
    Boolean2,
    c_int,
    "Boolean",
    |t| t == VarType::Boolean,
    |v: f64| (v != 0.0) as c_int,
    |c: c_int| (c != 0) as u8 as f64
);
access!(Float64, f64, "Float64", |t| t == VarType::Real, |v| v, |c| c);
access!(
    /// FMI 3 enumerations are Int64.
    Int64, i64, "Int64", |t| matches!(t, VarType::Enumeration(_)), |v: f64| v as i64, |c: i64| c as f64
);
access!(
    /// fmi3Boolean is C `bool`; read as a byte so a non-0/1 byte from C is no UB.
    Boolean3, u8, "Boolean", |t| t == VarType::Boolean, |v: f64| (v != 0.0) as u8, |c: u8| (c != 0) as u8 as f64
);
// FMI 3 types this FMU has no variables of: every value reference is refused.
access!(Float32, f32, "Float32", |_| false, |v: f64| v as f32, |c: f32| c as f64);
access!(Int8, i8, "Int8", |_| false, |v: f64| v as i8, |c: i8| c as f64);
access!(UInt8, u8, "UInt8", |_| false, |v: f64| v as u8, |c: u8| c as f64);
access!(Int16, i16, "Int16", |_| false, |v: f64| v as i16, |c: i16| c as f64);
access!(UInt16, u16, "UInt16", |_| false, |v: f64| v as u16, |c: u16| c as f64);
access!(Int32, i32, "Int32", |_| false, |v: f64| v as i32, |c: i32| c as f64);
access!(UInt32, u32, "UInt32", |_| false, |v: f64| v as u32, |c: u32| c as f64);
access!(UInt64, u64, "UInt64", |_| false, |v: f64| v as u64, |c: u64| c as f64);

/// Type name of a variable as the given FMI version spells it.
fn type_label(ty: VarType, version: Version) -> String {
    match (ty, version) {
        (VarType::Real, Version::Fmi2) => "Real".into(),
        (VarType::Real, Version::Fmi3) => "Float64".into(),
        (VarType::Boolean, _) => "Boolean".into(),
        (VarType::Enumeration(e), Version::Fmi2) => {
            format!("Enumeration {e} (use fmi2GetInteger/fmi2SetInteger)")
        }
        (VarType::Enumeration(e), Version::Fmi3) => {
            format!("Enumeration {e} (use fmi3GetInt64/fmi3SetInt64)")
        }
    }
}

impl Instance {
    fn enabled(&self, category: usize) -> bool {
        self.categories[category] || self.categories[LOG_ALL]
    }

    /// Logs if the category is enabled; Error and Fatal are always logged.
    pub(crate) fn log(&self, status: Status, category: usize, message: &str) {
        if matches!(status, Status::Error | Status::Fatal) || self.enabled(category) {
            self.logger.emit(&self.name, status, LOG_CATEGORIES[category].0, message);
        }
    }

    /// One "logAll" line; the text is only built when that category is on.
    fn trace(&self, message: impl FnOnce() -> String) {
        if self.categories[LOG_ALL] {
            self.logger.emit(&self.name, Status::OK, LOG_CATEGORIES[LOG_ALL].0, &message());
        }
    }

    /// Logs "<function>: <message>" as an error and returns `Error`.
    pub(crate) fn fail(&self, message: &str) -> Status {
        self.log(Status::Error, LOG_ERROR, &format!("{}: {message}", self.func));
        Status::Error
    }

    /// [`Instance::fail`] as `Err`, for `?`.
    pub(crate) fn error<T>(&self, message: &str) -> Result<T, Status> {
        Err(self.fail(message))
    }

    /// A function of a capability this FMU does not have: Error + "fmiX is not supported
    /// by EhsvActuator<why>".
    pub(crate) fn unsupported(&self, why: &str) -> Result<Status, Status> {
        let msg = format!("{} is not supported by EhsvActuator{why}", self.func);
        self.log(Status::Error, LOG_ERROR, &msg);
        Err(Status::Error)
    }

    /// Logs "<function>: <message>" as a warning (if enabled) and returns `Err(Discard)`.
    pub(crate) fn discard<T>(&self, message: &str) -> Result<T, Status> {
        self.log(Status::Discard, LOG_WARNING, &format!("{}: {message}", self.func));
        Err(Status::Discard)
    }

    /// `n` elements at `ptr` as a slice; NULL with `n > 0`, misalignment or an
    /// impossible size → Error naming the argument.
    ///
    /// # Safety
    /// A non-NULL `ptr` points to `n` initialised `T` that stay valid and unaliased by
    /// writes for the call (FMI contract for array arguments).
    pub(crate) unsafe fn slice<'a, T>(
        &self,
        what: &str,
        ptr: *const T,
        n: usize,
    ) -> Result<&'a [T], Status> {
        if n == 0 {
            return Ok(&[]);
        }
        self.check_array(what, ptr, n)?;
        // SAFETY: non-NULL, aligned, size fits isize (checked), validity per contract.
        Ok(unsafe { std::slice::from_raw_parts(ptr, n) })
    }

    /// Mutable variant of [`Instance::slice`] for output arrays.
    ///
    /// # Safety
    /// A non-NULL `ptr` points to `n` writable `T` not otherwise accessed during the call.
    pub(crate) unsafe fn slice_mut<'a, T>(
        &self,
        what: &str,
        ptr: *mut T,
        n: usize,
    ) -> Result<&'a mut [T], Status> {
        if n == 0 {
            return Ok(&mut []);
        }
        self.check_array(what, ptr, n)?;
        // SAFETY: as in `slice`, plus exclusive access per contract. Elements are plain
        // numbers, so writing over possibly uninitialised memory is fine.
        Ok(unsafe { std::slice::from_raw_parts_mut(ptr, n) })
    }

    fn check_array<T>(&self, what: &str, ptr: *const T, n: usize) -> Result<(), Status> {
        if ptr.is_null() {
            return self.error(&format!("{what} is NULL but {n} elements were announced"));
        }
        if !ptr.is_aligned() {
            return self.error(&format!("{what} is not aligned for its element type"));
        }
        if n.checked_mul(std::mem::size_of::<T>()).is_none_or(|b| b > isize::MAX as usize) {
            return self.error(&format!("{what}: {n} elements is not a possible array size"));
        }
        Ok(())
    }

    /// Out-parameter pointer check.
    ///
    /// # Safety
    /// A non-NULL `ptr` points to a writable `T`.
    pub(crate) unsafe fn out<'a, T>(&self, what: &str, ptr: *mut T) -> Result<&'a mut T, Status> {
        if ptr.is_null() || !ptr.is_aligned() {
            return self.error(&format!("{what} is NULL or misaligned"));
        }
        // SAFETY: non-NULL, aligned, writable per contract; T here is a plain number/pointer.
        Ok(unsafe { &mut *ptr })
    }

    /// The index of value reference `vr` if it names a variable of a type the accessor serves.
    fn resolve(
        &self,
        vr: u32,
        accessor: &str,
        accepts: fn(VarType) -> bool,
    ) -> Result<usize, Status> {
        let Some(var) = VARIABLES.get(vr as usize) else {
            return self.error(&format!("unknown value reference {vr}"));
        };
        if !accepts(var.ty) {
            return self.error(&format!(
                "value reference {vr} is {} of type {}, not {accessor}",
                var.name,
                type_label(var.ty, self.version)
            ));
        }
        Ok(vr as usize)
    }

    /// May variable `index` be set in the current state? (The table's
    /// [`settable_in`](crate::fmi_state_machine::settable_in).)
    fn check_settable(&self, index: usize) -> Result<(), Status> {
        let var = &VARIABLES[index];
        let Some(allowed) = settable_in(var.causality, var.variability) else {
            let kind = if var.causality == Causality::Output {
                "an output"
            } else {
                "the independent variable"
            };
            return self.error(&format!("{} is {kind} and cannot be set", var.name));
        };
        if !allowed.contains(self.state) {
            let kind = match (var.causality, var.variability) {
                (Causality::Input, _) => "an input",
                (_, Variability::Fixed) => {
                    "a fixed parameter (structure or hardware): it can be set only before \
                     initialisation ends (or after Reset); the tunable parameters and the \
                     inputs can be set during the run"
                }
                _ => "a tunable parameter",
            };
            return self.error(&format!(
                "{} is {kind}; it cannot be set in state {} (only in {})",
                var.name,
                self.state.name(self.version),
                allowed.names(self.version)
            ));
        }
        Ok(())
    }

    /// Typed getter shared by `fmi2GetReal/Integer/Boolean` and `fmi3Get<numeric>/Boolean`.
    /// FMI 2 passes `n_values = n_vr`.
    ///
    /// # Safety
    /// Array contracts of [`Instance::slice`] / [`Instance::slice_mut`].
    pub(crate) unsafe fn get_values<A: Access>(
        &self,
        vrs: *const u32,
        n_vr: usize,
        values: *mut A::C,
        n_values: usize,
    ) -> Result<Status, Status> {
        if n_values != n_vr {
            return self.error(&format!(
                "nValues = {n_values} but the {n_vr} value references (all scalars) need {n_vr}"
            ));
        }
        // SAFETY: forwarded array contracts.
        let (vrs, out) = unsafe {
            (self.slice("valueReferences", vrs, n_vr)?, self.slice_mut("values", values, n_values)?)
        };
        for (&vr, slot) in vrs.iter().zip(out.iter_mut()) {
            let index = self.resolve(vr, A::NAME, A::accepts)?;
            match self.model.get(index) {
                Some(v) => *slot = A::to_c(v),
                None => {
                    return self
                        .error(&format!("the model has no value for {}", VARIABLES[index].name))
                }
            }
        }
        Ok(Status::OK)
    }

    /// Typed setter: all references, types and states are checked first; values are
    /// then applied all-or-nothing (the model is untouched on any error).
    ///
    /// # Safety
    /// Array contracts of [`Instance::slice`].
    pub(crate) unsafe fn set_values<A: Access>(
        &mut self,
        vrs: *const u32,
        n_vr: usize,
        values: *const A::C,
        n_values: usize,
    ) -> Result<Status, Status> {
        if n_values != n_vr {
            return self.error(&format!(
                "nValues = {n_values} but the {n_vr} value references (all scalars) need {n_vr}"
            ));
        }
        // SAFETY: forwarded array contracts.
        let (vrs, vals) = unsafe {
            (self.slice("valueReferences", vrs, n_vr)?, self.slice("values", values, n_values)?)
        };
        for &vr in vrs {
            let index = self.resolve(vr, A::NAME, A::accepts)?;
            self.check_settable(index)?;
        }
        // All or nothing; tunable parameters set in Step Mode rebuild the physics here.
        let result =
            self.model.set_all(vrs.iter().zip(vals).map(|(&vr, &c)| (vr as usize, A::from_c(c))));
        match result {
            Ok(()) => Ok(Status::OK),
            Err(e) => self.error(&e),
        }
    }

    /// Get/Set of a type with no variables (strings, binaries, clocks): only `n_vr = 0`
    /// succeeds; every reference is refused as unknown or of another type.
    ///
    /// # Safety
    /// Array contract of [`Instance::slice`] for `vrs`.
    pub(crate) unsafe fn no_values(
        &self,
        type_name: &str,
        vrs: *const u32,
        n_vr: usize,
        n_values: Option<usize>,
    ) -> Result<Status, Status> {
        if let Some(n) = n_values.filter(|&n| n != n_vr) {
            return self.error(&format!(
                "nValues = {n} but the {n_vr} value references (all scalars) need {n_vr}"
            ));
        }
        // SAFETY: forwarded array contract.
        let vrs = unsafe { self.slice("valueReferences", vrs, n_vr)? };
        for &vr in vrs {
            self.resolve(vr, type_name, |_| false)?;
        }
        Ok(Status::OK)
    }

    /// `SetDebugLogging`: no categories → all categories on/off; otherwise the named
    /// ones (all checked before any is changed). Unknown category → Error.
    ///
    /// # Safety
    /// `categories` points to `n` NULL-or-C-string pointers.
    pub(crate) unsafe fn set_debug_logging(
        &mut self,
        on: bool,
        n: usize,
        categories: *const *const c_char,
    ) -> Result<Status, Status> {
        // SAFETY: forwarded array contract.
        let names = unsafe { self.slice("categories", categories, n)? };
        let mut chosen = [false; N_CATEGORIES];
        for &p in names {
            // SAFETY: each element is NULL or a C string (contract).
            let Some(name) = (unsafe { opt_str(p) }) else {
                return self.error("a category is NULL");
            };
            let name = name.to_string_lossy();
            match LOG_CATEGORIES.iter().position(|(c, _)| *c == name) {
                Some(i) => chosen[i] = true,
                None => {
                    let known: Vec<_> = LOG_CATEGORIES.iter().map(|(c, _)| *c).collect();
                    return self.error(&format!(
                        "unknown log category '{name}' (known: {})",
                        known.join(", ")
                    ));
                }
            }
        }
        for (flag, &pick) in self.categories.iter_mut().zip(&chosen) {
            if n == 0 || pick {
                *flag = on;
            }
        }
        Ok(Status::OK)
    }

    /// Start (and optional stop) time of the experiment.
    pub(crate) fn setup_experiment(
        &mut self,
        start: f64,
        stop: Option<f64>,
    ) -> Result<Status, Status> {
        if let Some(stop) = stop {
            if !stop.is_finite() || stop < start || start.is_nan() {
                return self.error(&format!(
                    "stopTime {stop} must be finite and not before startTime {start}"
                ));
            }
        }
        if let Err(e) = self.model.set_start_time(start) {
            return self.error(&e);
        }
        self.stop_time = stop;
        Ok(Status::OK)
    }

    pub(crate) fn enter_initialization(&mut self) -> Result<Status, Status> {
        self.state = InitializationMode;
        Ok(Status::OK)
    }

    pub(crate) fn terminate(&mut self) -> Result<Status, Status> {
        self.state = Terminated;
        Ok(Status::OK)
    }

    /// Ends initialisation: the model checks its parameters together (a refusal leaves
    /// the instance in Initialization Mode, to correct them).
    pub(crate) fn exit_initialization(&mut self) -> Result<Status, Status> {
        match self.model.initialize() {
            Ok(()) => {
                self.state = StepMode;
                Ok(Status::OK)
            }
            Err(e) => self.error(&format!("initialization failed: {e}")),
        }
    }

    /// Back to the state after instantiation (logging settings are kept).
    pub(crate) fn reset(&mut self) -> Result<Status, Status> {
        self.model.reset();
        self.state = Instantiated;
        self.stop_time = None;
        self.warned = [false; InputWarning::ALL.len()];
        Ok(Status::OK)
    }

    /// One communication step. A step the model refuses up front, or one past the stop
    /// time, is a refusal (nothing changes); a step whose computation fails puts the
    /// instance in the Error state (the model itself is left as before the call).
    pub(crate) fn do_step(&mut self, t: f64, h: f64) -> Result<Status, Status> {
        if let Err(e) = self.model.check_step(t, h) {
            return self.error(&e);
        }
        if let Some(stop) = self.stop_time {
            let end = t + h;
            if end > stop + communication_point_tolerance(stop, h) {
                return self.error(&format!(
                    "a step from {t} by {h} ends at {end}, after stopTime {stop}"
                ));
            }
        }
        let conditions = InputWarning::ALL.map(|w| self.model.input_warning(w));
        match self.model.do_step(t, h) {
            Ok(events) => {
                self.log_events(t, h, events);
                Ok(self.warn_about_inputs(t, conditions))
            }
            Err(e) => {
                self.state = State::Error;
                self.error(&format!(
                    "{e}; the step failed and the instance is in the Error state \
                     (SetFMUState to an earlier state, Reset or FreeInstance go on)"
                ))
            }
        }
    }

    /// Warning (and one logStatusWarning line each) for the input conditions that began
    /// with this step; OK while none began (a lasting condition is not repeated).
    fn warn_about_inputs(&mut self, t: f64, conditions: [bool; InputWarning::ALL.len()]) -> Status {
        let mut status = Status::OK;
        let log = self.enabled(LOG_WARNING);
        for ((warning, holds), warned) in
            InputWarning::ALL.into_iter().zip(conditions).zip(self.warned.iter_mut())
        {
            if holds && !*warned {
                status = Status::Warning;
                if log {
                    let text = self.model.input_warning_text(warning);
                    let message = format!("{}: step from {t}: {text}", self.func);
                    self.logger.emit(
                        &self.name,
                        Status::Warning,
                        LOG_CATEGORIES[LOG_WARNING].0,
                        &message,
                    );
                }
            }
            *warned = holds;
        }
        status
    }

    fn log_events(&self, t: f64, h: f64, events: StepEvents) {
        if !self.enabled(LOG_EVENTS) || events == StepEvents::default() {
            return;
        }
        if events.rail_entered + events.rail_left > 0 {
            self.log(
                Status::OK,
                LOG_EVENTS,
                &format!(
                    "step [{t}, {}]: driver output reached a supply rail {} time(s), left it {} time(s)",
                    t + h,
                    events.rail_entered,
                    events.rail_left
                ),
            );
        }
        for (opened, chamber) in events.relief_opened.iter().zip(["A", "B"]) {
            if *opened {
                let message = format!(
                    "step [{t}, {}]: relief valve of chamber {chamber} opened (p_{chamber} above relief.p_crack)",
                    t + h
                );
                self.log(Status::OK, LOG_EVENTS, &message);
            }
        }
    }

    /// The FMU state behind a pointer the importer hands back, if this instance made it
    /// and it was not freed; anything else is refused without being read.
    fn saved(&self, ptr: *mut c_void) -> Result<&SavedState, Status> {
        match self.fmu_states.get(&(ptr as usize)) {
            Some(saved) => Ok(saved),
            None => self.error(
                "the FMU state is NULL, freed, or not one this instance made \
                 (an FMU state belongs to the instance that took or deserialized it)",
            ),
        }
    }

    /// Stores `saved` into `*state`: a new FMU state for a NULL `*state`, else the one
    /// given is overwritten (as the standards require).
    ///
    /// # Safety
    /// `state` is NULL or points to a writable FMU-state pointer.
    unsafe fn store_state(
        &mut self,
        state: *mut *mut c_void,
        saved: SavedState,
    ) -> Result<Status, Status> {
        // SAFETY: forwarded contract.
        let slot = unsafe { self.out("FMUState", state)? };
        if slot.is_null() {
            let mut boxed = Box::new(saved);
            let address: *mut SavedState = &mut *boxed;
            self.fmu_states.insert(address as usize, boxed);
            *slot = address.cast();
        } else {
            match self.fmu_states.get_mut(&(*slot as usize)) {
                Some(old) => **old = saved,
                None => return self.saved(*slot).map(|_| Status::OK),
            }
        }
        Ok(Status::OK)
    }

    /// # Safety
    /// See [`Instance::store_state`].
    pub(crate) unsafe fn get_fmu_state(
        &mut self,
        state: *mut *mut c_void,
    ) -> Result<Status, Status> {
        let saved =
            SavedState { model: self.model.clone(), mode: self.state, stop_time: self.stop_time };
        // SAFETY: forwarded contract.
        unsafe { self.store_state(state, saved) }
    }

    /// Restores the model, the FMI state the FMU state was taken in and the stop time:
    /// the instance continues as it would have from there (also out of the Error state).
    pub(crate) fn set_fmu_state(&mut self, state: *mut c_void) -> Result<Status, Status> {
        let saved = self.saved(state)?;
        let (model, mode, stop_time) = (saved.model.clone(), saved.mode, saved.stop_time);
        self.model = model;
        self.state = mode;
        self.stop_time = stop_time;
        Ok(Status::OK)
    }

    /// Frees `*state` and sets it to NULL; NULL `state` or `*state` is a no-op.
    ///
    /// # Safety
    /// `state` is NULL or points to a readable and writable FMU-state pointer.
    pub(crate) unsafe fn free_fmu_state(
        &mut self,
        state: *mut *mut c_void,
    ) -> Result<Status, Status> {
        // SAFETY: a non-NULL `state` is a readable/writable pointer slot (contract).
        let Some(slot) = (unsafe { state.as_mut() }) else { return Ok(Status::OK) };
        if slot.is_null() {
            return Ok(Status::OK);
        }
        match self.fmu_states.remove(&(*slot as usize)) {
            Some(freed) => drop(freed),
            None => return self.saved(*slot).map(|_| Status::OK),
        }
        *slot = std::ptr::null_mut();
        Ok(Status::OK)
    }

    /// # Safety
    /// `size` is NULL or writable.
    pub(crate) unsafe fn serialized_size(
        &self,
        state: *mut c_void,
        size: *mut usize,
    ) -> Result<Status, Status> {
        let bytes = self.saved(state)?.to_bytes();
        // SAFETY: forwarded contract.
        *unsafe { self.out("size", size)? } = bytes.len();
        Ok(Status::OK)
    }

    /// # Safety
    /// `bytes` points to `size` writable bytes.
    pub(crate) unsafe fn serialize(
        &self,
        state: *mut c_void,
        bytes: *mut u8,
        size: usize,
    ) -> Result<Status, Status> {
        let data = self.saved(state)?.to_bytes();
        if size < data.len() {
            return self.error(&format!(
                "size {size} is too small: the serialized state has {} bytes",
                data.len()
            ));
        }
        // SAFETY: forwarded array contract.
        let out = unsafe { self.slice_mut("serializedState", bytes, size)? };
        out[..data.len()].copy_from_slice(&data);
        Ok(Status::OK)
    }

    /// # Safety
    /// `bytes` points to `size` readable bytes; `state` as in [`Instance::store_state`].
    pub(crate) unsafe fn deserialize(
        &mut self,
        bytes: *const u8,
        size: usize,
        state: *mut *mut c_void,
    ) -> Result<Status, Status> {
        // SAFETY: forwarded array contract.
        let data = unsafe { self.slice("serializedState", bytes, size)? };
        let saved = match SavedState::from_bytes(data) {
            Ok(saved) => saved,
            Err(e) => return self.error(&format!("cannot deserialize the FMU state: {e}")),
        };
        // SAFETY: forwarded contract.
        unsafe { self.store_state(state, saved) }
    }
}

/// What the checksum cannot vouch for in a well-formed frame built elsewhere: the time
/// is finite, parameters and inputs pass the checks of the setters, outputs are finite.
fn check_restored(model: &Model) -> Result<(), String> {
    if !model.time().is_finite() {
        return Err(format!("the state's time {} is not finite", model.time()));
    }
    for (index, var) in VARIABLES.iter().enumerate() {
        let value = model.get(index).unwrap_or(f64::NAN);
        match var.causality {
            Causality::Parameter | Causality::Input => var.check(value)?,
            Causality::Output if !value.is_finite() => {
                return Err(format!("the state's {} = {value} is not finite", var.name))
            }
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    extern "C" fn collect(
        env: *mut c_void,
        _status: c_int,
        _category: *const c_char,
        message: *const c_char,
    ) {
        // SAFETY: env is the Mutex below; message is a C string from the FMU.
        let log = unsafe { &*(env as *const Mutex<Vec<String>>) };
        log.lock().unwrap().push(unsafe { CStr::from_ptr(message) }.to_string_lossy().into_owned());
    }

    #[test]
    fn a_panic_becomes_an_error_and_the_instance_survives() {
        let log = Mutex::new(Vec::<String>::new());
        let env = &log as *const _ as *mut c_void;
        let token = CString::new(crate::variables::interface_token()).unwrap();
        // SAFETY: valid C strings and callback.
        let inst = unsafe {
            instantiate(
                Version::Fmi3,
                "fmi3InstantiateCoSimulation",
                c"p".as_ptr(),
                token.as_ptr(),
                Logger::Fmi3(collect, env),
                false,
                None,
            )
        };
        assert!(!inst.is_null());
        // SAFETY: `inst` is live.
        let status = unsafe {
            with_instance(inst, Version::Fmi3, "fmi3Boom", Call::GetValues, |_| {
                panic!("boom {}", 42)
            })
        };
        assert_eq!(status, Status::Error);
        assert!(
            log.lock()
                .unwrap()
                .iter()
                .any(|m| m
                    == "fmi3Boom: internal error: boom 42; the instance is in the Error state"),
            "{log:?}"
        );
        // SAFETY: still live.
        let status = unsafe {
            with_instance(inst, Version::Fmi3, "fmi3Terminate", Call::Terminate, |_| Ok(Status::OK))
        };
        assert_eq!(status, Status::Error, "the Error state refuses what is not a way out");
        // SAFETY: still live.
        let status =
            unsafe { with_instance(inst, Version::Fmi3, "fmi3Reset", Call::Reset, |i| i.reset()) };
        assert_eq!(status, Status::OK);
        // SAFETY: freed once.
        unsafe { free_instance(inst, Version::Fmi3, "fmi3FreeInstance") };
    }
}
