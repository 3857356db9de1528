"""Bad input gives an Error status with a log message naming the cause, and no crash.

Each case runs in a child Python process (python -m ehsv.bad_input ...), so a crash of
the FMU shows as a failed test instead of killing pytest. fmpy raises FMICallException
for a status of Error or Fatal; its .status tells which (3 = Error). The FMU is instantiated
with loggingOn = false: an FMU must report errors through the logger even then.
"""

import json
import subprocess
import sys

import pytest

import ehsv

FMI_ERROR = 3

# case -> (words the Error log message must contain, case-insensitive; any of each tuple)
EXPECTED = {
    "nan_input": (("i_ref",), ("nan", "finite")),
    "negative_step": (("step",), ("-0.0001", "-1e-4", "positive", "negative")),
    "coil_L_negative": (("coil.L",), ("-1", "range", "positive")),
}


@pytest.mark.parametrize("case", ehsv.BAD_INPUT_CASES)
def test_bad_input_is_an_error_with_a_log_message(version, case):
    proc = subprocess.run(
        [sys.executable, "-m", "ehsv.bad_input", version, case], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, (
        f"child process ended with {proc.returncode} (a crash is negative)\n"
        f"stdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    )
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result["exception"] is not None, f"no Error status: {result}"
    assert result["status"] == FMI_ERROR, f"expected fmiError (3): {result}"
    errors = [msg for status, _category, msg in result["log"] if status == FMI_ERROR]
    assert errors, f"no log message with status Error; log: {result['log']}"
    text = "\n".join(errors).lower()
    for alternatives in EXPECTED[case]:
        assert any(word.lower() in text for word in alternatives), (
            f"Error log does not name the cause ({alternatives}): {errors}"
        )
    assert result["freed"]


def test_each_instance_gets_its_own_log_messages(version):
    """Two live instances, the first made first: an error of the first is logged to the
    first only, also after a third instance has come and gone (one process-wide logger,
    as fmpy's native proxy keeps, would send it to the last instance made)."""
    import gc

    first, second = ehsv.Ehsv(version), ehsv.Ehsv(version)
    gone = ehsv.Ehsv(version)
    gone.free(terminate=False)
    del gone
    gc.collect()
    with pytest.raises(Exception, match="failed"):
        first.set("coil.L", -2.5)
    assert any("coil.L = -2.5" in r.message for r in first.log), first.log_text()
    assert second.log == []
    for inst in (first, second):
        inst.free(terminate=False)
