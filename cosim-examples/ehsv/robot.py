"""Hydraulic robots in MuJoCo: each joint driven by one EhsvActuator cylinder through a lever.

What cosim-examples/hydraulic_leg.py and quadruped.py share:

* ``Hydraulics``: supply, relief setting, position gain and the cylinder's areas, as the
  robot's MJCF configures its plugin actuators (``from_config``); the stall and
  relief-bounded forces the rod can carry,
* ``Lever``: the cylinder's mounting, read from the model (``lever_set``): the spatial
  tendon ``<joint>_cyl`` of the actuator named after the joint runs from the base pivot (a
  site on the parent link, ``d`` from the joint's axis) to the rod end (a site on the
  child link, the lever arm ``r``). The cylinder's length is the third side of that
  triangle, ``L(q) = sqrt(dz^2 + d^2 + r^2 - 2 d r cos(q + phase))`` (dz: the pivots'
  offset along the axis), MuJoCo's tendon length, and the rod's position is
  ``x_rod = L(q) - length_mid`` (the plugin's length_mid: L at mid-stroke, where the files
  put the lever perpendicular to the cylinder: the moment arm is largest there). So
  ``v_rod = L'(q) qdot`` and the joint torque of a rod force is ``tau = F_rod L'(q)``
  (virtual work). ``LeverSet`` evaluates all of a robot's levers at once (numpy): the
  controllers' joint commands become rod commands x_ref through it,
* ``FmuBank``: the EhsvActuator FMU with its motion port (``cylinder.port`` = motion: the
  host owns the moving mass and sends ``x_rod``/``v_rod``, the FMU answers ``F_rod``),
  called through fmpy's ctypes functions on preallocated arrays, one setReal / doStep /
  getReal per actuator and step (``make_bank``); the reference the MuJoCo plugin is
  checked against (the loop that runs either is ``ehsv.mjplugin.MjcfCosim``),
* ``Timing``, ``Record``: the wall time split into MuJoCo, the actuator calls and the
  Python around them; the records of a run,
* ``smooth``: the half-cosine ramps of the examples' plans,
* ``leg_ik``: the 2-link leg's joint angles that put the foot at a point below the hip;
  ``LegKinematics``: a leg's link lengths, foot, hip position and knee bend read from the
  model, and the joint angles of a trunk height through leg_ik,
* ``render_frames``/``save_strip``: MuJoCo's offscreen renderer (MUJOCO_GL=egl or osmesa);
  where no GL context can be made they say why and the caller goes on without a picture,
* the examples' command line (``parser``: --duration, --short, --actuator, --method,
  --no-render, --out, --fmi3) and what their main() does with it (``run_example``,
  ``run_methods``: one run
  per solver.method, each reported and plotted, the two side by side with ``--method
  both``; ``report_picture``: the strip of frames or why there is none).
"""

from __future__ import annotations

import argparse
import ctypes
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import cli
from .contract import method_params
from .fmu import model_description
from .paths import fmu_path, missing_fmu_message, require_fmu

#: the FMU's variables of the motion port (cylinder.port = 1)
PORT_FORCE, PORT_MOTION = 0, 1
CONTROL_POSITION = 2
#: recorded besides F_rod, at the recording rate
MONITORED = ("p_A", "p_B", "i_coil")


# ---------------------------------------------------------------------------------------
# hydraulics and levers
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Hydraulics:
    """Supply, relief setting, position loop and cylinder geometry of every actuator, as
    the robot's MJCF configures its plugin actuators (``from_config``): the FMU bank sets
    the same values on its instances (``fmu_values``), so both run one robot."""

    p_supply: float  # Pa, input p_supply
    p_crack: float  # Pa, relief.p_crack (must be above p_supply)
    dp_override: float  # Pa, relief.dp_override
    Kp: float  # A/m, position.Kp
    C_leak: float  # m3/(s Pa), cylinder.C_leak: a bypass across the piston
    f_loop: float  # Hz, loop.f_sample: the position loop's sampling rate
    bore: float  # m, cylinder.bore
    rod: float  # m, cylinder.rod
    stroke: float  # m, cylinder.stroke

    #: each field's FMU variable (the plugin's config key)
    KEYS = {
        "p_supply": "p_supply",
        "p_crack": "relief.p_crack",
        "dp_override": "relief.dp_override",
        "Kp": "position.Kp",
        "C_leak": "cylinder.C_leak",
        "f_loop": "loop.f_sample",
        "bore": "cylinder.bore",
        "rod": "cylinder.rod",
        "stroke": "cylinder.stroke",
    }
    #: config keys that are not the FMU's parameters: the plugin's transmission, and the
    #: control mode, which must be the position loop (the FMU bank sets it: FmuBank.MODES)
    PLUGIN_KEYS = ("length_mid", "control_mode")

    @classmethod
    def from_config(cls, config: dict[str, str]) -> Hydraulics:
        """The hydraulics of a plugin actuator's ``<config>`` (key -> text). Refuses a key
        it would not hand to the FMU (the FMU-driven robot would differ from the
        plugin-driven one) and a control mode other than the position loop."""
        names = {key: name for name, key in cls.KEYS.items()}
        unknown = set(config) - set(names) - set(cls.PLUGIN_KEYS)
        if unknown:
            raise ValueError(f"config keys {sorted(unknown)}: not hydraulics the FMU bank sets")
        missing = set(names) - set(config)
        if missing:
            raise ValueError(f"config lacks {sorted(missing)}")
        if config.get("control_mode") != "position":
            raise ValueError(f"control_mode {config.get('control_mode')!r}: the robots run the position loop")
        return cls(**{names[k]: float(v) for k, v in config.items() if k in names})

    @property
    def A_A(self) -> float:
        return math.pi * self.bore**2 / 4

    @property
    def A_B(self) -> float:
        return self.A_A - math.pi * self.rod**2 / 4

    def stall_force(self) -> tuple[float, float]:
        """The largest push and pull the supply holds still (N): p_S A_A, -p_S A_B."""
        return self.p_supply * self.A_A, -self.p_supply * self.A_B

    def relief_force(self) -> tuple[float, float]:
        """The force bounds a load can drive the rod to with both chambers under their
        relief valves' crack + override (plus the other chamber at the cavitation floor)."""
        p = self.p_crack + self.dp_override
        return p * self.A_A + 0.1e6 * self.A_B, -(p * self.A_B + 0.1e6 * self.A_A)

    def fmu_values(self) -> dict:
        return {key: getattr(self, name) for name, key in self.KEYS.items()}


@dataclass(frozen=True)
class Lever:
    """A cylinder mounted across one hinge (see the module's docstring), as the model has
    it: ``d``, ``r``: the base pivot's and the rod end's distances from the joint's axis
    (m), ``dz``: their offset along it, ``phase``: the angle from the base pivot to the rod
    end about the axis at q = 0 (rad), ``length_mid``: the cylinder's length at
    mid-stroke (the plugin's config), ``joint``: the hinge's name."""

    joint: str
    d: float
    r: float
    dz: float
    phase: float
    length_mid: float

    def rod(self, q: float) -> tuple[float, float]:
        """x_rod (m from mid-stroke) and dx_rod/dq (m/rad, the moment arm) at q."""
        L = math.sqrt(self.dz**2 + self.d**2 + self.r**2 - 2 * self.d * self.r * math.cos(q + self.phase))
        return L - self.length_mid, self.d * self.r * math.sin(q + self.phase) / L

    @classmethod
    def of_tendon(cls, model, rest, tendon: int, length_mid: float) -> Lever:
        """The lever of the spatial tendon ``tendon`` (two sites: the base pivot on the
        hinge's parent body, the rod end on the hinge's body); ``rest``: an MjData with
        the model's kinematics at qpos0, where the geometry is measured."""
        base, end = _tendon_sites(model, tendon)
        body = model.site_bodyid[end]
        joint = _hinge_of(model, body)
        if model.site_bodyid[base] != model.body_parentid[body]:
            name = model.tendon(tendon).name
            raise ValueError(f"tendon {name}: its first site is not on the hinge's parent body")
        axis, anchor = rest.xaxis[joint], rest.xanchor[joint]
        b, e = rest.site_xpos[base] - anchor, rest.site_xpos[end] - anchor
        b_plane, e_plane = b - (b @ axis) * axis, e - (e @ axis) * axis
        # the angle from the base pivot to the rod end about the axis, at the joint's qpos0
        angle = math.atan2(axis @ np.cross(b_plane, e_plane), b_plane @ e_plane)
        q0 = model.qpos0[model.jnt_qposadr[joint]]
        return cls(
            joint=model.joint(joint).name,
            d=float(np.linalg.norm(b_plane)),
            r=float(np.linalg.norm(e_plane)),
            dz=float((b - e) @ axis),
            phase=angle - float(q0),
            length_mid=length_mid,
        )


class LeverSet:
    """Every lever of a robot, evaluated at once."""

    def __init__(self, levers: Sequence[Lever]):
        self.levers = tuple(levers)
        d, r = np.array([lv.d for lv in levers]), np.array([lv.r for lv in levers])
        dz = np.array([lv.dz for lv in levers])
        self.phase = np.array([lv.phase for lv in levers])
        self.length_mid = np.array([lv.length_mid for lv in levers])
        self._squares = dz**2 + d**2 + r**2
        self._2dr = 2 * d * r
        self._dr = d * r

    def rod(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x_rod and dx_rod/dq for the joint angles q (one per lever)."""
        psi = q + self.phase
        L = np.sqrt(self._squares - self._2dr * np.cos(psi))
        return L - self.length_mid, self._dr * np.sin(psi) / L


def _tendon_sites(model, tendon: int) -> tuple[int, int]:
    """The two sites of a straight spatial tendon (the drawn cylinder)."""
    import mujoco

    adr, num = model.tendon_adr[tendon], model.tendon_num[tendon]
    types = model.wrap_type[adr : adr + num]
    if num != 2 or any(t != mujoco.mjtWrap.mjWRAP_SITE for t in types):
        raise ValueError(f"tendon {model.tendon(tendon).name}: not a spatial tendon between two sites")
    return int(model.wrap_objid[adr]), int(model.wrap_objid[adr + 1])


def _hinge_of(model, body: int) -> int:
    """The one joint of ``body``, a hinge (the joint a cylinder's rod end turns about)."""
    import mujoco

    if model.body_jntnum[body] != 1 or model.jnt_type[model.body_jntadr[body]] != mujoco.mjtJoint.mjJNT_HINGE:
        raise ValueError(f"body {model.body(body).name}: a rod end's body needs one hinge joint")
    return int(model.body_jntadr[body])


def rest_kinematics(model):
    """An MjData at the model's qpos0 with its kinematics computed: where geometry is read."""
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return data


def lever_set(model, joints: Sequence[str], length_mid: dict[str, float]) -> LeverSet:
    """The levers of the actuators named after ``joints`` (each on a tendon that turns
    about that joint), with their length_mid (by actuator name)."""
    rest = rest_kinematics(model)
    levers = []
    for name in joints:
        tendon = model.actuator_trnid[model.actuator(name).id, 0]
        lever = Lever.of_tendon(model, rest, tendon, length_mid[name])
        if lever.joint != name:
            raise ValueError(f"actuator {name}'s tendon turns about joint {lever.joint}")
        levers.append(lever)
    return LeverSet(levers)


# ---------------------------------------------------------------------------------------
# the actuators: one interface, two implementations
# ---------------------------------------------------------------------------------------
def motion_port_missing(version: str = "fmi2") -> str | None:
    """None if the built archive has the motion port, else why not."""
    msg = missing_fmu_message(version)
    if msg:
        return msg
    names = {v.name for v in model_description(fmu_path(version)).modelVariables}
    lacking = [n for n in ("cylinder.port", "x_rod", "v_rod", "F_rod") if n not in names]
    if lacking:
        return (
            f"{fmu_path(version).name} has no motion port (no {', '.join(lacking)} in its "
            f"modelDescription): rebuild it from a tree that has one"
        )
    return None


#: how the figures name the actuators of each bank kind
KIND_LABEL = {"fmu": "EhsvActuator FMU", "plugin": "ehsv.actuator MuJoCo plugin"}


class ActuatorBank:
    """n actuators stepped together: ``step(t, h, x, v, x_ref)`` takes the rods' positions
    and velocities (m, m/s) at t and the position commands, advances every actuator to
    t + h and leaves the rod forces over the step in ``F`` (numpy array, N; the FMU's
    F_rod: the force's mean over the step).
    ``monitor()`` returns the MONITORED outputs, shape (len(MONITORED), n)."""

    kind = "abstract"
    n: int
    F: np.ndarray

    def step(self, t: float, h: float, x, v, x_ref) -> None:  # pragma: no cover
        raise NotImplementedError

    def monitor(self) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def close(self) -> None:
        pass


class FmuBank(ActuatorBank):
    """n instances of the EhsvActuator FMU in motion-port mode, position loop on.

    The per-step calls go straight to the archive's fmi2SetReal / fmi2DoStep /
    fmi2GetReal (fmi3SetFloat64 / fmi3DoStep / fmi3GetFloat64) through ctypes on arrays
    made once: fmpy's Python wrappers (logging, status checks, list conversions) cost
    more than the FMU's own step here. A status above Warning raises at once."""

    kind = "fmu"
    #: the port's variables: what each step sets (in this order) and reads
    INPUTS = ("x_rod", "v_rod", "x_ref")
    OUTPUT = "F_rod"
    MODES = {"cylinder.port": PORT_MOTION, "control_mode": CONTROL_POSITION}

    def __init__(self, n: int, hyd: Hydraulics, x0, x_ref0, version: str = "fmi2", extra=None):
        from .fmu import Ehsv

        self.n, self.version, self.hyd = n, version, hyd
        self.F = np.zeros(n)
        self.insts = []
        for i in range(n):
            e = Ehsv(version, instance_name=f"cyl{i}")
            self.insts.append(e)
            for name, value in {**self.MODES, **hyd.fmu_values(), **(extra or {})}.items():
                e.set(name, value)
            for name, value in zip(self.INPUTS, (x0[i], 0.0, x_ref0[i]), strict=True):
                e.set(name, float(value))
            e.initialize(start_time=0.0)
        e = self.insts[0]
        fmi2 = version == "fmi2"
        dll = e.fmu.dll
        self._set = dll.fmi2SetReal if fmi2 else dll.fmi3SetFloat64
        self._get = dll.fmi2GetReal if fmi2 else dll.fmi3GetFloat64
        self._do = dll.fmi2DoStep if fmi2 else dll.fmi3DoStep
        self._fmi2 = fmi2
        self._c = [inst.fmu.component for inst in self.insts]
        self._vr_in = (ctypes.c_uint32 * 3)(*(e.vr(k) for k in self.INPUTS))
        self._vr_F = (ctypes.c_uint32 * 1)(e.vr(self.OUTPUT))
        self._vr_mon = (ctypes.c_uint32 * len(MONITORED))(*(e.vr(k) for k in MONITORED))
        self._in = [(ctypes.c_double * 3)() for _ in range(n)]
        self._out = (ctypes.c_double * n)()
        if not fmi2:  # fmi3DoStep's four out-arguments
            self._b = [ctypes.c_bool() for _ in range(3)]
            self._last = ctypes.c_double()
        self._T, self._H = ctypes.c_double(), ctypes.c_double()
        self._calls = self._make_calls()

    def _make_calls(self):
        """One closure per actuator that does its three calls (bound locals: lean).

        The functions come from a second handle on the same library, without fmpy's
        argtypes: every argument is handed over as a ready C object (the instance pointer,
        size_t counts, the time and step size as c_double updated once per step), which
        saves ctypes' conversions, about a microsecond per actuator and step."""
        calls = []
        self._monitor_calls = []
        raw = ctypes.CDLL(self.insts[0].fmu.dll._name)  # dlopen: the same loaded library
        prefix, setter, getter = (
            ("fmi2", "SetReal", "GetReal") if self._fmi2 else ("fmi3", "SetFloat64", "GetFloat64")
        )
        set_, do_, get_ = (getattr(raw, prefix + f) for f in (setter, "DoStep", getter))
        vr_in, vr_F = self._vr_in, self._vr_F
        n3, n1 = ctypes.c_size_t(3), ctypes.c_size_t(1)
        m = len(MONITORED)
        nm, vr_mon = ctypes.c_size_t(m), self._vr_mon
        T, H = self._T, self._H
        out = self._out
        for i, comp in enumerate(self._c):
            c = ctypes.c_void_p(comp)
            buf = self._in[i]
            dst = ctypes.cast(ctypes.addressof(out) + 8 * i, ctypes.POINTER(ctypes.c_double))
            if self._fmi2:
                yes = ctypes.c_int(1)

                def call(x, v, xr, c=c, buf=buf, dst=dst, yes=yes):
                    buf[0] = x
                    buf[1] = v
                    buf[2] = xr
                    return set_(c, vr_in, n3, buf) | do_(c, T, H, yes) | get_(c, vr_F, n1, dst)

            else:
                yes = ctypes.c_bool(True)
                b0, b1, b2 = (ctypes.byref(b) for b in self._b)
                last = ctypes.byref(self._last)

                def call(x, v, xr, c=c, buf=buf, dst=dst, yes=yes, b0=b0, b1=b1, b2=b2, last=last):
                    buf[0] = x
                    buf[1] = v
                    buf[2] = xr
                    return (
                        set_(c, vr_in, n3, buf, n3)
                        | do_(c, T, H, yes, b0, b1, b2, last)
                        | get_(c, vr_F, n1, dst, n1)
                    )

            calls.append(call)

            def mon(res, c=c, off=8 * m * i):
                dst = ctypes.cast(ctypes.addressof(res) + off, ctypes.POINTER(ctypes.c_double))
                return get_(c, vr_mon, nm, dst) if self._fmi2 else get_(c, vr_mon, nm, dst, nm)

            self._monitor_calls.append(mon)
        return calls

    def step(self, t, h, x, v, x_ref) -> None:
        self._T.value = t
        self._H.value = h
        status = 0
        for call, xi, vi, ri in zip(self._calls, x, v, x_ref, strict=True):
            status |= call(xi, vi, ri)
        if status > 1:
            self._raise(t)
        self.F[:] = self._out

    def _raise(self, t):
        logs = "\n".join(f"{inst.instance_name}: {inst.log_text()}" for inst in self.insts if inst.log)
        raise RuntimeError(f"an FMU call failed at t = {t:.6g} s\n{logs}")

    def monitor(self) -> np.ndarray:
        m = len(MONITORED)
        res = (ctypes.c_double * (m * self.n))()  # actuator by actuator
        for call in self._monitor_calls:
            call(res)
        return np.ctypeslib.as_array(res).reshape(self.n, m).T.copy()

    def close(self) -> None:
        for inst in self.insts:
            inst.free()
        self.insts = []


def make_bank(
    kind: str, n: int, hyd: Hydraulics, x0, x_ref0, version: str = "fmi2", method: str = "exact"
) -> tuple[ActuatorBank, str]:
    """The FMU bank (``kind`` 'fmu') and a line saying what it is. ``method``: the FMU's
    solver.method ('exact' or 'fixed_cost')."""
    if kind != "fmu":
        raise ValueError(f"unknown actuator kind {kind!r}")
    require_fmu(version)
    bank = FmuBank(n, hyd, x0, x_ref0, version, extra=method_params(method))
    return bank, (
        f"actuators: {n} x EhsvActuator FMU ({version}, motion port, position loop, solver.method = {method})"
    )


# ---------------------------------------------------------------------------------------
# kinematics
# ---------------------------------------------------------------------------------------
def smooth(t, t0, t1, a, b):
    """a before t0, b from t1 on, a half-cosine between (t0 == t1: a step to b at t1)."""
    if t >= t1:
        return b
    if t <= t0:
        return a
    s = (t - t0) / (t1 - t0)
    return a + (b - a) * (1 - math.cos(math.pi * s)) / 2


def leg_ik(depth: float, fwd: float, L1: float, L2: float, bend: int) -> tuple[float, float]:
    """Hip flexion and knee angles (rad, hinges about +y: a positive angle swings the
    link's lower end towards -x) that put the foot ``depth`` below and ``fwd`` ahead of
    the hip. ``bend`` = +1: the knee points forwards (knee angle > 0), -1: backwards."""
    dist = math.hypot(depth, fwd)
    dist = min(dist, (L1 + L2) * 0.9999)
    c = (dist**2 - L1**2 - L2**2) / (2 * L1 * L2)
    qk = bend * math.acos(max(-1.0, min(1.0, c)))
    # foot = R(qh) [ (0,-L1) + R(qk)(0,-L2) ] in (x, z) with x' = -L sin(angle)
    phi = math.atan2(-fwd, depth)  # direction of the foot from the hip, as a hinge angle
    alpha = math.atan2(L2 * math.sin(qk), L1 + L2 * math.cos(qk))
    return phi - alpha, qk


@dataclass(frozen=True)
class LegKinematics:
    """A 2-link leg as the model has it (hip flexion and knee hinges about the trunk's y
    axis, a round foot): ``hip``, the hip axis's point in the trunk's frame (m);
    ``thigh``, hip axis to knee axis; ``shank``, knee axis to the foot's centre;
    ``foot_radius``; ``bend``, leg_ik's knee direction: the sign of the knee's joint
    range (it lies on one side of the straight leg)."""

    hip: tuple[float, float, float]
    thigh: float
    shank: float
    foot_radius: float
    bend: int

    @classmethod
    def of(cls, model, trunk: str, hip: str, knee: str, foot: str) -> LegKinematics:
        """The leg of the joints ``hip`` and ``knee`` and the sphere geom ``foot``, below
        the body ``trunk``."""
        rest = rest_kinematics(model)
        t, h, k = model.body(trunk).id, model.joint(hip).id, model.joint(knee).id
        hip_pos, knee_pos = rest.xanchor[h], rest.xanchor[k]
        foot_pos = rest.geom_xpos[model.geom(foot).id]
        in_trunk = rest.xmat[t].reshape(3, 3).T @ (hip_pos - rest.xpos[t])
        return cls(
            hip=tuple(float(c) for c in in_trunk),
            thigh=float(np.linalg.norm(knee_pos - hip_pos)),
            shank=float(np.linalg.norm(foot_pos - knee_pos)),
            foot_radius=float(model.geom(foot).size[0]),
            bend=int(np.sign(model.jnt_range[k].sum())),
        )

    def angles(self, height: float) -> tuple[float, float]:
        """Hip flexion and knee angles that put the foot on the ground under the hip with
        the trunk level and its origin ``height`` above the ground (a foot lifted by l:
        ``height - l``)."""
        depth = height + self.hip[2] - self.foot_radius
        return leg_ik(depth, 0.0, self.thigh, self.shank, self.bend)


# ---------------------------------------------------------------------------------------
# the co-simulation loop
# ---------------------------------------------------------------------------------------
@dataclass
class Timing:
    steps: int = 0
    wall: float = 0.0
    mujoco: float = 0.0
    actuators: float = 0.0

    @property
    def python(self) -> float:
        return self.wall - self.mujoco - self.actuators

    def line(self, t_sim: float, n_act: int, kind: str = "fmu") -> str:
        us = 1e6 / max(self.steps, 1)
        head = (
            f"wall {self.wall:.2f} s for {t_sim:.2f} s simulated: real-time factor "
            f"{t_sim / self.wall:.2f} (> 1 is faster than real time); per step {self.wall * us:.1f} us = "
        )
        if kind == "plugin":
            inside = f"MuJoCo with {n_act} plugin actuators {self.mujoco * us:.1f}"
            return head + f"{inside} + Python {self.python * us:.1f}"
        return head + (
            f"MuJoCo {self.mujoco * us:.1f} + actuators ({n_act} x set/doStep/get) "
            f"{self.actuators * us:.1f} + Python {self.python * us:.1f}"
        )


@dataclass
class Record:
    t: list = field(default_factory=list)
    q: list = field(default_factory=list)
    q_cmd: list = field(default_factory=list)
    x_rod: list = field(default_factory=list)
    F: list = field(default_factory=list)
    mon: list = field(default_factory=list)
    probe: list = field(default_factory=list)
    qpos: list = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        keys = ("t", "q", "q_cmd", "x_rod", "F", "probe", "qpos")
        out = {k: np.asarray(getattr(self, k)) for k in keys}
        m = np.asarray(self.mon)  # (samples, len(MONITORED), n)
        for j, name in enumerate(MONITORED):
            out[name] = m[:, j, :]
        return out


def _as_slice(idx: np.ndarray):
    """A slice for consecutive indices (a view: cheaper than fancy indexing), else idx."""
    if len(idx) and np.all(np.diff(idx) == 1):
        return slice(int(idx[0]), int(idx[-1]) + 1)
    return idx


# ---------------------------------------------------------------------------------------
# pictures
# ---------------------------------------------------------------------------------------
def gl_backend() -> str:
    """The MUJOCO_GL in force, set to 'egl' when unset (must run before mujoco's import)."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    if os.environ["MUJOCO_GL"] in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])
    return os.environ["MUJOCO_GL"]


class Camera:
    """MuJoCo's offscreen renderer with a free camera; ``snap(data)`` returns an RGB
    array. ``error`` says why there is no renderer (no GL context could be made)."""

    def __init__(self, model, width=480, height=480, lookat=(0, 0, 0.4), distance=1.8, azimuth=90, elev=-12):
        import mujoco

        self.mj = mujoco
        self.renderer = None
        self.error = None
        try:
            self.renderer = mujoco.Renderer(model, height, width)
        except Exception as exc:  # noqa: BLE001 -- any GL failure means: no picture
            self.error = f"{type(exc).__name__}: {exc}".strip().splitlines()[0]
            return
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = lookat
        cam.distance, cam.azimuth, cam.elevation = distance, azimuth, elev
        self.cam = cam

    def snap(self, data, track_body_pos=None) -> np.ndarray:
        if track_body_pos is not None:
            self.cam.lookat[:2] = track_body_pos[:2]
        self.renderer.update_scene(data, camera=self.cam)
        return self.renderer.render().copy()

    def at(self, model, qpos: np.ndarray, track_body: int | None = None) -> np.ndarray:
        """The picture of the model in the pose ``qpos`` (a recorded state)."""
        data = self.mj.MjData(model)
        data.qpos[:] = qpos
        self.mj.mj_forward(model, data)
        return self.snap(data, None if track_body is None else data.xpos[track_body])

    def capture(self, model, r, times: dict[float, str], track_body: int | None = None) -> None:
        """Appends to the run ``r`` (its ``t``, ``rec["qpos"]``, ``frames``, ``frame_labels``)
        the recorded pose nearest after each time of ``times`` (label by time), in time
        order, captioned with its time and label; closes the renderer."""
        try:
            for t, label in sorted(times.items()):
                k = min(int(np.searchsorted(r.t, t)), len(r.t) - 1)
                r.frames.append(self.at(model, r.rec["qpos"][k], track_body=track_body))
                r.frame_labels.append(f"{r.t[k]:.2f} s: {label}")
        finally:
            self.close()

    def close(self):
        if self.renderer is not None:
            self.renderer.close()


def save_strip(images: Sequence[np.ndarray], labels: Sequence[str], out) -> None:
    """The frames side by side with a caption each, written as PNG."""
    from .plotting import pyplot

    plt = pyplot()
    n = len(images)
    h, w = images[0].shape[:2]
    fig, axes = plt.subplots(1, n, figsize=(2.6 * n * w / h, 2.9), squeeze=False)
    for ax, img, lab in zip(axes[0], images, labels, strict=True):
        ax.imshow(img)
        ax.set_title(lab, fontsize=9)
        ax.axis("off")
    fig.tight_layout(pad=0.3)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)


# ---------------------------------------------------------------------------------------
# the examples' command line and main()
# ---------------------------------------------------------------------------------------
#: --method: the FMU's solver.method, or both one after the other
METHOD_CHOICES = ("exact", "fixed_cost", "both")


def parser(doc: str, duration: float, short: str, out: str) -> argparse.ArgumentParser:
    """A robot example's command line: --fmi3, --duration (default ``duration`` s),
    --short (help ``short``), --actuator, --method, --no-render, --out (default
    out/``out``)."""
    ap = cli.parser(doc)
    ap.add_argument(
        "--duration", type=float, default=duration, help=f"simulated time, s (default {duration:g})"
    )
    ap.add_argument("--short", action="store_true", help=short)
    ap.add_argument(
        "--actuator",
        choices=("plugin", "fmu"),
        default="plugin",
        help="the ehsv.actuator MuJoCo plugin (default) or the FMU on the same tendons (the reference)",
    )
    ap.add_argument("--timestep", type=float, default=None, help="MuJoCo's timestep, s (the MJCF's: 1e-4)")
    ap.add_argument(
        "--method",
        choices=METHOD_CHOICES,
        default="exact",
        help="the FMU's solver.method; both: the same run with each, figures side by side (default exact)",
    )
    ap.add_argument("--no-render", action="store_true", help="no MuJoCo picture")
    ap.add_argument("--out", type=Path, default=cli.OUT_DIR / out)
    return ap


def methods(choice: str) -> tuple[str, ...]:
    """The solver.method of each run --method asks for."""
    return ("exact", "fixed_cost") if choice == "both" else (choice,)


def timing_figures(timing: Timing, t_sim: float) -> dict[str, str]:
    """The cost of a run as figures for ``side_by_side``."""
    us = 1e6 / max(timing.steps, 1)
    return {
        "wall real-time factor": f"{t_sim / timing.wall:.2f}",
        "wall per step, us": f"{timing.wall * us:.1f}",
        "actuators (set/doStep/get) per step, us": f"{timing.actuators * us:.1f}",
        "actuators' share of the step": f"{100 * timing.actuators / timing.wall:.0f} %",
    }


def side_by_side(columns: dict[str, dict[str, str]]) -> None:
    """Prints figures (label -> text) of several runs, one column per run."""
    labels = list(dict.fromkeys(k for col in columns.values() for k in col))
    width = max(len(k) for k in labels)
    print(f"{'':{width}}  " + "  ".join(f"{name:>14}" for name in columns))
    for k in labels:
        print(f"{k:{width}}  " + "  ".join(f"{col.get(k, '-'):>14}" for col in columns.values()))


def report_picture(args, r) -> None:
    """Writes the run's strip of frames next to args.out, or says why there is none."""
    if args.no_render:
        print("picture: skipped (--no-render)")
    elif r.render_error:
        print(f"picture: skipped, no OpenGL context (MUJOCO_GL={gl_backend()}): {r.render_error}")
    elif r.frames:
        out = args.out.with_name(args.out.stem + "_render.png")
        save_strip(r.frames, r.frame_labels, out)
        print(f"picture: {out}")


def run_example(args, run: Callable, report: Callable, plot: Callable, figures: Callable) -> dict | None:
    """A robot example's main() on its parsed ``args``: ``run(duration, short, actuator,
    version, render=, method=)`` through ``run_methods``. None (after saying how to build
    it) when --actuator fmu asks for an archive that is not built."""
    version = cli.version(args)
    if args.actuator == "fmu" and cli.archive_missing(version):
        return None
    if args.actuator == "plugin":
        from .mjplugin import plugin_missing

        if plugin_missing():
            print(plugin_missing())
            return None

    def one(method, render):
        kind, h = args.actuator, args.timestep
        return run(args.duration, args.short, kind, version, render=render, method=method, timestep=h)

    return run_methods(args, one, report, plot, figures)


def run_methods(args, run: Callable, report: Callable, plot: Callable, figures: Callable) -> dict:
    """``run(method, render)`` once per method of --method, each ``report``-ed and
    ``plot``-ted (the fixed_cost run of ``both`` to args.out's name + _fixed_cost), the first
    run's picture, and with ``both`` the runs' cost (timing_figures) and ``figures(run)``
    side by side. Returns {method: run}."""
    chosen = methods(args.method)
    runs = {}
    for i, method in enumerate(chosen):
        if len(chosen) > 1:
            print(f"== solver.method = {method}")
        r = runs[method] = run(method, render=not args.no_render and i == 0)
        report(r)
        out = args.out if i == 0 else args.out.with_name(f"{args.out.stem}_{method}{args.out.suffix}")
        plot(r, out)
    report_picture(args, next(iter(runs.values())))
    if len(runs) > 1:
        print("== side by side")
        side_by_side({m: {**timing_figures(r.timing, r.t_end), **figures(r)} for m, r in runs.items()})
    return runs
