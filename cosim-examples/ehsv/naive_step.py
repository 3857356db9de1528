"""Why the FMU does not integrate the cylinder with a plain fixed step: the piston retracts
into its end stop (i_ref 0 -> -5 mA, opamp_pi) and stalls there with chamber A at its
smallest volume and the valve's port to tank open around zero pressure drop, where the
chamber's rate reaches -1.4e5 1/s. At 1e-4 s explicit Euler (what a fixed-step FMU export
does by default) takes |1 + h lambda| > 1 there; the orifice law's square root caps the
growth, so instead of overflowing the pressure swings tens of bar below the cavitation
floor, where no oil can go, and never settles. The FMU's two methods stay physical.

``retract_to_stop`` runs both methods through the FMU and explicit Euler on the cylinder
equations written independently in numpy (``reference.cylinder_derivatives``), fed the
FMU's own spool path, so the only difference is the integrator."""

from __future__ import annotations

import numpy as np

from .contract import DRIVERS, INPUTS, SOLVER_METHODS, method_params
from .reference import cylinder_derivatives
from .scenarios import run_scenario

#: the command that retracts the piston into its stop (A)
RETRACT_COMMAND = -5e-3
#: communication step and fixed step of the comparison (s)
NAIVE_H = 1e-4
#: run length (s): the stop is reached after ~60 ms, the rest shows where each settles
NAIVE_T_STOP = 0.2


def explicit_euler(y0, x_spool, h: float, p_supply: float) -> np.ndarray:
    """Explicit Euler of the cylinder from ``y0`` = (p_A, p_B, x, v), the spool held at
    ``x_spool[k]`` over step k; the states at 0, h, ... (rows)."""
    y = np.array(y0, float)
    out = [y.copy()]
    for xs in x_spool[:-1]:
        y = y + h * np.array(cylinder_derivatives(y, float(xs), p_supply, 0.0))
        out.append(y.copy())
    return np.array(out)


def retract_to_stop(version: str) -> dict[str, dict[str, np.ndarray]]:
    """The retraction through each of the FMU's methods and through explicit Euler, all at
    ``NAIVE_H``: {name: {"time", "p_A", "p_B", "x_piston"}}."""
    runs = {}
    for method in SOLVER_METHODS:
        r = run_scenario(
            version,
            h=NAIVE_H,
            t_stop=NAIVE_T_STOP,
            params={"driver": DRIVERS["opamp_pi"], **method_params(method)},
            changes={"i_ref": RETRACT_COMMAND},
        )
        runs[method] = r
    exact = runs["exact"]
    y0 = [exact[k][0] for k in ("p_A", "p_B", "x_piston", "v_piston")]
    euler = explicit_euler(y0, exact["x_spool"], NAIVE_H, INPUTS["p_supply"][1])
    runs["explicit_euler"] = {
        "time": exact["time"],
        "p_A": euler[:, 0],
        "p_B": euler[:, 1],
        "x_piston": euler[:, 2],
    }
    return {name: {k: r[k] for k in ("time", "p_A", "p_B", "x_piston")} for name, r in runs.items()}


def settled_swing(run: dict[str, np.ndarray], last: float = 0.02) -> float:
    """Peak-to-peak of p_A over the ``last`` seconds (Pa): 0 for a run that settled."""
    tail = run["time"] >= run["time"][-1] - last
    return float(np.ptp(run["p_A"][tail]))
