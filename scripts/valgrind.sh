#!/usr/bin/env bash
# valgrind memcheck over the FMU's shared library, as it ships in both archives:
#   1. bench --quick --lib <.so from each archive>: a Rust driver that dlopens the library
#      and runs FMI 2.0 step loops (the importer's view);
#   2. the fuzzer (tests/src/bin/fuzz.rs, 5 s): every FMI 2/3 function with bad arguments;
#   3. fmpy (PYTHONMALLOC=malloc) simulating both archives (FMI 2.0 and FMI 3.0 paths);
#      Python's own noise is ignored: only error blocks with a frame in the FMU count.
# Pass: no invalid read/write and no definite leak. Logs in target/valgrind/.
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
OUT=target/valgrind
rm -rf "$OUT" && mkdir -p "$OUT"
cargo build --release -q -p ehsv-actuator -p ehsv-tests --bins && cargo run --release -q -p build-fmu >/dev/null || exit 1
VG=(valgrind --tool=memcheck --leak-check=full --show-leak-kinds=definite --errors-for-leak-kinds=definite)
failed=0
for v in fmi2 fmi3; do
    mkdir -p "$OUT/$v" && unzip -q -o "target/fmu/EhsvActuator-$v.fmu" -d "$OUT/$v"
done
run() {  # name, command...: valgrind's own error count must be 0
    local name="$1"; shift
    "${VG[@]}" --error-exitcode=99 --log-file="$OUT/$name.log" "$@" >"$OUT/$name.out" 2>&1
    local rc=$?
    echo "$name: $(grep -h 'ERROR SUMMARY' "$OUT/$name.log" | tail -1 | sed 's/==[0-9]*== //')" \
         "| $(grep -h 'definitely lost:' "$OUT/$name.log" | tail -1 | sed 's/==[0-9]*== *//')"
    [ $rc -eq 0 ] || { echo "  FAILED (exit $rc), see $OUT/$name.log"; failed=1; }
}
for v in fmi2 fmi3; do
    so=$(ls "$OUT/$v"/binaries/*/EhsvActuator.so)  # linux64 (FMI 2), x86_64-linux (FMI 3)
    run "bench-$v-archive" target/release/bench --quick --lib "$so"
done
run fuzz target/release/fuzz 5
# fmpy: Python leaks and uninitialised reads of its own are expected; count blocks that
# involve the FMU (a frame in EhsvActuator.so).
cat > "$OUT/fmpy_run.py" <<'PY'
import sys
from fmpy import simulate_fmu
for path in sys.argv[1:]:
    r = simulate_fmu(path, stop_time=0.01, step_size=1e-4, start_values={"i_ref": 5e-3})
    print(path, r["i_coil"][-1])
PY
PYTHONMALLOC=malloc "${VG[@]}" --log-file="$OUT/fmpy.log" .venv/bin/python "$OUT/fmpy_run.py" \
    target/fmu/EhsvActuator-fmi2.fmu target/fmu/EhsvActuator-fmi3.fmu >"$OUT/fmpy.out" 2>&1
ours=$(awk '/^==[0-9]+== $/ { if (block ~ /EhsvActuator|ehsv_actuator/ && block ~ /Invalid (read|write)|definitely lost|uninitialised|Invalid free/) n++; block=""; next }
            { block = block "\n" $0 } END { print n+0 }' "$OUT/fmpy.log")
echo "fmpy (both archives): $(grep -c 'EhsvActuator' "$OUT/fmpy.out") simulations ran;" \
     "$(grep -h 'ERROR SUMMARY' "$OUT/fmpy.log" | tail -1 | sed 's/==[0-9]*== //') (Python's own included);" \
     "error blocks involving the FMU: $ours"
[ "$ours" -eq 0 ] && [ "$(grep -c 'EhsvActuator' "$OUT/fmpy.out")" -eq 2 ] || { echo "  FAILED, see $OUT/fmpy.log"; failed=1; }
exit $failed
