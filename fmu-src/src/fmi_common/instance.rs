//! One FMU instance behind the `fmi2Component` / `fmi3Instance` pointer: its creation,
//! the frame every exported function on it runs in (instance and FMI version check, call
//! sequence, panics turned into the Error state) and its release.

use std::collections::HashMap;
use std::ffi::{c_char, c_void, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use super::arguments::opt_str;
use super::fmu_state::SavedState;
use super::logging::{Logger, Status, LOG_ALL, LOG_CATEGORIES, LOG_ERROR, N_CATEGORIES};
use super::state_machine::{Call, State, Version};
use crate::contract::ModelContract;

const INSTANCE_MAGIC: u64 = 0x4548_5356_494e_5354; // "EHSVINST"

/// One FMU instance, behind the `fmi2Component` / `fmi3Instance` pointer.
#[repr(C)]
pub(crate) struct Instance<M: ModelContract> {
    /// First field, so a foreign or freed pointer is likely to be recognised.
    magic: u64,
    pub(super) version: Version,
    pub(super) name: CString,
    pub(super) logger: Logger,
    pub(super) categories: [bool; N_CATEGORIES],
    /// The exported function being executed (prefix of error messages).
    pub(super) func: &'static str,
    pub(crate) model: M,
    pub(crate) state: State,
    pub(crate) stop_time: Option<f64>,
    /// The FMU states this instance handed out and the importer has not freed, by the
    /// address the importer holds: FreeInstance frees what is left, and a pointer that is
    /// not in here (freed, foreign, garbage) is refused without being read.
    pub(super) fmu_states: HashMap<usize, Box<SavedState<M>>>,
    /// Which of the model's input conditions held at the last doStep (bit i: condition
    /// i): each is reported when it begins.
    pub(super) warned: u32,
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

/// Creates an instance after checking name and token; on refusal logs through `logger`
/// (errors are always logged) and returns NULL.
///
/// # Safety
/// `name` and `token` are NULL or NUL-terminated strings.
pub(crate) unsafe fn instantiate<M: ModelContract>(
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
    let expected = M::interface_token();
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
        model: M::start(),
        state: State::Instantiated,
        stop_time: None,
        fmu_states: HashMap::new(),
        warned: 0,
    });
    inst.trace(|| format!("{func}: instance '{shown}' created"));
    Box::into_raw(inst).cast()
}

/// The instance behind `ptr` if it is one of ours; NULL or foreign → `None`.
///
/// # Safety
/// `ptr` is NULL or was returned by our `Instantiate` and not yet freed.
unsafe fn instance_ptr<M: ModelContract>(ptr: *mut c_void) -> Option<*mut Instance<M>> {
    let p = ptr.cast::<Instance<M>>();
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
pub(crate) unsafe fn with_instance<M: ModelContract>(
    ptr: *mut c_void,
    version: Version,
    func: &'static str,
    call: Call,
    f: impl FnOnce(&mut Instance<M>) -> Result<Status, Status>,
) -> Status {
    // SAFETY: forwarded contract.
    let Some(p) = (unsafe { instance_ptr::<M>(ptr) }) else { return Status::Error };
    guarded(
        || {
            // SAFETY: `p` is a live instance, exclusively ours for this call.
            let inst = unsafe { &mut *p };
            inst.func = func;
            // The common call, tested at once: of the instance's version, allowed in its
            // state, nothing to trace.
            let usual = inst.version == version
                && call.allowed().contains(inst.state)
                && !inst.categories[LOG_ALL];
            if !usual {
                if let Err(status) = inst.enter_unusual(version, call) {
                    return status;
                }
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

impl<M: ModelContract> Instance<M> {
    /// The checks of [`with_instance`] one by one, for a call that is not the common one:
    /// another FMI version or a call the table does not allow now (Error + log), or one
    /// to trace. Out of line: the messages would weigh on every call.
    #[cold]
    #[inline(never)]
    fn enter_unusual(&self, version: Version, call: Call) -> Result<(), Status> {
        let func = self.func;
        if self.version != version {
            return self.error("called with an instance of the other FMI version");
        }
        self.trace(|| format!("{func} (state {})", self.state.name(version)));
        let allowed = call.allowed();
        if !allowed.contains(self.state) {
            let after_error = if self.state == State::Error {
                "; after a failed call only SetFMUState, Reset and FreeInstance go on"
            } else {
                ""
            };
            return self.error(&format!(
                "illegal call sequence: {func} is not allowed in state {} (only in {}){after_error}",
                self.state.name(version),
                allowed.names(version)
            ));
        }
        Ok(())
    }
}

/// Frees an instance (NULL or foreign: nothing happens).
///
/// # Safety
/// As [`with_instance`]; `ptr` is not used afterwards.
pub(crate) unsafe fn free_instance<M: ModelContract>(
    ptr: *mut c_void,
    version: Version,
    func: &'static str,
) {
    // SAFETY: forwarded contract.
    let Some(p) = (unsafe { instance_ptr::<M>(ptr) }) else { return };
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::{c_int, CStr};
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
            instantiate::<crate::model::Model>(
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
            with_instance::<crate::model::Model>(
                inst,
                Version::Fmi3,
                "fmi3Boom",
                Call::GetValues,
                |_| panic!("boom {}", 42),
            )
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
            with_instance::<crate::model::Model>(
                inst,
                Version::Fmi3,
                "fmi3Terminate",
                Call::Terminate,
                |_| Ok(Status::OK),
            )
        };
        assert_eq!(status, Status::Error, "the Error state refuses what is not a way out");
        // SAFETY: still live.
        let status = unsafe {
            with_instance::<crate::model::Model>(
                inst,
                Version::Fmi3,
                "fmi3Reset",
                Call::Reset,
                |i| i.reset(),
            )
        };
        assert_eq!(status, Status::OK);
        // SAFETY: freed once.
        unsafe { free_instance::<crate::model::Model>(inst, Version::Fmi3, "fmi3FreeInstance") };
    }
}
