"""The hydraulic leg and quadruped in MuJoCo (cosim-examples/hydraulic_leg.py, quadruped.py),
each joint driven by the EhsvActuator FMU's motion port through a lever.

* the levers' geometry and the leg's inverse kinematics (no FMU),
* the leg stands up from sitting and holds its 20 kg trunk (0.6 s), against each built
  archive: trunk height on its command, rod forces inside what the supply and the relief
  valves allow, pressures under the relief setting, MuJoCo's tendon (the drawn cylinder)
  as long as the lever's law says,
* the same with solver.method = fixed_cost,
* the quadruped (68 kg, 12 actuators) holds its stance under its own weight (0.4 s),
* the same leg and quadruped on the ehsv.actuator MuJoCo plugin (the robots' MJCF as
  written; test_mujoco_plugin.py checks it against the FMU bit for bit).

The FMU runs are skipped, saying why, only when the archive's modelDescription has no
motion port (cylinder.port, x_rod, v_rod, F_rod).
"""

import functools
import math

import numpy as np
import pytest

import ehsv
from ehsv import robot

hydraulic_leg = pytest.importorskip("hydraulic_leg", reason="cosim-examples is not on the path")
quadruped = pytest.importorskip("quadruped", reason="cosim-examples is not on the path")
pytest.importorskip("mujoco", reason="mujoco is not installed (scripts/setup-venv.sh)")


def _require_port(version: str) -> None:
    missing = ehsv.missing_fmu_message(version)
    if missing:
        pytest.fail(missing, pytrace=False)
    why = robot.motion_port_missing(version)
    if why:
        pytest.skip(why)


def _require_plugin() -> None:
    from ehsv import mjplugin

    missing = mjplugin.plugin_missing()
    if missing:
        pytest.fail(missing, pytrace=False)


@functools.cache
def _fmu_leg(version: str, method: str = "exact"):
    """The short stand-up-and-hold run of the leg on the FMU, once per version and method
    (the tests only read it)."""
    _require_port(version)
    return hydraulic_leg.run(short=True, kind="fmu", version=version, render=False, method=method)


# -- geometry ----------------------------------------------------------------------------
@pytest.mark.parametrize("lever", hydraulic_leg.LEVERS + quadruped.LEVERS[:3])
def test_lever_law_and_its_slope(lever):
    """x_rod(q_mid) = 0, the slope is the moment arm (r at q_mid), and it is dx/dq."""
    x, arm = lever.rod(lever.q_mid)
    assert x == pytest.approx(0.0, abs=1e-15)
    assert abs(arm) == pytest.approx(lever.r * lever.d / lever.L_mid, rel=1e-12)
    for q in np.linspace(lever.q_mid - 1.0, lever.q_mid + 1.0, 9):
        e = 1e-6
        num = (lever.rod(q + e)[0] - lever.rod(q - e)[0]) / (2 * e)
        assert lever.rod(q)[1] == pytest.approx(num, rel=1e-6, abs=1e-9)
    vec = robot.LeverSet([lever, lever])
    q = np.array([lever.q_mid - 0.3, lever.q_mid + 0.4])
    xs, dxs = vec.rod(q)
    for i in range(2):
        assert (xs[i], dxs[i]) == pytest.approx(lever.rod(float(q[i])), rel=1e-12, abs=1e-15)


def test_leg_range_inside_the_stroke():
    """Every height the leg is commanded to maps inside the 80 mm stroke."""
    stroke = robot.Hydraulics().stroke
    for h in np.linspace(hydraulic_leg.H_SIT, 0.66, 40):
        q = hydraulic_leg.joint_command(h)
        for lever, qj in zip(hydraulic_leg.LEVERS, q, strict=True):
            assert abs(lever.rod(qj)[0]) < stroke / 2 - 0.005, (h, q)


@pytest.mark.parametrize("bend", [1, -1])
def test_leg_ik_puts_the_foot_there(bend):
    L1 = L2 = 0.35
    for depth, fwd in [(0.5, 0.0), (0.3, 0.1), (0.6, -0.2)]:
        qh, qk = robot.leg_ik(depth, fwd, L1, L2, bend)
        x = -L1 * math.sin(qh) - L2 * math.sin(qh + qk)
        z = -L1 * math.cos(qh) - L2 * math.cos(qh + qk)
        assert (x, z) == pytest.approx((fwd, -depth), abs=1e-12)
        assert qk * bend > 0


# -- the leg -----------------------------------------------------------------------------
def _check_leg(r) -> None:
    s = r.summary()
    hyd = r.hyd
    # stood up and holds the trunk at its command (0.55 m) within a few millimetres
    assert abs(s["hold_err_mean"]) < 0.005, s
    assert s["hold_err_max"] < 0.01, s
    assert abs(r.height[-1] - hydraulic_leg.H_STAND) < 0.005
    # the foot stayed on the ground
    assert r.rec["probe"][:, 2].max() - hydraulic_leg.FOOT_R < 0.005
    # forces: inside what the chambers can make under the relief valves; the knee carries
    # the trunk (pushes), holding it takes less than the stall force
    push, pull = hyd.relief_force()
    F = r.rec["F"]
    assert F.max() < push and F.min() > pull, (F.min(), F.max())
    hold = r.window(r.plan.t_up[1] + 0.1, r.t_end)
    stall_push, stall_pull = hyd.stall_force()
    knee = F[hold, 1]
    assert 0 < knee.min() and knee.max() < 0.8 * stall_push
    # at rest the joint torques F_rod x'(q) hold the weight (virtual work along the
    # commanded path, foot under the hip: the trunk rises by dh, the thigh's centre of
    # mass by 3/4 dh, the shank's by 1/4 dh)
    h = r.height[-1]
    e = 1e-6
    dq_dh = (np.array(hydraulic_leg.joint_command(h + e)) - hydraulic_leg.joint_command(h - e)) / (2 * e)
    tau = r.rec["F"][-1] * hydraulic_leg.LeverSet(hydraulic_leg.LEVERS).rod(r.rec["q"][-1])[1]
    m = hydraulic_leg.M_TRUNK + 0.75 * hydraulic_leg.M_THIGH + 0.25 * hydraulic_leg.M_SHANK
    assert float(tau @ dq_dh) == pytest.approx(m * 9.81, rel=0.1)  # still settling
    # pressures: below the relief setting, above the cavitation floor
    for p in ("p_A", "p_B"):
        assert r.rec[p].max() < hyd.p_crack
        assert r.rec[p].min() > -0.1e6
    assert np.abs(r.rec["i_coil"]).max() <= 0.0101
    # rods inside the stroke; MuJoCo's tendon between the pivots is the lever's L(q)
    assert np.abs(r.rec["x_rod"]).max() < hyd.stroke / 2
    assert r.tendon_error < 1e-6


@pytest.mark.parametrize("version", ehsv.VERSIONS)
def test_leg_stands_up_and_holds_its_trunk(version):
    r = _fmu_leg(version)
    assert r.kind == "fmu"
    _check_leg(r)


@pytest.mark.parametrize("version", ehsv.VERSIONS)
def test_leg_holds_its_trunk_with_fixed_cost(version):
    """The same stand-up and hold with solver.method = fixed_cost, within the same bounds
    as exact (the co-simulation's error is the host's step, not the FMU's integrator);
    the forces differ from exact's, or the method did not reach the instances."""
    r = _fmu_leg(version, "fixed_cost")
    assert "solver.method = fixed_cost" in r.actuator_line
    _check_leg(r)
    assert (r.rec["F"] != _fmu_leg(version).rec["F"]).any()


def test_leg_on_the_plugin():
    """The same run on the ehsv.actuator MuJoCo plugin (the MJCF as written)."""
    _require_plugin()
    r = hydraulic_leg.run(short=True, kind="plugin", render=False)
    assert r.kind == "plugin"
    _check_leg(r)


# -- the quadruped -----------------------------------------------------------------------
@pytest.mark.parametrize("version", ehsv.VERSIONS)
def test_quadruped_holds_its_stance(version):
    _require_port(version)
    r = quadruped.run(short=True, kind="fmu", version=version, render=False)
    assert r.kind == "fmu"
    _check_quadruped(r)


def test_quadruped_on_the_plugin():
    _require_plugin()
    r = quadruped.run(short=True, kind="plugin", render=False)
    assert r.kind == "plugin"
    _check_quadruped(r)


def _check_quadruped(r) -> None:
    assert not r.fell
    pr = r.rec["probe"]
    z, roll, pitch = pr[:, 0], pr[:, 2], pr[:, 3]
    # it settles in from a start with the chambers' forces at zero
    assert np.abs(z - quadruped.H_STAND).max() < 0.01
    assert np.abs(z[r.t > 0.15] - quadruped.H_STAND).max() < 0.005
    assert np.degrees(np.abs(roll)).max() < 0.5 and np.degrees(np.abs(pitch)).max() < 0.5
    push, pull = r.hyd.relief_force()
    F = r.rec["F"]
    assert F.max() < push and F.min() > pull
    # the knees carry the robot: their summed joint torques hold 68 kg
    knees = F[-1, 2::3]
    assert (knees > 0).all() and knees.max() < 0.8 * r.hyd.stall_force()[0]
    for p in ("p_A", "p_B"):
        assert r.rec[p].max() < r.hyd.p_crack
    assert np.abs(r.rec["x_rod"]).max() < r.hyd.stroke / 2
