"""The EhsvActuator as a MuJoCo engine plugin (``ehsv.actuator``, crate mujoco-plugin/):
loading it, the robots' MJCF files (cosim-examples/mjcf/), and the host loop the examples
and tests run them with, on the plugin or, as the reference, on the FMU.

* ``load_plugin()``: ``mujoco.mj_loadPluginLibrary`` on target/release/libehsv_mujoco.so
  (``cargo build --release -p ehsv-mujoco``; EHSV_MUJOCO_PLUGIN names another path),
* ``sensor_outputs(model, data, name, actuators)``: one output of plugin actuators from
  their sensors (``<sensor><plugin instance=.../>``: each gives the FMU's outputs in the
  table's order, ``contract.OUTPUTS``; docs/mujoco.md), for a model that has them (the
  robots' files do),
* ``outputs(model, data, name, actuators)``: the same from the instances' plugin_state
  slots (the low-level path, any model: the slots hold the outputs at ``data.time``),
* ``actuator_config(path)``: each plugin actuator's ``<config>`` in an MJCF file (its
  named instance's);
  ``length_mid(path)`` and ``hydraulics(path)`` (the ``robot.Hydraulics`` the FMU bank
  gets: the same as the plugin's) from it,
* ``load_model(path, actuators, timestep, config, sensors)``: an MJCF file as written
  (plugin actuators and their sensors) or with each plugin actuator turned into a
  ``general`` force actuator on the same tendon (``actuators="fmu"``: the FMU gives the
  force through ``ctrl``),
* ``MjcfCosim``: the loop, the same for both: mj_step1 -> the command (x_ref) -> with the
  FMU: x_rod = actuator_length - length_mid, v_rod = actuator_velocity, doStep, ctrl =
  F_rod; with the plugin: ctrl = x_ref -> mj_step2 (the plugin steps inside it).

The MJCF files are the one place of the robots' geometry and hydraulics: the examples read
the levers, link lengths, joint ranges and keyframes from the loaded model (``robot``).
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .contract import OUTPUTS
from .robot import MONITORED, Hydraulics, LeverSet, Record, Timing

ROOT = Path(__file__).resolve().parents[2]
MJCF_DIR = ROOT / "cosim-examples" / "mjcf"
_loaded: list[str] = []


def plugin_path() -> Path:
    env = os.environ.get("EHSV_MUJOCO_PLUGIN")
    return Path(env) if env else ROOT / "target" / "release" / "libehsv_mujoco.so"


def plugin_missing() -> str | None:
    """None if the plugin library is built, else how to build it."""
    p = plugin_path()
    if p.exists():
        return None
    return f"{p} is not built: cargo build --release -p ehsv-mujoco"


def load_plugin() -> Path:
    """Registers ehsv.actuator with MuJoCo (once per process)."""
    import mujoco

    p = plugin_path()
    if not _loaded:
        missing = plugin_missing()
        if missing:
            raise FileNotFoundError(missing)
        mujoco.mj_loadPluginLibrary(str(p))
        _loaded.append(str(p))
    return p


#: the robots' MJCF form (cosim-examples/mjcf/): each plugin actuator's config in a named
#: instance of the plugin's ``<extension>`` entry, the actuator and a ``<sensor>`` naming it
_EXTENSION = re.compile(r"\n  <extension>.*?</extension>", re.S)
_INSTANCE = re.compile(r'<instance name="([^"]+)">(.*?)</instance>', re.S)
_PLUGIN_ACTUATOR = re.compile(r'<plugin name="([^"]+)" instance="([^"]+)" tendon="([^"]+)"([^>]*)/>')
#: the files' sensor section holds the plugin sensors alone
_SENSORS = re.compile(r"\n  <sensor>.*?</sensor>", re.S)


def mjcf_text(
    path: Path, actuators: str = "plugin", timestep: float | None = None, config: dict | None = None
) -> str:
    """The MJCF at ``path`` with the changes ``load_model`` describes."""
    text = Path(path).read_text()
    if timestep is not None:
        text = re.sub(r'(<option[^>]*timestep=")[^"]*"', rf"\g<1>{timestep!r}" + '"', text, count=1)
    if actuators == "fmu":
        text = _SENSORS.sub("", _EXTENSION.sub("", text, count=1), count=1)
        text = _PLUGIN_ACTUATOR.sub(r'<general name="\1" tendon="\3" gainprm="1" ctrllimited="false"/>', text)
    elif config:
        extra = "".join(f'\n        <config key="{k}" value="{v}"/>' for k, v in config.items())
        text = _INSTANCE.sub(
            lambda m: f'<instance name="{m[1]}">{m[2].rstrip()}{extra}\n      </instance>', text
        )
    return text


def load_model(
    path: Path,
    actuators: str = "plugin",
    timestep: float | None = None,
    config: dict | None = None,
    sensors: bool = True,
):
    """The model of the MJCF file ``path``: ``actuators`` "plugin" (as written; the plugin
    is loaded) or "fmu" (each plugin actuator a general one, gain 1, on the same tendon:
    its force is its ctrl; no plugin, so no sensors); ``timestep`` replaces the option's;
    ``config`` adds keys to every plugin instance (e.g. solver.method, substep);
    ``sensors`` False leaves the plugin sensors out."""
    import mujoco

    if actuators == "plugin":
        load_plugin()
    text = mjcf_text(path, actuators, timestep, config)
    return mujoco.MjModel.from_xml_string(text if sensors else _SENSORS.sub("", text, count=1))


def actuator_config(path: Path) -> dict[str, dict[str, str]]:
    """Each plugin actuator's config keys and values (text) in the file (its instance's),
    by actuator name."""
    text = Path(path).read_text()
    configs = {
        name: dict(re.findall(r'<config key="([^"]+)" value="([^"]*)"/>', body))
        for name, body in _INSTANCE.findall(text)
    }
    return {name: configs[instance] for name, instance, *_ in _PLUGIN_ACTUATOR.findall(text)}


def length_mid(path: Path) -> dict[str, float]:
    """Each plugin actuator's length_mid in the file (by actuator name; 0 if not set)."""
    return {name: float(cfg.get("length_mid", 0.0)) for name, cfg in actuator_config(path).items()}


def hydraulics(path: Path) -> Hydraulics:
    """The hydraulics of the file's plugin actuators, which must all be the same (the FMU
    bank sets one Hydraulics on every instance)."""
    kinds = {Hydraulics.from_config(cfg) for cfg in actuator_config(path).values()}
    if len(kinds) != 1:
        raise ValueError(f"{path}: the plugin actuators' hydraulics differ ({len(kinds)} kinds)")
    return kinds.pop()


def outputs(model, data, name: str, actuators: Sequence[int]) -> np.ndarray:
    """Output ``name`` (one of the FMU's outputs) of the plugin actuators ``actuators`` (ids),
    from their plugin_state slots: the outputs at ``data.time``, in any model."""
    k = list(OUTPUTS).index(name)
    adr = [model.plugin_stateadr[model.actuator_plugin[a]] + k for a in actuators]
    return data.plugin_state[adr].copy()


def sensor_outputs(model, data, name: str, actuators: Sequence[int]) -> np.ndarray:
    """Output ``name`` of the plugin actuators ``actuators`` (ids) from their sensors (the
    first plugin sensor on each one's instance): the outputs when the last forward pass ran,
    so after ``mj_step`` those at the step's start, like every sensor of MuJoCo (after
    ``mj_forward`` or ``mj_step1``: those at ``data.time``, as ``outputs``). A KeyError
    names an actuator without a sensor."""
    import mujoco

    k = list(OUTPUTS).index(name)
    plugin = int(mujoco.mjtSensor.mjSENS_PLUGIN)
    adr = []
    for a in actuators:
        mine = (model.sensor_type == plugin) & (model.sensor_plugin == model.actuator_plugin[a])
        if not mine.any():
            raise KeyError(f"actuator {a} has no plugin sensor")
        adr.append(model.sensor_adr[np.argmax(mine)] + k)
    return data.sensordata[adr].copy()


class MjcfCosim:
    """A robot of an MJCF file whose actuators are named after ``joints``, driven by the
    plugin (``bank`` None) or by an FMU bank (``bank``: robot.FmuBank started at x_rod = 0,
    x_ref = 0, as the plugin starts; the model from ``load_model(..., "fmu")``). The
    commands: ``controller(t, data)`` gives joint angles every ``cmd_every`` steps, turned
    into x_ref through ``levers`` (robot.lever_set: read from the model; their length_mid
    gives the FMU's x_rod from the tendon's length). Records as robot.Cosim does."""

    def __init__(self, model, data, joints: Sequence[str], levers: LeverSet, controller, bank=None):
        import mujoco

        self.mj, self.model, self.data = mujoco, model, data
        self.levers, self.controller, self.bank = levers, controller, bank
        self.act = np.array([model.actuator(j).id for j in joints])
        ids = [model.joint(j).id for j in joints]
        self.qadr = np.array([model.jnt_qposadr[i] for i in ids])
        self.lmid = levers.length_mid
        self.timing, self.rec = Timing(), Record()
        self.q_cmd = np.zeros(len(joints))
        self.kind = "plugin" if bank is None else "fmu"

    def forces(self) -> np.ndarray:
        return self.bank.F.copy() if self.bank is not None else self.data.actuator_force[self.act].copy()

    def monitor(self) -> np.ndarray:
        if self.bank is not None:
            return self.bank.monitor()
        return np.vstack([outputs(self.model, self.data, n, self.act) for n in MONITORED])

    def run(
        self, t_end: float, record_every=10, cmd_every=10, probe: Callable | None = None, stop=None
    ) -> Timing:
        mj, model, data, bank, act = self.mj, self.model, self.data, self.bank, self.act
        h = float(model.opt.timestep)
        n_steps = int(round((t_end - data.time) / h))
        rod, rec, tim, pc = self.levers.rod, self.rec, self.timing, time.perf_counter
        t_mj = t_act = 0.0
        done = 0
        xref = np.zeros(len(act))
        w0 = pc()
        for k in range(n_steps):
            t = data.time
            c0 = pc()
            mj.mj_step1(model, data)
            c1 = pc()
            if k % cmd_every == 0:
                self.q_cmd = np.array(self.controller(t, data), dtype=float)
                xref = rod(self.q_cmd)[0]
                if stop is not None and stop(data):
                    break
            done += 1
            q = data.qpos[self.qadr].copy()
            x = data.actuator_length[act] - self.lmid
            if bank is not None:
                v = data.actuator_velocity[act]
                bank.step(t, h, x.tolist(), v.tolist(), xref.tolist())
                data.ctrl[act] = bank.F
            else:
                data.ctrl[act] = xref
            c2 = pc()
            mj.mj_step2(model, data)
            c3 = pc()
            t_mj += (c1 - c0) + (c3 - c2)
            t_act += c2 - c1
            if k % record_every == 0:
                rec.t.append(t + h)
                rec.q.append(q)
                rec.q_cmd.append(self.q_cmd)
                rec.x_rod.append(x)
                rec.F.append(self.forces())
                rec.mon.append(self.monitor())
                rec.probe.append(probe(data) if probe else ())
                rec.qpos.append(data.qpos.copy())
        tim.steps += done
        tim.wall += pc() - w0
        if bank is None:  # the plugin steps inside mj_step2: MuJoCo's time includes it
            t_mj += t_act
            t_act = 0.0
        tim.mujoco += t_mj
        tim.actuators += t_act
        return tim
