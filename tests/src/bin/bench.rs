//! Benchmark of the FMU through its real C API, loaded like an importer would (dlopen).
//!
//!     cargo build --release -p ehsv-actuator     # the cdylib (scripts/test.sh builds it)
//!     cargo run --release -p ehsv-tests --bin bench [-- --quick] [--lib PATH] [--repeat N]
//!
//! Scenario: op-amp PI driver, V_supply 72 V, i_ref 0 -> 5 mA at t = 0, simulated for
//! 1 s (0.05 s with --quick) at communication steps of 1e-3, 1e-4 and 1e-5 s, each run
//! repeated N times. For every step size it prints
//! * the real-time factor (simulated time / wall time) of a run without per-call timing,
//!   doStep plus one fmi2GetReal of three outputs per step, as a co-simulation master does,
//!   over the whole run and split at 0.2 s: before, the piston runs into its end stop and
//!   settles (the cylinder integrator works); after, it rests there (valve and driver only);
//! * the mean and worst wall time of one fmi2DoStep (std::time::Instant around each call).
//!
//! It exits non-zero if any call returns a status other than OK or the coil current does
//! not end at 5 mA, so `--quick` doubles as a smoke test of the C API (scripts/test.sh).

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use ehsv_actuator::variables::{interface_token, vr};

// ---- FMI 2.0 C types (fmi2TypesPlatform.h / fmi2FunctionTypes.h) -------------------------

type Fmi2Component = *mut c_void;
type Fmi2ComponentEnvironment = *mut c_void;
type Fmi2String = *const c_char;
type Fmi2Boolean = c_int;
type Fmi2Real = f64;
type Fmi2Integer = c_int;
type Fmi2ValueReference = u32;
type Fmi2Status = c_int;
const FMI2_OK: Fmi2Status = 0;
const FMI2_CO_SIMULATION: c_int = 1; // fmi2Type
const FMI2_TRUE: Fmi2Boolean = 1;
const FMI2_FALSE: Fmi2Boolean = 0;

/// The logger is variadic in C (`..., fmi2String message, ...)`). Stable Rust cannot define
/// a variadic function, so this one takes the fixed arguments only: on the C ABIs Rust
/// runs on, the callee can read the named arguments of a variadic call this way. The
/// message is printed unformatted (this FMU formats its messages itself).
type Fmi2CallbackLogger =
    extern "C" fn(Fmi2ComponentEnvironment, Fmi2String, Fmi2Status, Fmi2String, Fmi2String);
type Fmi2CallbackAllocateMemory = extern "C" fn(usize, usize) -> *mut c_void;
type Fmi2CallbackFreeMemory = extern "C" fn(*mut c_void);
type Fmi2StepFinished = Option<extern "C" fn(Fmi2ComponentEnvironment, Fmi2Status)>;

/// fmi2CallbackFunctions, field for field.
#[repr(C)]
struct Fmi2CallbackFunctions {
    logger: Fmi2CallbackLogger,
    allocate_memory: Fmi2CallbackAllocateMemory,
    free_memory: Fmi2CallbackFreeMemory,
    step_finished: Fmi2StepFinished,
    component_environment: Fmi2ComponentEnvironment,
}

extern "C" {
    fn calloc(n: usize, size: usize) -> *mut c_void;
    fn free(p: *mut c_void);
}

extern "C" fn bench_logger(
    _env: Fmi2ComponentEnvironment,
    instance: Fmi2String,
    status: Fmi2Status,
    category: Fmi2String,
    message: Fmi2String,
) {
    let s = |p: Fmi2String| {
        if p.is_null() {
            String::new()
        } else {
            // SAFETY: the FMU passes NUL-terminated strings valid for the call.
            unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
        }
    };
    eprintln!("[{}] status {status} [{}] {}", s(instance), s(category), s(message));
}
extern "C" fn bench_calloc(n: usize, size: usize) -> *mut c_void {
    // SAFETY: plain libc calloc.
    unsafe { calloc(n, size) }
}
extern "C" fn bench_free(p: *mut c_void) {
    // SAFETY: p comes from bench_calloc (or is NULL).
    unsafe { free(p) }
}

type Instantiate = unsafe extern "C" fn(
    Fmi2String,
    c_int,
    Fmi2String,
    Fmi2String,
    *const Fmi2CallbackFunctions,
    Fmi2Boolean,
    Fmi2Boolean,
) -> Fmi2Component;
type FreeInstance = unsafe extern "C" fn(Fmi2Component);
type SetupExperiment = unsafe extern "C" fn(
    Fmi2Component,
    Fmi2Boolean,
    Fmi2Real,
    Fmi2Real,
    Fmi2Boolean,
    Fmi2Real,
) -> Fmi2Status;
type NoArg = unsafe extern "C" fn(Fmi2Component) -> Fmi2Status;
type SetReal = unsafe extern "C" fn(
    Fmi2Component,
    *const Fmi2ValueReference,
    usize,
    *const Fmi2Real,
) -> Fmi2Status;
type GetReal = unsafe extern "C" fn(
    Fmi2Component,
    *const Fmi2ValueReference,
    usize,
    *mut Fmi2Real,
) -> Fmi2Status;
type SetInteger = unsafe extern "C" fn(
    Fmi2Component,
    *const Fmi2ValueReference,
    usize,
    *const Fmi2Integer,
) -> Fmi2Status;
type DoStep = unsafe extern "C" fn(Fmi2Component, Fmi2Real, Fmi2Real, Fmi2Boolean) -> Fmi2Status;

/// The FMI 2 functions the benchmark calls, resolved once from the shared library.
struct Fmi2 {
    instantiate: Instantiate,
    free_instance: FreeInstance,
    setup_experiment: SetupExperiment,
    enter_init: NoArg,
    exit_init: NoArg,
    terminate: NoArg,
    set_real: SetReal,
    get_real: GetReal,
    set_integer: SetInteger,
    do_step: DoStep,
    _lib: libloading::Library, // keeps the functions valid
}

impl Fmi2 {
    fn load(path: &Path) -> Result<Fmi2, String> {
        // SAFETY: loading our own cdylib runs no initialisers with preconditions.
        let lib = unsafe { libloading::Library::new(path) }
            .map_err(|e| format!("cannot load {}: {e}", path.display()))?;
        macro_rules! sym {
            ($name:literal, $ty:ty) => {{
                // SAFETY: the symbol has the standard FMI 2.0 signature $ty.
                let s: libloading::Symbol<$ty> = unsafe { lib.get($name) }.map_err(|e| {
                    format!("{}: {e}", String::from_utf8_lossy(&$name[..$name.len() - 1]))
                })?;
                *s
            }};
        }
        Ok(Fmi2 {
            instantiate: sym!(b"fmi2Instantiate\0", Instantiate),
            free_instance: sym!(b"fmi2FreeInstance\0", FreeInstance),
            setup_experiment: sym!(b"fmi2SetupExperiment\0", SetupExperiment),
            enter_init: sym!(b"fmi2EnterInitializationMode\0", NoArg),
            exit_init: sym!(b"fmi2ExitInitializationMode\0", NoArg),
            terminate: sym!(b"fmi2Terminate\0", NoArg),
            set_real: sym!(b"fmi2SetReal\0", SetReal),
            get_real: sym!(b"fmi2GetReal\0", GetReal),
            set_integer: sym!(b"fmi2SetInteger\0", SetInteger),
            do_step: sym!(b"fmi2DoStep\0", DoStep),
            _lib: lib,
        })
    }
}

fn check(what: &str, status: Fmi2Status) -> Result<(), String> {
    if status == FMI2_OK {
        Ok(())
    } else {
        Err(format!("{what} returned status {status}"))
    }
}

struct RunResult {
    wall: Duration,
    /// Wall time when the simulation reached T_SPLIT (the piston has come to rest by then).
    split: Option<Duration>,
    steps: usize,
    step_times: Option<(Duration, Duration)>, // (sum, worst) of the fmi2DoStep calls
    i_final: f64,
}

const I_STEP: f64 = 5e-3;
/// Phases: the piston runs to its end stop and settles (0 .. T_SPLIT), then rests there.
const T_SPLIT: f64 = 0.2;

/// One run of the scenario on a fresh instance.
fn run(
    f: &Fmi2,
    callbacks: &Fmi2CallbackFunctions,
    h: f64,
    t_end: f64,
    time_each_call: bool,
) -> Result<RunResult, String> {
    let name = CString::new("bench").unwrap();
    let guid = CString::new(interface_token()).unwrap();
    let resources = CString::new("file:///nonexistent/resources").unwrap();
    // SAFETY: standard FMI 2.0 calling sequence on an instance we own; arrays match their counts.
    unsafe {
        let c = (f.instantiate)(
            name.as_ptr(),
            FMI2_CO_SIMULATION,
            guid.as_ptr(),
            resources.as_ptr(),
            callbacks,
            FMI2_FALSE,
            FMI2_FALSE,
        );
        if c.is_null() {
            return Err("fmi2Instantiate returned NULL".into());
        }
        let result = (|| {
            check(
                "fmi2SetupExperiment",
                (f.setup_experiment)(c, FMI2_FALSE, 0.0, 0.0, FMI2_TRUE, t_end),
            )?;
            let driver = [vr::DRIVER as u32];
            check(
                "fmi2SetInteger(driver)",
                (f.set_integer)(c, driver.as_ptr(), 1, [2 as Fmi2Integer].as_ptr()),
            )?;
            let inputs = [vr::I_REF as u32, vr::V_SUPPLY as u32];
            check(
                "fmi2SetReal(inputs)",
                (f.set_real)(c, inputs.as_ptr(), 2, [0.0, 72.0].as_ptr()),
            )?;
            check("fmi2EnterInitializationMode", (f.enter_init)(c))?;
            check("fmi2ExitInitializationMode", (f.exit_init)(c))?;
            let i_ref = [vr::I_REF as u32];
            check("fmi2SetReal(i_ref)", (f.set_real)(c, i_ref.as_ptr(), 1, [I_STEP].as_ptr()))?;
            let outs = [vr::I_COIL as u32, vr::U_DRIVER as u32, vr::Q_VALVE as u32];
            let mut y = [0.0f64; 3];
            let steps = (t_end / h).round() as usize;
            let (mut sum, mut worst) = (Duration::ZERO, Duration::ZERO);
            let split_step = (T_SPLIT / h).round() as usize;
            let mut split = None;
            let start = Instant::now();
            for k in 0..steps {
                let t = k as f64 * h;
                if k == split_step {
                    split = Some(start.elapsed());
                }
                let status = if time_each_call {
                    let t0 = Instant::now();
                    let s = (f.do_step)(c, t, h, FMI2_TRUE);
                    let dt = t0.elapsed();
                    sum += dt;
                    worst = worst.max(dt);
                    s
                } else {
                    (f.do_step)(c, t, h, FMI2_TRUE)
                };
                if status != FMI2_OK {
                    return Err(format!("fmi2DoStep at t = {t} returned status {status}"));
                }
                check("fmi2GetReal", (f.get_real)(c, outs.as_ptr(), outs.len(), y.as_mut_ptr()))?;
            }
            let wall = start.elapsed();
            check("fmi2Terminate", (f.terminate)(c))?;
            Ok(RunResult {
                wall,
                split,
                steps,
                step_times: time_each_call.then_some((sum, worst)),
                i_final: y[0],
            })
        })();
        (f.free_instance)(c);
        result
    }
}

fn default_library() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("target"));
    let file = if cfg!(target_os = "windows") {
        "ehsv_actuator.dll"
    } else if cfg!(target_os = "macos") {
        "libehsv_actuator.dylib"
    } else {
        "libehsv_actuator.so"
    };
    target.join("release").join(file)
}

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let mut quick = false;
    let mut lib = default_library();
    if let Ok(canonical) = lib.canonicalize() {
        lib = canonical;
    }
    let mut repeat: Option<usize> = None;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--quick" => quick = true,
            "--lib" => lib = PathBuf::from(args.next().expect("--lib PATH")),
            "--repeat" => {
                repeat = Some(args.next().and_then(|n| n.parse().ok()).expect("--repeat N"))
            }
            "-h" | "--help" => {
                println!("usage: bench [--quick] [--lib PATH] [--repeat N]");
                return ExitCode::SUCCESS;
            }
            other => {
                eprintln!("bench: unknown argument {other}");
                return ExitCode::FAILURE;
            }
        }
    }
    let repeat = repeat.unwrap_or(if quick { 1 } else { 5 });
    let t_end = if quick { 0.05 } else { 1.0 };

    if !lib.exists() {
        eprintln!(
            "bench: {} not found: build it with `cargo build --release -p ehsv-actuator`",
            lib.display()
        );
        return ExitCode::FAILURE;
    }
    let f = match Fmi2::load(&lib) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("bench: {e}");
            return ExitCode::FAILURE;
        }
    };
    let callbacks = Fmi2CallbackFunctions {
        logger: bench_logger,
        allocate_memory: bench_calloc,
        free_memory: bench_free,
        step_finished: None,
        component_environment: std::ptr::null_mut(),
    };

    println!("EhsvActuator benchmark through the FMI 2.0 C API ({})", lib.display());
    println!("scenario: opamp_pi, V_supply 72 V, i_ref 0 -> 5 mA, {t_end} s simulated, best/worst of {repeat} run(s)");
    println!(
        "{:>8} {:>9} {:>10} {:>10} {:>13} {:>13} {:>14} {:>14} {:>12}",
        "h [s]",
        "steps",
        "RTF best",
        "RTF worst",
        "RTF 0-0.2 s",
        "RTF 0.2 s-",
        "doStep mean",
        "doStep worst",
        "i_end [mA]"
    );
    let mut failed = false;
    for h in [1e-3, 1e-4, 1e-5] {
        let mut rtf: Vec<f64> = Vec::new();
        // Best of the runs for each phase: (moving and settling, at rest).
        let (mut rtf_moving, mut rtf_resting) = (0.0f64, 0.0f64);
        let (mut sum, mut worst, mut calls) = (Duration::ZERO, Duration::ZERO, 0usize);
        let mut i_end = f64::NAN;
        for _ in 0..repeat {
            for timed in [false, true] {
                match run(&f, &callbacks, h, t_end, timed) {
                    Ok(r) => {
                        i_end = r.i_final;
                        match r.step_times {
                            None => {
                                rtf.push(t_end / r.wall.as_secs_f64());
                                if let Some(split) = r.split {
                                    rtf_moving = rtf_moving.max(T_SPLIT / split.as_secs_f64());
                                    rtf_resting = rtf_resting
                                        .max((t_end - T_SPLIT) / (r.wall - split).as_secs_f64());
                                }
                            }
                            Some((s, w)) => {
                                sum += s;
                                worst = worst.max(w);
                                calls += r.steps;
                            }
                        }
                    }
                    Err(e) => {
                        eprintln!("bench: h = {h}: {e}");
                        failed = true;
                    }
                }
            }
        }
        if rtf.is_empty() || calls == 0 {
            continue;
        }
        let best = rtf.iter().cloned().fold(f64::MIN, f64::max);
        let worst_rtf = rtf.iter().cloned().fold(f64::MAX, f64::min);
        let mean_us = sum.as_secs_f64() / calls as f64 * 1e6;
        let phase = |r: f64| if r > 0.0 { format!("{r:.0}") } else { "-".into() };
        println!(
            "{:>8.0e} {:>9} {:>10.0} {:>10.0} {:>13} {:>13} {:>11.3} us {:>11.3} us {:>12.6}",
            h,
            (t_end / h).round() as usize,
            best,
            worst_rtf,
            phase(rtf_moving),
            phase(rtf_resting),
            mean_us,
            worst.as_secs_f64() * 1e6,
            i_end * 1e3
        );
        if !((i_end - I_STEP).abs() <= 1e-6 * I_STEP) {
            eprintln!("bench: h = {h}: i_coil ended at {i_end} A, expected {I_STEP} A");
            failed = true;
        }
    }
    println!("RTF = simulated time / wall time of the untimed run (doStep + fmi2GetReal of 3 outputs per step);");
    println!(
        "0-0.2 s: the piston runs into its end stop (~0.05 s) and settles; 0.2 s-: it rests there"
    );
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
