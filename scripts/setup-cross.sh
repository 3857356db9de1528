#!/usr/bin/env bash
# Installs the cross-build routes of `cargo run --release -p build-fmu --all-targets` and the
# tools their tests need (scripts/test-cross.sh). Idempotent: a second run only checks.
# Needs root (or sudo) for apt-get on Debian bookworm, and the project venv for pip.
#
#   apt: rustc-web cargo-web rust-web-src  Debian's Rust with the standard library's source
#                                          (-Zbuild-std for targets rustup has no std for)
#        gcc-mingw-w64-x86-64              Windows linker and the test harness's compiler
#        wine64                            runs the Windows harness and DLL
#        qemu-user libc6-arm64-cross       runs the aarch64 smoke test
#        llvm                              llvm-objcopy for rustc's macOS debuginfo strip
#        binutils                          objdump -T for the glibc symbol-version check
#   pip (into .venv): ziglang cargo-zigbuild   zig as linker for old-glibc Linux and macOS
#
# The rustup toolchain stays first on PATH; Debian's cargo and rustc are only called by
# their full paths (build-fmu/src/targets.rs).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
APT_PACKAGES=(rustc-web cargo-web rust-web-src gcc-mingw-w64-x86-64 wine64 qemu-user
    libc6-arm64-cross llvm binutils)
PIP_PACKAGES=(ziglang==0.15.2 cargo-zigbuild==0.24.0)

"$ROOT/scripts/apt-install.sh" setup-cross "${APT_PACKAGES[@]}"

"$ROOT/scripts/setup-venv.sh"
if ! "$ROOT/.venv/bin/python" -m pip show --quiet "${PIP_PACKAGES[@]%%==*}" >/dev/null 2>&1; then
    echo "setup-cross: pip install ${PIP_PACKAGES[*]}" >&2
    "$ROOT/.venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "${PIP_PACKAGES[@]}" >&2
fi
echo "setup-cross: ready" >&2
