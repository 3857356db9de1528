"""The archives are valid FMUs and keep the interface contract (names, causality, units,
start values, driver enumeration)."""

import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

import ehsv

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
    proc = subprocess.run(
        [str(fmutool), "-input", str(fmu), "-check"], capture_output=True, text=True, timeout=120
    )
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


#: the published interface users' scripts and models bind to (docs/model.md): inputs with
#: unit and start value, outputs with unit (None: Boolean), the two enumerations
INPUTS = {
    "i_ref": ("A", 0.0),
    "V_supply": ("V", 72.0),
    "p_supply": ("Pa", 6.8948e6),
    "F_ext": ("N", 0.0),
    "Q_ref": ("m3/s", 0.0),
    "x_ref": ("m", 0.0),
    "x_rod": ("m", 0.0),
    "v_rod": ("m/s", 0.0),
}
OUTPUTS = {
    "i_coil": "A",
    "u_driver": "V",
    "driver_saturated": None,
    "x_flapper": "m",
    "x_spool": "m",
    "Q_valve": "m3/s",
    "Q_A": "m3/s",
    "Q_B": "m3/s",
    "p_A": "Pa",
    "p_B": "Pa",
    "x_piston": "m",
    "v_piston": "m/s",
    "F_hydraulic": "N",
    "Q_supply": "m3/s",
    "F_rod": "N",
    "dF_rod_dx": "N/m",
    "dF_rod_dv": "N.s/m",
}
DRIVERS = {"ideal_current": 0, "voltage": 1, "opamp_pi": 2, "industrial": 3, "hbridge_pid": 4}
CONTROL_MODES = {"current": 0, "flow": 1, "position": 2}

# US customary units of the paper's appendix table
IN, LBF_IN, MA = 0.0254, 0.1129848290276167, 1e-3  # m; N m per in-lb; A

#: the valve and coil defaults are the paper's appendix table converted to SI here
PAPER_TABLE = {
    "valve.K1": 0.025 * LBF_IN / MA,  # 0.025 in-lb/mA
    "valve.Kf": 115 * LBF_IN / IN,  # 115 in-lb/in
    "valve.Kw": 16.7 * LBF_IN / IN,  # 16.7 in-lb/in
    "valve.K2": 150 * IN**2,  # 150 in3/s/in
    "valve.K3": 1030 * IN**2,  # 1030 in3/s/in
    "valve.A_s": 0.026 * IN**2,  # 0.026 in2
    "valve.zeta": 0.4,
    "valve.f_n": 814.0,  # Hz
    "coil.L": 3.2,  # H
    "coil.R": 1000.0,  # ohm
}

#: other defaults docs/model.md states (SI)
DOCUMENTED = {
    "driver": 2,
    "control_mode": 0,
    "driver.Kp": 1.6e5,
    "driver.Ki": 5.0e7,
    "driver.V_drop": 0.0,
    "driver.slew_rate": 2.0e7,
    "coil.R_sense": 0.0,
    "coil.K_b": 0.0,
    "valve.x_flapper_max": 0.0,
    "valve.x_spool_max": 0.0,
    "valve.dp_rated": 6.8948e6,
    "cylinder.bore": 0.016,
    "cylinder.rod": 0.010,
    "cylinder.stroke": 0.080,
    "cylinder.mass": 5.0,
    "cylinder.beta": 1.0e9,
    "cylinder.V_dead": 2.0e-6,
    "cylinder.b_viscous": 200.0,
    "cylinder.F_coulomb": 20.0,
    "cylinder.F_static": 30.0,
    "cylinder.v_stribeck": 0.01,
    "cylinder.k_endstop": 1.0e8,
    "cylinder.c_endstop": 1.0e4,
    "hydraulics.p_cavitation": -0.9e5,
    "loop.f_sample": 20000.0,
    "loop.i_max": 0.01,
    "hbridge.f_pwm": 20000.0,
}


def test_inputs_and_outputs_by_contract(md):
    vs = _vars(md)
    for name, (unit, start) in INPUTS.items():
        assert name in vs, f"input {name} missing"
        assert vs[name].causality == "input"
        assert vs[name].unit == unit
        assert float(vs[name].start) == start
    for name, unit in OUTPUTS.items():
        assert name in vs, f"output {name} missing"
        assert vs[name].causality == "output"
        if unit is None:
            assert vs[name].type == "Boolean"
        else:
            assert vs[name].type in ("Real", "Float64")
            assert vs[name].unit == unit, name
    # nothing more: every input and output is in the published list
    assert {v.name for v in md.modelVariables if v.causality == "input"} == set(INPUTS)
    assert {v.name for v in md.modelVariables if v.causality == "output"} == set(OUTPUTS)


@pytest.mark.parametrize("table", [PAPER_TABLE, DOCUMENTED], ids=["paper_table", "documented"])
def test_parameter_defaults(md, table):
    vs = _vars(md)
    for name, value in table.items():
        assert name in vs, f"parameter {name} missing"
        assert vs[name].causality == "parameter", name
        # the paper's table is given to 3 digits; the FMU's SI values carry 6
        assert float(vs[name].start) == pytest.approx(value, rel=1e-5), name


def test_enumerations(md):
    for name, expected in (("driver", DRIVERS), ("control_mode", CONTROL_MODES)):
        v = _vars(md)[name]
        assert v.type == "Enumeration"
        assert {item.name: int(item.value) for item in v.declaredType.items} == expected, name


def test_both_archives_carry_the_same_interface():
    """The package reads the FMI 2.0 archive's XML (ehsv.contract); the FMI 3.0 one must
    say the same: names, causality, units, start values, enumerations."""
    a, b = (ehsv.interface(v) for v in ehsv.VERSIONS)
    assert a == b
    assert len(a.parameters) > 40 and a.drivers == DRIVERS
