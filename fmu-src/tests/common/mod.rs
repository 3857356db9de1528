//! Harness shared by the C API test files: instances of both FMI versions over the
//! rlib's `extern "C"` functions, with a logger that records every line.
#![allow(dead_code)]

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::ptr::null;
use std::sync::Mutex;

pub use ehsv_actuator::fmi2::*;
pub use ehsv_actuator::fmi3::*;
pub use ehsv_actuator::fmi_common::{Fmi2Logger, Status};
pub use ehsv_actuator::variables::{interface_token, vr};

// ---------------------------------------------------------------- logging harness

#[derive(Clone, Debug)]
pub struct Line {
    pub instance: String,
    pub status: c_int,
    pub category: String,
    pub message: String,
}

#[derive(Default)]
pub struct Log(pub Mutex<Vec<Line>>);

impl Log {
    pub fn lines(&self) -> Vec<Line> {
        self.0.lock().unwrap().clone()
    }
    pub fn clear(&self) {
        self.0.lock().unwrap().clear();
    }
    /// Is there a line containing every needle?
    pub fn has(&self, needles: &[&str]) -> bool {
        self.lines().iter().any(|l| needles.iter().all(|n| l.message.contains(n)))
    }
    pub fn dump(&self) -> String {
        self.lines()
            .iter()
            .map(|l| format!("[{} {} {}] {}\n", l.instance, l.status, l.category, l.message))
            .collect()
    }
    pub fn env(&self) -> *mut c_void {
        self as *const Log as *mut c_void
    }
}

pub unsafe fn text(p: *const c_char) -> String {
    if p.is_null() {
        "<NULL>".into()
    } else {
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }
}

/// The FMI 2 logger with its fixed arguments only; see [`fmi2_logger`].
pub extern "C" fn fmi2_logger_fixed(
    env: *mut c_void,
    instance: *const c_char,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    // SAFETY: env is the &Log given at instantiation; strings are C strings from the FMU.
    let log = unsafe { &*(env as *const Log) };
    let line = unsafe {
        Line { instance: text(instance), status, category: text(category), message: text(message) }
    };
    log.0.lock().unwrap().push(line);
}

/// TEST ONLY: stable Rust cannot define a C-variadic function, so the FMI 2 logger is a
/// fixed-argument function cast to the variadic pointer type. The FMU passes no variadic
/// arguments, and on the supported ABIs (x86_64 SysV, aarch64) the fixed arguments of a
/// variadic call are passed exactly like those of a non-variadic one — this is what C
/// importers effectively rely on as well. The message is the printf *format* (with '%'
/// escaped as "%%"), which the tests check verbatim.
pub fn fmi2_logger() -> Fmi2Logger {
    type Fixed = extern "C" fn(*mut c_void, *const c_char, c_int, *const c_char, *const c_char);
    // SAFETY: see above; both are plain function pointers of the same size.
    unsafe { std::mem::transmute::<Fixed, Fmi2Logger>(fmi2_logger_fixed) }
}

pub extern "C" fn fmi3_logger(
    env: *mut c_void,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    // SAFETY: as in fmi2_logger_fixed.
    let log = unsafe { &*(env as *const Log) };
    let line = unsafe {
        Line { instance: String::new(), status, category: text(category), message: text(message) }
    };
    log.0.lock().unwrap().push(line);
}

pub const OK: Status = Status::OK;
pub const ERROR: Status = Status::Error;

pub fn token() -> CString {
    CString::new(interface_token()).unwrap()
}

// ---------------------------------------------------------------- FMI 2 harness

pub struct Fmu2 {
    pub c: fmi2Component,
    pub log: Box<Log>,
}

impl Fmu2 {
    /// The instance, or the log of the refusal.
    pub fn try_new(name: &str, fmu_type: fmi2Type, guid: &str) -> Result<Fmu2, Box<Log>> {
        // The Box keeps the Log at a fixed address: it is the componentEnvironment.
        let log = Box::<Log>::default();
        let functions = fmi2CallbackFunctions {
            logger: Some(fmi2_logger()),
            allocateMemory: None,
            freeMemory: None,
            stepFinished: None,
            componentEnvironment: log.env(),
        };
        let name = CString::new(name).unwrap();
        let guid = CString::new(guid).unwrap();
        let c = unsafe {
            fmi2Instantiate(
                name.as_ptr(),
                fmu_type,
                guid.as_ptr(),
                null(),
                &functions,
                fmi2False,
                fmi2False,
            )
        };
        if c.is_null() {
            Err(log)
        } else {
            Ok(Fmu2 { c, log })
        }
    }

    pub fn new(name: &str) -> Fmu2 {
        Self::try_new(name, fmi2CoSimulation, &interface_token())
            .unwrap_or_else(|log| panic!("{}", log.dump()))
    }

    /// Instantiated, set up from 0 (no stop time), initialised.
    pub fn initialized(name: &str) -> Fmu2 {
        let f = Self::new(name);
        unsafe {
            assert_eq!(fmi2SetupExperiment(f.c, fmi2False, 0.0, 0.0, fmi2False, 0.0), OK);
            assert_eq!(fmi2EnterInitializationMode(f.c), OK);
            assert_eq!(fmi2ExitInitializationMode(f.c), OK, "{}", f.log.dump());
        }
        f
    }

    pub fn get_real(&self, r: usize) -> (Status, f64) {
        let mut v = f64::NAN;
        let s = unsafe { fmi2GetReal(self.c, &(r as u32), 1, &mut v) };
        (s, v)
    }
    pub fn set_real(&self, r: usize, v: f64) -> Status {
        unsafe { fmi2SetReal(self.c, &(r as u32), 1, &v) }
    }
    pub fn step(&self, t: f64, h: f64) -> Status {
        unsafe { fmi2DoStep(self.c, t, h, fmi2True) }
    }
    pub fn time(&self) -> f64 {
        self.get_real(vr::TIME).1
    }
    pub fn outputs(&self) -> Vec<f64> {
        let refs = [vr::TIME, vr::I_COIL, vr::U_DRIVER, vr::X_FLAPPER, vr::X_SPOOL, vr::Q_VALVE]
            .map(|r| r as u32);
        let mut v = [0.0; 6];
        assert_eq!(unsafe { fmi2GetReal(self.c, refs.as_ptr(), refs.len(), v.as_mut_ptr()) }, OK);
        v.to_vec()
    }
}

impl Drop for Fmu2 {
    fn drop(&mut self) {
        unsafe { fmi2FreeInstance(self.c) }
    }
}

// ---------------------------------------------------------------- FMI 3 harness

pub struct Fmu3 {
    pub i: fmi3Instance,
    pub log: Box<Log>,
}

impl Fmu3 {
    pub fn try_new(name: &str, token: &str, event_mode_used: bool) -> Result<Fmu3, Box<Log>> {
        let log = Box::<Log>::default();
        let name = CString::new(name).unwrap();
        let token = CString::new(token).unwrap();
        let i = unsafe {
            fmi3InstantiateCoSimulation(
                name.as_ptr(),
                token.as_ptr(),
                null(),
                false,
                false,
                event_mode_used,
                false,
                null(),
                0,
                log.env(),
                Some(fmi3_logger),
                None,
            )
        };
        if i.is_null() {
            Err(log)
        } else {
            Ok(Fmu3 { i, log })
        }
    }

    pub fn new(name: &str) -> Fmu3 {
        Self::try_new(name, &interface_token(), false)
            .unwrap_or_else(|log| panic!("{}", log.dump()))
    }

    pub fn initialized(name: &str, stop: Option<f64>) -> Fmu3 {
        let f = Self::new(name);
        unsafe {
            assert_eq!(
                fmi3EnterInitializationMode(
                    f.i,
                    false,
                    0.0,
                    0.0,
                    stop.is_some(),
                    stop.unwrap_or(0.0)
                ),
                OK
            );
            assert_eq!(fmi3ExitInitializationMode(f.i), OK, "{}", f.log.dump());
        }
        f
    }

    pub fn get(&self, r: usize) -> (Status, f64) {
        let mut v = f64::NAN;
        let s = unsafe { fmi3GetFloat64(self.i, &(r as u32), 1, &mut v, 1) };
        (s, v)
    }
    pub fn set(&self, r: usize, v: f64) -> Status {
        unsafe { fmi3SetFloat64(self.i, &(r as u32), 1, &v, 1) }
    }

    /// DoStep with all out-flags preset to true/NaN to see them written.
    pub fn step(&self, t: f64, h: f64) -> (Status, [bool; 3], f64) {
        let (mut ev, mut term, mut early, mut last) = (true, true, true, f64::NAN);
        let s =
            unsafe { fmi3DoStep(self.i, t, h, false, &mut ev, &mut term, &mut early, &mut last) };
        (s, [ev, term, early], last)
    }
    pub fn outputs(&self) -> Vec<f64> {
        let refs = [vr::TIME, vr::I_COIL, vr::U_DRIVER, vr::X_FLAPPER, vr::X_SPOOL, vr::Q_VALVE]
            .map(|r| r as u32);
        let mut v = [0.0; 6];
        assert_eq!(
            unsafe { fmi3GetFloat64(self.i, refs.as_ptr(), refs.len(), v.as_mut_ptr(), v.len()) },
            OK
        );
        v.to_vec()
    }
}

impl Drop for Fmu3 {
    fn drop(&mut self) {
        unsafe { fmi3FreeInstance(self.i) }
    }
}

// ---------------------------------------------------------------- both versions behind one trait

/// What the robustness tests do with an instance, the same way in both FMI versions, so
/// each test is written once and run for FMI 2 and FMI 3.
pub trait Api: Sized {
    const VERSION: &'static str;
    fn create(name: &str) -> Self;
    fn log(&self) -> &Log;
    /// Setup (start 0, optional stop time) and enter initialisation.
    fn enter_init(&self, stop: Option<f64>) -> Status;
    fn exit_init(&self) -> Status;
    /// Setup, enter and exit initialisation.
    fn init(&self, stop: Option<f64>) -> Status {
        match self.enter_init(stop) {
            Status::OK => self.exit_init(),
            s => s,
        }
    }
    fn step(&self, t: f64, h: f64) -> Status;
    /// Any Real / Float64 variable.
    fn get(&self, r: usize) -> (Status, f64);
    fn set(&self, r: usize, v: f64) -> Status;
    /// Enumerations through fmi2SetInteger / fmi3SetInt64.
    fn set_enum(&self, r: usize, v: i64) -> Status;
    fn terminate(&self) -> Status;
    fn reset(&self) -> Status;
    fn set_logging(&self, on: bool, categories: &[&str]) -> Status;
    /// Get FMU state, serialize it, free it.
    fn save(&self) -> Vec<u8>;
    /// Deserialize `bytes` (Error → returned, nothing leaked), set the state, free it.
    fn restore(&self, bytes: &[u8]) -> Status;

    fn initialized(name: &str) -> Self {
        let f = Self::create(name);
        assert_eq!(f.init(None), OK, "{}", f.log().dump());
        f
    }
    /// Every variable the getters can read (Reals, Booleans and enumerations as f64), as bits.
    fn snapshot(&self) -> Vec<u64> {
        (0..ehsv_actuator::variables::N_VARIABLES)
            .map(|r| match ehsv_actuator::variables::VARIABLES[r].ty {
                ehsv_actuator::variables::VarType::Real => self.get(r),
                _ => self.get_other(r),
            })
            .map(|(s, v)| {
                assert_eq!(s, OK);
                v.to_bits()
            })
            .collect()
    }
    /// A Boolean or enumeration as f64.
    fn get_other(&self, r: usize) -> (Status, f64);
    /// True when a log line has `category` and contains every needle.
    fn logged(&self, category: &str, needles: &[&str]) -> bool {
        self.log()
            .lines()
            .iter()
            .any(|l| l.category == category && needles.iter().all(|n| l.message.contains(n)))
    }
}

fn c_strings(names: &[&str]) -> (Vec<CString>, Vec<*const c_char>) {
    let owned: Vec<CString> = names.iter().map(|n| CString::new(*n).unwrap()).collect();
    let ptrs = owned.iter().map(|c| c.as_ptr()).collect();
    (owned, ptrs)
}

impl Api for Fmu2 {
    const VERSION: &'static str = "FMI 2";
    fn create(name: &str) -> Self {
        Fmu2::new(name)
    }
    fn log(&self) -> &Log {
        &self.log
    }
    fn enter_init(&self, stop: Option<f64>) -> Status {
        unsafe {
            match fmi2SetupExperiment(
                self.c,
                fmi2False,
                0.0,
                0.0,
                stop.is_some() as fmi2Boolean,
                stop.unwrap_or(0.0),
            ) {
                Status::OK => fmi2EnterInitializationMode(self.c),
                s => s,
            }
        }
    }
    fn exit_init(&self) -> Status {
        unsafe { fmi2ExitInitializationMode(self.c) }
    }
    fn step(&self, t: f64, h: f64) -> Status {
        Fmu2::step(self, t, h)
    }
    fn get(&self, r: usize) -> (Status, f64) {
        self.get_real(r)
    }
    fn get_other(&self, r: usize) -> (Status, f64) {
        let mut v = -1;
        let s = unsafe {
            match ehsv_actuator::variables::VARIABLES[r].ty {
                ehsv_actuator::variables::VarType::Boolean => {
                    fmi2GetBoolean(self.c, &(r as u32), 1, &mut v)
                }
                _ => fmi2GetInteger(self.c, &(r as u32), 1, &mut v),
            }
        };
        (s, v as f64)
    }
    fn set(&self, r: usize, v: f64) -> Status {
        self.set_real(r, v)
    }
    fn set_enum(&self, r: usize, v: i64) -> Status {
        unsafe { fmi2SetInteger(self.c, &(r as u32), 1, &(v as fmi2Integer)) }
    }
    fn terminate(&self) -> Status {
        unsafe { fmi2Terminate(self.c) }
    }
    fn reset(&self) -> Status {
        unsafe { fmi2Reset(self.c) }
    }
    fn set_logging(&self, on: bool, categories: &[&str]) -> Status {
        let (_owned, ptrs) = c_strings(categories);
        unsafe { fmi2SetDebugLogging(self.c, on as fmi2Boolean, ptrs.len(), ptrs.as_ptr()) }
    }
    fn save(&self) -> Vec<u8> {
        unsafe {
            let mut s: fmi2FMUstate = std::ptr::null_mut();
            assert_eq!(fmi2GetFMUstate(self.c, &mut s), OK);
            let mut size = 0;
            assert_eq!(fmi2SerializedFMUstateSize(self.c, s, &mut size), OK);
            let mut bytes = vec![0u8; size];
            assert_eq!(fmi2SerializeFMUstate(self.c, s, bytes.as_mut_ptr().cast(), size), OK);
            assert_eq!(fmi2FreeFMUstate(self.c, &mut s), OK);
            bytes
        }
    }
    fn restore(&self, bytes: &[u8]) -> Status {
        unsafe {
            let mut s: fmi2FMUstate = std::ptr::null_mut();
            let status =
                fmi2DeSerializeFMUstate(self.c, bytes.as_ptr().cast(), bytes.len(), &mut s);
            if status != OK {
                assert!(s.is_null(), "a refused deserialization hands out no state");
                return status;
            }
            let status = fmi2SetFMUstate(self.c, s);
            assert_eq!(fmi2FreeFMUstate(self.c, &mut s), OK);
            status
        }
    }
}

impl Api for Fmu3 {
    const VERSION: &'static str = "FMI 3";
    fn create(name: &str) -> Self {
        Fmu3::new(name)
    }
    fn log(&self) -> &Log {
        &self.log
    }
    fn enter_init(&self, stop: Option<f64>) -> Status {
        unsafe {
            fmi3EnterInitializationMode(
                self.i,
                false,
                0.0,
                0.0,
                stop.is_some(),
                stop.unwrap_or(0.0),
            )
        }
    }
    fn exit_init(&self) -> Status {
        unsafe { fmi3ExitInitializationMode(self.i) }
    }
    fn step(&self, t: f64, h: f64) -> Status {
        Fmu3::step(self, t, h).0
    }
    fn get(&self, r: usize) -> (Status, f64) {
        Fmu3::get(self, r)
    }
    fn get_other(&self, r: usize) -> (Status, f64) {
        unsafe {
            match ehsv_actuator::variables::VARIABLES[r].ty {
                ehsv_actuator::variables::VarType::Boolean => {
                    let mut b = false;
                    (fmi3GetBoolean(self.i, &(r as u32), 1, &mut b, 1), b as u8 as f64)
                }
                _ => {
                    let mut v = -1i64;
                    (fmi3GetInt64(self.i, &(r as u32), 1, &mut v, 1), v as f64)
                }
            }
        }
    }
    fn set(&self, r: usize, v: f64) -> Status {
        Fmu3::set(self, r, v)
    }
    fn set_enum(&self, r: usize, v: i64) -> Status {
        unsafe { fmi3SetInt64(self.i, &(r as u32), 1, &v, 1) }
    }
    fn terminate(&self) -> Status {
        unsafe { fmi3Terminate(self.i) }
    }
    fn reset(&self) -> Status {
        unsafe { fmi3Reset(self.i) }
    }
    fn set_logging(&self, on: bool, categories: &[&str]) -> Status {
        let (_owned, ptrs) = c_strings(categories);
        unsafe { fmi3SetDebugLogging(self.i, on, ptrs.len(), ptrs.as_ptr()) }
    }
    fn save(&self) -> Vec<u8> {
        unsafe {
            let mut s: fmi3FMUState = std::ptr::null_mut();
            assert_eq!(fmi3GetFMUState(self.i, &mut s), OK);
            let mut size = 0;
            assert_eq!(fmi3SerializedFMUStateSize(self.i, s, &mut size), OK);
            let mut bytes = vec![0u8; size];
            assert_eq!(fmi3SerializeFMUState(self.i, s, bytes.as_mut_ptr(), size), OK);
            assert_eq!(fmi3FreeFMUState(self.i, &mut s), OK);
            bytes
        }
    }
    fn restore(&self, bytes: &[u8]) -> Status {
        unsafe {
            let mut s: fmi3FMUState = std::ptr::null_mut();
            let status = fmi3DeserializeFMUState(self.i, bytes.as_ptr(), bytes.len(), &mut s);
            if status != OK {
                assert!(s.is_null(), "a refused deserialization hands out no state");
                return status;
            }
            let status = fmi3SetFMUState(self.i, s);
            assert_eq!(fmi3FreeFMUState(self.i, &mut s), OK);
            status
        }
    }
}
