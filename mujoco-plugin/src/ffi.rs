//! The few parts of MuJoCo 4.0.0's C ABI the plugin uses: the `mjpPlugin` struct
//! (`include/mujoco/mjplugin.h`), byte offsets of the `mjModel` and `mjData` fields it
//! reads and writes, and four functions of libmujoco, resolved when the library is loaded
//! (from the libmujoco already in the process). The offsets are checked against the
//! pinned wheel's headers by `tests/abi.rs` (a C program compiled against them).

use std::ffi::{c_char, c_int, c_void, CStr};
use std::sync::OnceLock;

/// The MuJoCo version whose ABI this file describes.
pub const MUJOCO_VERSION: &str = "4.0.0";
/// `mjPLUGIN_ACTUATOR`.
pub const PLUGIN_ACTUATOR: c_int = 1;
/// `mjPLUGIN_SENSOR`.
pub const PLUGIN_SENSOR: c_int = 2;
/// `mjSENS_PLUGIN` (mjtSensor): a sensor computed by a plugin.
pub const SENS_PLUGIN: c_int = 47;
/// `mjSTAGE_POS` (mjtStage).
pub const STAGE_POS: c_int = 1;

/// Opaque `mjModel` / `mjData`.
#[repr(C)]
pub struct MjModel {
    _private: [u8; 0],
}
#[repr(C)]
pub struct MjData {
    _private: [u8; 0],
}

type Callback = Option<unsafe extern "C" fn()>;

/// `mjpPlugin` of mjplugin.h, field for field.
#[repr(C)]
pub struct MjpPlugin {
    pub name: *const c_char,
    pub nattribute: c_int,
    pub attributes: *const *const c_char,
    pub capabilityflags: c_int,
    pub needstage: c_int,
    pub nstate: Option<unsafe extern "C" fn(*const MjModel, c_int) -> c_int>,
    pub nsensordata: Option<unsafe extern "C" fn(*const MjModel, c_int, c_int) -> c_int>,
    pub init: Option<unsafe extern "C" fn(*const MjModel, *mut MjData, c_int) -> c_int>,
    pub destroy: Option<unsafe extern "C" fn(*mut MjData, c_int)>,
    pub copy: Option<unsafe extern "C" fn(*mut MjData, *const MjModel, *const MjData, c_int)>,
    pub reset: Option<unsafe extern "C" fn(*const MjModel, *mut f64, *mut c_void, c_int)>,
    pub compute: Option<unsafe extern "C" fn(*const MjModel, *mut MjData, c_int, c_int)>,
    pub advance: Option<unsafe extern "C" fn(*const MjModel, *mut MjData, c_int)>,
    pub visualize: Callback,
    pub actuator_act_dot: Option<unsafe extern "C" fn(*const MjModel, *mut MjData, c_int)>,
    pub sdf_distance: Callback,
    pub sdf_gradient: Callback,
    pub sdf_staticdistance: Callback,
    pub sdf_attribute: Callback,
    pub sdf_aabb: Callback,
}

// The layout of mjplugin.h on LP64 (tests/abi.rs checks it against the header).
const _: () = {
    use std::mem::{offset_of, size_of};
    assert!(offset_of!(MjpPlugin, nattribute) == 8);
    assert!(offset_of!(MjpPlugin, attributes) == 16);
    assert!(offset_of!(MjpPlugin, capabilityflags) == 24);
    assert!(offset_of!(MjpPlugin, needstage) == 28);
    assert!(offset_of!(MjpPlugin, nstate) == 32);
    assert!(offset_of!(MjpPlugin, init) == 48);
    assert!(offset_of!(MjpPlugin, reset) == 72);
    assert!(offset_of!(MjpPlugin, compute) == 80);
    assert!(offset_of!(MjpPlugin, advance) == 88);
    assert!(offset_of!(MjpPlugin, actuator_act_dot) == 104);
    assert!(size_of::<MjpPlugin>() == 152);
};

/// Byte offsets of the fields used, in MuJoCo 4.0.0 (x86_64 / aarch64 Linux, LP64).
pub mod offsets {
    pub const MODEL_NACTUATOR: usize = 24; // mjtSize
    pub const MODEL_NSENSOR: usize = 496; // mjtSize
    pub const MODEL_TIMESTEP: usize = 792; // opt.timestep, mjtNum
    pub const MODEL_ACTUATOR_CTRLADR: usize = 4800; // int*
    pub const MODEL_ACTUATOR_OUTADR: usize = 4824; // int*
    pub const MODEL_ACTUATOR_PLUGIN: usize = 4984; // int*
    pub const MODEL_SENSOR_TYPE: usize = 5056; // int*
    pub const MODEL_SENSOR_DIM: usize = 5120; // int*
    pub const MODEL_SENSOR_ADR: usize = 5128; // int*
    pub const MODEL_SENSOR_PLUGIN: usize = 5192; // int*
    pub const MODEL_PLUGIN_STATEADR: usize = 5208; // int*
    pub const MODEL_PLUGIN_STATENUM: usize = 5216; // int*
    pub const DATA_TIME: usize = 160648; // mjtNum
    pub const DATA_PLUGIN_STATE: usize = 160736; // mjtNum*
    pub const DATA_CTRL: usize = 160744; // mjtNum*
    pub const DATA_SENSORDATA: usize = 160816; // mjtNum*
    pub const DATA_PLUGIN_DATA: usize = 160840; // uintptr_t*
    pub const DATA_ACTUATOR_LENGTH: usize = 161152; // mjtNum*
    pub const DATA_ACTUATOR_VELOCITY: usize = 161288; // mjtNum*
    pub const DATA_ACTUATOR_FORCE: usize = 161416; // mjtNum*
    /// Every (C expression, offset) above, for the ABI test.
    pub const ALL: [(&str, usize); 20] = [
        ("offsetof(mjModel, nactuator)", MODEL_NACTUATOR),
        ("offsetof(mjModel, nsensor)", MODEL_NSENSOR),
        ("offsetof(mjModel, opt.timestep)", MODEL_TIMESTEP),
        ("offsetof(mjModel, actuator_ctrladr)", MODEL_ACTUATOR_CTRLADR),
        ("offsetof(mjModel, actuator_outadr)", MODEL_ACTUATOR_OUTADR),
        ("offsetof(mjModel, actuator_plugin)", MODEL_ACTUATOR_PLUGIN),
        ("offsetof(mjModel, sensor_type)", MODEL_SENSOR_TYPE),
        ("offsetof(mjModel, sensor_dim)", MODEL_SENSOR_DIM),
        ("offsetof(mjModel, sensor_adr)", MODEL_SENSOR_ADR),
        ("offsetof(mjModel, sensor_plugin)", MODEL_SENSOR_PLUGIN),
        ("offsetof(mjModel, plugin_stateadr)", MODEL_PLUGIN_STATEADR),
        ("offsetof(mjModel, plugin_statenum)", MODEL_PLUGIN_STATENUM),
        ("offsetof(mjData, time)", DATA_TIME),
        ("offsetof(mjData, plugin_state)", DATA_PLUGIN_STATE),
        ("offsetof(mjData, ctrl)", DATA_CTRL),
        ("offsetof(mjData, sensordata)", DATA_SENSORDATA),
        ("offsetof(mjData, plugin_data)", DATA_PLUGIN_DATA),
        ("offsetof(mjData, actuator_length)", DATA_ACTUATOR_LENGTH),
        ("offsetof(mjData, actuator_velocity)", DATA_ACTUATOR_VELOCITY),
        ("offsetof(mjData, actuator_force)", DATA_ACTUATOR_FORCE),
    ];
}

/// Reads a field of type `T` at `offset` bytes into `base`.
///
/// # Safety
/// `base` must point to a live mjModel/mjData of MuJoCo 4.0.0 and `offset` be one of
/// [`offsets`] with its type.
pub unsafe fn field<T: Copy>(base: *const c_void, offset: usize) -> T {
    base.cast::<u8>().add(offset).cast::<T>().read_unaligned()
}

/// Element `i` of the array that the pointer field at `offset` points to.
///
/// # Safety
/// As [`field`], and `i` within the array.
pub unsafe fn element<T: Copy>(base: *const c_void, offset: usize, i: usize) -> T {
    field::<*const T>(base, offset).add(i).read()
}

type RegisterPlugin = unsafe extern "C" fn(*const MjpPlugin) -> c_int;
type GetPluginConfig = unsafe extern "C" fn(*const MjModel, c_int, *const c_char) -> *const c_char;
type Warning = unsafe extern "C" fn(*const c_char, ...);
type VersionString = unsafe extern "C" fn() -> *const c_char;

/// The libmujoco functions the plugin calls (mjp_registerPlugin, mj_getPluginConfig,
/// mju_warning, mj_versionString).
pub struct Api {
    pub register_plugin: RegisterPlugin,
    pub get_plugin_config: GetPluginConfig,
    pub warning: Warning,
    pub version_string: VersionString,
}

const RTLD_LAZY: c_int = 0x1;
const RTLD_NOLOAD: c_int = 0x4;

extern "C" {
    fn dlopen(filename: *const c_char, flags: c_int) -> *mut c_void;
    fn dlsym(handle: *mut c_void, symbol: *const c_char) -> *mut c_void;
}

static API: OnceLock<Option<Api>> = OnceLock::new();

/// libmujoco's functions, from the copy already loaded in the process (by its soname;
/// else from the global scope); `None` if there is none.
pub fn api() -> Option<&'static Api> {
    API.get_or_init(|| {
        // SAFETY: dlopen with RTLD_NOLOAD only finds an already loaded library; dlsym
        // returns the symbols' addresses, whose C types are those of mujoco.h.
        unsafe {
            let soname = c"libmujoco.so.4.0.0";
            let mut handle = dlopen(soname.as_ptr(), RTLD_LAZY | RTLD_NOLOAD);
            if handle.is_null() {
                handle = std::ptr::null_mut(); // RTLD_DEFAULT
            }
            let symbol = |name: &CStr| {
                let p = dlsym(handle, name.as_ptr());
                (!p.is_null()).then_some(p)
            };
            Some(Api {
                register_plugin: std::mem::transmute::<*mut c_void, RegisterPlugin>(symbol(
                    c"mjp_registerPlugin",
                )?),
                get_plugin_config: std::mem::transmute::<*mut c_void, GetPluginConfig>(symbol(
                    c"mj_getPluginConfig",
                )?),
                warning: std::mem::transmute::<*mut c_void, Warning>(symbol(c"mju_warning")?),
                version_string: std::mem::transmute::<*mut c_void, VersionString>(symbol(
                    c"mj_versionString",
                )?),
            })
        }
    })
    .as_ref()
}
