//! The platforms an archive can carry a binary for, and how each is built here.
//!
//! The host build needs only cargo. The cross routes need what scripts/setup-cross.sh
//! installs: Debian bookworm's Rust (`rustc-web`, `cargo-web`, `rust-web-src`), whose
//! sysroot carries the standard library's source so `-Zbuild-std` builds std for targets
//! rustup has none for here; the mingw-w64 linker; and zig with cargo-zigbuild (pip, in
//! the project's .venv) as the linker for Linux against glibc 2.17 and for macOS.

use std::env::consts::{ARCH, DLL_PREFIX, DLL_SUFFIX, OS};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The package and `[lib] name` of the FMU crate (fmu-src/Cargo.toml).
pub const FMU_PACKAGE: &str = "ehsv-actuator";
const FMU_LIBRARY: &str = "ehsv_actuator";

/// Debian's toolchain, called by its full path: the rustup toolchain stays first on PATH.
const DEBIAN_CARGO: &str = "/usr/bin/cargo";
const DEBIAN_RUSTC: &str = "/usr/bin/rustc";
const DEBIAN_RUSTDOC: &str = "/usr/bin/rustdoc";
const BUILD_STD: &str = "-Zbuild-std=std,panic_unwind";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Route {
    /// rustup's cargo + `cargo zigbuild` against an old glibc (its std is there).
    Zig,
    /// Debian's cargo with -Zbuild-std, linked by the mingw-w64 gcc.
    DebianMingw,
    /// Debian's cargo with -Zbuild-std through `cargo zigbuild` (zig links).
    DebianZig,
}

#[derive(Debug, PartialEq, Eq)]
pub struct Platform {
    /// FMI 3.0 platform tuple (`binaries/<fmi3>/`), also the name on the command line.
    pub fmi3: &'static str,
    /// FMI 2.0 folder; FMI 2.0 names no folder for 64-bit ARM.
    pub fmi2: Option<&'static str>,
    /// Rust target triple; cargo-zigbuild reads a `.2.17` suffix as the glibc version.
    triple: &'static str,
    route: Route,
    /// Extra environment of the build (deployment target, strip).
    env: &'static [(&'static str, &'static str)],
    library_suffix: &'static str,
}

/// rustc strips debuginfo of a release build with `rust-objcopy`, which Debian's
/// toolchain does not ship for Mach-O; the profile has no debuginfo to strip.
const NO_STRIP: (&str, &str) = ("CARGO_PROFILE_RELEASE_STRIP", "none");

pub const PLATFORMS: &[Platform] = &[
    Platform {
        fmi3: "x86_64-linux",
        fmi2: Some("linux64"),
        triple: "x86_64-unknown-linux-gnu.2.17",
        route: Route::Zig,
        env: &[],
        library_suffix: ".so",
    },
    Platform {
        fmi3: "aarch64-linux",
        fmi2: None,
        triple: "aarch64-unknown-linux-gnu.2.17",
        route: Route::DebianZig,
        env: &[],
        library_suffix: ".so",
    },
    Platform {
        fmi3: "x86_64-windows",
        fmi2: Some("win64"),
        triple: "x86_64-pc-windows-gnu",
        route: Route::DebianMingw,
        env: &[("CARGO_TARGET_X86_64_PC_WINDOWS_GNU_LINKER", "x86_64-w64-mingw32-gcc")],
        library_suffix: ".dll",
    },
    Platform {
        fmi3: "x86_64-darwin",
        fmi2: Some("darwin64"),
        triple: "x86_64-apple-darwin",
        route: Route::DebianZig,
        env: &[("MACOSX_DEPLOYMENT_TARGET", "10.12"), NO_STRIP],
        library_suffix: ".dylib",
    },
    Platform {
        fmi3: "aarch64-darwin",
        fmi2: None,
        triple: "aarch64-apple-darwin",
        route: Route::DebianZig,
        env: &[("MACOSX_DEPLOYMENT_TARGET", "11.0"), NO_STRIP],
        library_suffix: ".dylib",
    },
];

/// A platform by its FMI 3.0 name, or by its FMI 2.0 folder name.
pub fn platform(name: &str) -> Result<&'static Platform, String> {
    PLATFORMS.iter().find(|p| p.fmi3 == name || p.fmi2 == Some(name)).ok_or_else(|| {
        let names: Vec<&str> = PLATFORMS.iter().map(|p| p.fmi3).collect();
        format!("unknown platform {name:?}: one of {}", names.join(", "))
    })
}

/// The platform this program runs on, if an archive can carry it.
pub fn host() -> Result<&'static Platform, String> {
    let os = match OS {
        "macos" => "darwin",
        other => other,
    };
    platform(&format!("{ARCH}-{os}"))
        .map_err(|_| format!("no FMI platform folder for this host ({ARCH}-{OS})"))
}

/// Builds the host library with plain cargo (the one `cargo run` uses) into `target`.
pub fn build_host(workspace: &Path, target: &Path) -> Result<PathBuf, String> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut command = Command::new(cargo);
    command.args(["build", "--release", "-p", FMU_PACKAGE]).current_dir(workspace);
    run(&mut command, "the host library")?;
    Ok(target.join("release").join(format!("{DLL_PREFIX}{FMU_LIBRARY}{DLL_SUFFIX}")))
}

impl Platform {
    /// Builds this platform's library by its cross route into `<target>/cross/<fmi3>/`
    /// (one target directory per route, so routes never invalidate each other's builds).
    pub fn build(&self, workspace: &Path, target: &Path) -> Result<PathBuf, String> {
        let target_dir = target.join("cross").join(self.fmi3);
        let venv_bin = workspace.join(".venv").join("bin");
        let mut command = match self.route {
            Route::Zig => {
                let mut c = Command::new(venv_bin.join("cargo-zigbuild"));
                c.arg("zigbuild");
                c
            }
            Route::DebianMingw => {
                let mut c = Command::new(DEBIAN_CARGO);
                c.arg("build");
                c
            }
            Route::DebianZig => {
                let mut c = Command::new(venv_bin.join("cargo-zigbuild"));
                c.arg("zigbuild").env("CARGO", DEBIAN_CARGO);
                c
            }
        };
        command
            .args(["--release", "-p", FMU_PACKAGE, "--target", self.triple])
            .current_dir(workspace)
            .env("CARGO_TARGET_DIR", &target_dir)
            .envs(self.env.iter().copied());
        if self.route != Route::Zig {
            command
                .arg(BUILD_STD)
                .env("RUSTC", DEBIAN_RUSTC)
                .env("RUSTDOC", DEBIAN_RUSTDOC)
                .env("RUSTC_BOOTSTRAP", "1");
        }
        if self.route != Route::DebianMingw {
            // cargo-zigbuild runs `python3 -m ziglang` when no zig is on PATH: the venv's.
            let path = std::env::var_os("PATH").unwrap_or_default();
            let mut dirs = vec![venv_bin.clone()];
            dirs.extend(std::env::split_paths(&path));
            command.env("PATH", std::env::join_paths(dirs).map_err(|e| e.to_string())?);
        }
        self.check_tools(&venv_bin)?;
        run(&mut command, self.fmi3)?;
        let triple = self.triple.split(".2.").next().expect("a triple");
        let prefix = if self.library_suffix == ".dll" { "" } else { "lib" };
        let file = format!("{prefix}{FMU_LIBRARY}{}", self.library_suffix);
        Ok(target_dir.join(triple).join("release").join(file))
    }

    /// The file name inside `binaries/<platform>/`.
    pub fn library_name(&self, model_identifier: &str) -> String {
        format!("{model_identifier}{}", self.library_suffix)
    }

    fn check_tools(&self, venv_bin: &Path) -> Result<(), String> {
        let mut needed = vec![];
        if self.route != Route::Zig {
            needed.push(PathBuf::from(DEBIAN_CARGO));
        }
        if self.route != Route::DebianMingw {
            needed.push(venv_bin.join("cargo-zigbuild"));
        }
        match needed.iter().find(|tool| !tool.exists()) {
            Some(tool) => Err(format!(
                "{}: {} is missing; scripts/setup-cross.sh installs the cross routes",
                self.fmi3,
                tool.display()
            )),
            None => Ok(()),
        }
    }
}

fn run(command: &mut Command, what: &str) -> Result<(), String> {
    let status = command.status().map_err(|e| {
        format!(
            "{what}: cannot run {}: {e} (scripts/setup-cross.sh installs the cross routes)",
            command.get_program().to_string_lossy()
        )
    })?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{what}: {command:?} failed ({status})"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn platform_names_are_the_fmi_folders() {
        assert_eq!(platform("win64").unwrap().fmi3, "x86_64-windows");
        assert_eq!(platform("x86_64-darwin").unwrap().fmi2, Some("darwin64"));
        assert!(platform("aarch64-linux").unwrap().fmi2.is_none());
        assert!(platform("riscv64-linux").is_err());
        assert_eq!(platform("x86_64-windows").unwrap().library_name("M"), "M.dll");
    }

    #[test]
    fn host_is_a_platform_on_the_usual_hosts() {
        if matches!(OS, "linux" | "windows" | "macos") && matches!(ARCH, "x86_64" | "aarch64") {
            assert_eq!(host().unwrap().library_suffix, DLL_SUFFIX);
        }
    }
}
