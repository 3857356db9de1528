"""Reference models written in numpy and scipy, independent of the FMU's code: the yardsticks
the tests and the examples measure the FMU against.

* the cylinder's geometry (``Cylinder``), the spring-mass end-stop penetration
  (``impact_estimate``) and the cylinder equations written again (``cylinder_derivatives``)
  integrated by scipy's solve_ivp (``cylinder_solve``; ``cylinder_reference`` at a fixed spool),
* the exact solution of the linear cases (ideal_current and voltage drivers): the state
  space of the valve (``linear_model``) and its matrix exponential (``expm``, scipy's),
  at given times or on a dense grid (``linear_step_response``,
  ``linear_step_response_dense``).

Parameters default to the FMU's own (contract.NOMINAL); pass a dict to override any.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.integrate
import scipy.linalg

from .contract import INPUTS, parameters


@dataclass(frozen=True)
class Cylinder:
    """Geometry and oil of the double-acting cylinder (rod on the B side), SI."""

    bore: float
    rod: float
    stroke: float
    mass: float
    beta: float
    v_dead: float
    k_endstop: float
    c_endstop: float
    p_tank: float
    p_cavitation: float

    @classmethod
    def from_params(cls, params: dict | None = None) -> Cylinder:
        p = parameters(params)
        return cls(
            p["cylinder.bore"],
            p["cylinder.rod"],
            p["cylinder.stroke"],
            p["cylinder.mass"],
            p["cylinder.beta"],
            p["cylinder.V_dead"],
            p["cylinder.k_endstop"],
            p["cylinder.c_endstop"],
            p["hydraulics.p_tank"],
            p["hydraulics.p_cavitation"],
        )

    @property
    def area_a(self) -> float:
        return math.pi / 4 * self.bore**2

    @property
    def area_b(self) -> float:
        return self.area_a - math.pi / 4 * self.rod**2

    def stall_force(self, p_supply: float | None = None) -> float:
        """Extension stall force (p_S - p_T) * A_A, N (p_S: the input's start value)."""
        if p_supply is None:
            p_supply = INPUTS["p_supply"][1]
        return (p_supply - self.p_tank) * self.area_a

    def volume_a(self, x):
        """Oil volume of chamber A at piston position x (0 = mid-stroke), m3."""
        return self.v_dead + self.area_a * (np.asarray(x, float) + self.stroke / 2)


def impact_estimate(v_impact: float, cyl: Cylinder | None = None, force: float = 0.0) -> float:
    """Peak end-stop penetration of a mass ``cyl.mass`` hitting the spring-damper stop
    (k_endstop, c_endstop) at ``v_impact`` with a constant ``force`` pressing it in:
    the linear damped oscillator x'' + 2 zeta w x' + w^2 x = F/m from x = 0, x' = v
    (the contact force k d + c d' stays positive until the peak, so the no-pull rule does
    not act before it). Ignores the change of the hydraulic force during the contact."""
    cyl = cyl or Cylinder.from_params()
    m, k, c = cyl.mass, cyl.k_endstop, cyl.c_endstop
    w = math.sqrt(k / m)
    z = c / (2 * math.sqrt(k * m))
    wd = w * math.sqrt(1 - z * z)
    d_static = force / k
    # x(t) = d_s + e^{-z w t} (-d_s cos(wd t) + b sin(wd t)), b = (v - z w d_s)/wd; its
    # first maximum lies within the first half period
    tt = np.linspace(0.0, math.pi / wd, 20001)
    b = (v_impact - z * w * d_static) / wd
    x = d_static + np.exp(-z * w * tt) * (-d_static * np.cos(wd * tt) + b * np.sin(wd * tt))
    return float(np.max(x))


# -- an independent reference for the cylinder: the equations of docs/model.md, solve_ivp --


def cylinder_derivatives(y, x_s: float, p_supply: float, f_ext: float, params: dict | None = None):
    """[p_A', p_B', x', v'] of the cylinder model as docs/model.md states it
    (gauge pressures; critically centred ports with the signed square root made laminar
    below dp_laminar by the C1 odd cubic; cavitation floor by fading an emptying chamber's
    bulk modulus over dp_cavitation_band; smooth Stribeck friction with tanh; end stops as
    spring-dampers that never pull; no leakage), written again here in plain Python so
    the FMU's integrator can be checked against an independent one."""
    p = parameters(params)
    cyl = Cylinder.from_params(p)
    p_a, p_b, x, v = y
    a_a, a_b, half = cyl.area_a, cyl.area_b, cyl.stroke / 2
    vol_a = max(cyl.v_dead + a_a * (x + half), 1e-3 * cyl.v_dead)
    vol_b = max(cyl.v_dead + a_b * (half - x), 1e-3 * cyl.v_dead)
    lam = p["valve.dp_laminar"]

    def rsqrt(dp):
        if abs(dp) >= lam:
            return math.copysign(math.sqrt(abs(dp)), dp)
        s = dp / lam
        return math.sqrt(lam) * s * (1.25 - 0.25 * s * s)

    pa_r, pb_r = max(p_a, cyl.p_cavitation), max(p_b, cyl.p_cavitation)
    gain = p["valve.K3"] * x_s / math.sqrt(0.5 * p["valve.dp_rated"])
    if x_s >= 0:
        q_a, q_b = gain * rsqrt(p_supply - pa_r), gain * rsqrt(pb_r - cyl.p_tank)
    else:
        q_a, q_b = gain * rsqrt(pa_r - cyl.p_tank), gain * rsqrt(p_supply - pb_r)

    def fade(pc, inflow):
        if inflow >= 0:
            return 1.0
        u = min(max((pc - cyl.p_cavitation) / p["hydraulics.dp_cavitation_band"], 0.0), 1.0)
        return u * (2 - u)

    in_a = q_a - a_a * v
    in_b = -q_b + a_b * v
    dry = p["cylinder.F_coulomb"] + (p["cylinder.F_static"] - p["cylinder.F_coulomb"]) * math.exp(
        -((v / p["cylinder.v_stribeck"]) ** 2)
    )
    friction = dry * math.tanh(v / p["cylinder.v_friction_smooth"]) + p["cylinder.b_viscous"] * v
    if x > half:
        stop = -max(cyl.k_endstop * (x - half) + cyl.c_endstop * v, 0.0)
    elif x < -half:
        stop = max(cyl.k_endstop * (-half - x) - cyl.c_endstop * v, 0.0)
    else:
        stop = 0.0
    force = p_a * a_a - p_b * a_b - friction + f_ext + stop
    return (
        cyl.beta / vol_a * in_a * fade(p_a, in_a),
        cyl.beta / vol_b * in_b * fade(p_b, in_b),
        v,
        force / cyl.mass,
    )


def cylinder_reference(
    y0,
    x_s: float,
    *,
    h: float,
    n: int,
    p_supply: float | None = None,
    f_ext: float = 0.0,
    params: dict | None = None,
    rtol: float = 1e-12,
) -> np.ndarray:
    """cylinder_derivatives integrated at a constant spool position from state y0
    = (p_A, p_B, x, v) by ``cylinder_solve``: the states at 0, h, ..., n*h (rows)."""
    t = np.arange(n + 1) * h
    return cylinder_solve(
        y0, x_s, (0.0, t[-1]), t_eval=t, p_supply=p_supply, f_ext=f_ext, params=params, rtol=rtol
    )


def cylinder_solve(
    y0,
    x_s,
    t_span,
    *,
    t_eval=None,
    p_supply: float | None = None,
    f_ext: float = 0.0,
    params: dict | None = None,
    rtol: float = 1e-12,
) -> np.ndarray:
    """cylinder_derivatives from state y0 = (p_A, p_B, x, v) over ``t_span``, the spool at
    ``x_s`` (a position, or a function of time), integrated by scipy's solve_ivp (DOP853:
    explicit Runge-Kutta of order 8 with adaptive steps, nothing shared with the FMU's
    Rodas4 and its analytic Jacobian): the states at ``t_eval`` (from its dense output),
    else at the solver's steps, the last at the span's end (rows).

    ``rtol`` applies to every state, with absolute tolerances rtol times the size of each
    (p_supply for the pressures, the stroke, 1 m/s), so a pressure crossing zero or a
    piston at rest is held to the same scale. DOP853's stability bound (lambda dt down to
    -6.4 on the real axis) allows steps of ~45 us against the model's fastest eigenvalue
    (docs/model.md: -1.4e5 1/s); the tolerance, not stability, sets its steps. The end
    stop's contact force k d + c d' starts at c v, a jump of the acceleration that the
    step control meets by rejecting steps until it is passed; compare two rtol (say 1e-10
    and 1e-12) to see the result converged."""
    if p_supply is None:
        p_supply = INPUTS["p_supply"][1]
    cyl = Cylinder.from_params(params)
    scale = np.array([p_supply, p_supply, cyl.stroke, 1.0])
    spool = x_s if callable(x_s) else (lambda _t: x_s)

    def f(t, z):
        return cylinder_derivatives(z, spool(t), p_supply, f_ext, params)

    sol = scipy.integrate.solve_ivp(
        f, t_span, np.array(y0, float), method="DOP853", t_eval=t_eval, rtol=rtol, atol=rtol * scale
    )
    if not sol.success:
        raise RuntimeError(f"cylinder_solve: solve_ivp failed: {sol.message}")
    return sol.y.T


# --------------------------------------------------------------------------------------


def expm(a: np.ndarray) -> np.ndarray:
    """Matrix exponential (scipy.linalg.expm: Pade approximation with scaling and squaring)."""
    return scipy.linalg.expm(np.asarray(a, float))


def linear_model(driver: str, p: dict | None = None):
    """State-space (A, B, names) of the linear cases with the coil current command as the
    single input u = i_ref (held constant between communication points).

    First stage (flapper): x_f'' + 2 zeta wn x_f' + wn^2 x_f = wn^2 (K1 i - Kw x_s) / Kf,
    spool: x_s' = (K2 / A_s) x_f, flow: Q = K3 x_s, wn = 2 pi f_n.
    ideal_current: i = i_ref, states (x_f, v_f, x_s).
    voltage: u = (R + R_sense) i_ref (below the rails), L i' = u - (R + R_sense) i,
    states (i, x_f, v_f, x_s).
    """
    p = parameters(p)
    wn = 2 * math.pi * p["valve.f_n"]
    z = p["valve.zeta"]
    g = wn * wn / p["valve.Kf"]
    c_spool = p["valve.K2"] / p["valve.A_s"]
    valve = np.array(
        [
            [0.0, 1.0, 0.0],
            [-wn * wn, -2 * z * wn, -g * p["valve.Kw"]],
            [c_spool, 0.0, 0.0],
        ]
    )
    torque_in = np.array([0.0, g * p["valve.K1"], 0.0])
    if driver == "ideal_current":
        return valve, torque_in, ("x_flapper", "v_flapper", "x_spool")
    if driver == "voltage":
        r = p["coil.R"] + p["coil.R_sense"]
        a = np.zeros((4, 4))
        a[0, 0] = -r / p["coil.L"]
        a[1:, 1:] = valve
        a[1:, 0] = torque_in
        b = np.array([r / p["coil.L"], 0.0, 0.0, 0.0])  # (R/L) i_ref: u/L with u = R i_ref
        return a, b, ("i_coil", "x_flapper", "v_flapper", "x_spool")
    raise ValueError(f"{driver} is not a linear case")


def augmented_linear_model(driver: str, p: dict):
    """[[A, B], [0, 0]] of linear_model: with the constant input as the last state, the
    response to a step is the top of expm(M t) applied to (0, ..., 0, u)."""
    a, b, names = linear_model(driver, p)
    n = len(a)
    m = np.zeros((n + 1, n + 1))
    m[:n, :n] = a
    m[:n, n] = b
    return m, names


def linear_step_response(driver: str, i_step: float, t, p: dict | None = None) -> dict[str, np.ndarray]:
    """Exact response to i_ref stepping from 0 to i_step at t = 0 (from rest), at times t.

    For a constant input the augmented system [[A, B], [0, 0]] has the state (x, u), so
    x(t) is the top of expm(M t) (0, ..., 0, u). Each time is evaluated directly (no
    accumulated rounding). Returns i_coil, x_flapper, x_spool and Q_valve.
    """
    p = parameters(p)
    m, names = augmented_linear_model(driver, p)
    n = len(names)
    t = np.asarray(t, float)
    x = np.empty((len(t), n))
    for k, tk in enumerate(t):
        x[k] = expm(m * tk)[:n, n] * i_step
    out = {"time": t}
    for j, name in enumerate(names):
        out[name] = x[:, j]
    if "i_coil" not in out:
        out["i_coil"] = np.where(t >= 0, i_step, 0.0)
    out["Q_valve"] = p["valve.K3"] * out["x_spool"]
    return out


def linear_step_response_dense(
    driver: str, i_step: float, dt: float, t_stop: float, p: dict | None = None
) -> dict[str, np.ndarray]:
    """Like linear_step_response on the grid k*dt, propagated with one transition matrix
    (fast for fine grids; rounding grows ~1e-16 per step)."""
    p = parameters(p)
    m, names = augmented_linear_model(driver, p)
    n = len(names)
    phi = expm(m * dt)
    steps = int(round(t_stop / dt))
    z = np.zeros(n + 1)
    z[n] = i_step
    x = np.empty((steps + 1, n))
    x[0] = 0.0
    for k in range(steps):
        z = phi @ z
        x[k + 1] = z[:n]
    t = np.arange(steps + 1) * dt
    out = {"time": t}
    for j, name in enumerate(names):
        out[name] = x[:, j]
    if "i_coil" not in out:
        out["i_coil"] = np.full(len(t), i_step)
    out["Q_valve"] = p["valve.K3"] * out["x_spool"]
    return out
