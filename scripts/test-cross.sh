#!/usr/bin/env bash
# Cross-platform archives and their tests (docs/fmi.md "Platforms", docs/testing.md "Cross builds"):
#   1. scripts/setup-cross.sh                          installs the routes (apt-get, pip)
#   2. cargo run --release -p build-fmu -- --all-targets   target/fmu/ with all five binaries
#   3. tests/cross/run_cross.py                        Windows DLL under Wine, aarch64 under
#      qemu-user, glibc <= 2.17, Mach-O checks; outputs equal x86_64 Linux within 1e-12
# Each route builds in its own target/cross/<platform>/; the build prints the seconds each
# platform took (cold: about 3 min per build-std route on 2 cores; warm: seconds).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

scripts/setup-cross.sh
cargo run --release -p build-fmu -- --all-targets
.venv/bin/python tests/cross/run_cross.py target/fmu
