#!/usr/bin/env bash
# Longer fuzzing of the C API: scripts/fuzz.sh [SECONDS] [SEED]   (or EHSV_FUZZ_SECONDS=...)
# Prints the number of FMI calls made; exits non-zero on a crash, panic or hang (20 s watchdog).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
exec cargo run --release -q -p ehsv-tests --bin fuzz -- "${1:-${EHSV_FUZZ_SECONDS:-60}}" ${2:+"$2"}
