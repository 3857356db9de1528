//! The plugin's view of MuJoCo's ABI (`src/ffi.rs`) against the pinned wheel's headers: a C
//! program compiled against `include/mujoco/` prints each offset and size the plugin
//! uses. The headers come from the mujoco package of the repository's `.venv`
//! (scripts/setup-venv.sh), or the directory in `MUJOCO_INCLUDE`.

use std::path::{Path, PathBuf};
use std::process::Command;

use ehsv_mujoco::ffi::{offsets, MUJOCO_VERSION};

fn include_dir() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("MUJOCO_INCLUDE") {
        return Some(PathBuf::from(dir));
    }
    let python = Path::new(env!("CARGO_MANIFEST_DIR")).join("../.venv/bin/python");
    let out = Command::new(python)
        .args(["-c", "import mujoco, os; print(os.path.dirname(mujoco.__file__))"])
        .output()
        .ok()?;
    let dir = PathBuf::from(String::from_utf8(out.stdout).ok()?.trim()).join("include");
    dir.join("mujoco/mjplugin.h").exists().then_some(dir)
}

#[test]
fn offsets_and_plugin_struct_match_the_wheels_headers() {
    let Some(include) = include_dir() else {
        panic!("no MuJoCo headers: run scripts/setup-venv.sh or set MUJOCO_INCLUDE");
    };
    let mut checks: Vec<(String, usize)> =
        offsets::ALL.iter().map(|(expr, off)| (expr.to_string(), *off)).collect();
    for (field, off) in [
        ("nattribute", 8),
        ("attributes", 16),
        ("capabilityflags", 24),
        ("needstage", 28),
        ("nstate", 32),
        ("nsensordata", 40),
        ("init", 48),
        ("destroy", 56),
        ("copy", 64),
        ("reset", 72),
        ("compute", 80),
        ("advance", 88),
        ("visualize", 96),
        ("actuator_act_dot", 104),
        ("sdf_aabb", 144),
    ] {
        checks.push((format!("offsetof(mjpPlugin, {field})"), off));
    }
    checks.push(("sizeof(mjpPlugin)".into(), std::mem::size_of::<ehsv_mujoco::ffi::MjpPlugin>()));
    checks.push(("sizeof(mjtNum)".into(), 8));
    checks.push(("sizeof(mjtSize)".into(), 8));
    checks.push(("mjPLUGIN_ACTUATOR".into(), ehsv_mujoco::ffi::PLUGIN_ACTUATOR as usize));
    checks.push(("mjPLUGIN_SENSOR".into(), ehsv_mujoco::ffi::PLUGIN_SENSOR as usize));
    checks.push(("mjSENS_PLUGIN".into(), ehsv_mujoco::ffi::SENS_PLUGIN as usize));
    checks.push(("mjSTAGE_POS".into(), ehsv_mujoco::ffi::STAGE_POS as usize));
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let mut program = String::from(
        "#include <stdio.h>\n#include <stddef.h>\n#include <string.h>\n#include <mujoco/mujoco.h>\n\
         int main(void) {\n  printf(\"%s\\n\", mjVERSION_HEADER == 4000000 ? \"4.0.0\" : \"other\");\n",
    );
    for (expr, _) in &checks {
        program.push_str(&format!("  printf(\"%zu\\n\", (size_t)({expr}));\n"));
    }
    program.push_str("  return 0;\n}\n");
    let source = dir.join("abi.c");
    std::fs::write(&source, program).unwrap();
    let exe = dir.join("abi");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let status = Command::new(cc)
        .arg(format!("-I{}", include.display()))
        .arg(&source)
        .arg("-o")
        .arg(&exe)
        .status()
        .expect("a C compiler (cc)");
    assert!(status.success(), "compiling {}", source.display());
    let out = String::from_utf8(Command::new(&exe).output().unwrap().stdout).unwrap();
    let mut lines = out.lines();
    assert_eq!(lines.next(), Some(MUJOCO_VERSION), "header version");
    for ((expr, expected), line) in checks.iter().zip(lines) {
        assert_eq!(line.parse::<usize>().unwrap(), *expected, "{expr}");
    }
}
