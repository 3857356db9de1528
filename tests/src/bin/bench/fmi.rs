//! The FMU's C API, loaded from the shared library with `dlopen` as an importer does:
//! the few FMI 2.0 and FMI 3.0 Co-Simulation functions the benchmark calls, behind one
//! [`Slave`] type so every workload runs the same code on both versions.

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::Path;

use ehsv_actuator::variables::interface_token;

/// Which FMI version a run goes through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Version {
    Fmi2,
    Fmi3,
}

impl Version {
    pub fn label(self) -> &'static str {
        match self {
            Version::Fmi2 => "FMI2",
            Version::Fmi3 => "FMI3",
        }
    }
}

// ---- FMI 2.0 C types (fmi2TypesPlatform.h / fmi2FunctionTypes.h) -------------------------

type Env = *mut c_void;
type CStrPtr = *const c_char;
type Fmi2Status = c_int;
const FMI2_CO_SIMULATION: c_int = 1; // fmi2Type
const OK: c_int = 0; // fmi2OK and fmi3OK

/// The FMI 2 logger is variadic in C. Stable Rust cannot define a variadic function, so this
/// one takes the fixed arguments only: on the C ABIs Rust runs on, the callee can read the
/// named arguments of a variadic call this way. The message is printed unformatted (this
/// FMU formats its messages itself).
type Fmi2Logger = extern "C" fn(Env, CStrPtr, Fmi2Status, CStrPtr, CStrPtr);

/// fmi2CallbackFunctions, field for field.
#[repr(C)]
pub struct Fmi2CallbackFunctions {
    logger: Fmi2Logger,
    allocate_memory: extern "C" fn(usize, usize) -> *mut c_void,
    free_memory: extern "C" fn(*mut c_void),
    step_finished: Option<extern "C" fn(Env, Fmi2Status)>,
    component_environment: Env,
}

extern "C" {
    fn calloc(n: usize, size: usize) -> *mut c_void;
    fn free(p: *mut c_void);
}

fn c_text(p: CStrPtr) -> String {
    if p.is_null() {
        String::new()
    } else {
        // SAFETY: the FMU passes NUL-terminated strings valid for the call.
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }
}

extern "C" fn fmi2_logger(
    _: Env,
    instance: CStrPtr,
    status: Fmi2Status,
    cat: CStrPtr,
    msg: CStrPtr,
) {
    eprintln!("[{}] status {status} [{}] {}", c_text(instance), c_text(cat), c_text(msg));
}
unsafe extern "C" fn fmi3_logger(_: Env, status: c_int, cat: CStrPtr, msg: CStrPtr) {
    eprintln!("[fmi3] status {status} [{}] {}", c_text(cat), c_text(msg));
}
extern "C" fn bench_calloc(n: usize, size: usize) -> *mut c_void {
    // SAFETY: plain libc calloc.
    unsafe { calloc(n, size) }
}
extern "C" fn bench_free(p: *mut c_void) {
    // SAFETY: p comes from bench_calloc (or is NULL).
    unsafe { free(p) }
}

static FMI2_CALLBACKS: Fmi2CallbackFunctions = Fmi2CallbackFunctions {
    logger: fmi2_logger,
    allocate_memory: bench_calloc,
    free_memory: bench_free,
    step_finished: None,
    component_environment: std::ptr::null_mut(),
};
// SAFETY: the callbacks table is immutable and holds only function pointers and NULL.
unsafe impl Sync for Fmi2CallbackFunctions {}

type Vr = u32;
type NoArg = unsafe extern "C" fn(*mut c_void) -> c_int;
type Free = unsafe extern "C" fn(*mut c_void);

/// The functions of one FMI version, resolved once.
enum Functions {
    Fmi2 {
        instantiate: unsafe extern "C" fn(
            CStrPtr,
            c_int,
            CStrPtr,
            CStrPtr,
            *const Fmi2CallbackFunctions,
            c_int,
            c_int,
        ) -> *mut c_void,
        setup: unsafe extern "C" fn(*mut c_void, c_int, f64, f64, c_int, f64) -> c_int,
        enter_init: NoArg,
        set_real: unsafe extern "C" fn(*mut c_void, *const Vr, usize, *const f64) -> c_int,
        get_real: unsafe extern "C" fn(*mut c_void, *const Vr, usize, *mut f64) -> c_int,
        set_integer: unsafe extern "C" fn(*mut c_void, *const Vr, usize, *const c_int) -> c_int,
        do_step: unsafe extern "C" fn(*mut c_void, f64, f64, c_int) -> c_int,
    },
    Fmi3 {
        #[allow(clippy::type_complexity)]
        instantiate: unsafe extern "C" fn(
            CStrPtr,
            CStrPtr,
            CStrPtr,
            bool,
            bool,
            bool,
            bool,
            *const Vr,
            usize,
            Env,
            Option<unsafe extern "C" fn(Env, c_int, CStrPtr, CStrPtr)>,
            *const c_void,
        ) -> *mut c_void,
        enter_init: unsafe extern "C" fn(*mut c_void, bool, f64, f64, bool, f64) -> c_int,
        set_float64:
            unsafe extern "C" fn(*mut c_void, *const Vr, usize, *const f64, usize) -> c_int,
        get_float64: unsafe extern "C" fn(*mut c_void, *const Vr, usize, *mut f64, usize) -> c_int,
        set_int64: unsafe extern "C" fn(*mut c_void, *const Vr, usize, *const i64, usize) -> c_int,
        #[allow(clippy::type_complexity)]
        do_step: unsafe extern "C" fn(
            *mut c_void,
            f64,
            f64,
            bool,
            *mut bool,
            *mut bool,
            *mut bool,
            *mut f64,
        ) -> c_int,
    },
}

/// The FMU library with the functions of one version.
pub struct Fmu {
    version: Version,
    functions: Functions,
    exit_init: NoArg,
    terminate: NoArg,
    free_instance: Free,
    _lib: libloading::Library, // keeps the function pointers valid
}

impl Fmu {
    pub fn load(path: &Path, version: Version) -> Result<Fmu, String> {
        // SAFETY: loading our own cdylib runs no initialisers with preconditions.
        let lib = unsafe { libloading::Library::new(path) }
            .map_err(|e| format!("cannot load {}: {e}", path.display()))?;
        macro_rules! sym {
            ($name:literal) => {{
                // SAFETY: the symbol has the standard FMI signature of the field it fills.
                let s = unsafe { lib.get($name) }.map_err(|e| {
                    format!("{}: {e}", String::from_utf8_lossy(&$name[..$name.len() - 1]))
                })?;
                *s
            }};
        }
        let (functions, exit_init, terminate, free_instance) = match version {
            Version::Fmi2 => (
                Functions::Fmi2 {
                    instantiate: sym!(b"fmi2Instantiate\0"),
                    setup: sym!(b"fmi2SetupExperiment\0"),
                    enter_init: sym!(b"fmi2EnterInitializationMode\0"),
                    set_real: sym!(b"fmi2SetReal\0"),
                    get_real: sym!(b"fmi2GetReal\0"),
                    set_integer: sym!(b"fmi2SetInteger\0"),
                    do_step: sym!(b"fmi2DoStep\0"),
                },
                sym!(b"fmi2ExitInitializationMode\0"),
                sym!(b"fmi2Terminate\0"),
                sym!(b"fmi2FreeInstance\0"),
            ),
            Version::Fmi3 => (
                Functions::Fmi3 {
                    instantiate: sym!(b"fmi3InstantiateCoSimulation\0"),
                    enter_init: sym!(b"fmi3EnterInitializationMode\0"),
                    set_float64: sym!(b"fmi3SetFloat64\0"),
                    get_float64: sym!(b"fmi3GetFloat64\0"),
                    set_int64: sym!(b"fmi3SetInt64\0"),
                    do_step: sym!(b"fmi3DoStep\0"),
                },
                sym!(b"fmi3ExitInitializationMode\0"),
                sym!(b"fmi3Terminate\0"),
                sym!(b"fmi3FreeInstance\0"),
            ),
        };
        Ok(Fmu { version, functions, exit_init, terminate, free_instance, _lib: lib })
    }

    pub fn version(&self) -> Version {
        self.version
    }
}

fn check(what: &str, status: c_int) -> Result<(), String> {
    if status == OK {
        Ok(())
    } else {
        Err(format!("{what} returned status {status}"))
    }
}

/// One instance in Step Mode. Freed on drop.
pub struct Slave<'a> {
    fmu: &'a Fmu,
    c: *mut c_void,
}

impl<'a> Slave<'a> {
    /// Instantiates, sets the enumerations and reals given (parameters and start inputs)
    /// and initialises at t = 0.
    pub fn start(
        fmu: &'a Fmu,
        enums: &[(usize, i64)],
        reals: &[(usize, f64)],
        t_end: f64,
    ) -> Result<Slave<'a>, String> {
        let name = CString::new("bench").unwrap();
        let token = CString::new(interface_token()).unwrap();
        let resources = CString::new("file:///nonexistent/resources").unwrap();
        // SAFETY: standard calling sequences; strings live across the calls.
        let c = unsafe {
            match fmu.functions {
                Functions::Fmi2 { instantiate, .. } => instantiate(
                    name.as_ptr(),
                    FMI2_CO_SIMULATION,
                    token.as_ptr(),
                    resources.as_ptr(),
                    &FMI2_CALLBACKS,
                    0,
                    0,
                ),
                Functions::Fmi3 { instantiate, .. } => instantiate(
                    name.as_ptr(),
                    token.as_ptr(),
                    resources.as_ptr(),
                    false,
                    false,
                    false,
                    false,
                    std::ptr::null(),
                    0,
                    std::ptr::null_mut(),
                    Some(fmi3_logger),
                    std::ptr::null(),
                ),
            }
        };
        if c.is_null() {
            return Err(format!("{} instantiate returned NULL", fmu.version.label()));
        }
        let slave = Slave { fmu, c };
        for &(vr, value) in enums {
            slave.set_enum(vr, value)?;
        }
        let (vrs, values): (Vec<u32>, Vec<f64>) = reals.iter().map(|&(r, v)| (r as u32, v)).unzip();
        slave.set_reals(&vrs, &values)?;
        // SAFETY: live instance, state machine order of the standard.
        unsafe {
            match fmu.functions {
                Functions::Fmi2 { setup, enter_init, .. } => {
                    check("fmi2SetupExperiment", setup(c, 0, 0.0, 0.0, 1, t_end))?;
                    check("fmi2EnterInitializationMode", enter_init(c))?;
                }
                Functions::Fmi3 { enter_init, .. } => check(
                    "fmi3EnterInitializationMode",
                    enter_init(c, false, 0.0, 0.0, true, t_end),
                )?,
            }
            check("ExitInitializationMode", (fmu.exit_init)(c))?;
        }
        Ok(slave)
    }

    fn set_enum(&self, vr: usize, value: i64) -> Result<(), String> {
        let r = [vr as u32];
        // SAFETY: live instance, arrays of one element.
        let status = unsafe {
            match self.fmu.functions {
                Functions::Fmi2 { set_integer, .. } => {
                    set_integer(self.c, r.as_ptr(), 1, &(value as c_int))
                }
                Functions::Fmi3 { set_int64, .. } => set_int64(self.c, r.as_ptr(), 1, &value, 1),
            }
        };
        check("set enumeration", status)
    }

    pub fn set_reals(&self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        assert_eq!(vrs.len(), values.len());
        // SAFETY: live instance; both arrays have vrs.len() elements.
        let status = unsafe {
            match self.fmu.functions {
                Functions::Fmi2 { set_real, .. } => {
                    set_real(self.c, vrs.as_ptr(), vrs.len(), values.as_ptr())
                }
                Functions::Fmi3 { set_float64, .. } => {
                    set_float64(self.c, vrs.as_ptr(), vrs.len(), values.as_ptr(), values.len())
                }
            }
        };
        check("set reals", status)
    }

    pub fn get_reals(&self, vrs: &[u32], values: &mut [f64]) -> Result<(), String> {
        assert_eq!(vrs.len(), values.len());
        // SAFETY: live instance; both arrays have vrs.len() elements.
        let status = unsafe {
            match self.fmu.functions {
                Functions::Fmi2 { get_real, .. } => {
                    get_real(self.c, vrs.as_ptr(), vrs.len(), values.as_mut_ptr())
                }
                Functions::Fmi3 { get_float64, .. } => {
                    get_float64(self.c, vrs.as_ptr(), vrs.len(), values.as_mut_ptr(), values.len())
                }
            }
        };
        check("get reals", status)
    }

    /// One communication step, as the master calls it (FMI 2: newStep = true).
    #[inline]
    pub fn do_step(&self, t: f64, h: f64) -> Result<(), String> {
        // SAFETY: live instance in Step Mode; the out-pointers are locals.
        let status = unsafe {
            match self.fmu.functions {
                Functions::Fmi2 { do_step, .. } => do_step(self.c, t, h, 1),
                Functions::Fmi3 { do_step, .. } => {
                    let (mut event, mut terminate, mut early, mut last) =
                        (false, false, false, 0.0);
                    do_step(self.c, t, h, true, &mut event, &mut terminate, &mut early, &mut last)
                }
            }
        };
        if status == OK {
            Ok(())
        } else {
            Err(format!("{} doStep at t = {t} returned status {status}", self.fmu.version.label()))
        }
    }
}

impl Drop for Slave<'_> {
    fn drop(&mut self) {
        // SAFETY: live instance, freed once; Terminate is refused outside Step Mode, harmless.
        unsafe {
            (self.fmu.terminate)(self.c);
            (self.fmu.free_instance)(self.c);
        }
    }
}
