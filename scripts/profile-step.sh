#!/usr/bin/env bash
# Instructions per doStep, by part of the step, of one benchmark workload:
#
#     scripts/profile-step.sh WORKLOAD exact|fixed_cost [STEPS] [--c-api]   # e.g. gait_position fixed_cost
#
# Runs tests/src/bin/step_profile.rs (the workload through the model's Rust API, STEPS
# doSteps of 1e-4 s, default 5000: the bench's --t-end 0.5) under callgrind, built with debug
# info into target/profile so that the normal release build is left as it is. Instruction
# counts, unlike the bench's times, do not move with what else the machine does.
#
# --c-api: the workload through the FMI 2 C API instead, as the bench's instr/step counts it
# (SetReal of the inputs, DoStep, GetReal of i_coil, x_piston, p_A, Q_valve per instance and
# step, inside capi_steps::communication_step); "rest" then holds the FMI layer as well.
#
# callgrind records every call chain (--separate-callers) and callgrind_annotate prints each
# chain's own instructions; only chains through step_profile::one_do_step count, so the start-up
# (instantiation, initialisation) and the driving loop fall outside and no second run needs
# subtracting. Per part, two figures: "inclusive", every instruction with a function of the part
# on its call chain (parts nest: evolve holds most, so these do not add up), and "own", each
# instruction charged to the innermost part on its chain ("rest": none, the model layer and
# the step's frame, not the C API, which the bench's idle row measures; these add up to the
# doStep). The chains' own counts are added up here rather
# than read from --inclusive=yes, which splits a function by the source file of its inlined code
# and counts its calls once per piece. Functions are matched by substrings, so a renamed helper in
# the physics crate costs a line "matched nothing", not a failure; a function the compiler
# inlined is counted in its caller.
set -euo pipefail
[ $# -ge 2 ] || { echo "usage: $0 WORKLOAD exact|fixed_cost [STEPS] [--c-api]" >&2; exit 2; }
steps=5000 c_api= marker=step_profile::one_do_step
for a in "${@:3}"; do
    case "$a" in
        --c-api) c_api=--c-api marker=capi_steps::communication_step ;;
        *) steps=$a ;;
    esac
done
cd "$(dirname "$0")/.."
CARGO_PROFILE_RELEASE_DEBUG=true CARGO_TARGET_DIR=target/profile \
    cargo build --quiet --release -p ehsv-tests --bin step_profile
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
valgrind --tool=callgrind --separate-callers=100 --callgrind-out-file="$out/cg" \
    target/profile/release/step_profile "$1" "$2" "$steps" $c_api >"$out/run" 2>"$out/valgrind" \
    || { cat "$out/valgrind" >&2; exit 1; }
callgrind_annotate --inclusive=no --threshold=100 --auto=no "$out/cg" >"$out/annotated" 2>/dev/null
python=python3; [ -x .venv/bin/python ] && python=.venv/bin/python
"$python" - "$out/run" "$out/annotated" "$marker" <<'PY'
import collections, re, sys

MARKER = sys.argv[3]  # step_profile::one_do_step, or capi_steps::communication_step
PARTS = {  # name: substrings of a function's name; an instruction's own part is the innermost
    "integrator's evolve": ["::evolve"],
    "driver/coil/valve propagation": ["::propagate", "taylor_propagate", "PropagatorCache::get", "WholeSteps::"],
    "mode choice": ["consistent_state", "::settle", "first_crossing", "slew_end"],
    "cylinder linearisation": ["cylinder_jacobian::linearis", "Linearised::at", "friction_at"],
    "cylinder step (solve, cuts)": ["lean_cylinder::advance_once", "Linearised::step"],
    "LU (factor, solve)": ["lu4::Lu4::factor", "lu4::Lu4::solve"],
    "cylinder right-hand side": ["cylinder::derivatives"],
    "outputs": ["outputs_at"],
}
run = open(sys.argv[1]).read()
calls = int(re.search(r"(\d+) doSteps", run).group(1))
inclusive, own = collections.Counter(), collections.Counter()
for line in open(sys.argv[2]):
    m = re.match(r"\s*([\d,]+) \([ \d.]+%\)  [^:]*:(.*?)( \[[^\]]*\])?$", line)
    if not m or MARKER not in m.group(2):
        continue
    count, frames = int(m.group(1).replace(",", "")), m.group(2).split("'")
    frames = frames[: next(i for i, f in enumerate(frames) if MARKER in f)]  # inside the doStep
    parts = [p for f in frames for p, names in PARTS.items() if any(s in f for s in names)]
    own[parts[0] if parts else "rest (model layer)"] += count
    for p in set(parts) | {"doStep (whole)"}:  # once per chain, however deep a part nests
        inclusive[p] += count
print(f"{run.strip()}; instructions per doStep (inclusive, own):")
for name in ["doStep (whole)", *PARTS, "rest (model layer)"]:
    if name not in inclusive and name not in own:
        print(f"  {name:<31} matched nothing")
        continue
    incl = inclusive[name] or own[name]  # rest: the instructions outside every part
    mine = f"{own[name] / calls:9.0f}" if name != "doStep (whole)" else ""
    print(f"  {name:<31} {incl / calls:9.0f} {mine}")
PY
