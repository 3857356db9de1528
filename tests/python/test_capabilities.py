"""The capability flags in each modelDescription.xml say what the binary does: every
capability declared is there, and every function behind a flag declared false (or an
interface not declared) answers Error with a log line saying it is not supported."""

import xml.etree.ElementTree as ET
import zipfile

import pytest
from fmpy.fmi1 import FMICallException

import ehsv


def declared(version):
    """The archive's own XML: the CoSimulation element's attributes, and which interfaces."""
    with zipfile.ZipFile(ehsv.fmu_path(version)) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    flags = {k: v for k, v in root.find("CoSimulation").attrib.items()}
    return flags, [
        child.tag for child in root if child.tag in ("ModelExchange", "CoSimulation", "ScheduledExecution")
    ]


def started(version):
    inst = ehsv.Ehsv(version)
    inst.initialize(start_time=0.0)
    return inst


def refused(inst, call, reason="not supported"):
    """``call`` fails with Error (status 3) and the FMU logs why."""
    before = len(inst.log)
    with pytest.raises(FMICallException) as e:
        call()
    assert e.value.status == 3
    assert any(reason in r.message for r in inst.log[before:]), inst.log_text()


def check_output_derivatives(inst, get):
    """Order 1 of every real output; x_piston's is v_piston; order 2 is refused."""
    inst.set("i_ref", 5e-3)
    inst.do_step(4e-4, 1e-3)
    x_piston, v_piston = inst.vr("x_piston"), inst.vr("v_piston")
    (rate,) = get([x_piston], [1])
    assert rate == pytest.approx(inst.get(["v_piston"])[0], rel=1e-6, abs=1e-12)
    assert rate != 0.0, "the piston moves"
    refused(inst, lambda: get([v_piston], [2]), "order 2 for v_piston")
    inst.set("i_ref", 0.0)
    inst.do_step(1.4e-3, 1e-4)


def test_declared_capabilities_work_and_undeclared_are_refused(version):
    inst = started(version)
    flags, interfaces = declared(version)
    on = {k for k, v in flags.items() if v == "true"}
    off = {k for k, v in flags.items() if v == "false"}
    assert interfaces == ["CoSimulation"]
    fmu = inst.fmu
    i_coil = inst.vr("i_coil")
    i_ref = inst.vr("i_ref")
    assert "canHandleVariableCommunicationStepSize" in on
    inst.do_step(0.0, 1e-4)
    inst.do_step(1e-4, 3e-4)
    if version == "fmi2":
        assert {"canGetAndSetFMUstate", "canSerializeFMUstate"} <= on
        state = fmu.getFMUstate()
        assert len(fmu.serializeFMUstate(state)) > 0
        fmu.setFMUstate(state)
        fmu.freeFMUstate(state)
        assert {"providesDirectionalDerivative", "canRunAsynchronuously"} <= off
        refused(inst, lambda: fmu.getDirectionalDerivative([i_coil], [i_ref], [1.0]))
        assert "canInterpolateInputs" in on
        fmu.setRealInputDerivatives([i_ref], [1], [0.0])
        refused(inst, lambda: fmu.setRealInputDerivatives([i_ref], [2], [0.0]), "order 2 for i_ref")
        assert flags["maxOutputDerivativeOrder"] == "1"
        check_output_derivatives(inst, fmu.getRealOutputDerivatives)
        refused(inst, fmu.cancelStep, "fmi2DoStep is synchronous")
    else:
        assert {"canGetAndSetFMUState", "canSerializeFMUState"} <= on
        state = fmu.getFMUState()
        assert len(fmu.serializeFMUState(state)) > 0
        fmu.setFMUState(state)
        fmu.freeFMUState(state)
        assert {"providesDirectionalDerivatives", "providesAdjointDerivatives", "hasEventMode"} <= off
        refused(inst, lambda: fmu.getDirectionalDerivative([i_coil], [i_ref], [1.0], 1))
        refused(inst, lambda: fmu.getAdjointDerivative([i_ref], [i_coil], [1.0], 1))
        refused(inst, fmu.enterEventMode)
        assert flags["maxOutputDerivativeOrder"] == "1"
        check_output_derivatives(inst, fmu.getOutputDerivatives)
    inst.do_step(1.5e-3, 1e-4)  # the refusals left the instance usable
    inst.free()
