"""Hydraulic robots in MuJoCo: each joint driven by one EhsvActuator cylinder through a lever.

What cosim-examples/hydraulic_leg.py and quadruped.py share:

* ``Hydraulics``: supply, relief setting, position gain and the cylinder's areas; the
  stall and relief-bounded forces the rod can carry,
* ``Lever``: the cylinder's mounting. Its base pivot sits on the parent link at ``d`` from
  the joint, its rod end on the child link at the lever arm ``r``; the cylinder's length
  is the third side of that triangle, ``L(q) = sqrt(d^2 + r^2 - 2 d r cos psi(q))`` with
  ``psi = pi/2 + sign (q - q_mid)``, so the lever is perpendicular to the cylinder (the
  moment arm is largest, ~r) at ``q_mid``, which is mapped to mid-stroke:
  ``x_rod = L(q) - L(q_mid)``, ``v_rod = L'(q) qdot`` and the joint torque of a rod force
  is ``tau = F_rod L'(q)`` (virtual work). ``LeverSet`` evaluates all of a robot's levers
  at once (numpy),
* ``FmuBank``: the EhsvActuator FMU with its motion port (``cylinder.port`` = motion: the
  host owns the moving mass and sends ``x_rod``/``v_rod``, the FMU answers ``F_rod``),
  called through fmpy's ctypes functions on preallocated arrays, one setReal / doStep /
  getReal per actuator and step (``make_bank``); the reference the MuJoCo plugin is
  checked against (the loop that runs either is ``ehsv.mjplugin.MjcfCosim``),
* ``Timing``, ``Record``: the wall time split into MuJoCo, the actuator calls and the
  Python around them; the records of a run,
* ``smooth``: the half-cosine ramps of the examples' plans,
* ``leg_ik``: the 2-link leg's joint angles that put the foot at a point below the hip,
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
    """Supply, relief setting, position loop and cylinder geometry of every actuator."""

    p_supply: float = 16e6  # Pa, input p_supply
    p_crack: float = 21e6  # Pa, relief.p_crack (must be above p_supply)
    dp_override: float = 1e6  # Pa, relief.dp_override (the FMU's default)
    Kp: float = 0.6  # A/m, position.Kp (0.6 mA per mm)
    C_leak: float = 1e-12  # m3/(s Pa), cylinder.C_leak: a bypass across the piston
    f_loop: float = 10e3  # Hz, loop.f_sample: the position loop sampled at the host's 1e-4 s
    bore: float = 0.016
    rod: float = 0.010
    stroke: float = 0.08

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
        return {
            "cylinder.bore": self.bore,
            "cylinder.rod": self.rod,
            "cylinder.stroke": self.stroke,
            "relief.p_crack": self.p_crack,
            "relief.dp_override": self.dp_override,
            "position.Kp": self.Kp,
            "cylinder.C_leak": self.C_leak,
            "loop.f_sample": self.f_loop,
            "p_supply": self.p_supply,
        }


@dataclass(frozen=True)
class Lever:
    """A cylinder mounted across one joint (see the module's docstring).

    ``d``: base pivot's distance from the joint on the parent link (m), ``r``: the lever
    arm on the child link (m), ``q_mid``: the joint angle at mid-stroke (rad, the lever
    perpendicular to the cylinder), ``sign``: +1 when the rod extends as q grows.
    ``base_angle``: the direction of the base pivot from the joint in the parent's frame,
    measured in the joint's plane (only for drawing the cylinder; the physics needs d, r,
    q_mid and sign)."""

    d: float
    r: float
    q_mid: float
    sign: int
    base_angle: float = 0.0

    @property
    def L_mid(self) -> float:
        return math.hypot(self.d, self.r)

    def rod(self, q: float) -> tuple[float, float]:
        """x_rod (m from mid-stroke) and dx_rod/dq (m/rad, the moment arm) at q."""
        psi = math.pi / 2 + self.sign * (q - self.q_mid)
        L = math.sqrt(self.d**2 + self.r**2 - 2 * self.d * self.r * math.cos(psi))
        return L - self.L_mid, self.sign * self.d * self.r * math.sin(psi) / L

    def rod_end_angle(self) -> float:
        """The lever's direction in the child's frame (same angle convention as
        base_angle), so that the angle between base and rod end is psi."""
        return self.base_angle + self.sign * math.pi / 2 - self.q_mid

    def joint_range(self, stroke: float, margin: float = 0.002) -> tuple[float, float]:
        """The joint angles between which the rod stays ``margin`` inside its stroke
        (searched on a grid over |q - q_mid| < pi)."""
        q = self.q_mid + np.linspace(-math.pi * 0.999, math.pi * 0.999, 20001)
        x = np.array([self.rod(float(a))[0] for a in q])
        ok = np.abs(x) <= stroke / 2 - margin
        i0 = len(q) // 2
        lo = i0
        while lo > 0 and ok[lo - 1]:
            lo -= 1
        hi = i0
        while hi < len(q) - 1 and ok[hi + 1]:
            hi += 1
        return float(q[lo]), float(q[hi])


class LeverSet:
    """Every lever of a robot, evaluated at once."""

    def __init__(self, levers: Sequence[Lever]):
        self.levers = tuple(levers)
        self.d = np.array([lv.d for lv in levers])
        self.r = np.array([lv.r for lv in levers])
        self.q_mid = np.array([lv.q_mid for lv in levers])
        self.sign = np.array([float(lv.sign) for lv in levers])
        self._dd_rr = self.d**2 + self.r**2
        self._2dr = 2 * self.d * self.r
        self._sdr = self.sign * self.d * self.r
        self._L_mid = np.sqrt(self._dd_rr)
        self._offset = math.pi / 2 - self.sign * self.q_mid

    def rod(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x_rod and dx_rod/dq for the joint angles q (one per lever)."""
        psi = self.sign * q + self._offset
        L = np.sqrt(self._dd_rr - self._2dr * np.cos(psi))
        return L - self._L_mid, self._sdr * np.sin(psi) / L


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
# MJCF helpers and pictures
# ---------------------------------------------------------------------------------------
def planar(angle: float, length: float, axis: str) -> tuple[float, float, float]:
    """A point at ``length`` from a hinge about ``axis`` ('x' or 'y') in the direction
    ``angle`` (0 = +z; a positive angle is where a positive hinge rotation turns +z)."""
    if axis == "y":
        return (length * math.sin(angle), 0.0, length * math.cos(angle))
    return (0.0, -length * math.sin(angle), length * math.cos(angle))


def fmt(v: Sequence[float]) -> str:
    return " ".join(f"{c:.6g}" for c in v)


def cylinder_sites(
    name: str, lever: Lever, axis: str, joint_pos=(0.0, 0.0, 0.0), side: float = 0.0
) -> tuple[str, str]:
    """MJCF of the two sites (base pivot in the parent body, relative to the joint at
    ``joint_pos``; rod end in the child body, whose origin is the joint), both moved by
    ``side`` along the joint's axis (the cylinder beside the links: same length)."""
    k = 1 if axis == "y" else 0
    b = list(planar(lever.base_angle, lever.d, axis))
    e = list(planar(lever.rod_end_angle(), lever.r, axis))
    b[k] += side
    e[k] += side
    base = tuple(j + c for j, c in zip(joint_pos, b, strict=True))
    return (
        f'<site name="{name}_base" pos="{fmt(base)}" size="0.012" rgba=".3 .3 .35 1"/>',
        f'<site name="{name}_end" pos="{fmt(e)}" size="0.01" rgba=".75 .75 .8 1"/>',
    )


def cylinder_tendon(name: str) -> str:
    """A spatial tendon between the two sites: drawn as the cylinder; its length is the
    lever's L(q), a check of the geometry (no stiffness: no force)."""
    return (
        f'<spatial name="{name}" width="0.013" rgba=".9 .55 .1 1">'
        f'<site site="{name}_base"/><site site="{name}_end"/></spatial>'
    )


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


def scene_head(name: str, texrepeat: int, light: str, light_dir: str, floor: float) -> str:
    """The MJCF both robots open with: compiler, the 1e-4 s Euler step of the coupling
    loop, the look (checker floor, sky, one light) and the floor they stand on."""
    return f"""<mujoco model="{name}">
  <compiler angle="radian"/>
  <extension><plugin plugin="ehsv.actuator"/></extension>
  <option timestep="1e-4" integrator="Euler"/>
  <visual><global offwidth="800" offheight="800"/><quality shadowsize="2048"/></visual>
  <asset>
    <texture name="grid" type="2d" builtin="checker" rgb1=".82 .84 .86" rgb2=".70 .72 .75"
             width="256" height="256"/>
    <material name="grid" texture="grid" texrepeat="{texrepeat} {texrepeat}" reflectance="0"/>
    <texture name="sky" type="skybox" builtin="gradient" rgb1=".95 .97 1" rgb2=".75 .8 .9"
             width="256" height="256"/>
  </asset>
  <default>
    <joint armature="0.002" damping="0.05"/>
    <geom contype="0" conaffinity="0"/>
    <default class="link"><geom rgba=".25 .45 .7 1"/></default>
  </default>
  <worldbody>
    <light pos="{light}" dir="{light_dir}" diffuse=".8 .8 .8" castshadow="true"/>
    <geom name="floor" type="plane" size="{floor} {floor} 0.05" material="grid" contype="1" conaffinity="1"
          friction="1 0.005 0.0001" solref="0.004 1"/>"""


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
