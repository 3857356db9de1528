"""Figures taken from recorded runs: settling time, time on a rail, PWM-period means,
the volume balance of chamber A."""

from __future__ import annotations

import math

import numpy as np

from .contract import parameters
from .reference import Cylinder


def settling_time(
    t, y, t_step: float, band: float, y_final: float | None = None, y_initial: float | None = None
) -> float:
    """Last time ``y`` is outside ``y_final +- band*|y_final - y_initial|``, measured from
    ``t_step`` (linear interpolation of the crossing between samples).

    y_final defaults to the last sample, y_initial to the sample at t_step (the value
    before the step). Returns inf if the last sample is still outside the band.
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    i0 = int(np.searchsorted(t, t_step - 1e-15))
    if y_initial is None:
        y_initial = y[i0]
    if y_final is None:
        y_final = y[-1]
    tol = band * abs(y_final - y_initial)
    if tol == 0:
        raise ValueError("zero step: the settling time is undefined")
    excess = np.abs(y[i0:] - y_final) - tol
    outside = np.nonzero(excess > 0)[0]
    if len(outside) == 0:
        return 0.0
    j = outside[-1] + i0
    if j == len(t) - 1:
        return math.inf
    e0, e1 = excess[j - i0], excess[j + 1 - i0]
    frac = e0 / (e0 - e1) if e0 != e1 else 0.0
    return float(t[j] + frac * (t[j + 1] - t[j]) - t_step)


def time_at_rail(t, u, t_step: float, rail: float, tol: float = 0.05) -> float:
    """Length of the first contiguous stretch after t_step during which u is within
    ``tol`` of ``rail`` (the driver output pinned at its supply)."""
    t = np.asarray(t, float)
    u = np.asarray(u, float)
    at = (np.abs(u - rail) <= tol) & (t >= t_step)
    idx = np.nonzero(at)[0]
    if len(idx) == 0:
        return 0.0
    first = idx[0]
    last = first
    while last + 1 < len(t) and at[last + 1]:
        last += 1
    return float(t[last] - t[first])


def pwm_period(params: dict | None = None) -> float:
    """PWM period of the H-bridge driver, s (1/hbridge.f_pwm)."""
    return 1.0 / parameters(params)["hbridge.f_pwm"]


def period_average(t, y, period: float):
    """Mean of ``y`` over exactly one ``period`` ending at each sample: the integral of
    the linear interpolation of the samples over [t_k - period, t_k], divided by period
    (trapezoid rule over n + 1 samples, n = period / grid step; with 1 us samples and a
    50 us PWM period, 50 intervals). ``t`` must be a uniform grid on which the period is
    a whole number of steps. Returns (t[n:], mean) -- the first full period ends at t[n].
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    h = (t[-1] - t[0]) / (len(t) - 1)
    n = int(round(period / h))
    if n < 2 or abs(n * h - period) > 1e-9 * period:
        raise ValueError(f"the period {period:g} s is not a whole number of grid steps {h:g} s")
    if not np.allclose(np.diff(t), h, rtol=1e-6, atol=0):
        raise ValueError("period_average needs a uniform time grid")
    # cumulative trapezoid integral, then differences n samples apart
    c = np.concatenate(([0.0], np.cumsum((y[1:] + y[:-1]) * 0.5)))
    return t[n:], (c[n:] - c[:-n]) / n


def volume_balance(run: dict, cyl: Cylinder | None = None) -> dict[str, float]:
    """Volume balance of chamber A over a recorded run (no leakage):
    integral of Q_A dt = A_A * (x_end - x_0) + compressed volume.

    ``inflow``: trapezoid integral of Q_A over the samples; ``displaced``: A_A * dx;
    ``compressed``: V_A(x_end)/beta * (p_A_end - p_A_0) (the end-point form);
    ``compressed_path``: trapezoid integral of V_A/beta dp_A along the run (the exact form
    when V_A changes during the run); ``residual`` and ``residual_path``: inflow minus
    displaced minus each, relative to |inflow|."""
    cyl = cyl or Cylinder.from_params()
    t, q, x, p = run["time"], run["Q_A"], run["x_piston"], run["p_A"]
    inflow = float(np.sum(0.5 * (q[1:] + q[:-1]) * np.diff(t)))
    displaced = cyl.area_a * float(x[-1] - x[0])
    compressed = float(cyl.volume_a(x[-1]) / cyl.beta * (p[-1] - p[0]))
    va = cyl.volume_a(x)
    compressed_path = float(np.sum(0.5 * (va[1:] + va[:-1]) / cyl.beta * np.diff(p)))
    return {
        "inflow": inflow,
        "displaced": displaced,
        "compressed": compressed,
        "compressed_path": compressed_path,
        "residual": (inflow - displaced - compressed) / abs(inflow),
        "residual_path": (inflow - displaced - compressed_path) / abs(inflow),
    }
