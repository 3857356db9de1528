"""The actuator coupled to a rigid mass by a host of our own, the plainest co-simulation
loop a multibody simulator runs, against the same system simulated as one FMU.

The host owns the mass ``M`` on the rod and integrates it with semi-implicit Euler; the
FMU (``cylinder.port = motion``) takes the rod's motion and returns ``F_rod``, the mean
force of the actuator on the rod over the step::

    set x_rod, v_rod (and x_ref)   ->   doStep(t, h)   ->   get F_rod
    a = (F_rod + F_load) / M;  v += h a;  x += h v

The reference is the FMU alone with ``cylinder.port = force`` and ``cylinder.mass = M``
under ``F_ext = F_load``. Both run the position loop on ``x_ref``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .contract import SOLVER_METHODS
from .fmu import Ehsv

#: Outputs are compared at this interval (s): a multiple of every step size used.
SAMPLE = 1e-3

#: A reference signal: ``t -> (x_ref in m, load on the rod in N, + = extension)``.
Signal = Callable[[float], tuple[float, float]]


def position_step(t: float) -> tuple[float, float]:
    """The position loop takes the piston 0 -> 5 mm at t = 0, no load."""
    return 5e-3, 0.0


def gait(t: float) -> tuple[float, float]:
    """A leg's stride: 15 mm at 2 Hz plus a second harmonic; a 1.5 kN half-sine touchdown
    load pushing the rod in during the first half of each 0.5 s period (0 at t = 0)."""
    w = 2 * math.pi / 0.5
    x_ref = 15e-3 * math.sin(w * t) + 3e-3 * math.sin(2 * w * t + 0.5) - 3e-3 * math.sin(0.5)
    phase = t % 0.5
    load = -1500.0 * math.sin(math.pi * phase / 0.25) if phase < 0.25 else 0.0
    return x_ref, load


SIGNALS: dict[str, Signal] = {"position_step": position_step, "gait": gait}


@dataclass
class Trace:
    """Piston position (m) at every multiple of :data:`SAMPLE`, from t = SAMPLE."""

    x: np.ndarray


def _samples(duration: float, h: float) -> tuple[int, int]:
    steps = round(duration / h)
    every = round(SAMPLE / h)
    if abs(every * h - SAMPLE) > 1e-12 or abs(steps * h - duration) > 1e-12:
        raise ValueError(f"step {h} must divide {SAMPLE} and {duration}")
    return steps, every


def run_coupled(
    version: str,
    mass: float,
    h: float,
    duration: float,
    signal: Signal,
    input_derivatives: bool = False,
    method: str | None = None,
) -> Trace:
    """The host loop above; with ``input_derivatives`` the host also gives the rod's
    acceleration (its last one) as the derivative of v_rod (FMI 2 only); ``method``: the
    FMU's solver.method by name ('exact', 'fixed_cost'; None: the default)."""
    fmu = Ehsv(version)
    settings = {"cylinder__port": 1, "control_mode": 2}
    if method is not None:
        settings["solver__method"] = SOLVER_METHODS[method]
    fmu.initialize(**settings)
    vrs = [fmu.vr(n) for n in ("x_rod", "v_rod", "x_ref")]
    f_rod = [fmu.vr("F_rod")]
    v_rod = [fmu.vr("v_rod")]
    steps, every = _samples(duration, h)
    out = np.empty(steps // every)
    x = v = a = 0.0
    for k in range(steps):
        t = k * h
        x_ref, load = signal(t)
        fmu._set_real(vrs, [x, v, x_ref])
        if input_derivatives:
            fmu.fmu.setRealInputDerivatives(v_rod, [1], [a])
        fmu.do_step(t, h)
        force = fmu._get_real(f_rod)[0]
        a = (force + load) / mass
        v += h * a
        x += h * v
        if (k + 1) % every == 0:
            out[(k + 1) // every - 1] = x
    fmu.free()
    return Trace(out)


def run_monolithic(version: str, mass: float, h: float, duration: float, signal: Signal) -> Trace:
    """The same system as one FMU: the load mass inside, the load as F_ext."""
    fmu = Ehsv(version)
    fmu.initialize(cylinder__mass=mass, control_mode=2)
    vrs = [fmu.vr(n) for n in ("x_ref", "F_ext")]
    x_piston = [fmu.vr("x_piston")]
    steps, every = _samples(duration, h)
    out = np.empty(steps // every)
    for k in range(steps):
        t = k * h
        fmu._set_real(vrs, list(signal(t)))
        fmu.do_step(t, h)
        if (k + 1) % every == 0:
            out[(k + 1) // every - 1] = fmu._get_real(x_piston)[0]
    fmu.free()
    return Trace(out)


def difference(coupled: Trace, reference: Trace) -> float:
    """Largest difference in x_piston as a fraction of the reference's motion (inf if the
    coupled run left the numbers)."""
    if not np.all(np.isfinite(coupled.x)):
        return math.inf
    motion = float(np.ptp(reference.x))
    return float(np.max(np.abs(coupled.x - reference.x))) / motion


def order(errors: list[float], ratio: float = 10.0) -> list[float]:
    """Measured orders of convergence between successive step sizes ``ratio`` apart."""
    return [
        math.log(e0 / e1) / math.log(ratio) if e0 > 0 and e1 > 0 else math.nan
        for e0, e1 in zip(errors, errors[1:], strict=False)
    ]
