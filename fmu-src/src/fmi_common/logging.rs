//! Logging: the log categories the FMU declares and accepts, the importer's logger
//! callback (FMI 2 or FMI 3 form), the [`Status`] every call returns and every log line
//! carries, and the instance's logging methods (`SetDebugLogging` among them).

use std::ffi::{c_char, c_int, c_void, CStr, CString};

use super::arguments::opt_str;
use super::instance::Instance;
use crate::contract::ModelContract;

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
pub(super) const LOG_EVENTS: usize = 0;
pub(super) const LOG_WARNING: usize = 1;
pub(crate) const LOG_ERROR: usize = 2;
pub(super) const LOG_ALL: usize = 3;
pub(super) const N_CATEGORIES: usize = LOG_CATEGORIES.len();

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

impl<M: ModelContract> Instance<M> {
    pub(super) fn enabled(&self, category: usize) -> bool {
        self.categories[category] || self.categories[LOG_ALL]
    }

    /// Logs if the category is enabled; Error and Fatal are always logged.
    pub(crate) fn log(&self, status: Status, category: usize, message: &str) {
        if matches!(status, Status::Error | Status::Fatal) || self.enabled(category) {
            self.logger.emit(&self.name, status, LOG_CATEGORIES[category].0, message);
        }
    }

    /// One "logAll" line; the text is only built when that category is on.
    pub(super) fn trace(&self, message: impl FnOnce() -> String) {
        if self.categories[LOG_ALL] {
            self.logger.emit(&self.name, Status::OK, LOG_CATEGORIES[LOG_ALL].0, &message());
        }
    }

    /// Logs `"<function>: <message>"` as an error and returns `Error`.
    pub(crate) fn fail(&self, message: &str) -> Status {
        self.log(Status::Error, LOG_ERROR, &format!("{}: {message}", self.func));
        Status::Error
    }

    /// [`Instance::fail`] as `Err`, for `?`.
    pub(crate) fn error<T>(&self, message: &str) -> Result<T, Status> {
        Err(self.fail(message))
    }

    /// A function of a capability this FMU does not have: Error + `"fmiX is not supported
    /// by EhsvActuator<why>"`.
    pub(crate) fn unsupported(&self, why: &str) -> Result<Status, Status> {
        let msg = format!("{} is not supported by EhsvActuator{why}", self.func);
        self.log(Status::Error, LOG_ERROR, &msg);
        Err(Status::Error)
    }

    /// Logs `"<function>: <message>"` as a warning (if enabled) and returns `Err(Discard)`.
    pub(crate) fn discard<T>(&self, message: &str) -> Result<T, Status> {
        self.log(Status::Discard, LOG_WARNING, &format!("{}: {message}", self.func));
        Err(Status::Discard)
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
}
