"""FMU state across processes, through fmpy: one process steps, serializes the state and
writes the bytes to a file; another process (a new instance in a new address space,
maybe the other FMI version) deserializes them and continues. The continuation must be
bit-identical to the first process's own. Corrupted and truncated bytes must give an
Error status and a log line in the loading process, never a crash.

Each role runs as `python test_robustness_state.py {save|load|corrupt} ...` in a child
process, so a crash of the FMU shows as a failed test, not a dead pytest.
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

import ehsv

HERE = Path(__file__).resolve()
H = 1e-4
K_SAVE, N_AFTER = 37, 50
NAMES = ("i_coil", "u_driver", "driver_saturated", "x_flapper", "x_spool", "Q_valve", "time")
FMI_ERROR = 3


def i_ref(k):
    """+-10 mA square wave, period 50 steps: the op-amp driver runs into its rails."""
    return 0.01 if (k // 25) % 2 == 0 else -0.01


def run(inst, k0, n):
    rows = []
    for k in range(k0, k0 + n):
        inst.set("i_ref", i_ref(k))
        inst.do_step(k * H, H)
        rows.append([v.hex() for v in inst.get(NAMES)])  # exact: hex floats
    return rows


def state_calls(inst):
    f = inst.fmu
    if inst.version == "fmi2":
        return f.getFMUstate, f.setFMUstate, f.freeFMUstate, f.serializeFMUstate, f.deSerializeFMUstate
    return f.getFMUState, f.setFMUState, f.freeFMUState, f.serializeFMUState, f.deserializeFMUState


def child_save(version, state_file, out_file):
    inst = ehsv.Ehsv(version)
    inst.initialize()
    run(inst, 0, K_SAVE)
    get, _set, free, serialize, _deserialize = state_calls(inst)
    state = get()
    Path(state_file).write_bytes(serialize(state))
    free(state)
    Path(out_file).write_text(json.dumps(run(inst, K_SAVE, N_AFTER)))
    inst.free()


def child_load(version, state_file, out_file):
    inst = ehsv.Ehsv(version)
    inst.initialize()
    _get, set_, free, _serialize, deserialize = state_calls(inst)
    state = deserialize(Path(state_file).read_bytes())
    set_(state)
    free(state)
    Path(out_file).write_text(json.dumps(run(inst, K_SAVE, N_AFTER)))
    inst.free()


def child_corrupt(version, state_file, out_file):
    """Every byte flipped, every truncation, a few foreign strings: count the refusals."""
    from fmpy.fmi1 import FMICallException

    good = Path(state_file).read_bytes()
    bad = [good[:i] + bytes([good[i] ^ 0xFF]) + good[i + 1 :] for i in range(len(good))]
    bad += [good[:n] for n in range(1, len(good))]  # (fmpy cannot pass 0 bytes)
    bad += [good + b"\0", b"EHSVFS02" + good[8:], bytes(range(256)) * 3]
    inst = ehsv.Ehsv(version)
    inst.initialize()
    _get, set_, free, _serialize, deserialize = state_calls(inst)
    refused = 0
    for b in bad:
        before = len(inst.log)
        try:
            deserialize(b)
        except FMICallException as e:
            lines = [
                r for r in inst.log[before:] if r.status == FMI_ERROR and "cannot deserialize" in r.message
            ]
            refused += e.status == FMI_ERROR and len(lines) == 1
    state = deserialize(good)  # the good bytes still work after all that
    set_(state)
    free(state)
    inst.do_step(K_SAVE * H, H)
    inst.free()
    Path(out_file).write_text(json.dumps({"tried": len(bad), "refused": refused}))


def child(*args):
    proc = subprocess.run(
        [sys.executable, str(HERE), *map(str, args)], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, (
        f"child {args[0]} ended with {proc.returncode} (negative: a crash)\n"
        f"stdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    )


@pytest.mark.parametrize("load_version", ehsv.VERSIONS)
def test_state_continues_bit_identically_in_another_process(version, load_version, tmp_path):
    if ehsv.missing_fmu_message(load_version):
        pytest.fail(ehsv.missing_fmu_message(load_version))
    state, saved, loaded = tmp_path / "state.bin", tmp_path / "saved.json", tmp_path / "loaded.json"
    child("save", version, state, saved)
    child("load", load_version, state, loaded)
    a, b = json.loads(saved.read_text()), json.loads(loaded.read_text())
    assert len(a) == N_AFTER and a == b, f"{version} -> {load_version}: the continuation differs"
    assert len({row[0] for row in a}) > 10, "the continuation is not trivial"


def test_corrupted_state_bytes_are_refused_in_another_process(version, tmp_path):
    state, saved, result = tmp_path / "state.bin", tmp_path / "saved.json", tmp_path / "result.json"
    child("save", version, state, saved)
    child("corrupt", version, state, result)
    r = json.loads(result.read_text())
    assert r["tried"] > 2 * len(state.read_bytes()) - 2
    assert r["refused"] == r["tried"], r


if __name__ == "__main__":
    role, version, state_file, out_file = sys.argv[1:5]
    {"save": child_save, "load": child_load, "corrupt": child_corrupt}[role](version, state_file, out_file)
