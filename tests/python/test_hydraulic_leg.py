"""The hydraulic leg and quadruped in MuJoCo (cosim-examples/hydraulic_leg.py, quadruped.py),
each joint driven by the EhsvActuator FMU's motion port through a lever.

* the levers' law (as read from the robots' MJCF), the rods' travel over the stances the
  examples command, and the leg's inverse kinematics (no FMU),
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


def _model(example):
    """The example's MJCF with general actuators on the cylinders (no plugin needed)."""
    from ehsv import mjplugin

    return mjplugin.load_model(example.MJCF, "fmu")


# -- geometry ----------------------------------------------------------------------------
@pytest.mark.parametrize("example", [hydraulic_leg, quadruped])
def test_lever_law_and_its_slope(example):
    """x_rod is 0 where the lever is perpendicular to the cylinder (mid-stroke), the
    slope there is the moment arm d r / L, and it is dx/dq; LeverSet is each Lever."""
    model = _model(example)
    levers = (
        hydraulic_leg.Leg.of(model) if example is hydraulic_leg else quadruped.Quadruped.of(model)
    ).levers
    for lever in levers.levers:
        q_mid = math.pi / 2 - lever.phase
        x, arm = lever.rod(q_mid)
        assert x == pytest.approx(0.0, abs=1e-6)  # the sites' 6 digits
        assert abs(arm) == pytest.approx(lever.r * lever.d / lever.length_mid, rel=1e-6)
        for q in np.linspace(q_mid - 1.0, q_mid + 1.0, 9):
            e = 1e-6
            num = (lever.rod(q + e)[0] - lever.rod(q - e)[0]) / (2 * e)
            assert lever.rod(q)[1] == pytest.approx(num, rel=1e-6, abs=1e-9)
    q = np.linspace(-0.5, 0.5, len(levers.levers))
    xs, dxs = levers.rod(q)
    for i, lever in enumerate(levers.levers):
        assert (xs[i], dxs[i]) == pytest.approx(lever.rod(float(q[i])), rel=1e-12, abs=1e-15)


def test_leg_range_inside_the_stroke():
    """Every height the leg is commanded to (sitting to the hop's push-off and beyond)
    maps inside the stroke."""
    from ehsv import mjplugin

    leg = hydraulic_leg.Leg.of(_model(hydraulic_leg))
    stroke = mjplugin.hydraulics(hydraulic_leg.MJCF).stroke
    for h in np.linspace(leg.h_sit, 0.66, 40):
        x = leg.levers.rod(np.array(leg.joint_command(h)))[0]
        assert np.abs(x).max() < stroke / 2 - 0.005, (h, x)


def test_quadruped_range_inside_the_stroke():
    """Every stance the quadruped is commanded to (the crouch to the stance, a foot lifted
    by the trot's 5 cm, the attitude feedback's few cm) maps inside the stroke."""
    from ehsv import mjplugin

    quad = quadruped.Quadruped.of(_model(quadruped))
    stroke = mjplugin.hydraulics(quadruped.MJCF).stroke
    for h in np.linspace(quad.h_crouch, quad.h_stand + 0.03, 40):
        x = quad.levers.rod(quad.stance(h))[0]
        assert np.abs(x).max() < stroke / 2 - 0.005, (h, x)


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
    assert abs(r.height[-1] - r.plan.h_stand) < 0.005
    # the foot stayed on the ground
    assert r.rec["probe"][:, 2].max() - r.leg.kinematics.foot_radius < 0.005
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
    dq_dh = (np.array(r.leg.joint_command(h + e)) - r.leg.joint_command(h - e)) / (2 * e)
    tau = r.rec["F"][-1] * r.leg.levers.rod(r.rec["q"][-1])[1]
    model = _model(hydraulic_leg)
    trunk, thigh, shank = (float(model.body(b).mass[0]) for b in ("trunk", "thigh", "shank"))
    m = trunk + 0.75 * thigh + 0.25 * shank  # the shank's mass holds its foot
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
    assert np.abs(z - r.plan.h_stand).max() < 0.01
    assert np.abs(z[r.t > 0.15] - r.plan.h_stand).max() < 0.005
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
