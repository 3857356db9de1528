"""One scenario, four importers: the same numbers (within 1e-9 of each signal's range).

Scenario: opamp_pi driver (default), V_supply 72 V, i_ref 0 -> 5 mA at t = 1 ms, 10 ms at
1e-4 s communication steps. The reference is fmpy's FMU2Slave/FMU3Slave stepped by hand
(ehsv.run_step); compared with
* fmpy.simulate_fmu (fmpy's own master, input table with the step),
* libcosimpy 0.0.6 (libcosim through its C API; FMI 2.0 only: libcosim's FMI library
  loads FMI 1.0/2.0 FMUs), the command set with an override manipulator,
* an fmu-manipulation-toolbox container (fmucontainer CLI) wrapping the archive, as an
  FMI 2.0 and as an FMI 3.0 container. The FMI 3.0 one runs in fmpy.simulate_fmu; the
  FMI 2.0 one is stepped by hand with a logger that records the raw format string,
  because the toolbox 2.0 container logs "%s" messages whose argument is sometimes a
  dangling pointer, and fmpy's native proxy formats it and crashes the process (seen in
  container_configure -> logger_message; our FMU is not on that stack).
"""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ehsv

H, T_STOP, T_STEP, I_STEP = 1e-4, 0.01, 1e-3, 5e-3
OUTPUTS = ("i_coil", "u_driver", "x_spool", "Q_valve")
N = int(round(T_STOP / H))
INPUT = np.array(
    [(0.0, 0.0), (T_STEP, 0.0), (T_STEP, I_STEP), (T_STOP, I_STEP)],
    dtype=[("time", np.float64), ("i_ref", np.float64)],
)


def reference(version):
    return ehsv.run_step(version, "opamp_pi", I_STEP, h=H, t_stop=T_STOP, t_step=T_STEP, outputs=OUTPUTS)


def assert_agree(name, ref, other):
    """Every output at every communication point within 1e-9 of the signal's range."""
    assert len(other["i_coil"]) == N + 1, f"{name}: {len(other['i_coil'])} samples"
    worst = {}
    for o in OUTPUTS:
        scale = np.max(np.abs(ref[o]))
        worst[o] = float(np.max(np.abs(np.asarray(other[o]) - ref[o])) / scale)
    print(f"{name}: largest difference / signal range: {worst}")
    assert max(worst.values()) <= 1e-9, f"{name} disagrees with the hand-stepped fmpy run: {worst}"


def simulate(path):
    from fmpy import simulate_fmu

    r = simulate_fmu(
        str(path),
        start_time=0.0,
        stop_time=T_STOP,
        step_size=H,
        output_interval=H,
        input=INPUT,
        output=list(OUTPUTS),
    )
    assert np.allclose(r["time"], np.arange(N + 1) * H, rtol=0, atol=1e-12)
    return r


def test_reference_has_the_step(version):
    ref = reference(version)
    assert ref["i_coil"][10] == 0.0 and abs(ref["i_coil"][-1] - I_STEP) < 1e-3 * I_STEP
    assert np.max(ref["u_driver"]) > 71.9  # the op-amp on its rail


def test_fmpy_simulate_fmu(version, fmu):
    assert_agree(f"fmpy.simulate_fmu {version}", reference(version), simulate(fmu))


def test_libcosimpy(fmu, version):
    if version != "fmi2":
        pytest.skip("libcosim (libcosimpy 0.0.6) imports FMI 1.0/2.0 FMUs only")
    from fmpy import read_model_description
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    vr = {v.name: v.valueReference for v in read_model_description(str(fmu)).modelVariables}
    execution = CosimExecution.from_step_size(int(round(H * 1e9)))  # nanoseconds
    slave = CosimLocalSlave(fmu_path=str(fmu), instance_name="ehsv")
    index = execution.add_local_slave(slave)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    override = CosimManipulator.create_override()
    execution.add_manipulator(override)
    refs = [vr[o] for o in OUTPUTS]
    rows = []
    for k in range(N):
        if k == int(round(T_STEP / H)):
            assert override.slave_real_values(index, [vr["i_ref"]], [I_STEP])
        assert execution.step(), f"libcosim step {k} failed: {execution.status()}"
        rows.append(observer.last_real_values(index, refs))
    assert execution.status().current_time == int(round(T_STOP * 1e9))
    first = [0.0] * len(OUTPUTS)  # at rest before the first step (the reference's row 0)
    table = np.array([first] + rows)
    assert_agree("libcosimpy", reference(version), {o: table[:, j] for j, o in enumerate(OUTPUTS)})


@pytest.fixture(scope="module")
def containers(fmu, tmp_path_factory):
    """The archive wrapped by fmucontainer, as an FMI 2.0 and an FMI 3.0 container."""
    tool = Path(sys.executable).with_name("fmucontainer")
    if not tool.exists():
        pytest.skip(f"{tool} not installed (fmu-manipulation-toolbox)")
    work = tmp_path_factory.mktemp("container")
    shutil.copy(fmu, work / fmu.name)
    built = {}
    for fmi in ("2", "3"):
        csv = work / f"ehsv_container_fmi{fmi}.csv"
        lines = [
            "rule;from_fmu;from_port;to_fmu;to_port",
            f"FMU;{fmu.name};;;",
            f"INPUT;;i_ref;{fmu.name};i_ref",
        ]
        lines += [f"OUTPUT;{fmu.name};{o};;{o}" for o in OUTPUTS]
        csv.write_text("\n".join(lines) + "\n")
        proc = subprocess.run(
            [str(tool), "-container", f"{csv.name}:{H}", "-fmi", fmi, "-fmu-directory", str(work)],
            cwd=work,
            capture_output=True,
            text=True,
            timeout=300,
        )
        out = csv.with_suffix(".fmu")
        assert proc.returncode == 0 and out.exists(), f"fmucontainer failed:\n{proc.stdout}\n{proc.stderr}"
        built[fmi] = out
    return built


def step_fmi2_by_hand(path):
    """The scenario through FMU2Slave with a fixed-argument logger (no varargs formatting)."""
    import ctypes

    from fmpy import extract, read_model_description
    from fmpy.fmi2 import (
        FMU2Slave,
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
    )

    md = read_model_description(str(path))
    refs = {v.name: v.valueReference for v in md.modelVariables}
    raw_logger = ctypes.CFUNCTYPE(
        None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p
    )(lambda env, name, status, category, message: None)
    keep = []  # buffers handed to the FMU live as long as the run

    def allocate(n, size):
        buf = ctypes.create_string_buffer(max(n * size, 1))
        keep.append(buf)
        return ctypes.addressof(buf)

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = ctypes.cast(raw_logger, fmi2CallbackLoggerTYPE)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(allocate)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(lambda p: None)
    fmu = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(str(path)),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="container",
    )
    fmu.instantiate(callbacks=callbacks)
    fmu.setupExperiment(startTime=0.0, stopTime=T_STOP)
    fmu.enterInitializationMode()
    fmu.setReal([refs["i_ref"]], [0.0])
    fmu.exitInitializationMode()
    out = [refs[o] for o in OUTPUTS]
    rows = [fmu.getReal(out)]
    for k in range(N):
        fmu.setReal([refs["i_ref"]], [I_STEP if k * H >= T_STEP - 1e-12 else 0.0])
        fmu.doStep(currentCommunicationPoint=k * H, communicationStepSize=H)
        rows.append(fmu.getReal(out))
    fmu.terminate()
    fmu.freeInstance()
    # The container's own "Solver configure...." line comes with status Error on every
    # healthy run, so the agreement of the numbers, not the log status, is the check.
    table = np.array(rows)
    return {o: table[:, j] for j, o in enumerate(OUTPUTS)}


@pytest.mark.parametrize("container_fmi", ["2", "3"])
def test_fmu_manipulation_toolbox_container(version, containers, container_fmi):
    path = containers[container_fmi]
    result = step_fmi2_by_hand(path) if container_fmi == "2" else simulate(path)
    assert_agree(f"container FMI {container_fmi}.0 around {version}", reference(version), result)
