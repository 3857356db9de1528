#!/usr/bin/env bash
# THE build + demo command: builds both FMUs and runs the 0 -> 5 mA current-step demo
# (prints the settling time and driver voltage, writes out/current_step.png).
# Extra arguments go to the demo, e.g. scripts/demo.sh --fmi3
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

scripts/setup-venv.sh
scripts/setup-gl.sh || echo "demo: setup-gl failed, the MuJoCo picture will be skipped"
cargo run --release -p build-fmu
cargo build --release -p ehsv-mujoco   # the MuJoCo plugin the robot examples run on
.venv/bin/python cosim-examples/current_step.py "$@"
# Every figure of the paper the FMU reproduces (rows 1-11), through fmpy on both archives.
.venv/bin/python cosim-examples/figures.py
# The hydraulic leg in MuJoCo on the ehsv.actuator plugin (plots and a rendered picture in out/).
.venv/bin/python cosim-examples/hydraulic_leg.py
