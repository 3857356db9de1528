//! EhsvActuator as a MuJoCo engine plugin: `ehsv.actuator`, with the actuator and sensor
//! capabilities.
//! `mujoco.mj_loadPluginLibrary("target/release/libehsv_mujoco.so")` registers it (a
//! constructor in `.init_array` calls libmujoco's `mjp_registerPlugin`). Each plugin
//! actuator of an MJCF is one EhsvActuator with the motion port; see docs/mujoco.md.
//!
//! * [`config`]: config keys (the FMU's variable names), defaults, refusals.
//! * [`actuator`]: one actuator, its state in mjData's `plugin_state`, sub-stepping.
//! * [`sensor`]: the sensors on an instance, its outputs copied from `plugin_state`.
//! * [`ffi`]: the part of MuJoCo 4.0.0's ABI used (checked against the wheel's headers).
//!
//! Every callback catches panics: nothing unwinds into MuJoCo.

pub mod actuator;
pub mod config;
pub mod ffi;
pub mod sensor;

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use actuator::{Actuator, HostStep};
use ffi::{element, field, offsets as o, MjData, MjModel, MjpPlugin};

/// The plugin's name in MJCF (`<plugin plugin="ehsv.actuator">`).
pub const PLUGIN_NAME: &CStr = c"ehsv.actuator";

/// What plugin_data holds for one instance.
struct Instance {
    actuator: Actuator,
    ctrladr: usize,
    outadr: usize,
    /// Its plugin sensors' places in sensordata ([`sensor::of_instance`]).
    sensors: Vec<(usize, usize)>,
    /// A refused step has been reported (once per instance).
    warned: bool,
}

/// Reports `message` through mju_warning (the host's warning handler).
fn warn(message: &str) {
    if let Some(api) = ffi::api() {
        let text = CString::new(format!("ehsv.actuator: {message}").replace('\0', " "))
            .unwrap_or_default();
        // SAFETY: mju_warning is printf-like; "%s" with a NUL-terminated string.
        unsafe { (api.warning)(c"%s".as_ptr(), text.as_ptr()) };
    }
}

/// Runs `f`, turning a panic into `fallback` and a warning.
fn guard<T>(fallback: T, f: impl FnOnce() -> T) -> T {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|_| {
        warn("internal error (panic caught)");
        fallback
    })
}

/// The instance's configuration, from the compiled model.
///
/// # Safety
/// `m` is a live mjModel holding plugin instance `instance`.
unsafe fn read_config(m: *const MjModel, instance: c_int) -> Result<config::Config, String> {
    let api = ffi::api().ok_or("libmujoco's functions not found")?;
    config::parse(|key| {
        let key = CString::new(key).ok()?;
        let value = (api.get_plugin_config)(m, instance, key.as_ptr());
        (!value.is_null()).then(|| CStr::from_ptr(value).to_string_lossy().into_owned())
    })
}

/// The slots of instance `instance` in `d`'s plugin_state.
///
/// # Safety
/// `m`, `d` live, `instance` one of `m`'s plugin instances.
unsafe fn slots<'a>(m: *const MjModel, d: *mut MjData, instance: c_int) -> &'a mut [f64] {
    let i = instance as usize;
    let adr: c_int = element(m.cast(), o::MODEL_PLUGIN_STATEADR, i);
    let num: c_int = element(m.cast(), o::MODEL_PLUGIN_STATENUM, i);
    let state: *mut f64 = field(d.cast(), o::DATA_PLUGIN_STATE);
    std::slice::from_raw_parts_mut(state.add(adr as usize), num as usize)
}

/// The instance's object in `d`'s plugin_data (null before init or after destroy).
///
/// # Safety
/// As [`slots`].
unsafe fn instance_ptr(d: *mut MjData, instance: c_int) -> *mut *mut Instance {
    let data: *mut usize = field(d.cast(), o::DATA_PLUGIN_DATA);
    data.add(instance as usize).cast()
}

unsafe extern "C" fn nstate(m: *const MjModel, instance: c_int) -> c_int {
    guard(0, || match read_config(m, instance).and_then(Actuator::new) {
        Ok(actuator) => actuator.layout.slots() as c_int,
        // init refuses the configuration, naming the key
        Err(_) => 0,
    })
}

/// Builds the instance's actuator; refuses (-1, the reason in a warning) a bad
/// configuration or an instance that is not exactly one actuator.
unsafe fn build(m: *const MjModel, d: *mut MjData, instance: c_int) -> Result<(), String> {
    let nactuator: i64 = field(m.cast(), o::MODEL_NACTUATOR);
    let mine: Vec<usize> = (0..nactuator as usize)
        .filter(|&a| element::<c_int>(m.cast(), o::MODEL_ACTUATOR_PLUGIN, a) == instance)
        .collect();
    let [id] = mine[..] else {
        return Err(format!("plugin instance {instance} drives {} actuators, not one", mine.len()));
    };
    let actuator =
        Actuator::new(read_config(m, instance)?).map_err(|e| format!("actuator {id}: {e}"))?;
    let num = slots(m, d, instance).len();
    if num != actuator.layout.slots() {
        return Err(format!(
            "actuator {id}: {num} state slots, {} needed",
            actuator.layout.slots()
        ));
    }
    let ctrladr = element::<c_int>(m.cast(), o::MODEL_ACTUATOR_CTRLADR, id) as usize;
    let outadr = element::<c_int>(m.cast(), o::MODEL_ACTUATOR_OUTADR, id) as usize;
    let sensors = sensor::of_instance(m, instance);
    let boxed = Box::new(Instance { actuator, ctrladr, outadr, sensors, warned: false });
    *instance_ptr(d, instance) = Box::into_raw(boxed);
    Ok(())
}

unsafe extern "C" fn init(m: *const MjModel, d: *mut MjData, instance: c_int) -> c_int {
    guard(-1, || match build(m, d, instance) {
        Ok(()) => 0,
        Err(e) => {
            warn(&e);
            -1
        }
    })
}

unsafe extern "C" fn destroy(d: *mut MjData, instance: c_int) {
    guard((), || {
        let p = instance_ptr(d, instance);
        if !(*p).is_null() {
            drop(Box::from_raw(*p));
            *p = std::ptr::null_mut();
        }
    })
}

unsafe extern "C" fn reset(m: *const MjModel, state: *mut f64, data: *mut c_void, instance: c_int) {
    guard((), || {
        let instance_data = data.cast::<Instance>();
        if let Some(inst) = instance_data.as_mut() {
            let num: c_int = element(m.cast(), o::MODEL_PLUGIN_STATENUM, instance as usize);
            inst.actuator.reset(std::slice::from_raw_parts_mut(state, num as usize));
        }
    })
}

/// MuJoCo's `compute`, called once per capability: the actuator's force, or its sensors.
unsafe extern "C" fn compute(m: *const MjModel, d: *mut MjData, instance: c_int, bit: c_int) {
    guard((), || {
        let Some(inst) = (*instance_ptr(d, instance)).as_mut() else { return };
        if bit & ffi::PLUGIN_SENSOR != 0 {
            let outputs = &slots(m, d, instance)[..inst.actuator.layout.outputs];
            sensor::write(d, &inst.sensors, outputs);
        }
        if bit & ffi::PLUGIN_ACTUATOR == 0 {
            return;
        }
        let host = HostStep {
            time: field(d.cast(), o::DATA_TIME),
            timestep: field(m.cast(), o::MODEL_TIMESTEP),
            length: element(d.cast(), o::DATA_ACTUATOR_LENGTH, inst.outadr),
            velocity: element(d.cast(), o::DATA_ACTUATOR_VELOCITY, inst.outadr),
            ctrl: element(d.cast(), o::DATA_CTRL, inst.ctrladr),
        };
        let force = match inst.actuator.compute(slots(m, d, instance), &host) {
            Ok(force) => force,
            Err(e) => {
                if !std::mem::replace(&mut inst.warned, true) {
                    let t = ehsv_physics::readable(host.time);
                    warn(&format!("step at t = {t} refused, force 0: {e}"));
                }
                0.0
            }
        };
        let out: *mut f64 = field(d.cast(), o::DATA_ACTUATOR_FORCE);
        *out.add(inst.outadr) = force;
    })
}

unsafe extern "C" fn advance(m: *const MjModel, d: *mut MjData, instance: c_int) {
    guard((), || {
        if let Some(inst) = (*instance_ptr(d, instance)).as_mut() {
            inst.actuator.commit(slots(m, d, instance));
        }
    })
}

/// Registers `ehsv.actuator` with the libmujoco in this process (4.0.0 only: the ABI).
fn register() {
    let Some(api) = ffi::api() else { return };
    // SAFETY: mj_versionString returns a static C string.
    let version = unsafe { CStr::from_ptr((api.version_string)()) };
    if version.to_bytes() != ffi::MUJOCO_VERSION.as_bytes() {
        eprintln!(
            "ehsv.actuator: built for MuJoCo {}, this is {}: not registered",
            ffi::MUJOCO_VERSION,
            version.to_string_lossy()
        );
        return;
    }
    let names: Vec<*const c_char> = config::keys()
        .into_iter()
        .map(|k| CString::new(k).expect("no NUL in a key").into_raw().cast_const())
        .collect();
    let names = Box::leak(names.into_boxed_slice());
    let plugin = MjpPlugin {
        name: PLUGIN_NAME.as_ptr(),
        nattribute: names.len() as c_int,
        attributes: names.as_ptr(),
        capabilityflags: ffi::PLUGIN_ACTUATOR | ffi::PLUGIN_SENSOR,
        // The sensors copy plugin_state, which no stage of a forward pass changes (only
        // advance does): the position stage fills them as early as any, in mj_step1 too.
        needstage: ffi::STAGE_POS,
        nstate: Some(nstate),
        nsensordata: Some(sensor::nsensordata),
        init: Some(init),
        destroy: Some(destroy),
        copy: None,
        reset: Some(reset),
        compute: Some(compute),
        advance: Some(advance),
        visualize: None,
        actuator_act_dot: None,
        sdf_distance: None,
        sdf_gradient: None,
        sdf_staticdistance: None,
        sdf_attribute: None,
        sdf_aabb: None,
    };
    // SAFETY: a complete mjpPlugin; MuJoCo copies it (and its strings) when registering.
    unsafe { (api.register_plugin)(&plugin) };
}

/// The library's constructor (what mjPLUGIN_LIB_INIT expands to in C with GCC/Clang): an
/// ELF `.init_array` entry; Linux only (the offsets of `ffi` are those of Linux's LP64).
#[cfg(target_os = "linux")]
#[used]
#[link_section = ".init_array"]
static REGISTER: extern "C" fn() = {
    extern "C" fn on_load() {
        let _ = catch_unwind(register);
    }
    on_load
};
