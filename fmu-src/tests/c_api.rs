//! The FMI 2.0 / 3.0 C API called directly through the rlib (the same `extern "C"`
//! functions the cdylib exports). Tests the mechanics of the API — call sequence,
//! argument checks, logging, FMU states — not the physics values.

use std::ffi::{c_char, c_int, CStr, CString};
use std::ptr::{null, null_mut};

mod common;
use common::*;
use ehsv_actuator::fmi_common::LOG_CATEGORIES;

// ---------------------------------------------------------------- allocation counter

/// Counts heap allocations and live bytes per thread (tests run in parallel), to check
/// that the real-time path (set inputs, step, get outputs) does not allocate and that
/// FreeInstance gives back everything an instance took.
struct Counting;

thread_local! {
    static ALLOCATIONS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
    static LIVE_BYTES: std::cell::Cell<isize> = const { std::cell::Cell::new(0) };
}

unsafe impl std::alloc::GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        let _ = LIVE_BYTES.try_with(|n| n.set(n.get() + layout.size() as isize));
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        let _ = LIVE_BYTES.try_with(|n| n.set(n.get() - layout.size() as isize));
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> usize {
    ALLOCATIONS.with(|n| n.get())
}

fn live_bytes() -> isize {
    LIVE_BYTES.with(|n| n.get())
}

// ---------------------------------------------------------------- FMI 2 tests

#[test]
fn fmi2_version_and_platform() {
    unsafe {
        assert_eq!(CStr::from_ptr(fmi2GetVersion()).to_str().unwrap(), "2.0");
        assert_eq!(CStr::from_ptr(fmi2GetTypesPlatform()).to_str().unwrap(), "default");
    }
}

#[test]
fn fmi2_instantiate_checks_guid_type_and_name() {
    let log = Fmu2::try_new("bad_guid", fmi2CoSimulation, "{00000000-0000-0000-0000-000000000000}")
        .err()
        .unwrap();
    assert!(log.has(&["fmi2Instantiate", "fmuGUID", "does not match"]), "{}", log.dump());
    assert_eq!(log.lines()[0].status, Status::Error as c_int);
    assert_eq!(log.lines()[0].instance, "bad_guid");

    let log = Fmu2::try_new("me", fmi2ModelExchange, &interface_token()).err().unwrap();
    assert!(log.has(&["fmuType 0", "Co-Simulation"]), "{}", log.dump());

    let log = Fmu2::try_new("", fmi2CoSimulation, &interface_token()).err().unwrap();
    assert!(log.has(&["instanceName"]), "{}", log.dump());

    // NULL callbacks and NULL resource location are accepted (nothing is logged then).
    let name = CString::new("quiet").unwrap();
    let t = token();
    unsafe {
        let c = fmi2Instantiate(
            name.as_ptr(),
            fmi2CoSimulation,
            t.as_ptr(),
            null(),
            null(),
            fmi2False,
            fmi2True,
        );
        assert!(!c.is_null());
        assert_eq!(fmi2DoStep(c, 0.0, 1e-3, fmi2False), ERROR); // error without a logger: no crash
        fmi2FreeInstance(c);
        // NULL GUID is refused.
        assert!(fmi2Instantiate(name.as_ptr(), fmi2CoSimulation, null(), null(), null(), 0, 0)
            .is_null());
    }
}

#[test]
fn fmi2_happy_path() {
    let f = Fmu2::new("happy");
    unsafe {
        // Outputs can be read before initialisation (initial equilibrium).
        assert_eq!(f.get_real(vr::I_COIL).0, OK);
        assert_eq!(fmi2SetupExperiment(f.c, fmi2True, 1e-6, 0.0, fmi2True, 0.01), OK);
        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        assert_eq!(f.set_real(vr::I_REF, 0.01), OK);
        assert_eq!(fmi2ExitInitializationMode(f.c), OK, "{}", f.log.dump());
        let h = 1e-4;
        for k in 0..5 {
            assert_eq!(f.step(k as f64 * h, h), OK, "{}", f.log.dump());
        }
        let out = f.outputs();
        assert!(out.iter().all(|v| v.is_finite()), "{out:?}");
        assert!((out[0] - 5.0 * h).abs() < 1e-15);

        let mut sat = -1;
        // The flag must read the driver's state, not just be 0 or 1 (which the type
        // guarantees): i_ref = 10 mA was set during initialisation, so the op-amp starts
        // in equilibrium inside its rails (false); a 20 mA reversal needs more than the
        // 72 V supply across the coil, so one step later it sits on a rail (true).
        assert_eq!(fmi2GetBoolean(f.c, &(vr::DRIVER_SATURATED as u32), 1, &mut sat), OK);
        assert_eq!(sat, fmi2False);
        assert_eq!(f.set_real(vr::I_REF, -0.01), OK);
        assert_eq!(f.step(5.0 * h, h), OK);
        assert_eq!(fmi2GetBoolean(f.c, &(vr::DRIVER_SATURATED as u32), 1, &mut sat), OK);
        assert_eq!(sat, fmi2True, "a 20 mA reversal drives the op-amp onto a rail");
        assert_eq!(f.set_real(vr::I_REF, 0.01), OK);
        let mut driver = -1;
        assert_eq!(fmi2GetInteger(f.c, &(vr::DRIVER as u32), 1, &mut driver), OK);
        assert_eq!(driver, 2);

        let mut t = 0.0;
        assert_eq!(fmi2GetRealStatus(f.c, fmi2LastSuccessfulTime, &mut t), OK);
        assert!((t - 6.0 * h).abs() < 1e-15);
        let mut terminated = fmi2True;
        assert_eq!(fmi2GetBooleanStatus(f.c, fmi2Terminated, &mut terminated), OK);
        assert_eq!(terminated, fmi2False);
        let mut st = Status::OK;
        assert_eq!(fmi2GetStatus(f.c, fmi2DoStepStatus, &mut st), Status::Discard);
        let mut i = 0;
        assert_eq!(fmi2GetIntegerStatus(f.c, fmi2LastSuccessfulTime, &mut i), Status::Discard);
        let mut s: fmi2String = null();
        assert_eq!(fmi2GetStringStatus(f.c, fmi2PendingStatus, &mut s), Status::Discard);
        assert_eq!(fmi2CancelStep(f.c), ERROR);

        assert_eq!(fmi2Terminate(f.c), OK);
        assert_eq!(f.get_real(vr::X_SPOOL).0, OK, "getters work after Terminate");
        assert_eq!(f.set_real(vr::I_REF, 0.0), ERROR, "no setters after Terminate");
        assert_eq!(f.step(5.0 * h, h), ERROR);
        assert_eq!(fmi2Terminate(f.c), ERROR);
    }
    assert!(f.log.lines().iter().all(|l| l.instance == "happy"));
}

#[test]
fn fmi2_illegal_call_sequence() {
    let f = Fmu2::new("seq");
    unsafe {
        assert_eq!(f.step(0.0, 1e-3), ERROR);
        assert!(f.log.has(&["fmi2DoStep", "Instantiated"]), "{}", f.log.dump());
        assert_eq!(fmi2ExitInitializationMode(f.c), ERROR);
        assert_eq!(fmi2Terminate(f.c), ERROR);
        let mut t = 0.0;
        assert_eq!(fmi2GetRealStatus(f.c, fmi2LastSuccessfulTime, &mut t), ERROR);
        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        assert_eq!(fmi2SetupExperiment(f.c, 0, 0.0, 0.0, 0, 0.0), ERROR);
        assert!(f.log.has(&["fmi2SetupExperiment", "InitializationMode"]));
        assert_eq!(fmi2EnterInitializationMode(f.c), ERROR);
        assert_eq!(f.step(0.0, 1e-3), ERROR);
        // The errors did not break the instance.
        assert_eq!(fmi2ExitInitializationMode(f.c), OK);
        assert_eq!(f.step(0.0, 1e-3), OK);
        assert_eq!(fmi2EnterInitializationMode(f.c), ERROR);
        assert!(f.log.has(&["fmi2EnterInitializationMode", "StepComplete"]), "{}", f.log.dump());
    }
}

#[test]
fn fmi2_value_references_types_and_pointers() {
    let f = Fmu2::initialized("refs");
    unsafe {
        let mut v = 0.0;
        assert_eq!(fmi2GetReal(f.c, &999, 1, &mut v), ERROR);
        assert!(f.log.has(&["fmi2GetReal", "unknown value reference 999"]), "{}", f.log.dump());
        // A fixed parameter in StepComplete.
        assert_eq!(fmi2SetReal(f.c, &(vr::VALVE_K1 as u32), 1, &v), ERROR);
        assert!(f.log.has(&["valve.K1", "fixed parameter", "StepComplete"]), "{}", f.log.dump());

        assert_eq!(fmi2GetReal(f.c, &(vr::DRIVER_SATURATED as u32), 1, &mut v), ERROR);
        assert!(f.log.has(&["driver_saturated", "Boolean", "not Real"]), "{}", f.log.dump());
        let mut i = 0;
        assert_eq!(fmi2GetInteger(f.c, &(vr::I_REF as u32), 1, &mut i), ERROR);
        assert!(f.log.has(&["i_ref", "Real", "not Integer"]));
        assert_eq!(fmi2GetReal(f.c, &(vr::DRIVER as u32), 1, &mut v), ERROR);
        assert!(f.log.has(&["driver", "Enumeration DriverType"]));

        assert_eq!(f.set_real(vr::I_COIL, 1.0), ERROR);
        assert!(f.log.has(&["i_coil", "output", "cannot be set"]));
        assert_eq!(f.set_real(vr::TIME, 1.0), ERROR);

        // NULL arrays with n > 0; n = 0 with NULL is fine.
        assert_eq!(fmi2GetReal(f.c, null(), 1, &mut v), ERROR);
        assert_eq!(fmi2GetReal(f.c, &1, 1, null_mut()), ERROR);
        assert!(f.log.has(&["values is NULL"]), "{}", f.log.dump());
        assert_eq!(fmi2GetReal(f.c, null(), 0, null_mut()), OK);
        assert_eq!(fmi2SetReal(f.c, null(), 0, null()), OK);
        // No String variables.
        assert_eq!(fmi2GetString(f.c, null(), 0, null_mut()), OK);
        let mut s: fmi2String = null();
        assert_eq!(fmi2GetString(f.c, &1, 1, &mut s), ERROR);
        assert!(f.log.has(&["i_ref", "not String"]));
        assert_eq!(fmi2SetString(f.c, &999, 1, &s), ERROR);

        // A failing multi-value set changes nothing.
        let refs = [vr::I_REF as u32, vr::V_SUPPLY as u32];
        assert_eq!(fmi2SetReal(f.c, refs.as_ptr(), 2, [0.02, -5.0].as_ptr()), ERROR);
        assert!(f.log.has(&["V_supply"]));
        assert_eq!(f.get_real(vr::I_REF).1, 0.0);
        assert_eq!(fmi2SetReal(f.c, refs.as_ptr(), 2, [0.02, 50.0].as_ptr()), OK);
        assert_eq!(f.get_real(vr::I_REF).1, 0.02);
        assert_eq!(f.get_real(vr::V_SUPPLY).1, 50.0);

        // Null instance: Error, nothing else.
        assert_eq!(fmi2GetReal(null_mut(), &1, 1, &mut v), ERROR);
        assert_eq!(fmi2DoStep(null_mut(), 0.0, 1.0, 0), ERROR);
        assert_eq!(fmi2Reset(null_mut()), ERROR);
        fmi2FreeInstance(null_mut());
    }
}

#[test]
fn fmi2_nan_input_is_refused_and_instance_keeps_stepping() {
    let f = Fmu2::initialized("nan");
    assert_eq!(f.set_real(vr::I_REF, 0.005), OK);
    assert_eq!(f.step(0.0, 1e-4), OK);
    assert_eq!(f.set_real(vr::I_REF, f64::NAN), ERROR);
    assert!(f.log.has(&["fmi2SetReal", "i_ref", "finite"]), "{}", f.log.dump());
    assert_eq!(f.get_real(vr::I_REF).1, 0.005);
    assert_eq!(f.set_real(vr::I_REF, f64::INFINITY), ERROR);
    assert_eq!(f.step(1e-4, 1e-4), OK, "{}", f.log.dump());
    assert!((f.time() - 2e-4).abs() < 1e-15);
}

#[test]
fn fmi2_bad_steps_are_refused_without_changing_state() {
    let f = Fmu2::new("steps");
    unsafe {
        assert_eq!(fmi2SetupExperiment(f.c, 0, 0.0, 1.0, fmi2True, 1.001), OK);
        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        assert_eq!(fmi2ExitInitializationMode(f.c), OK);
    }
    let before = f.outputs();
    assert_eq!(f.step(1.0, -1e-3), ERROR);
    assert!(f.log.has(&["fmi2DoStep", "-0.001"]), "{}", f.log.dump());
    assert_eq!(f.step(1.0, 0.0), ERROR);
    assert_eq!(f.step(1.0, f64::NAN), ERROR);
    assert_eq!(f.step(1.0005, 1e-4), ERROR, "communication point must match the FMU time");
    assert!(f.log.has(&["currentCommunicationPoint"]));
    assert_eq!(f.step(1.0, 0.01), ERROR, "past stopTime");
    assert!(f.log.has(&["stopTime"]), "{}", f.log.dump());
    assert_eq!(f.outputs(), before);
    assert_eq!(f.step(1.0, 0.0005), OK);
    assert_eq!(f.step(1.0005, 0.0005), OK, "the last step may end at stopTime");
    unsafe {
        let f2 = Fmu2::new("stop_before_start");
        assert_eq!(fmi2SetupExperiment(f2.c, 0, 0.0, 1.0, fmi2True, 0.5), ERROR);
        assert_eq!(fmi2SetupExperiment(f2.c, 0, 0.0, f64::NAN, 0, 0.0), ERROR);
    }
}

#[test]
fn fmi2_parameters_range_and_state_rules() {
    let f = Fmu2::new("params");
    assert_eq!(f.set_real(vr::COIL_L, -1.0), ERROR);
    assert!(f.log.has(&["fmi2SetReal", "coil.L", "-1"]), "{}", f.log.dump());
    assert_eq!(f.get_real(vr::COIL_L).1, 3.2);
    assert_eq!(f.set_real(vr::COIL_L, 2.0), OK);
    unsafe {
        // Enumerations through fmi2SetInteger, range-checked by the model.
        assert_eq!(fmi2SetInteger(f.c, &(vr::DRIVER as u32), 1, &7), ERROR);
        assert!(f.log.has(&["driver"]));
        assert_eq!(fmi2SetInteger(f.c, &(vr::DRIVER as u32), 1, &1), OK);
        assert_eq!(fmi2SetReal(f.c, &(vr::DRIVER as u32), 1, &1.0), ERROR);
        // Outputs are not settable, not even as Boolean.
        assert_eq!(fmi2SetBoolean(f.c, &(vr::DRIVER_SATURATED as u32), 1, &fmi2True), ERROR);
        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        assert_eq!(f.set_real(vr::COIL_R, 900.0), OK, "fixed parameters in InitializationMode");
        assert_eq!(fmi2ExitInitializationMode(f.c), OK, "{}", f.log.dump());
        assert_eq!(f.set_real(vr::COIL_L, 3.0), ERROR);
        assert!(f.log.has(&["coil.L", "fixed parameter", "StepComplete"]), "{}", f.log.dump());
        assert_eq!(f.set_real(vr::I_REF, 0.001), OK, "inputs in StepComplete");
        assert_eq!(f.get_real(vr::COIL_L).1, 2.0);
        let mut d = 0;
        assert_eq!(fmi2GetInteger(f.c, &(vr::DRIVER as u32), 1, &mut d), OK);
        assert_eq!(d, 1);
    }
}

#[test]
fn fmi2_percent_in_user_text_is_escaped() {
    let log = Fmu2::try_new("pump%s%n", fmi2CoSimulation, "{wrong%d}").err().unwrap();
    let lines = log.lines();
    assert_eq!(lines[0].instance, "pump%s%n", "instanceName is not a format: passed as is");
    assert!(
        lines[0].message.contains("pump%%s%%n") && lines[0].message.contains("{wrong%%d}"),
        "{}",
        log.dump()
    );

    let f = Fmu2::new("100%");
    let cat = CString::new("log%s").unwrap();
    unsafe {
        assert_eq!(fmi2SetDebugLogging(f.c, fmi2True, 1, &cat.as_ptr()), ERROR);
    }
    assert!(f.log.has(&["unknown log category 'log%%s'"]), "{}", f.log.dump());
    for l in f.log.lines().iter().chain(&lines) {
        // Every run of '%' in a format string is of even length: no conversion left.
        for run in l.message.split(|c| c != '%').filter(|r| !r.is_empty()) {
            assert!(run.len() % 2 == 0, "unescaped % in {:?}", l.message);
        }
    }
}

#[test]
fn fmi2_debug_logging_categories() {
    let f = Fmu2::initialized("cats");
    f.log.clear();
    let all = CString::new("logAll").unwrap();
    unsafe {
        assert_eq!(fmi2SetDebugLogging(f.c, fmi2True, 1, &all.as_ptr()), OK);
        assert_eq!(f.step(0.0, 1e-4), OK);
        assert!(
            f.log
                .lines()
                .iter()
                .any(|l| l.category == "logAll" && l.message.contains("fmi2DoStep")),
            "{}",
            f.log.dump()
        );
        assert_eq!(fmi2SetDebugLogging(f.c, fmi2False, 0, null()), OK);
        f.log.clear();
        assert_eq!(f.step(1e-4, 1e-4), OK);
        assert!(f.log.lines().is_empty(), "{}", f.log.dump());
        // Errors are logged even with logging off.
        assert_eq!(f.step(0.0, 1e-4), ERROR);
        assert_eq!(f.log.lines().len(), 1);
        assert_eq!(f.log.lines()[0].category, "logStatusError");
        // Every declared category is accepted.
        let names: Vec<CString> =
            LOG_CATEGORIES.iter().map(|(n, _)| CString::new(*n).unwrap()).collect();
        let ptrs: Vec<*const c_char> = names.iter().map(|n| n.as_ptr()).collect();
        assert_eq!(fmi2SetDebugLogging(f.c, fmi2True, ptrs.len(), ptrs.as_ptr()), OK);
        assert_eq!(fmi2SetDebugLogging(f.c, fmi2True, 2, null()), ERROR);
        let null_entry = [all.as_ptr(), null()];
        assert_eq!(fmi2SetDebugLogging(f.c, fmi2True, 2, null_entry.as_ptr()), ERROR);
    }
}

#[test]
fn fmi2_fmu_state_round_trip() {
    let f = Fmu2::initialized("state");
    let h = 1e-4;
    let mut t = 0.0;
    let run = |f: &Fmu2, t: &mut f64, n: usize, i_ref: f64| {
        assert_eq!(f.set_real(vr::I_REF, i_ref), OK);
        for _ in 0..n {
            assert_eq!(f.step(*t, h), OK, "{}", f.log.dump());
            *t += h;
        }
    };
    run(&f, &mut t, 3, 0.004);
    unsafe {
        let mut s: fmi2FMUstate = null_mut();
        assert_eq!(fmi2GetFMUstate(f.c, &mut s), OK);
        assert!(!s.is_null());
        let t_saved = t;
        run(&f, &mut t, 4, -0.003);
        let reference = f.outputs();

        // Restore in memory and replay.
        assert_eq!(fmi2SetFMUstate(f.c, s), OK);
        assert_eq!(f.time(), t_saved);
        t = t_saved;
        run(&f, &mut t, 4, -0.003);
        assert_eq!(f.outputs(), reference);

        // Serialize, deserialize into a new state, restore and replay.
        let mut size = 0usize;
        assert_eq!(fmi2SerializedFMUstateSize(f.c, s, &mut size), OK);
        assert!(size > 24);
        let mut bytes = vec![0 as fmi2Byte; size];
        assert_eq!(
            fmi2SerializeFMUstate(f.c, s, bytes.as_mut_ptr(), size - 1),
            ERROR,
            "buffer too small"
        );
        assert_eq!(fmi2SerializeFMUstate(f.c, s, bytes.as_mut_ptr(), size), OK);
        let mut s2: fmi2FMUstate = null_mut();
        assert_eq!(
            fmi2DeSerializeFMUstate(f.c, bytes.as_ptr(), size, &mut s2),
            OK,
            "{}",
            f.log.dump()
        );
        assert_eq!(fmi2SetFMUstate(f.c, s2), OK);
        t = t_saved;
        run(&f, &mut t, 4, -0.003);
        assert_eq!(f.outputs(), reference);

        // The same bytes restore a second instance.
        let g = Fmu2::initialized("state_copy");
        let mut s3: fmi2FMUstate = null_mut();
        assert_eq!(fmi2DeSerializeFMUstate(g.c, bytes.as_ptr(), size, &mut s3), OK);
        assert_eq!(fmi2SetFMUstate(g.c, s3), OK);
        t = t_saved;
        run(&g, &mut t, 4, -0.003);
        assert_eq!(g.outputs(), reference);
        assert_eq!(fmi2FreeFMUstate(g.c, &mut s3), OK);

        // GetFMUstate with a non-NULL *state reuses it.
        let kept = s;
        assert_eq!(fmi2GetFMUstate(f.c, &mut s), OK);
        assert_eq!(s, kept);

        assert_eq!(fmi2FreeFMUstate(f.c, &mut s), OK);
        assert!(s.is_null());
        assert_eq!(fmi2FreeFMUstate(f.c, &mut s), OK, "freeing NULL is fine");
        // A stale copy of a freed state, or a state of another instance, is refused
        // without being read (no double free, no use after free).
        let mut stale = kept;
        assert_eq!(fmi2FreeFMUstate(f.c, &mut stale), ERROR, "double free");
        assert_eq!(fmi2SetFMUstate(f.c, stale), ERROR, "use after free");
        assert!(f.log.has(&["not one this instance made"]), "{}", f.log.dump());
        let mut foreign: fmi2FMUstate = null_mut();
        assert_eq!(fmi2GetFMUstate(g.c, &mut foreign), OK);
        assert_eq!(fmi2SetFMUstate(f.c, foreign), ERROR, "a state of instance g set in f");
        assert_eq!(fmi2FreeFMUstate(f.c, &mut foreign), ERROR, "freed through f");
        assert_eq!(fmi2FreeFMUstate(g.c, &mut foreign), OK, "its own instance frees it");
        assert_eq!(fmi2FreeFMUstate(f.c, &mut s2), OK);
        assert_eq!(fmi2FreeFMUstate(f.c, null_mut()), OK);

        // NULL pointers.
        assert_eq!(fmi2GetFMUstate(f.c, null_mut()), ERROR);
        assert_eq!(fmi2SetFMUstate(f.c, null_mut()), ERROR);
        assert_eq!(fmi2SerializedFMUstateSize(f.c, null_mut(), &mut size), ERROR);
    }
}

#[test]
fn fmi2_corrupted_state_bytes_are_refused() {
    let f = Fmu2::initialized("corrupt");
    assert_eq!(f.step(0.0, 1e-4), OK);
    unsafe {
        let mut s: fmi2FMUstate = null_mut();
        assert_eq!(fmi2GetFMUstate(f.c, &mut s), OK);
        let mut size = 0;
        assert_eq!(fmi2SerializedFMUstateSize(f.c, s, &mut size), OK);
        let mut bytes = vec![0 as fmi2Byte; size];
        assert_eq!(fmi2SerializeFMUstate(f.c, s, bytes.as_mut_ptr(), size), OK);
        bytes[size / 2] ^= 0x55;
        let mut s2: fmi2FMUstate = null_mut();
        assert_eq!(fmi2DeSerializeFMUstate(f.c, bytes.as_ptr(), size, &mut s2), ERROR);
        assert!(s2.is_null());
        assert!(f.log.has(&["fmi2DeSerializeFMUstate", "cannot deserialize"]), "{}", f.log.dump());
        assert_eq!(fmi2DeSerializeFMUstate(f.c, bytes.as_ptr(), 10, &mut s2), ERROR, "truncated");
        assert_eq!(fmi2DeSerializeFMUstate(f.c, null(), size, &mut s2), ERROR);
        // A pointer that is not an FMU state of ours.
        let mut junk = [0u64; 64];
        assert_eq!(fmi2SetFMUstate(f.c, junk.as_mut_ptr().cast()), ERROR);
        assert!(f.log.has(&["not one this instance made"]), "{}", f.log.dump());
        assert_eq!(fmi2FreeFMUstate(f.c, &mut s), OK);
        // The instance still works.
        assert_eq!(f.step(1e-4, 1e-4), OK);
    }
}

#[test]
fn fmi2_two_instances_at_once() {
    let a = Fmu2::initialized("a");
    let b = Fmu2::initialized("b");
    assert_eq!(a.set_real(vr::I_REF, 0.01), OK);
    assert_eq!(b.set_real(vr::I_REF, -0.01), OK);
    for k in 0..3 {
        assert_eq!(a.step(k as f64 * 1e-4, 1e-4), OK);
    }
    assert_eq!(b.step(0.0, 1e-3), OK);
    assert!((a.time() - 3e-4).abs() < 1e-15);
    assert!((b.time() - 1e-3).abs() < 1e-15);
    assert_eq!(a.get_real(vr::I_REF).1, 0.01);
    assert_eq!(b.get_real(vr::I_REF).1, -0.01);
    assert_eq!(b.step(0.0, 1e-3), ERROR);
    assert!(b.log.has(&["fmi2DoStep"]));
    assert!(!a.log.has(&["fmi2DoStep"]), "errors go to the instance's own logger");
    assert!(b.log.lines().iter().all(|l| l.instance == "b"));
    // Instances on other threads.
    let handles: Vec<_> = (0..4)
        .map(|i| {
            std::thread::spawn(move || {
                let f = Fmu2::initialized(&format!("thread{i}"));
                for k in 0..20 {
                    assert_eq!(f.step(k as f64 * 1e-4, 1e-4), OK);
                }
                f.time()
            })
        })
        .collect();
    for h in handles {
        assert!((h.join().unwrap() - 2e-3).abs() < 1e-12);
    }
}

#[test]
fn fmi2_reset_and_unsupported_functions() {
    let f = Fmu2::initialized("reset");
    assert_eq!(f.set_real(vr::I_REF, 0.01), OK);
    assert_eq!(f.step(0.0, 1e-3), OK);
    unsafe {
        assert_eq!(fmi2Reset(f.c), OK);
        assert_eq!(f.time(), 0.0);
        assert_eq!(f.get_real(vr::I_REF).1, 0.0);
        assert_eq!(f.step(0.0, 1e-3), ERROR, "back in Instantiated");
        assert_eq!(f.set_real(vr::COIL_L, 1.0), OK, "fixed parameters settable again");
        assert_eq!(fmi2SetupExperiment(f.c, 0, 0.0, 0.0, 0, 0.0), OK);
        assert_eq!(fmi2EnterInitializationMode(f.c), OK);
        assert_eq!(fmi2ExitInitializationMode(f.c), OK);
        assert_eq!(f.step(0.0, 1e-3), OK);

        let mut d = 0.0;
        assert_eq!(fmi2GetDirectionalDerivative(f.c, &3, 1, &1, 1, &1.0, &mut d), ERROR);
        assert!(
            f.log.has(&["fmi2GetDirectionalDerivative is not supported by EhsvActuator"]),
            "{}",
            f.log.dump()
        );
        // Input and output derivatives of order 1 (canInterpolateInputs,
        // maxOutputDerivativeOrder = 1); others refused, naming the variable and the order.
        let v_rod = vr::V_ROD as u32;
        assert_eq!(fmi2SetRealInputDerivatives(f.c, &v_rod, 1, &1, &2.0), OK);
        assert_eq!(fmi2SetRealInputDerivatives(f.c, &v_rod, 1, &2, &2.0), ERROR);
        assert!(f.log.has(&["order 2 for v_rod"]), "{}", f.log.dump());
        let (x_piston, i_coil) = (vr::X_PISTON as u32, vr::I_COIL as u32);
        assert_eq!(fmi2GetRealOutputDerivatives(f.c, &x_piston, 1, &1, &mut d), OK);
        assert_eq!(d, f.get_real(vr::V_PISTON).1, "x_piston's rate is v_piston");
        assert_eq!(fmi2GetRealOutputDerivatives(f.c, &i_coil, 1, &0, &mut d), ERROR);
        assert!(f.log.has(&["order 0 for i_coil"]), "{}", f.log.dump());
        assert_eq!(fmi2GetRealOutputDerivatives(f.c, &v_rod, 1, &1, &mut d), ERROR);
        assert!(f.log.has(&["v_rod is not a real output"]), "{}", f.log.dump());
    }
}

// ---------------------------------------------------------------- FMI 3 tests

#[test]
fn fmi3_instantiation() {
    unsafe {
        assert_eq!(CStr::from_ptr(fmi3GetVersion()).to_str().unwrap(), "3.0");
    }
    let log = Fmu3::try_new("bad", "{nope}", false).err().expect("wrong token refused");
    assert!(
        log.has(&["fmi3InstantiateCoSimulation", "instantiationToken", "does not match"]),
        "{}",
        log.dump()
    );
    let log = Fmu3::try_new("events", &interface_token(), true).err().expect("event mode refused");
    assert!(log.has(&["eventModeUsed"]), "{}", log.dump());
    let log = Fmu3::try_new("", &interface_token(), false).err().expect("empty name refused");
    assert!(log.has(&["instanceName"]));

    let log = Log::default();
    let name = CString::new("me").unwrap();
    let t = token();
    unsafe {
        let i = fmi3InstantiateModelExchange(
            name.as_ptr(),
            t.as_ptr(),
            null(),
            false,
            false,
            log.env(),
            Some(fmi3_logger),
        );
        assert!(i.is_null());
        assert!(
            log.has(&["fmi3InstantiateModelExchange is not supported by EhsvActuator"]),
            "{}",
            log.dump()
        );
        let i = fmi3InstantiateScheduledExecution(
            name.as_ptr(),
            t.as_ptr(),
            null(),
            false,
            false,
            log.env(),
            Some(fmi3_logger),
            None,
            None,
            None,
        );
        assert!(i.is_null());
        assert!(log.has(&["fmi3InstantiateScheduledExecution is not supported by EhsvActuator"]));
        // No logger at all: still NULL, no crash.
        assert!(fmi3InstantiateModelExchange(
            name.as_ptr(),
            t.as_ptr(),
            null(),
            false,
            false,
            null_mut(),
            None
        )
        .is_null());
    }
}

#[test]
fn fmi3_happy_path_and_do_step_out_flags() {
    let f = Fmu3::new("happy3");
    unsafe {
        assert_eq!(f.get(vr::Q_VALVE).0, OK, "outputs readable before initialisation");
        assert_eq!(fmi3EnterInitializationMode(f.i, true, 1e-6, 0.5, true, 0.6), OK);
        assert_eq!(f.set(vr::I_REF, 0.01), OK);
        assert_eq!(fmi3ExitInitializationMode(f.i), OK, "{}", f.log.dump());
    }
    let h = 1e-4;
    for k in 0..5 {
        let t = 0.5 + k as f64 * h;
        let (s, flags, last) = f.step(t, h);
        assert_eq!(s, OK, "{}", f.log.dump());
        assert_eq!(flags, [false; 3]);
        assert_eq!(last, f.get(vr::TIME).1);
        assert!((last - (t + h)).abs() < 1e-12);
    }
    assert!(f.outputs().iter().all(|v| v.is_finite()));
    unsafe {
        let mut driver = 0i64;
        assert_eq!(fmi3GetInt64(f.i, &(vr::DRIVER as u32), 1, &mut driver, 1), OK);
        assert_eq!(driver, 2);
        let mut sat = true;
        assert_eq!(fmi3GetBoolean(f.i, &(vr::DRIVER_SATURATED as u32), 1, &mut sat, 1), OK);
        assert!(!sat, "in equilibrium at the 10 mA set during initialisation: inside the rails");
        assert_eq!(fmi3Terminate(f.i), OK);
        assert_eq!(f.get(vr::X_SPOOL).0, OK);
        assert_eq!(f.step(0.5 + 5.0 * h, h).0, ERROR);
        assert!(f.log.has(&["fmi3DoStep", "Terminated"]), "{}", f.log.dump());
        assert_eq!(fmi3Reset(f.i), OK);
        assert_eq!(f.get(vr::TIME).1, 0.0);
    }
}

#[test]
fn fmi3_illegal_sequence_and_do_step_errors() {
    let f = Fmu3::new("seq3");
    let (s, flags, _) = f.step(0.0, 1e-3);
    assert_eq!(s, ERROR);
    assert_eq!(flags, [true; 3], "flags untouched when the call itself is illegal");
    assert!(f.log.has(&["fmi3DoStep", "Instantiated"]), "{}", f.log.dump());
    unsafe {
        assert_eq!(fmi3Terminate(f.i), ERROR);
        assert_eq!(fmi3ExitInitializationMode(f.i), ERROR);
        assert_eq!(fmi3EnterInitializationMode(f.i, false, 0.0, 0.0, true, 1e-3), OK);
        assert_eq!(fmi3ExitInitializationMode(f.i), OK);
        assert_eq!(fmi3EnterInitializationMode(f.i, false, 0.0, 0.0, false, 0.0), ERROR);
        assert!(f.log.has(&["fmi3EnterInitializationMode", "StepMode"]));

        // Out-pointers must not be NULL.
        let (mut a, mut b, mut c, mut t) = (true, true, true, 0.0);
        assert_eq!(fmi3DoStep(f.i, 0.0, 1e-4, false, null_mut(), &mut b, &mut c, &mut t), ERROR);
        assert!(f.log.has(&["eventHandlingNeeded"]));
        assert_eq!(fmi3DoStep(f.i, 0.0, 1e-4, false, &mut a, &mut b, &mut c, null_mut()), ERROR);
    }
    // Step errors still report lastSuccessfulTime and clear the flags.
    let (s, flags, last) = f.step(0.0, -1e-4);
    assert_eq!((s, flags, last), (ERROR, [false; 3], 0.0));
    let (s, _, last) = f.step(0.0, 2e-3);
    assert_eq!((s, last), (ERROR, 0.0));
    assert!(f.log.has(&["stopTime"]), "{}", f.log.dump());
    assert_eq!(f.set(vr::I_REF, f64::NAN), ERROR);
    assert!(f.log.has(&["fmi3SetFloat64", "i_ref"]));
    let (s, _, last) = f.step(0.0, 1e-3);
    assert_eq!(s, OK, "{}", f.log.dump());
    assert!((last - 1e-3).abs() < 1e-15);
}

#[test]
fn fmi3_value_counts_types_and_references() {
    let f = Fmu3::initialized("vals3", None);
    unsafe {
        let refs = [vr::I_REF as u32, vr::V_SUPPLY as u32];
        let mut v = [0.0; 3];
        assert_eq!(fmi3GetFloat64(f.i, refs.as_ptr(), 2, v.as_mut_ptr(), 3), ERROR);
        assert!(f.log.has(&["fmi3GetFloat64", "nValues = 3"]), "{}", f.log.dump());
        assert_eq!(fmi3GetFloat64(f.i, refs.as_ptr(), 2, v.as_mut_ptr(), 1), ERROR);
        assert_eq!(fmi3SetFloat64(f.i, refs.as_ptr(), 2, v.as_ptr(), 3), ERROR);
        assert_eq!(fmi3GetFloat64(f.i, refs.as_ptr(), 2, v.as_mut_ptr(), 2), OK);
        assert_eq!(v[1], 72.0);

        assert_eq!(fmi3GetFloat64(f.i, &500, 1, v.as_mut_ptr(), 1), ERROR);
        assert!(f.log.has(&["unknown value reference 500"]));
        assert_eq!(fmi3GetFloat64(f.i, &(vr::DRIVER as u32), 1, v.as_mut_ptr(), 1), ERROR);
        assert!(f.log.has(&["driver", "Enumeration DriverType", "Int64"]), "{}", f.log.dump());
        let mut i32v = 0i32;
        assert_eq!(fmi3GetInt32(f.i, &(vr::DRIVER as u32), 1, &mut i32v, 1), ERROR);
        assert!(f.log.has(&["not Int32"]));
        let mut f32v = 0f32;
        assert_eq!(fmi3GetFloat32(f.i, &(vr::I_REF as u32), 1, &mut f32v, 1), ERROR);
        assert!(f.log.has(&["i_ref", "Float64", "not Float32"]));
        let mut b = false;
        assert_eq!(fmi3GetBoolean(f.i, &(vr::I_REF as u32), 1, &mut b, 1), ERROR);
        let mut i64v = 0i64;
        assert_eq!(
            fmi3SetInt64(f.i, &(vr::DRIVER as u32), 1, &1, 1),
            ERROR,
            "fixed parameter in StepMode"
        );
        assert!(f.log.has(&["driver", "fixed parameter", "StepMode"]), "{}", f.log.dump());
        assert_eq!(fmi3GetInt64(f.i, &(vr::CONTROL_MODE as u32), 1, &mut i64v, 1), OK);

        // Empty requests of every type are fine; types without variables refuse any reference.
        assert_eq!(fmi3GetUInt16(f.i, null(), 0, null_mut(), 0), OK);
        assert_eq!(fmi3SetUInt64(f.i, null(), 0, null(), 0), OK);
        let mut s: fmi3String = null();
        assert_eq!(fmi3GetString(f.i, null(), 0, null_mut(), 0), OK);
        assert_eq!(fmi3GetString(f.i, &1, 1, &mut s, 1), ERROR);
        assert_eq!(fmi3SetString(f.i, &1, 1, &s, 1), ERROR);
        let mut size = 0usize;
        let mut bin: fmi3Binary = null();
        assert_eq!(fmi3GetBinary(f.i, &1, 1, &mut size, &mut bin, 1), ERROR);
        assert_eq!(fmi3SetBinary(f.i, null(), 0, null(), null(), 0), OK);
        let mut clock = false;
        assert_eq!(fmi3GetClock(f.i, &1, 1, &mut clock), ERROR);
        assert_eq!(fmi3SetClock(f.i, null(), 0, null()), OK);

        // Booleans: outputs are not settable; a NULL value array is refused.
        assert_eq!(fmi3SetBoolean(f.i, &(vr::DRIVER_SATURATED as u32), 1, &true, 1), ERROR);
        assert_eq!(fmi3GetBoolean(f.i, &(vr::DRIVER_SATURATED as u32), 1, null_mut(), 1), ERROR);
        // Cross-version use of an instance is refused.
        let mut r = 0.0;
        assert_eq!(fmi2GetReal(f.i, &1, 1, &mut r), ERROR);
        assert!(f.log.has(&["other FMI version"]));
        fmi2FreeInstance(f.i); // refused, the instance stays alive
        assert_eq!(f.get(vr::I_REF).0, OK);
    }
}

#[test]
fn fmi3_fmu_state_round_trip_and_corruption() {
    let f = Fmu3::initialized("state3", None);
    let h = 1e-4;
    assert_eq!(f.set(vr::I_REF, 0.006), OK);
    for k in 0..3 {
        assert_eq!(f.step(k as f64 * h, h).0, OK);
    }
    unsafe {
        let mut s: fmi3FMUState = null_mut();
        assert_eq!(fmi3GetFMUState(f.i, &mut s), OK);
        let mut size = 0;
        assert_eq!(fmi3SerializedFMUStateSize(f.i, s, &mut size), OK);
        let mut bytes = vec![0u8; size];
        assert_eq!(fmi3SerializeFMUState(f.i, s, bytes.as_mut_ptr(), size), OK);
        assert_eq!(fmi3FreeFMUState(f.i, &mut s), OK);
        assert!(s.is_null());

        assert_eq!(f.set(vr::I_REF, -0.002), OK);
        for k in 3..6 {
            assert_eq!(f.step(k as f64 * h, h).0, OK);
        }
        let reference = f.outputs();

        let mut s2: fmi3FMUState = null_mut();
        assert_eq!(
            fmi3DeserializeFMUState(f.i, bytes.as_ptr(), size, &mut s2),
            OK,
            "{}",
            f.log.dump()
        );
        assert_eq!(fmi3SetFMUState(f.i, s2), OK);
        assert!((f.get(vr::TIME).1 - 3.0 * h).abs() < 1e-15);
        assert_eq!(f.get(vr::I_REF).1, 0.006);
        assert_eq!(f.set(vr::I_REF, -0.002), OK);
        for k in 3..6 {
            assert_eq!(f.step(k as f64 * h, h).0, OK);
        }
        assert_eq!(f.outputs(), reference);
        assert_eq!(fmi3FreeFMUState(f.i, &mut s2), OK);

        let mut bad = bytes.clone();
        let n = bad.len();
        bad[n - 1] ^= 1;
        assert_eq!(fmi3DeserializeFMUState(f.i, bad.as_ptr(), n, &mut s2), ERROR);
        assert!(f.log.has(&["fmi3DeserializeFMUState", "cannot deserialize"]), "{}", f.log.dump());
        assert_eq!(fmi3DeserializeFMUState(f.i, b"garbage".as_ptr(), 7, &mut s2), ERROR);
        assert_eq!(fmi3DeserializeFMUState(f.i, bytes.as_ptr(), size, null_mut()), ERROR);
        assert!(s2.is_null());
        assert_eq!(fmi3SetFMUState(f.i, null_mut()), ERROR);
    }
}

#[test]
fn fmi3_unsupported_functions_log_and_fail() {
    let f = Fmu3::initialized("unsup3", None);
    unsafe {
        let mut n = 0usize;
        let mut x = 0.0;
        let mut b = false;
        let cases: Vec<(&str, Status)> = vec![
            ("fmi3EnterEventMode", fmi3EnterEventMode(f.i)),
            ("fmi3EnterStepMode", fmi3EnterStepMode(f.i)),
            ("fmi3SetTime", fmi3SetTime(f.i, 1.0)),
            ("fmi3GetNumberOfContinuousStates", fmi3GetNumberOfContinuousStates(f.i, &mut n)),
            ("fmi3GetNumberOfEventIndicators", fmi3GetNumberOfEventIndicators(f.i, &mut n)),
            (
                "fmi3GetNumberOfVariableDependencies",
                fmi3GetNumberOfVariableDependencies(f.i, 3, &mut n),
            ),
            (
                "fmi3GetDirectionalDerivative",
                fmi3GetDirectionalDerivative(f.i, &3, 1, &1, 1, &1.0, 1, &mut x, 1),
            ),
            (
                "fmi3GetAdjointDerivative",
                fmi3GetAdjointDerivative(f.i, &3, 1, &1, 1, &1.0, 1, &mut x, 1),
            ),
            ("fmi3EnterConfigurationMode", fmi3EnterConfigurationMode(f.i)),
            ("fmi3ExitConfigurationMode", fmi3ExitConfigurationMode(f.i)),
            ("fmi3GetIntervalDecimal", fmi3GetIntervalDecimal(f.i, &1, 1, &mut x, &mut 0)),
            ("fmi3SetShiftFraction", fmi3SetShiftFraction(f.i, &1, 1, &1, &1)),
            ("fmi3EvaluateDiscreteStates", fmi3EvaluateDiscreteStates(f.i)),
            (
                "fmi3UpdateDiscreteStates",
                fmi3UpdateDiscreteStates(f.i, &mut b, &mut b, &mut b, &mut b, &mut b, &mut x),
            ),
            (
                "fmi3CompletedIntegratorStep",
                fmi3CompletedIntegratorStep(f.i, false, &mut b, &mut b),
            ),
            ("fmi3GetContinuousStates", fmi3GetContinuousStates(f.i, &mut x, 1)),
            ("fmi3ActivateModelPartition", fmi3ActivateModelPartition(f.i, 0, 0.0)),
        ];
        for (name, status) in cases {
            assert_eq!(status, ERROR, "{name}");
            assert!(
                f.log.has(&[&format!("{name} is not supported by EhsvActuator")]),
                "{name}:\n{}",
                f.log.dump()
            );
        }
        // NULL instance: Error without logging.
        assert_eq!(fmi3EnterEventMode(null_mut()), ERROR);
        assert_eq!(fmi3GetFloat64(null_mut(), null(), 0, null_mut(), 0), ERROR);
        fmi3FreeInstance(null_mut());
    }
    // Still usable.
    assert_eq!(f.step(0.0, 1e-4).0, OK);
}

#[test]
fn fmi3_debug_logging_and_two_instances() {
    let a = Fmu3::initialized("a3", None);
    let b = Fmu3::initialized("b3", None);
    let cat = CString::new("logAll").unwrap();
    let bad = CString::new("logNothing").unwrap();
    unsafe {
        assert_eq!(fmi3SetDebugLogging(a.i, true, 1, &cat.as_ptr()), OK);
        assert_eq!(fmi3SetDebugLogging(b.i, true, 1, &bad.as_ptr()), ERROR);
    }
    assert!(b.log.has(&["unknown log category 'logNothing'"]));
    a.log.clear();
    b.log.clear();
    assert_eq!(a.step(0.0, 1e-4).0, OK);
    assert_eq!(b.step(0.0, 1e-4).0, OK);
    assert!(a.log.has(&["fmi3DoStep"]), "{}", a.log.dump());
    assert!(b.log.lines().is_empty(), "{}", b.log.dump());
    assert_eq!(a.set(vr::I_REF, 0.003), OK);
    assert_eq!(b.get(vr::I_REF).1, 0.0);
}

#[test]
fn step_loop_does_not_allocate() {
    let f2 = Fmu2::initialized("rt2");
    let f3 = Fmu3::initialized("rt3", Some(1.0));
    let inputs = [vr::I_REF as u32, vr::V_SUPPLY as u32];
    let outputs = [vr::I_COIL as u32, vr::U_DRIVER as u32, vr::X_SPOOL as u32, vr::Q_VALVE as u32];
    let mut out = [0.0; 4];
    let (mut sat2, mut sat3) = (0, false);
    let (mut ev, mut term, mut early, mut last) = (false, false, false, 0.0);
    let h = 1e-4;
    let probe = allocations();
    drop(std::hint::black_box(vec![1u8; 16]));
    assert!(allocations() > probe, "the counter counts");
    let before = allocations();
    unsafe {
        for k in 0..200 {
            let t = k as f64 * h;
            // +-10 mA, the valve's rating: the rail is reached and left, no warning.
            let u = [if k % 50 < 25 { 0.01 } else { -0.01 }, 72.0];
            assert_eq!(fmi2SetReal(f2.c, inputs.as_ptr(), 2, u.as_ptr()), OK);
            assert_eq!(fmi2DoStep(f2.c, t, h, fmi2True), OK);
            assert_eq!(fmi2GetReal(f2.c, outputs.as_ptr(), 4, out.as_mut_ptr()), OK);
            assert_eq!(fmi2GetBoolean(f2.c, &(vr::DRIVER_SATURATED as u32), 1, &mut sat2), OK);
            assert_eq!(fmi3SetFloat64(f3.i, inputs.as_ptr(), 2, u.as_ptr(), 2), OK);
            assert_eq!(fmi3DoStep(f3.i, t, h, true, &mut ev, &mut term, &mut early, &mut last), OK);
            assert_eq!(fmi3GetFloat64(f3.i, outputs.as_ptr(), 4, out.as_mut_ptr(), 4), OK);
            assert_eq!(fmi3GetBoolean(f3.i, &(vr::DRIVER_SATURATED as u32), 1, &mut sat3, 1), OK);
        }
    }
    assert_eq!(allocations() - before, 0, "the step loop allocated");
}

// ---------------------------------------------------------------- FMU states and FreeInstance

/// FreeInstance frees every FMU state the instance made and the importer did not free
/// (FMI 2.0.4 2.1.8, FMI 3.0 fmi3FreeInstance): 3000 instances, each left holding one
/// state, give back every byte; a state freed explicitly before is not freed twice.
#[test]
fn free_instance_frees_the_fmu_states_it_holds() {
    let per_instance = |version: &str, keep_one_freed: bool| {
        let before = live_bytes();
        for k in 0..3000 {
            if version == "FMI 2" {
                let f = Fmu2::initialized("leak2");
                let (mut s, mut freed) = (null_mut(), null_mut());
                unsafe {
                    assert_eq!(fmi2GetFMUstate(f.c, &mut s), OK);
                    if keep_one_freed {
                        assert_eq!(fmi2GetFMUstate(f.c, &mut freed), OK);
                        assert_eq!(fmi2FreeFMUstate(f.c, &mut freed), OK);
                    }
                }
                assert!(!s.is_null(), "instance {k}");
            } else {
                let f = Fmu3::initialized("leak3", None);
                let (mut s, mut freed) = (null_mut(), null_mut());
                unsafe {
                    assert_eq!(fmi3GetFMUState(f.i, &mut s), OK);
                    if keep_one_freed {
                        assert_eq!(fmi3GetFMUState(f.i, &mut freed), OK);
                        assert_eq!(fmi3FreeFMUState(f.i, &mut freed), OK);
                    }
                }
                assert!(!s.is_null(), "instance {k}");
            } // Drop: FreeInstance with the state still held.
        }
        let grown = live_bytes() - before;
        println!(
            "{version}: 3000 instances each freed holding one FMU state{}: heap grew by {grown} bytes",
            if keep_one_freed { " (and one freed before)" } else { "" }
        );
        grown
    };
    for version in ["FMI 2", "FMI 3"] {
        for keep_one_freed in [false, true] {
            assert_eq!(per_instance(version, keep_one_freed), 0, "{version}: states leaked");
        }
    }
}

// ---------------------------------------------------------------- communication-point tolerance

/// The FMU accepts a communication point 4 ulps of t (rounding of the importer's t + h)
/// plus a millionth of the step away from its own time, never more: at t = 1e6 s a point
/// 0.9 ms behind (which the old |t|-relative tolerance of 1 ms accepted, letting time run
/// backwards) is refused, and so is twice the tolerance (2 us at an epoch start of 1.7e9 s,
/// where the old tolerance was 1.7 s).
#[test]
fn communication_point_tolerance_is_tied_to_the_step_and_ulps_of_t() {
    for start in [0.0, 1e6, 1.7e9] {
        for version in [2, 3] {
            let h = 1e-3;
            let (status, time, log) = run_from(version, start, &mut |step| {
                // Correct callers: accumulated t += h, then t0 + k h from there (a few
                // ulps away from the FMU's own current + step).
                let mut t = start;
                for k in 0..200 {
                    assert_eq!(step(t, h), OK, "t += h at step {k} from {start}");
                    t += h;
                }
                let t0 = t;
                for k in 0..200 {
                    let t = t0 + k as f64 * h;
                    assert_eq!(step(t, h), OK, "t0 + k h at step {k} from {t0}");
                }
                let now = t0 + 200.0 * h;
                // Behind or ahead by 0.9 ms, or by twice the tolerance: refused.
                let twice = 8.0 * ulp(now) + 2e-6 * h;
                for offset in [-0.9e-3, 0.9e-3, -twice, twice] {
                    assert_eq!(step(now + offset, h), ERROR, "{offset} s off at t = {now}");
                }
                step(now, h)
            });
            assert_eq!(status, OK, "FMI {version} from {start}: {log}");
            let expected = time_after(start, h);
            assert!(
                (time - expected).abs() <= 4.0 * ulp(expected),
                "FMI {version} from {start}: time {time}, expected {expected}"
            );
            assert!(log.contains("currentCommunicationPoint"), "{log}");
        }
    }
}

/// The FMU time after the run above: 200 accumulated steps, 200 from that origin, one more.
fn time_after(start: f64, h: f64) -> f64 {
    let t0 = (0..200).fold(start, |t, _| t + h);
    t0 + 200.0 * h + h
}

fn ulp(x: f64) -> f64 {
    f64::from_bits(x.abs().to_bits() + 1) - x.abs()
}

type Stepper<'a> = dyn FnMut(f64, f64) -> Status + 'a;

/// Initialises an instance of FMI `version` at `start`, runs `steps` with a doStep
/// closure that also checks time never runs backwards; returns its status, the final
/// FMU time and the log.
fn run_from(
    version: u32,
    start: f64,
    steps: &mut dyn FnMut(&mut Stepper) -> Status,
) -> (Status, f64, String) {
    if version == 2 {
        let f = Fmu2::new("tolerance2");
        unsafe {
            assert_eq!(fmi2SetupExperiment(f.c, 0, 0.0, start, 0, 0.0), OK);
            assert_eq!(fmi2EnterInitializationMode(f.c), OK);
            assert_eq!(fmi2ExitInitializationMode(f.c), OK);
        }
        let mut last = f.time();
        let status = steps(&mut |t, h| {
            let s = f.step(t, h);
            assert!(f.time() >= last, "time ran backwards: {} after {last}", f.time());
            last = f.time();
            s
        });
        (status, f.time(), f.log.dump())
    } else {
        let f = Fmu3::new("tolerance3");
        unsafe {
            assert_eq!(fmi3EnterInitializationMode(f.i, false, 0.0, start, false, 0.0), OK);
            assert_eq!(fmi3ExitInitializationMode(f.i), OK);
        }
        let mut last = f.get(vr::TIME).1;
        let status = steps(&mut |t, h| {
            let (s, _, time) = f.step(t, h);
            assert!(time >= last, "time ran backwards: {time} after {last}");
            last = time;
            s
        });
        (status, f.get(vr::TIME).1, f.log.dump())
    }
}
