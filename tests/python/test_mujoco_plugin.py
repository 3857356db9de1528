"""The ehsv.actuator MuJoCo plugin (mujoco-plugin/, target/release/libehsv_mujoco.so):

* it loads and registers, and the robots' MJCF files compile with it,
* the MJCF files are the robots' one description: the levers the examples read from them
  are MuJoCo's cylinders (tendons), perpendicular at mid-stroke, their "stand" keyframes
  are the examples' stance with the rods' commands that hold it, and their actuators'
  config is the hydraulics the FMU-driven robot gets,
* the plugin-driven leg equals the FMU-driven leg (same MJCF, same scenario and loop
  order) to 1e-9 of each signal's range,
* mj_getState / mj_setState mid-run restores the hydraulic state bit for bit (into the
  same mjData and a fresh one), and so do mj_copyData and mj_resetData,
* a mujoco.rollout on two threads equals a serial run, bit for bit,
* the plugin's sensors give each actuator's outputs, bit for bit those in plugin_state,
  change no simulated number, come out of a rollout as from a serial run, and a sensor
  on an instance without an actuator is refused with a message,
* a bad configuration is refused with a message that names the key,
* the leg stands at each documented host timestep (docs/mujoco.md).
"""

import math

import numpy as np
import pytest

from ehsv import mjplugin

mujoco = pytest.importorskip("mujoco", reason="mujoco is not installed (scripts/setup-venv.sh)")
hydraulic_leg = pytest.importorskip("hydraulic_leg", reason="cosim-examples is not on the path")
quadruped = pytest.importorskip("quadruped", reason="cosim-examples is not on the path")

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


# the plugin, loaded once for every test here (conftest.py)
pytestmark = pytest.mark.usefixtures("mujoco_plugin")


def _state(model, data) -> np.ndarray:
    out = np.empty(mujoco.mj_stateSize(model, FULL))
    mujoco.mj_getState(model, data, out, FULL)
    return out


def _bits(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def _leg(timestep=None, sensors=True):
    model = mjplugin.load_model(hydraulic_leg.MJCF, "plugin", timestep, sensors=sensors)
    data = mujoco.MjData(model)
    leg = hydraulic_leg.Leg.of(model)
    q0 = leg.joint_command(leg.h_stand)
    data.qpos[model.joint("rail").qposadr[0]] = leg.h_stand
    for j, q in zip(hydraulic_leg.JOINTS, q0, strict=True):
        data.qpos[model.joint(j).qposadr[0]] = q
    mujoco.mj_forward(model, data)
    return model, data


def _x_ref(k: int) -> np.ndarray:
    """A moving command of the leg's two rods (m)."""
    return np.array([-0.004, -0.010]) + 0.003 * np.sin(2 * np.pi * 3.0 * k * 1e-4)


def _steps(model, data, k0: int, n: int) -> list[np.ndarray]:
    states = []
    for k in range(k0, k0 + n):
        data.ctrl[:] = _x_ref(k)
        mujoco.mj_step(model, data)
        states.append(_state(model, data))
    return states


def test_plugin_loads_and_the_robots_compile():
    for path, n in [(hydraulic_leg.MJCF, 2), (quadruped.MJCF, 12)]:
        model = mujoco.MjModel.from_xml_path(str(path))  # as the viewer opens it
        assert model.nplugin == n and model.nu == n
        data = mujoco.MjData(model)
        mujoco.mj_step(model, data)
        # every actuator has its slots: the outputs, then the state bytes
        assert model.npluginstate == n * model.plugin_statenum[0]
        p_a = mjplugin.outputs(model, data, "p_A", range(n))
        assert np.all(p_a > 1e5), p_a


def test_plugin_leg_equals_fmu_leg():
    """Same MJCF, scenario and loop order: the plugin and the FMU agree to 1e-9 of each
    signal's range (they are in fact bit for bit equal)."""
    from ehsv.robot import motion_port_missing

    why = motion_port_missing("fmi2")
    if why:
        pytest.fail(why, pytrace=False)
    a = hydraulic_leg.run(short=True, kind="plugin", render=False)
    b = hydraulic_leg.run(short=True, kind="fmu", render=False)
    assert (a.kind, b.kind) == ("plugin", "fmu")
    for key in ("q", "x_rod", "F", "p_A", "p_B", "i_coil", "probe"):
        x, y = a.rec[key], b.rec[key]
        assert x.shape == y.shape and len(x) == 600, key
        span = np.ptp(y, axis=0)
        assert np.all(np.abs(x - y) <= 1e-9 * np.where(span > 0, span, 1.0)), key
    assert abs(a.summary()["hold_err_max"]) < 3e-3


def test_get_and_set_state_mid_run_bit_for_bit():
    model, data = _leg()
    _steps(model, data, 0, 300)
    mid = _state(model, data)
    ahead = _steps(model, data, 300, 200)
    # back into the same mjData (its cache holds the later state), and into a fresh one
    mujoco.mj_setState(model, data, mid, FULL)
    again = _steps(model, data, 300, 200)
    fresh = mujoco.MjData(model)
    mujoco.mj_setState(model, fresh, mid, FULL)
    restored = _steps(model, fresh, 300, 200)
    for k, (s0, s1, s2) in enumerate(zip(ahead, again, restored, strict=True)):
        assert np.array_equal(_bits(s0), _bits(s1)), f"same mjData, step {k}"
        assert np.array_equal(_bits(s0), _bits(s2)), f"fresh mjData, step {k}"
    assert np.ptp([s[1] for s in ahead]) > 0  # the trunk moved


def test_copy_and_reset_carry_the_hydraulic_state():
    model, data = _leg()
    start = _bits(data.plugin_state).copy()
    _steps(model, data, 0, 100)
    copy = mujoco.MjData(model)
    mujoco.mj_copyData(copy, model, data)
    a, b = _steps(model, data, 100, 50), _steps(model, copy, 100, 50)
    assert all(np.array_equal(_bits(x), _bits(y)) for x, y in zip(a, b, strict=True))
    mujoco.mj_resetData(model, data)
    assert np.array_equal(_bits(data.plugin_state), start)
    assert not np.array_equal(_bits(copy.plugin_state), start)


def _quadruped(sensors=True):
    model = mjplugin.load_model(quadruped.MJCF, sensors=sensors)
    data = mujoco.MjData(model)
    quad = quadruped.Quadruped.of(model)
    quadruped.initial_pose(model, data, quadruped.Plan.short(quad), quad)
    return model, data


def test_rollout_equals_serial_run():
    """Two threads of mujoco.rollout give a serial run's states and sensors bit for bit."""
    from mujoco import rollout

    model, data = _quadruped()
    x0 = _state(model, data)
    nstep, nu = 150, model.nu
    rng = np.random.default_rng(1)
    ctrl = np.stack([np.tile(rng.uniform(-3e-3, 3e-3, nu), (nstep, 1)) for _ in range(3)])
    states, sensordata = rollout.rollout(
        model, [mujoco.MjData(model) for _ in range(2)], x0, ctrl, nstep=nstep
    )
    for b in range(3):
        serial = mujoco.MjData(model)
        mujoco.mj_setState(model, serial, x0, FULL)
        for k in range(nstep):
            serial.ctrl[:] = ctrl[b, k]
            mujoco.mj_step(model, serial)
            assert np.array_equal(_bits(states[b, k]), _bits(_state(model, serial))), (b, k)
            assert np.array_equal(_bits(sensordata[b, k]), _bits(serial.sensordata)), (b, k)
    assert np.count_nonzero(sensordata[:, -1]) > 0


def _output_slots(model, data, a: int) -> np.ndarray:
    """Slots 0-16 (the outputs) of actuator ``a``'s instance."""
    adr = model.plugin_stateadr[model.actuator_plugin[a]]
    return data.plugin_state[adr : adr + len(mjplugin.OUTPUTS)].copy()


def test_sensors_are_the_outputs_in_plugin_state():
    """Each sensor is its instance's slots 0-16: after mj_step those at the step's start (a
    sensor is computed in the forward pass before the step, as MuJoCo's own), after
    mj_forward those at data.time; the pressures and forces of a loaded, moving leg."""
    names = list(mjplugin.OUTPUTS)
    model, data = _leg()
    assert model.nsensordata == model.nu * len(names)
    cfg = mjplugin.actuator_config(hydraulic_leg.MJCF)["knee"]
    floor, relief = -90000.0, float(cfg["relief.p_crack"]) + float(cfg["relief.dp_override"])
    for k in range(400):
        before = [_output_slots(model, data, a) for a in range(model.nu)]
        data.ctrl[:] = _x_ref(k)
        mujoco.mj_step(model, data)
        for a, name in enumerate(("hip", "knee")):
            assert np.array_equal(_bits(data.sensor(f"{name}_hydraulics").data), _bits(before[a])), (k, a)
    mujoco.mj_forward(model, data)
    for a, name in enumerate(("hip", "knee")):
        sensed = dict(zip(names, data.sensor(f"{name}_hydraulics").data, strict=True))
        assert np.array_equal(_bits(list(sensed.values())), _bits(_output_slots(model, data, a)))
        for p in ("p_A", "p_B"):
            assert floor < sensed[p] < relief, (name, p, sensed[p])
        assert abs(sensed["F_rod"]) > 10.0 and sensed["v_piston"] != 0.0, sensed
    p_a = mjplugin.sensor_outputs(model, data, "p_A", range(model.nu))
    assert np.array_equal(_bits(p_a), _bits(mjplugin.outputs(model, data, "p_A", range(model.nu))))


@pytest.mark.parametrize("example", [hydraulic_leg, quadruped])
def test_sensors_change_no_simulated_number(example):
    runs = []
    for sensors in (False, True):
        model, data = _leg(sensors=sensors) if example is hydraulic_leg else _quadruped(sensors)
        rng = np.random.default_rng(2)
        ctrl = rng.uniform(-3e-3, 3e-3, model.nu)
        for k in range(300):
            data.ctrl[:] = ctrl * np.sin(2 * np.pi * 5.0 * k * 1e-4)
            mujoco.mj_step(model, data)
        assert model.nsensor == (model.nu if sensors else 0)
        runs.append([data.qpos, data.qvel, data.actuator_force, data.plugin_state, [data.time]])
    for a, b in zip(*runs, strict=True):
        assert np.array_equal(_bits(a), _bits(b))


def test_a_sensor_on_an_instance_without_actuator_is_refused():
    """MuJoCo compiles the plugin's init for every instance: one that drives no actuator
    is refused with a message (nothing of it is read)."""
    xml = """<mujoco><extension><plugin plugin="ehsv.actuator">
    <instance name="lone"><config key="control_mode" value="position"/></instance>
    </plugin></extension>
    <worldbody><body><joint type="slide"/><geom size=".1" mass="1"/></body></worldbody>
    <sensor><plugin name="lone_hydraulics" instance="lone"/></sensor></mujoco>"""
    with pytest.raises(ValueError, match="drives 0 actuators"):
        model = mujoco.MjModel.from_xml_string(xml)
        mujoco.MjData(model)


MINIMAL = """<mujoco><option timestep="1e-4"/><extension><plugin plugin="ehsv.actuator"/></extension>
<worldbody><body><joint name="s" type="slide" axis="1 0 0"/>
<geom type="box" size=".1 .1 .1" mass="5"/></body></worldbody>
<actuator><plugin plugin="ehsv.actuator" joint="s">{config}</plugin></actuator></mujoco>"""


@pytest.mark.parametrize(
    "key, value",
    [
        ("cylinder.bogus", "1"),  # no such variable
        ("x_ref", "0"),  # the control, not a key
        ("cylinder.bore", "-1"),  # out of range
        ("driver", "turbo"),  # no such item
        ("solver.method", "7"),
        ("cylinder.port", "force"),  # a MuJoCo actuator is the motion port
        ("p_supply", "30e6"),  # above the relief valves' setting
        ("substep", "0"),
    ],
)
def test_bad_config_is_refused_naming_the_key(key, value):
    xml = MINIMAL.format(config=f'<config key="{key}" value="{value}"/>')
    with pytest.raises(ValueError, match=key.replace(".", r"\.")):
        model = mujoco.MjModel.from_xml_string(xml)
        mujoco.MjData(model)


def test_enumerations_by_name_or_number():
    """control_mode by name or number: the same run, the 5 kg slider on the position loop."""
    ends = []
    for mode in ("position", "2"):
        xml = MINIMAL.format(config=f'<config key="control_mode" value="{mode}"/>')
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        data.ctrl[0] = 0.004
        for _ in range(3000):
            mujoco.mj_step(model, data)
        assert data.qpos[0] == pytest.approx(0.004, abs=3e-4)
        ends.append(_state(model, data))
    assert np.array_equal(_bits(ends[0]), _bits(ends[1]))


@pytest.mark.parametrize("timestep", [1e-4, 5e-4, 1e-3, 2e-3])
def test_leg_stands_at_the_documented_host_timesteps(timestep):
    r = hydraulic_leg.run(short=True, kind="plugin", render=False, timestep=timestep)
    s = r.summary()
    assert np.all(np.isfinite(r.rec["F"]))
    assert s["hold_err_max"] < 3e-3, s["hold_err_max"]
    assert s["p_max"] < r.hyd.p_crack + r.hyd.dp_override


def _robot(example, model):
    """The example's robot as it reads it from the model (its levers, heights, legs)."""
    return hydraulic_leg.Leg.of(model) if example is hydraulic_leg else quadruped.Quadruped.of(model)


def _stance(example, robot, height: float) -> np.ndarray:
    """The example's joint commands (JOINTS' order) for a level stance at ``height``."""
    return np.array(robot.joint_command(height) if example is hydraulic_leg else robot.stance(height))


def _joint_qpos(model, joints) -> np.ndarray:
    return np.array([model.joint(j).qposadr[0] for j in joints])


@pytest.mark.parametrize("example", [hydraulic_leg, quadruped])
def test_the_levers_read_from_the_model_are_its_cylinders(example):
    """At any pose, the rod position the examples command through the levers (read from
    the sites) is MuJoCo's cylinder (the tendon between the sites) minus length_mid, the
    rod the actuator moves; the levers' moment arm is the tendon length's slope."""
    model = mjplugin.load_model(example.MJCF, "fmu")  # the same tendons, no plugin needed
    data = mujoco.MjData(model)
    levers = _robot(example, model).levers
    adr = _joint_qpos(model, example.JOINTS)
    act = [model.actuator(j).id for j in example.JOINTS]
    rng = np.random.default_rng(7)
    lo, hi = (np.array([model.joint(j).range[k] for j in example.JOINTS]) for k in (0, 1))
    for _ in range(20):
        q = rng.uniform(lo, hi)
        data.qpos[adr] = q
        mujoco.mj_fwdPosition(model, data)
        x, arm = levers.rod(q)
        assert np.allclose(x, data.actuator_length[act] - levers.length_mid, rtol=0, atol=1e-12)
        for i in range(len(q)):
            e = 1e-6
            dq = np.zeros(len(q))
            dq[i] = e
            slope = (levers.rod(q + dq)[0][i] - levers.rod(q - dq)[0][i]) / (2 * e)
            data.qpos[adr] = q + dq
            mujoco.mj_fwdPosition(model, data)
            up = data.actuator_length[act[i]]
            data.qpos[adr] = q - dq
            mujoco.mj_fwdPosition(model, data)
            assert arm[i] == pytest.approx(slope, abs=1e-9)
            assert arm[i] == pytest.approx((up - data.actuator_length[act[i]]) / (2 * e), abs=1e-9)


@pytest.mark.parametrize("example", [hydraulic_leg, quadruped])
def test_each_lever_is_perpendicular_at_mid_stroke(example):
    """length_mid (the plugin's) is the cylinder's length where the lever is perpendicular
    to it, so the rod's whole stroke is spent where the moment arm is largest; the
    actuator's control range is the stroke."""
    model = mjplugin.load_model(example.MJCF)
    hyd = mjplugin.hydraulics(example.MJCF)
    for lever in _robot(example, model).levers.levers:
        perpendicular = math.pi / 2 - lever.phase
        x, arm = lever.rod(perpendicular)
        assert abs(x) < 1e-6, lever  # the sites' 6 digits
        assert abs(arm) == pytest.approx(lever.d * lever.r / lever.length_mid, rel=1e-6)
        assert model.actuator(lever.joint).ctrlrange == pytest.approx([-hyd.stroke / 2, hyd.stroke / 2])


@pytest.mark.parametrize("example", [hydraulic_leg, quadruped])
def test_the_stand_keyframe_is_the_examples_stance(example):
    """The keyframe the viewer loads is the examples' stance at its height (foot under the
    hip) with the rods' commands that hold it: the joints' x_ref through the levers."""
    model = mjplugin.load_model(example.MJCF, "fmu")
    robot = _robot(example, model)
    key = model.key("stand")
    q = key.qpos[_joint_qpos(model, example.JOINTS)]
    assert q == pytest.approx(_stance(example, robot, robot.h_stand), abs=1e-12)
    assert key.ctrl == pytest.approx(robot.levers.rod(q)[0], abs=1e-7)


@pytest.mark.parametrize("example", [hydraulic_leg, quadruped])
def test_the_fmu_gets_the_plugins_hydraulics(example):
    """Every plugin actuator's config is one robot.Hydraulics, which the FMU bank sets on
    its instances: the FMU-driven robot is the plugin-driven one."""
    hyd = mjplugin.hydraulics(example.MJCF)
    configs = mjplugin.actuator_config(example.MJCF)
    assert sorted(configs) == sorted(example.JOINTS)
    for config in configs.values():
        for key, value in hyd.fmu_values().items():
            assert float(config[key]) == value, key


def test_hydraulics_refuse_what_the_fmu_bank_would_not_set():
    from ehsv.robot import Hydraulics

    config = next(iter(mjplugin.actuator_config(hydraulic_leg.MJCF).values()))
    with pytest.raises(ValueError, match="cylinder.beta"):
        Hydraulics.from_config({**config, "cylinder.beta": "1e9"})
    with pytest.raises(ValueError, match="control_mode"):
        Hydraulics.from_config({**config, "control_mode": "current"})


@pytest.mark.parametrize("example, height", [(hydraulic_leg, 0), (quadruped, 2)])
def test_the_stand_keyframe_stands(example, height):
    """What the viewer shows after Simulation > Key > Load: the robot holds its stance."""
    model = mjplugin.load_model(example.MJCF)
    data = mujoco.MjData(model)
    key = model.key("stand")
    mujoco.mj_resetDataKeyframe(model, data, key.id)
    for _ in range(2000):
        mujoco.mj_step(model, data)
    assert data.qpos[height] == pytest.approx(key.qpos[height], abs=0.01)


@pytest.mark.parametrize("timestep", [1e-3, 2e-3])
def test_leg_hops_and_lands_at_long_host_timesteps(timestep):
    """The whole leg run (stand, squat, hop, land) at the longer documented timesteps: the
    leg hops and ends standing on its command (the host-timestep table's "stable")."""
    host_timestep = pytest.importorskip("host_timestep")
    r = hydraulic_leg.run(kind="plugin", render=False, timestep=timestep)
    assert host_timestep.leg_stood(r)
    assert r.summary()["hop_trunk_rise"] > 0.03


def test_a_rod_beyond_its_travel_gives_no_force_and_one_warning():
    """A transmission that puts the rod beyond the stroke and the end stop's deepest
    penetration: the step is refused (force 0, state held), said once, no crash."""
    warnings = []
    mujoco.set_mju_user_warning(warnings.append)
    try:
        model = mujoco.MjModel.from_xml_string(MINIMAL.format(config=""))
        data = mujoco.MjData(model)
        state = data.plugin_state.copy()
        data.qpos[0] = 0.2  # 200 mm: beyond the 80 mm stroke's end
        for _ in range(5):
            mujoco.mj_step(model, data)
            data.qvel[0] = 0.0
            data.qpos[0] = 0.2
    finally:
        mujoco.set_mju_user_warning(None)
    assert data.actuator_force[0] == 0.0
    assert np.array_equal(_bits(data.plugin_state), _bits(state))
    assert len([w for w in warnings if "ehsv.actuator" in w]) == 1, warnings
