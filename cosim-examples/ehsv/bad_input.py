"""Bad input cases, each run in a child process by the tests so that a crash of the FMU
cannot take pytest down:

    python -m ehsv.bad_input {fmi2|fmi3} {nan_input|negative_step|coil_L_negative}

prints one JSON line: what happened (the exception, its FMI status, the captured log,
whether the instance could still be freed).
"""

from __future__ import annotations

import json
import sys

from .fmu import Ehsv

BAD_INPUT_CASES = ("nan_input", "negative_step", "coil_L_negative")


def bad_input_case(version: str, case: str) -> dict:
    """Runs one bad-input case; returns what happened: the exception text (fmpy raises
    FMICallException for Error/Fatal), its FMI status, the captured log, and whether the
    instance could still be freed afterwards."""
    from fmpy.fmi1 import FMICallException

    inst = Ehsv(version, logging_on=False)
    result = {
        "case": case,
        "version": version,
        "exception": None,
        "status": None,
        "function": None,
        "log": [],
        "freed": False,
    }
    try:
        if case == "coil_L_negative":
            inst.set("coil.L", -1.0)
            inst.initialize()
        else:
            inst.initialize()
            if case == "nan_input":
                inst.set("i_ref", float("nan"))
                inst.do_step(0.0, 1e-4)
            elif case == "negative_step":
                inst.do_step(0.0, -1e-4)
            else:
                raise ValueError(f"unknown case {case}")
    except FMICallException as e:
        result.update(exception=str(e), status=e.status, function=e.function)
    except Exception as e:  # anything else is reported, not swallowed
        result.update(exception=f"{type(e).__name__}: {e}")
    result["log"] = [[r.status, r.category, r.message] for r in inst.log]
    inst.free(terminate=False)  # after Error only freeInstance/reset are allowed
    result["freed"] = True
    return result


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: python -m ehsv.bad_input {fmi2|fmi3} {" + "|".join(BAD_INPUT_CASES) + "}")
    print(json.dumps(bad_input_case(sys.argv[1], sys.argv[2])))
