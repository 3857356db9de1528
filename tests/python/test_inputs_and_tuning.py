"""Input ranges, input warnings and tunable parameters on the built archives (both versions).

* Every input carries a physical range (min/max in modelDescription.xml); a value beyond
  it is refused with Error and a log line naming the variable, the value and the range.
* A current command above the valve's rating, or a supply at 0 while a command asks for
  motion (an importer feeding 0 to an unconnected input), gives doStep status Warning and
  one logStatusWarning line when it begins.
* Tunable parameters (gains, limits, friction, load) change during a run and take effect
  at the next communication point; fmpy's simulate_fmu reuses one instance across a
  parameter sweep with reset() between the runs.
"""

import numpy as np
import pytest
from fmpy import instantiate_fmu, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException

import ehsv

INPUTS = ("i_ref", "V_supply", "p_supply", "F_ext", "Q_ref", "x_ref")
# Chosen in fmu-src/variables/src/variables.rs: what a user tunes or varies during a run.
TUNABLE = {
    "driver.Kp", "driver.Ki", "driver.V_drop", "driver.slew_rate",
    "industrial.Kp", "industrial.Ki", "industrial.slew_rate",
    "hbridge.Kp", "hbridge.Ki",
    "cylinder.mass", "cylinder.b_viscous", "cylinder.F_coulomb", "cylinder.F_static",
    "cylinder.v_stribeck", "cylinder.v_friction_smooth", "cylinder.C_leak", "cylinder.C_leak_external",
    "loop.i_max", "flow.Kp", "flow.Ki", "flow.Kd", "position.Kp", "position.Ki", "position.Kd",
}  # fmt: skip


def variables(fmu):
    return {v.name: v for v in read_model_description(str(fmu)).modelVariables}


def test_every_input_has_a_range_and_the_tunables_are_declared(fmu):
    v = variables(fmu)
    for name in INPUTS:
        assert v[name].min is not None and v[name].max is not None, name
        assert float(v[name].min) < float(v[name].start) <= float(v[name].max) or name == "V_supply", name
    assert (float(v["i_ref"].min), float(v["i_ref"].max)) == (-0.1, 0.1)
    assert (float(v["F_ext"].min), float(v["F_ext"].max)) == (-1e5, 1e5)
    tunable = {n for n, var in v.items() if var.causality == "parameter" and var.variability == "tunable"}
    assert tunable == TUNABLE
    for fixed in ("driver", "control_mode", "coil.L", "valve.K3", "cylinder.stroke", "loop.f_sample"):
        assert v[fixed].variability == "fixed", fixed


def test_out_of_range_input_is_refused_with_a_log_line(version):
    inst = ehsv.Ehsv(version)
    inst.initialize()
    with pytest.raises(FMICallException) as e:
        inst.set("i_ref", 5.0)  # 5 mA typed in A
    assert e.value.status == 3
    expected = "i_ref = 5 rejected: allowed range is [-0.1, 0.1]"
    assert any(expected in r.message for r in inst.log), inst.log_text()
    assert inst.get(["i_ref"]) == [0.0]
    inst.do_step(0.0, 1e-4)  # still usable
    inst.free()


def test_unconnected_supply_warns_once(version):
    """Simulink feeds 0 to an unconnected input: V_supply 0 with a current command."""
    inst = ehsv.Ehsv(version, logging_on=True)
    inst.initialize(V_supply=0.0)
    inst.set("i_ref", 5e-3)
    for k in range(20):
        inst.do_step(k * 1e-4, 1e-4)  # Warning is not an exception in fmpy
    warnings = [r for r in inst.log if r.category == "logStatusWarning"]
    assert len(warnings) == 1, inst.log_text()
    assert warnings[0].status == 1 and "V_supply = 0 V" in warnings[0].message
    assert "unconnected" in warnings[0].message
    assert inst.get(["i_coil"]) == [0.0], "no supply, no current"
    inst.free()


# ---------------------------------------------------------------- tunable parameters

T_STOP, H, X_SET = 0.1, 1e-4, 2e-3


def position_step(fmu, kp, fmu_instance=None):
    """Position loop, x_ref 2 mm from rest at mid-stroke (unsaturated: Kp * 2 mm < 10 mA)."""
    return simulate_fmu(
        str(fmu),
        stop_time=T_STOP,
        step_size=H,
        output_interval=H,
        start_values={"control_mode": 2, "x_ref": X_SET, "position.Kp": kp},
        output=["x_piston", "i_coil"],
        fmu_instance=fmu_instance,
    )


def rise_time(r):
    """Time to 63 % of the set point (first crossing, interpolated)."""
    x, t = r["x_piston"], r["time"]
    k = int(np.argmax(x >= 0.632 * X_SET))
    return t[k - 1] + (0.632 * X_SET - x[k - 1]) / (x[k] - x[k - 1]) * (t[k] - t[k - 1])


def test_parameter_sweep_reuses_one_instance_after_reset(fmu, version):
    """simulate_fmu(fmu_instance=...) with reset() between runs gives exactly the runs of
    fresh instances, and the loop gain acts as the physics says: the valve-controlled
    cylinder integrates flow, so with P control x follows a first-order lag whose time
    constant is inversely proportional to Kp (doubling Kp halves the rise time, within
    what the valve lag and the hydraulic resonance add)."""
    md = read_model_description(str(fmu))
    instance = instantiate_fmu(ehsv.fmu._unzip(fmu), md, fmi_type="CoSimulation")
    rises = []
    try:
        for kp in (0.25, 0.5, 1.0):
            reused = position_step(fmu, kp, fmu_instance=instance)
            instance.reset()
            fresh = position_step(fmu, kp)
            for name in ("x_piston", "i_coil"):
                assert np.array_equal(reused[name], fresh[name]), f"Kp {kp}: {name} differs after reset"
            # Slowest (Kp 0.25, time constant ~25 ms) 4 time constants in: within 2 %;
            # no overshoot beyond 1 % at these gains (at Kp 2 friction makes it hunt).
            assert abs(reused["x_piston"][-1] - X_SET) < 0.02 * X_SET, reused["x_piston"][-1]
            assert np.max(reused["x_piston"]) < 1.01 * X_SET
            rises.append(rise_time(reused))
    finally:
        instance.freeInstance()
    print(f"{version}: 63 % rise times for Kp 0.25, 0.5, 1 A/m: {[f'{r * 1e3:.2f} ms' for r in rises]}")
    assert rises[0] > rises[1] > rises[2]
    for slow, fast in zip(rises, rises[1:], strict=False):
        assert 1.8 < slow / fast < 2.2, rises  # measured 2.03, 2.00


def test_tunable_change_mid_run_acts_from_the_next_step(version):
    """position.Kp raised from 0.25 to 1 A/m at 10 ms in one of two identical runs: the
    outputs read right after the set are unchanged, the next step differs (four times the
    current command), and the stiffer loop gets there sooner (time constant ~6 ms instead
    of ~25 ms: at 30 ms its error is a small fraction of the other's)."""
    a, b = ehsv.Ehsv(version), ehsv.Ehsv(version)
    outputs = ["x_piston", "i_coil", "Q_valve", "p_A"]
    for inst in (a, b):
        inst.initialize(control_mode=2, x_ref=X_SET, position__Kp=0.25)
    for k in range(100):
        a.do_step(k * H, H)
        b.do_step(k * H, H)
    before = a.get(outputs)
    a.set("position.Kp", 1.0)
    assert a.get(outputs) == before == b.get(outputs), "no effect before the next step"
    a.do_step(100 * H, H)
    b.do_step(100 * H, H)
    assert a.get(["i_coil"])[0] > b.get(["i_coil"])[0] * 3, "the gain acts in the next step"
    for k in range(101, 300):
        a.do_step(k * H, H)
        b.do_step(k * H, H)
    err_a, err_b = (abs(X_SET - inst.get(["x_piston"])[0]) for inst in (a, b))
    assert err_a < 0.2 * err_b, (err_a, err_b)
    with pytest.raises(FMICallException):
        a.set("coil.L", 3.0)  # fixed: refused during the run
    # fmpy's FMI 2 logger proxy is one per process: the line may land in b's record.
    assert any("coil.L is a fixed parameter" in r.message for r in a.log + b.log), a.log_text()
    a.free()
    b.free()
