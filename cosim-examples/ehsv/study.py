"""Parameter studies: a design over named FMU parameters and inputs, one FMU run per
point, the metrics of each run in one tidy table (one row per point).

Factors (``parse_factor``), written as on the command line:

* ``V_supply=10:72``: a range (``:log`` appended for log spacing),
* ``driver=opamp_pi,industrial`` or ``flow.Kp=1,2,4``: levels,
* ``valve.K3=5%``: the default value +-5 % (tolerances, Monte Carlo with ``lhs``).

Designs (``design``): ``grid`` crosses every level of every factor, a range giving
``points`` evenly spaced values; ``lhs`` crosses the level factors and draws ``points``
Latin hypercube samples of the ranges for each combination (numpy, seeded).

Scenarios (``SCENARIOS``): ``current_step`` (i_ref 0 -> 5 mA at t = 0 from rest) and
``flow_step`` (control_mode 1, Q_ref 0 -> 2e-4 m3/s). Metrics (``METRICS``): settling
times, overshoot, rise time, an equivalent bandwidth, the driver's peak voltage, ...
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from itertools import product

import numpy as np

from .bands import FLOW_STEP, PAPER_STEP
from .contract import CONTROL_MODES, DRIVERS, INPUTS, NOMINAL, PWM_DRIVERS, flow_gain
from .measures import period_average, pwm_period, settling_time
from .scenarios import run_scenario

# --------------------------------------------------------------------------------------
# Factors and designs
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Factor:
    """One varied parameter or input: a range (lo, hi, log) or a tuple of levels."""

    name: str
    lo: float = math.nan
    hi: float = math.nan
    log: bool = False
    levels: tuple = ()

    @property
    def is_range(self) -> bool:
        return not self.levels

    def spaced(self, n: int) -> list:
        """n evenly spaced values of a range (log-spaced if ``log``)."""
        if n == 1:
            return [math.sqrt(self.lo * self.hi) if self.log else 0.5 * (self.lo + self.hi)]
        if self.log:
            return list(np.geomspace(self.lo, self.hi, n))
        return list(np.linspace(self.lo, self.hi, n))

    def scale(self, u: np.ndarray) -> np.ndarray:
        """Maps u in [0, 1) onto the range."""
        if self.log:
            return self.lo * (self.hi / self.lo) ** u
        return self.lo + (self.hi - self.lo) * u


def default_value(name: str) -> float:
    """The FMU's start value of a parameter or input."""
    if name in NOMINAL:
        return float(NOMINAL[name])
    if name in INPUTS:
        return INPUTS[name][1]
    raise KeyError(f"the FMU has no parameter or input {name!r}")


def parse_factor(text: str) -> Factor:
    """``name=lo:hi[:log]``, ``name=a,b,c`` or ``name=P%`` (see the module docstring)."""
    name, sep, spec = text.partition("=")
    name, spec = name.strip(), spec.strip()
    if not sep or not name or not spec:
        raise ValueError(f"{text!r}: expected name=lo:hi[:log], name=a,b,c or name=P%")
    if spec.endswith("%"):
        nominal = default_value(name)
        rel = float(spec.rstrip("%").lstrip("+-±")) / 100
        return Factor(name, nominal * (1 - rel), nominal * (1 + rel))
    if ":" in spec:
        parts = spec.split(":")
        log = parts[-1] == "log"
        lo, hi = (float(x) for x in parts[: 2 if log else None][:2])
        return Factor(name, lo, hi, log=log)
    levels = tuple(_level(x.strip()) for x in spec.split(","))
    return Factor(name, levels=levels)


def _level(text: str):
    try:
        return float(text)
    except ValueError:
        return text  # an enumeration item by name (driver=opamp_pi)


def latin_hypercube(n: int, d: int, seed: int) -> np.ndarray:
    """n points in [0, 1)^d, one in each of the n strata of every axis, stratum order
    shuffled per axis, uniform within the stratum."""
    rng = np.random.default_rng(seed)
    u = (np.arange(n)[:, None] + rng.random((n, d))) / n
    for j in range(d):
        u[:, j] = u[rng.permutation(n), j]
    return u


def design(factors: list[Factor], points: int, kind: str = "grid", seed: int = 1) -> list[dict]:
    """The points of the study: dicts factor name -> value, in a fixed order."""
    levels = [f for f in factors if not f.is_range]
    ranges = [f for f in factors if f.is_range]
    combos = list(product(*(f.levels for f in levels))) or [()]
    out = []
    for k, combo in enumerate(combos):
        fixed = {f.name: v for f, v in zip(levels, combo, strict=True)}
        if not ranges:
            out.append(fixed)
        elif kind == "grid":
            for values in product(*(f.spaced(points) for f in ranges)):
                out.append({**fixed, **{f.name: float(v) for f, v in zip(ranges, values, strict=True)}})
        elif kind == "lhs":
            u = latin_hypercube(points, len(ranges), seed + k)
            for row in u:
                out.append({**fixed, **{f.name: float(f.scale(x)) for f, x in zip(ranges, row, strict=True)}})
        else:
            raise ValueError(f"unknown design {kind!r} (grid or lhs)")
    return out


# --------------------------------------------------------------------------------------
# Scenarios and metrics
# --------------------------------------------------------------------------------------

STEP_OUTPUTS = ("i_coil", "u_driver", "driver_saturated", "Q_valve")


@dataclass(frozen=True)
class Scenario:
    """A step of one input at t = 0 from rest: what changes, what the outputs settle to."""

    name: str
    control_mode: str
    change: str  # the stepped input
    step: float  # its new value
    h: float  # s, communication step
    t_stop: float  # s

    def targets(self, values: dict) -> tuple[float, float]:
        """(i_coil, Q_valve) the run settles to."""
        if self.change == "i_ref":
            return self.step, flow_gain(values) * self.step
        return self.step / flow_gain(values), self.step


SCENARIOS = {
    "current_step": Scenario("current_step", "current", "i_ref", PAPER_STEP, 2e-6, 20e-3),
    "flow_step": Scenario("flow_step", "flow", "Q_ref", FLOW_STEP, 10e-6, 30e-3),
}


def _overshoot(y, target: float) -> float:
    return float(max(0.0, (np.max(y) - target) / abs(target)) * 100) if target else math.nan


def _rise(t, y, target: float) -> float:
    """10-90 % rise time, s (nan if it never gets there)."""
    above10, above90 = np.nonzero(y >= 0.1 * target)[0], np.nonzero(y >= 0.9 * target)[0]
    if len(above10) == 0 or len(above90) == 0:
        return math.nan
    return float(t[above90[0]] - t[above10[0]])


#: metric name -> (description, function of (run, i_target, q_target, mean current))
METRICS = {
    "settling_i": ("2 % settling time of i_coil (PWM: period mean), s",
                   lambda r, it, qt, im: settling_time(im[0], im[1], 0.0, 0.02, it, 0.0)),
    "settling_q": ("5 % settling time of Q_valve, s",
                   lambda r, it, qt, im: settling_time(r["time"], r["Q_valve"], 0.0, 0.05, qt, 0.0)),
    "overshoot_i": ("overshoot of i_coil (PWM: period mean), %",
                    lambda r, it, qt, im: _overshoot(im[1], it)),
    "overshoot_q": ("overshoot of Q_valve, %", lambda r, it, qt, im: _overshoot(r["Q_valve"], qt)),
    "rise_q": ("10-90 % rise time of Q_valve, s", lambda r, it, qt, im: _rise(r["time"], r["Q_valve"], qt)),
    "bandwidth_q": ("first-order equivalent bandwidth 0.35 / rise_q, Hz",
                    lambda r, it, qt, im: 0.35 / _rise(r["time"], r["Q_valve"], qt)),
    "u_peak": ("largest |u_driver|, V", lambda r, it, qt, im: float(np.max(np.abs(r["u_driver"])))),
    "t_rail": ("time the driver spends at a rail (sampled), s",
               lambda r, it, qt, im: float(np.count_nonzero(r["driver_saturated"][1:]) * r["time"][1])),
    "q_final": ("Q_valve at the end, m3/s", lambda r, it, qt, im: float(r["Q_valve"][-1])),
}  # fmt: skip


def _fmu_values(point: dict) -> dict:
    """The point's factor values as the FMU takes them (enumeration items by name)."""
    values = {}
    for name, v in point.items():
        if name == "driver" and isinstance(v, str):
            v = DRIVERS[v]
        elif name == "control_mode" and isinstance(v, str):
            v = CONTROL_MODES[v]
        values[name] = v
    return values


def run_point(point: dict) -> dict:
    """One FMU run of a study point and its metrics. ``point`` holds the factor values and
    the settings ``_scenario``, ``_version``, ``_metrics`` (names), optional ``_h`` and
    ``_t_stop``. Returns the metrics, the wall time and the process that ran it."""
    settings = {k: v for k, v in point.items() if k.startswith("_")}
    values = _fmu_values({k: v for k, v in point.items() if not k.startswith("_")})
    sc = SCENARIOS[settings["_scenario"]]
    values.setdefault("control_mode", CONTROL_MODES[sc.control_mode])
    start = time.perf_counter()
    r = run_scenario(
        settings["_version"],
        h=settings.get("_h", sc.h),
        t_stop=settings.get("_t_stop", sc.t_stop),
        initial=values,
        changes={sc.change: sc.step},
        outputs=STEP_OUTPUTS,
        reuse=True,
    )
    i_target, q_target = sc.targets({k: v for k, v in values.items() if k in NOMINAL})
    driver = values.get("driver", NOMINAL["driver"])
    if driver in (DRIVERS[d] for d in PWM_DRIVERS):
        mean = period_average(r["time"], r["i_coil"], pwm_period(values))
    else:
        mean = (r["time"], r["i_coil"])
    out = {name: METRICS[name][1](r, i_target, q_target, mean) for name in settings["_metrics"]}
    out["seconds"] = time.perf_counter() - start
    out["pid"] = os.getpid()
    return out


# --------------------------------------------------------------------------------------
# A study: its points and its table
# --------------------------------------------------------------------------------------

#: columns that depend on where and when a point ran, not on the point
RUN_COLUMNS = ("seconds", "pid")


def points(
    vary: list[str],
    n: int,
    *,
    kind: str = "grid",
    seed: int = 1,
    scenario: str = "current_step",
    version: str = "fmi2",
    metrics: list[str] | None = None,
    h: float | None = None,
    t_stop: float | None = None,
) -> list[dict]:
    """The design's points (factors written as on the command line), each with the run
    settings run_point reads."""
    metrics = list(metrics or METRICS)
    unknown = [m for m in metrics if m not in METRICS]
    if unknown:
        raise ValueError(f"unknown metrics {unknown}; known: {', '.join(METRICS)}")
    if scenario not in SCENARIOS:
        raise ValueError(f"unknown scenario {scenario!r}; known: {', '.join(SCENARIOS)}")
    settings = {"_scenario": scenario, "_version": version, "_metrics": metrics}
    if h:
        settings["_h"] = h
    if t_stop:
        settings["_t_stop"] = t_stop
    factors = [parse_factor(v) for v in vary]
    return [{**p, **settings} for p in design(factors, n, kind, seed)]


def results_table(points: list[dict], results: list[dict]):
    """One row per point (a pandas DataFrame): point index, factor values, metrics (nan
    where the run failed), error (None if it ran), seconds and pid of the run."""
    import pandas as pd

    rows = []
    for k, (p, r) in enumerate(zip(points, results, strict=True)):
        row = {"point": k, **{n: v for n, v in p.items() if not n.startswith("_")}}
        row.update({m: r.get(m, math.nan) for m in p["_metrics"]})
        row.update(error=r.get("error"), seconds=r.get("seconds", math.nan), pid=r.get("pid", -1))
        rows.append(row)
    return pd.DataFrame(rows)
