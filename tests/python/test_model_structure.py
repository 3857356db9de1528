"""The ModelStructure's dependencies are what the binary does (FMI 2.0.4 section 2.2.8,
FMI 3.0 section 2.4.8): an output changes without a doStep only with the knowns it
declares. Outputs declare none (no direct feedthrough, so a master closing x_piston ->
i_ref sees no algebraic loop); an initial unknown changes in Initialization Mode only
with the inputs and parameters listed for it. The operating points here differ from the
ones modelDescription/src/dependencies.rs measures the lists at."""

import xml.etree.ElementTree as ET
import zipfile

import pytest
from fmpy.fmi1 import FMICallException

import ehsv

# (driver, control mode, values): commands non-zero, one point at the driver's rail
# (3 mA x 1 kOhm > 2 V) and one with the spool against its stop.
POINTS = [
    ("opamp_pi", "current", {"i_ref": 3e-3, "F_ext": -40.0}),
    ("ideal_current", "position", {"x_ref": 2e-3, "F_ext": 50.0}),
    ("voltage", "flow", {"Q_ref": 5e-5, "V_supply": 2.0, "valve.x_spool_max": 2e-5}),
    ("industrial", "current", {"i_ref": -3e-3, "V_supply": 2.0}),
]


def structure(version):
    """{output name: set of declared known names} for Output and InitialUnknown."""
    with zipfile.ZipFile(ehsv.fmu_path(version)) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
    ms = root.find("ModelStructure")
    if version == "fmi2":
        names = [v.get("name") for v in root.find("ModelVariables")]
        key, by = "index", lambda i: names[int(i) - 1]
        outputs, initial = ms.find("Outputs"), ms.find("InitialUnknowns")
    else:
        names = {v.get("valueReference"): v.get("name") for v in root.find("ModelVariables")}
        key, by = "valueReference", lambda vr: names[vr]
        outputs, initial = ms.findall("Output"), ms.findall("InitialUnknown")

    def lists(unknowns):
        found = {}
        for u in unknowns:
            deps = u.get("dependencies")
            assert deps is not None, f"{by(u.get(key))}: no dependencies attribute"
            found[by(u.get(key))] = {by(d) for d in deps.split()}
        return found

    return lists(outputs), lists(initial)


def moved(var, current):
    """Another allowed value for a known."""
    if var.type == "Boolean":
        return not bool(current)
    if var.type == "Enumeration":
        lo, hi = int(var.min), int(var.max)
        return lo + (int(current) - lo + 1) % (hi - lo + 1)
    value = current * 1.1 if current != 0 else 1e-3
    if var.max is not None and value > float(var.max):
        value = current * 0.9
    return value


def snapshot(inst, outputs):
    return dict(zip(outputs, inst.get(outputs), strict=True))


def changed(before, after):
    return {n for n in before if before[n] != after[n]}


def in_initialization_mode(version, driver, mode, values):
    inst = ehsv.Ehsv(version)
    if version == "fmi2":
        inst.fmu.setupExperiment(startTime=0.0)
        inst.fmu.enterInitializationMode()
    else:
        inst.fmu.enterInitializationMode(startTime=0.0)
    inst.set("driver", ehsv.DRIVERS[driver])
    inst.set("control_mode", ehsv.CONTROL_MODES[mode])
    for name, value in values.items():
        inst.set(name, value)
    return inst


@pytest.mark.parametrize("driver,mode,values", POINTS)
def test_outputs_do_not_feed_through(version, driver, mode, values):
    declared, _ = structure(version)
    assert all(deps == set() for deps in declared.values()), declared
    inst = in_initialization_mode(version, driver, mode, values)
    inst.fmu.exitInitializationMode()
    outputs = list(declared)
    inputs = [n for n, v in inst.variables.items() if v.causality == "input"]
    try:
        for t in (0.0, 1e-3):  # right after initialisation and after a step
            if t:
                inst.do_step(0.0, t)
            for name in inputs:
                before = snapshot(inst, outputs)
                current = inst.get([name])[0]
                inst.set(name, moved(inst.variables[name], current))
                after = snapshot(inst, outputs)
                inst.set(name, current)
                assert not changed(before, after), f"setting {name} changed {changed(before, after)}"
    finally:
        inst.free(terminate=False)


@pytest.mark.parametrize("driver,mode,values", POINTS)
def test_initial_unknowns_change_only_with_declared_knowns(version, driver, mode, values):
    _, declared = structure(version)
    inst = in_initialization_mode(version, driver, mode, values)
    outputs = list(declared)
    knowns = [n for n, v in inst.variables.items() if v.causality in ("input", "parameter")]
    seen, checked = set(), 0
    try:
        for name in knowns:
            before = snapshot(inst, outputs)
            current = inst.get([name])[0]
            try:
                inst.set(name, moved(inst.variables[name], current))
            except FMICallException:
                continue  # refused value: nothing to observe
            checked += 1
            after = snapshot(inst, outputs)
            inst.set(name, current)
            for output in changed(before, after):
                assert name in declared[output], f"{output} changed with undeclared {name}"
                seen.add((output, name))
    finally:
        inst.free(terminate=False)
    assert checked >= len(knowns) - 2, f"only {checked} of {len(knowns)} knowns could be moved"
    # The check can fail: the commands and the supply move the initial equilibrium.
    assert ("p_A", "p_supply") in seen
    # ... and the coil current follows i_ref, or at the rail the supply.
    assert mode != "current" or {("i_coil", "i_ref"), ("i_coil", "V_supply")} & seen
