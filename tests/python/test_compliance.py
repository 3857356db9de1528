"""The archives are valid FMUs and keep the interface contract (names, causality, units,
start values, driver enumeration)."""
import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

import ehsv_scenarios as ehsv

FMI_VERSION = {"fmi2": "2.0", "fmi3": "3.0"}


def test_fmpy_validation_finds_no_problem(fmu):
    problems = validate_fmu(str(fmu))
    assert problems == [], "\n".join(problems)


def test_fmutool_check_reports_compliance(fmu, version):
    # fmu-manipulation-toolbox 2.0: `fmutool -input X.fmu -check` validates the XML against
    # the FMI XSD and checks the semantic rules; it logs to stdout and exits with 0, or 7
    # when a check found an error (ExitCode.CHECK_FAILED).
    fmutool = Path(sys.executable).parent / "fmutool"
    assert fmutool.exists(), f"{fmutool} missing: install requirements.txt into this venv"
    proc = subprocess.run([str(fmutool), "-input", str(fmu), "-check"],
                          capture_output=True, text=True, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    assert f"This FMU seems to be compliant with FMI-{FMI_VERSION[version]}." in out, out
    assert f"No semantic error against the FMI-{FMI_VERSION[version][0]} standard." in out, out
    assert "ERROR" not in out, out


@pytest.fixture(scope="module")
def md(fmu):
    return read_model_description(str(fmu))


def _vars(md):
    return {v.name: v for v in md.modelVariables}


def test_co_simulation_interface(md, version):
    assert md.fmiVersion == FMI_VERSION[version]
    assert md.coSimulation is not None
    assert md.modelName == "EhsvActuator"


def test_inputs_and_outputs_by_contract(md):
    vs = _vars(md)
    for name, (unit, start) in ehsv.INPUTS.items():
        assert name in vs, f"input {name} missing"
        assert vs[name].causality == "input"
        assert vs[name].unit == unit
        assert float(vs[name].start) == start
    for name, unit in ehsv.OUTPUTS.items():
        assert name in vs, f"output {name} missing"
        assert vs[name].causality == "output"
        if unit is None:
            assert vs[name].type == "Boolean"
        else:
            assert vs[name].type in ("Real", "Float64")
            assert vs[name].unit == unit, name


def test_parameter_defaults_by_contract(md):
    vs = _vars(md)
    for name, value in ehsv.NOMINAL.items():
        assert name in vs, f"parameter {name} missing"
        assert vs[name].causality == "parameter", name
        assert float(vs[name].start) == pytest.approx(value, rel=1e-12), name


def test_driver_enumeration(md):
    v = _vars(md)["driver"]
    assert v.type == "Enumeration"
    items = {item.name: int(item.value) for item in v.declaredType.items}
    for name, value in ehsv.DRIVERS.items():
        assert items.get(name) == value, items
