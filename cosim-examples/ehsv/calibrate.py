"""Calibrate the FMU's parameters to a recording: bounded nonlinear least squares from
several starts, on dask, with 95 % intervals and identifiability flags.

    python -m ehsv.calibrate bench.csv --set control_mode=position \\
        --fit cylinder.beta,cylinder.mass,offset:p_A,delay:x_piston --out out/fit

The same as a function: ``calibrate(data, fit=[...], set_values={...}, out=Path(...))``.
Everything the user gives is checked before the first simulation (``CalibrationError``
names the column, row or parameter; nothing is written to the output folder then).
docs/calibration.md says what to measure and how to read the results.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .fmu import model_description, pooled_instance
from .paths import require_fmu

#: parameters that change the model's structure: only by --set, never fitted
STRUCTURAL = ("driver", "control_mode", "valve.parameterization", "cylinder.port", "solver.method")
_REAL = ("Real", "Float64")
OFFSET, DELAY = "offset:", "delay:"
#: the default search box of a positive scale parameter: this factor either side of its
#: start value (inside the variable's range), since the ranges themselves span decades
DEFAULT_DECADE = 10.0
#: finite-difference step in the unit box: large enough that the exact solver's error
#: control (rtol 1e-7) does not swamp the difference, small against the box
DIFF_STEP = 1e-4
#: the first stage of each start fits residuals averaged over this time, s
SMOOTH_S = 5e-3
#: a Jacobian eigenvalue below this fraction of the largest is a direction the data does
#: not determine (infinite variance along it)
EIG_CUTOFF = 1e-10
CORRELATION_LIMIT = 0.99
#: an output whose residuals' lag-1 autocorrelation exceeds this (an autocorrelation
#: factor above 2) and whose residual variance exceeds this multiple of its noise's is
#: not fitted to its noise (a fit converged on a noise-free recording leaves correlated
#: residuals too, but far below the noise floor: the solver's, not a misfit)
CORRELATED_LAG1 = 1.0 / 3.0
UNEXPLAINED_VARIANCE = 1.5
#: while the best start's residuals are not its noise as above, up to this many rounds of
#: starts are made around it, in a box of this half-width in the unit box: the cost is
#: rugged (each cycle of the oil column's oscillation that friction ends early or late is
#: its own basin), and a start that settled one basin off has the truth's basin close by
REFINE_ROUNDS = 2
REFINE_HALF_WIDTH = 0.05
#: a start that has not converged after this many evaluations per unknown is given up
#: (a start far from the optimum wanders in this model's rugged landscape)
MAX_NFEV_PER_UNKNOWN = 40
#: fewer samples than this per fitted unknown cannot pin them down (a warning)
MIN_SAMPLES_PER_UNKNOWN = 20


class CalibrationError(ValueError):
    """Bad input, found before any simulation."""


class ExcitationWarning(UserWarning):
    """The recording is too short or too still to identify what is fitted."""


# -- the recording ----------------------------------------------------------------------
@dataclass
class Recording:
    time: np.ndarray
    inputs: dict[str, np.ndarray]
    outputs: dict[str, np.ndarray]
    source: str = ""


def _variables(version: str) -> dict:
    return {v.name: v for v in model_description(require_fmu(version)).modelVariables}


def _frame(data):
    import pandas as pd

    if isinstance(data, pd.DataFrame):
        return data, "DataFrame"
    path = Path(data)
    if not path.is_file():
        raise CalibrationError(f"{path}: no such file")
    if path.suffix.lower() in (".parquet", ".pq"):
        return pd.read_parquet(path), str(path)
    return pd.read_csv(path), str(path)


def _check_columns(columns, variables) -> None:
    for col in columns:
        if col == "time":
            continue
        var = variables.get(col)
        if var is None:
            raise CalibrationError(f"column {col!r}: the FMU has no variable of that name")
        if var.causality not in ("input", "output"):
            raise CalibrationError(f"column {col!r}: a {var.causality}, neither an input nor an output")
        if var.type not in _REAL:
            raise CalibrationError(f"column {col!r}: a {var.type} {var.causality}, only real ones are used")


def _check_values(df) -> None:
    values = df.to_numpy(dtype=float)
    bad = ~np.isfinite(values)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise CalibrationError(f"column {df.columns[col]!r}, row {row}: {values[row, col]} is not finite")
    t = df["time"].to_numpy(dtype=float)
    steps = np.diff(t)
    if (steps <= 0).any():
        row = int(np.argmax(steps <= 0)) + 1
        raise CalibrationError(f"column 'time', row {row}: {t[row]} does not increase on {t[row - 1]}")


def read_recording(data, version: str = "fmi2") -> Recording:
    """The recording ``data`` (a CSV or Parquet path, or a DataFrame), checked: a
    ``time`` column increasing, every other column a real input or output of the FMU,
    every value finite, at least one output."""
    df, source = _frame(data)
    if "time" not in df.columns:
        raise CalibrationError(f"{source}: no 'time' column")
    variables = _variables(version)
    _check_columns(df.columns, variables)
    if len(df) < 2:
        raise CalibrationError(f"{source}: {len(df)} row(s), a recording needs at least two")
    _check_values(df)
    inputs = {
        c: df[c].to_numpy(dtype=float)
        for c in df.columns
        if c != "time" and variables[c].causality == "input"
    }
    outputs = {c: df[c].to_numpy(dtype=float) for c in df.columns if c != "time" and c not in inputs}
    if not outputs:
        raise CalibrationError(f"{source}: no output column, nothing to fit to")
    return Recording(df["time"].to_numpy(dtype=float), inputs, outputs, source)


# -- parameters ------------------------------------------------------------------------
def _number(name: str, text, var):
    """A --set value: an enumeration by item name or number, a Boolean, a number."""
    if var.type == "Enumeration":
        from .contract import enumeration_value

        try:
            return enumeration_value(name, text)
        except ValueError as e:
            raise CalibrationError(f"--set {name}={text}: {e}") from None
    if var.type == "Boolean":
        if str(text).lower() in ("1", "true", "0", "false"):
            return str(text).lower() in ("1", "true")
        raise CalibrationError(f"--set {name}={text}: a Boolean, true or false")
    try:
        value = float(text)
    except ValueError:
        raise CalibrationError(f"--set {name}={text}: not a number") from None
    return value if var.type in _REAL else int(value)


def resolve_set(set_values: dict, version: str, method: str | None = None) -> dict:
    """--set NAME=VALUE as the FMU's values (enumerations by name or number), checked
    against each variable's range; ``method`` gives solver.method unless it is --set."""
    variables = _variables(version)
    out = {}
    for name, text in set_values.items():
        var = variables.get(name)
        if var is None or var.causality not in ("parameter", "input"):
            raise CalibrationError(f"--set {name}: the FMU has no parameter or input of that name")
        value = _number(name, text, var)
        lo, hi = _range(var)
        if not lo <= float(value) <= hi:
            raise CalibrationError(f"--set {name}={text}: outside the variable's range [{lo:g}, {hi:g}]")
        out[name] = value
    if method is not None and "solver.method" not in out:
        out["solver.method"] = _number("solver.method", method, variables["solver.method"])
    return out


def _range(var) -> tuple[float, float]:
    lo = float(var.min) if var.min is not None else -math.inf
    hi = float(var.max) if var.max is not None else math.inf
    return lo, hi


@dataclass(frozen=True)
class Unknown:
    """One fitted quantity: an FMU parameter, or a sensor's offset or delay."""

    name: str
    lo: float
    hi: float
    start: float
    log: bool = False

    @property
    def kind(self) -> str:
        return self.name.split(":", 1)[0] if ":" in self.name else "parameter"

    @property
    def target(self) -> str:
        return self.name.split(":", 1)[1] if ":" in self.name else self.name

    def to_value(self, u: float) -> float:
        """From the unit box (0 at lo, 1 at hi; log-spaced for scale parameters)."""
        if self.log:
            return math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo)))
        return self.lo + u * (self.hi - self.lo)

    def to_unit(self, value: float) -> float:
        if self.log:
            return (math.log(value) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        return (value - self.lo) / (self.hi - self.lo)


def _parameter_unknown(name, var, fixed, bounds) -> Unknown:
    if var is None:
        raise CalibrationError(f"--fit {name}: the FMU has no parameter of that name")
    if var.causality != "parameter":
        raise CalibrationError(f"--fit {name}: a {var.causality}, only parameters are fitted")
    if name in STRUCTURAL or var.type not in _REAL:
        raise CalibrationError(
            f"--fit {name}: structural ({var.type}), give it by --set, it cannot be fitted"
        )
    lo, hi = _range(var)
    start = float(fixed.get(name, var.start))
    log = start > 0 and lo >= 0
    if name in bounds:
        b_lo, b_hi = bounds[name]
        if b_lo < lo or b_hi > hi:
            raise CalibrationError(
                f"--bounds {name}={b_lo:g}:{b_hi:g}: outside the variable's range [{lo:g}, {hi:g}]"
            )
        lo, hi = b_lo, b_hi
        log = log and lo > 0
    elif log:
        lo, hi = max(lo, start / DEFAULT_DECADE), min(hi, start * DEFAULT_DECADE)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise CalibrationError(f"--fit {name}: its range is unbounded, give --bounds {name}=LO:HI")
    return Unknown(name, lo, hi, min(max(start, lo), hi), log)


def _sensor_unknown(name, rec: Recording, bounds) -> Unknown:
    kind, target = name.split(":", 1)
    if target not in rec.outputs:
        raise CalibrationError(f"--fit {name}: {target!r} is not a measured output of the recording")
    if name in bounds:
        lo, hi = bounds[name]
    elif kind == "offset":
        span = float(np.ptp(rec.outputs[target])) or max(abs(float(rec.outputs[target][0])), 1.0)
        lo, hi = -0.1 * span, 0.1 * span
    else:
        lo, hi = 0.0, 0.1 * float(rec.time[-1] - rec.time[0])
    if kind == "delay" and lo < 0:
        raise CalibrationError(f"--bounds {name}: a delay cannot be negative")
    start = 0.0 if lo <= 0.0 <= hi else lo
    return Unknown(name, lo, hi, start)


def resolve_unknowns(fit, bounds: dict, fixed: dict, rec: Recording, version: str) -> list[Unknown]:
    """The fitted quantities of ``fit`` (names), with their search boxes, checked."""
    variables = _variables(version)
    unknowns = []
    for name in fit:
        if name.startswith((OFFSET, DELAY)):
            unknowns.append(_sensor_unknown(name, rec, bounds))
        else:
            unknowns.append(_parameter_unknown(name, variables.get(name), fixed, bounds))
        if not unknowns[-1].lo < unknowns[-1].hi:
            raise CalibrationError(f"--bounds {name}: empty box [{unknowns[-1].lo:g}, {unknowns[-1].hi:g}]")
    for name in bounds:
        if name not in fit:
            raise CalibrationError(f"--bounds {name}: not in --fit")
    if len(set(fit)) != len(fit):
        raise CalibrationError("--fit names a quantity twice")
    return unknowns


def _warn_excitation(rec: Recording, unknowns) -> None:
    n = len(rec.time)
    if n < MIN_SAMPLES_PER_UNKNOWN * len(unknowns):
        warnings.warn(
            f"{rec.source}: {n} samples for {len(unknowns)} unknowns (fewer than "
            f"{MIN_SAMPLES_PER_UNKNOWN} each): too short to identify them",
            ExcitationWarning,
            stacklevel=3,
        )
    if not any(np.ptp(v) > 0 for v in rec.inputs.values()):
        warnings.warn(
            f"{rec.source}: no input changes over the recording, nothing excites "
            f"{', '.join(u.name for u in unknowns if u.kind == 'parameter') or 'the model'}",
            ExcitationWarning,
            stacklevel=3,
        )


def noise_sigma(y: np.ndarray) -> float:
    """The white noise on ``y``, from its second differences (robust to steps: a median):
    a smooth signal's second difference at a fine sampling is nearly zero, white noise's
    has the variance 6 sigma^2. Floored at 1e-4 of the signal's range so that a
    noise-free recording still weights its outputs by their ranges."""
    d2 = np.diff(y, 2)
    sigma = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0) if d2.size else 0.0
    floor = 1e-4 * max(float(np.ptp(y)), float(np.max(np.abs(y))) * 1e-3, 1e-300)
    return max(sigma, floor)


# -- the simulation ---------------------------------------------------------------------
@dataclass
class Problem:
    """Everything one start needs (picklable: shipped to dask workers)."""

    version: str
    fixed: dict
    unknowns: list[Unknown]
    rec: Recording
    sigma: dict[str, float]
    evaluations: int = 0
    _cache: dict = field(default_factory=dict, repr=False)

    def parameters(self, values) -> dict:
        p = dict(self.fixed)
        p.update({u.name: v for u, v in zip(self.unknowns, values, strict=True) if u.kind == "parameter"})
        return p

    def model(self, values, rec: Recording | None = None) -> dict[str, np.ndarray]:
        """The model's outputs at the recording's times, sensor offsets and delays applied."""
        rec = rec or self.rec
        params = self.parameters(values)
        key = (id(rec), tuple(sorted(params.items())))
        if key not in self._cache:
            self._cache.clear()  # offsets/delays move without a new simulation
            self._cache[key] = simulate(self.version, params, rec)
            self.evaluations += 1
        sim = self._cache[key]
        out = {}
        for name, y in sim.items():
            delay = self._sensor(values, DELAY + name)
            y = _delayed(rec.time, y, delay) if delay else y
            out[name] = y + self._sensor(values, OFFSET + name)
        return out

    def _sensor(self, values, name) -> float:
        for u, v in zip(self.unknowns, values, strict=True):
            if u.name == name:
                return v
        return 0.0

    def residuals(self, units, smooth: int = 1) -> np.ndarray:
        """Weighted residuals at the unit-box point ``units``, each output's averaged over
        ``smooth`` samples (1: raw)."""
        from scipy.ndimage import uniform_filter1d

        values = [u.to_value(x) for u, x in zip(self.unknowns, units, strict=True)]
        model = self.model(values)
        r = [(model[k] - y) / self.sigma[k] for k, y in self.rec.outputs.items()]
        return np.concatenate([uniform_filter1d(x, smooth) if smooth > 1 else x for x in r])


def _delayed(t: np.ndarray, y: np.ndarray, delay: float) -> np.ndarray:
    """y read at t - delay (its first value before the start): a cubic spline, whose slope
    in the delay is continuous, where linear interpolation would put a kink in the cost
    at every whole sample of delay."""
    from scipy.interpolate import CubicSpline

    return CubicSpline(t, y)(np.maximum(t - delay, t[0]))


def _fast_io(inst, names_in, names_out):
    """set(values) / get() -> ndarray on preallocated ctypes arrays: fmpy's setReal and
    getReal build new arrays on every call, which costs more than this FMU's step."""
    import ctypes

    fmu, fmi2 = inst.fmu, inst.version == "fmi2"
    vr_in = (ctypes.c_uint * len(names_in))(*[inst.vr(n) for n in names_in])
    vr_out = (ctypes.c_uint * len(names_out))(*[inst.vr(n) for n in names_out])
    v_in = (ctypes.c_double * len(names_in))()
    v_out = (ctypes.c_double * len(names_out))()
    out_view = np.frombuffer(v_out, dtype=float)
    setter = fmu.fmi2SetReal if fmi2 else fmu.fmi3SetFloat64
    getter = fmu.fmi2GetReal if fmi2 else fmu.fmi3GetFloat64
    extra_in = () if fmi2 else (len(names_in),)
    extra_out = () if fmi2 else (len(names_out),)

    def set_inputs(values):
        v_in[:] = values
        setter(fmu.component, vr_in, len(names_in), v_in, *extra_in)

    def get_outputs():
        getter(fmu.component, vr_out, len(names_out), v_out, *extra_out)
        return out_view

    return set_inputs, get_outputs


def simulate(version: str, params: dict, rec: Recording) -> dict[str, np.ndarray]:
    """The FMU's measured outputs at ``rec.time``: started in equilibrium with the first
    row's inputs, each input held from its sample to the next (one doStep per interval)."""
    inst = pooled_instance(version)
    names_in, names_out = list(rec.inputs), list(rec.outputs)
    u = np.column_stack([rec.inputs[n] for n in names_in]) if names_in else np.zeros((len(rec.time), 0))
    try:
        for k, v in params.items():
            inst.set(k, v)
        set_inputs, get_outputs = _fast_io(inst, names_in, names_out)
        t = rec.time
        if names_in:
            set_inputs(u[0])
        inst.initialize(start_time=float(t[0]), stop_time=float(t[-1]))
        y = np.empty((len(t), len(names_out)))
        y[0] = get_outputs()
        changed = np.r_[False, (np.diff(u, axis=0) != 0).any(axis=1)] if names_in else np.zeros(len(t), bool)
        do_step = inst.fmu.doStep
        for k in range(len(t) - 1):
            if changed[k]:
                set_inputs(u[k])
            do_step(float(t[k]), float(t[k + 1] - t[k]))
            y[k + 1] = get_outputs()
    except Exception as e:  # keep the FMU's own words with the exception
        raise RuntimeError(f"{e}\nFMU log:\n{inst.log_text()}" if inst.log else str(e)) from e
    return {n: y[:, j].copy() for j, n in enumerate(names_out)}


# -- the fit ----------------------------------------------------------------------------
def _run_start(problem: Problem, u0, progress=None, smooth: bool = True) -> dict:
    """One start of least_squares (a dask task or a plain call); a start whose
    simulation fails is recorded with the FMU's message, the others go on."""
    problem = replace(problem, evaluations=0, _cache={})
    try:
        return _least_squares(problem, u0, progress, smooth)
    except RuntimeError as e:
        return {"cost": math.inf, "error": str(e), "start": list(u0), "evaluations": problem.evaluations}


def _least_squares(problem: Problem, u0, progress, smooth: bool = True) -> dict:
    """Two stages: residuals averaged over SMOOTH_S first, then the raw ones from there
    (only the raw ones where not ``smooth``). The oil column's oscillations make the raw
    cost a narrow well on a plateau (a model whose oscillation is out of phase is as
    wrong as one that does not oscillate); the averaged residuals keep the slow response,
    whose cost slopes toward the well from far off."""
    from scipy.optimize import least_squares

    window = int(round(SMOOTH_S / float(np.median(np.diff(problem.rec.time)))))
    stages = ([window] if smooth and window >= 3 else []) + [1]
    start = list(u0)
    for w in stages:

        def fun(u, w=w):
            r = problem.residuals(u, smooth=w)
            if progress is not None:
                progress(0.5 * float(r @ r))
            return r

        # the unknowns live in the unit box: one scale and one finite-difference step fit all
        res = least_squares(
            fun,
            u0,
            bounds=(0.0, 1.0),
            method="trf",
            x_scale=np.ones(len(u0)),
            diff_step=DIFF_STEP,
            xtol=1e-10,
            max_nfev=MAX_NFEV_PER_UNKNOWN * len(u0),
        )
        u0 = res.x
    return {
        "u": res.x,
        "cost": float(res.cost),
        "jac": res.jac,
        "fun": res.fun,
        "evaluations": problem.evaluations,
        "status": int(res.status),
        "start": start,
    }


def start_points(unknowns, n: int, seed: int = 0) -> list[np.ndarray]:
    """The unknowns' start values, then n - 1 points of a Latin hypercube in the box."""
    from scipy.stats import qmc

    first = np.array([u.to_unit(u.start) for u in unknowns])
    if n <= 1:
        return [first]
    lhs = qmc.LatinHypercube(d=len(unknowns), seed=seed).random(n - 1)
    return [first, *lhs]


def _solve(problem: Problem, starts, client, progress: bool, smooth: bool = True) -> list[dict]:
    from tqdm import tqdm

    if client is None:
        bar = tqdm(desc="fit", unit="sim", disable=not progress)
        best = [math.inf]

        def report(cost):
            best[0] = min(best[0], cost)
            bar.set_postfix(cost=f"{cost:.4g}", best=f"{best[0]:.4g}", refresh=False)
            bar.update()

        try:
            return [_run_start(problem, u0, report, smooth) for u0 in starts]
        finally:
            bar.close()
    from dask.distributed import as_completed

    # the data goes to the workers once per round, under a key of its own (hash=False: not
    # the key the round before is releasing); each start is one task
    shared = client.scatter(problem, broadcast=True, hash=False)
    futures = [client.submit(_run_start, shared, u0, None, smooth, pure=False) for u0 in starts]
    best = math.inf
    with tqdm(total=len(futures), desc="starts", disable=not progress) as bar:
        for fut in as_completed(futures):
            best = min(best, fut.result()["cost"])
            bar.set_postfix(best_cost=f"{best:.4g}")
            bar.update()
    return client.gather(futures)


def unexplained(weighted: np.ndarray) -> bool:
    """Whether an output's residuals over its noise level are something other than its
    noise: correlated, and larger than it."""
    return (
        lag1_correlation(weighted) > CORRELATED_LAG1
        and float(np.mean(weighted * weighted)) > UNEXPLAINED_VARIANCE
    )


def _misfit(result: dict, blocks: int) -> bool:
    """Whether some output's residuals at a start's end are not its noise."""
    per_output = np.array_split(result["fun"], blocks)
    return math.isfinite(result["cost"]) and any(unexplained(r) for r in per_output)


def _refine(problem: Problem, results, client, progress: bool, n: int, seed: int) -> list[dict]:
    """Rounds of ``n`` raw-residual starts (a Latin hypercube of REFINE_HALF_WIDTH) around
    the best start while its residuals are not the noise: the new starts, each marked."""
    from scipy.stats import qmc

    added: list[dict] = []
    blocks = len(problem.rec.outputs)
    for round_ in range(REFINE_ROUNDS):
        best = min(results + added, key=lambda r: r["cost"])
        if not _misfit(best, blocks):
            break
        lhs = qmc.LatinHypercube(d=len(best["u"]), seed=seed + 1 + round_).random(n)
        points = list(np.clip(best["u"] + (2.0 * lhs - 1.0) * REFINE_HALF_WIDTH, 0.0, 1.0))
        for r in _solve(problem, points, client, progress, smooth=False):
            added.append({**r, "refine": round_ + 1})
    return added


# -- uncertainty --------------------------------------------------------------------------
def intervals(unknowns, u, jac, fun, blocks: int = 1) -> tuple[list, np.ndarray, np.ndarray]:
    """95 % intervals (t distribution), the correlation matrix and which directions are
    undetermined, from the weighted Jacobian in the unit box; ``fun`` holds ``blocks``
    outputs' residuals one after the other.

    Cov = s2 (J^T J)^-1, with s2 = r.r / (n - p) taken per output (and scaled by
    ``autocorrelation_inflation`` of its residuals): an output whose noise
    was misjudged (the estimate from second differences sees some of the signal) would
    otherwise lend its error to the others. With one s2 per output this is the sandwich
    A^-1 (J^T S J) A^-1, A = J^T J, S the per-output s2. A^-1 comes from an
    eigen-decomposition: an eigenvalue below EIG_CUTOFF of the largest is a direction the
    data does not fix, and a parameter with weight on it has an unbounded interval.
    Intervals are mapped back through each unknown's scale (asymmetric in value for
    log-scaled ones)."""
    from scipy.stats import t as student

    n, p = jac.shape
    dof = max(n - p, 1)
    s2 = np.concatenate(
        [
            np.full(len(b), float(b @ b) / len(b) * n / dof * autocorrelation_inflation(b))
            for b in np.array_split(fun, blocks)
        ]
    )
    lam, vec = np.linalg.eigh(jac.T @ jac)
    keep = lam > EIG_CUTOFF * max(lam.max(), 1e-300)
    a_inv = (vec[:, keep] / lam[keep]) @ vec[:, keep].T
    cov = a_inv @ (jac.T @ (s2[:, None] * jac)) @ a_inv
    loose = (np.abs(vec[:, ~keep]) > 1e-3).any(axis=1) if (~keep).any() else np.zeros(p, bool)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    tq = float(student.ppf(0.975, dof))
    cis = []
    for i, unk in enumerate(unknowns):
        if loose[i]:
            cis.append([-math.inf, math.inf])
            continue
        lo, hi = u[i] - tq * sd[i], u[i] + tq * sd[i]
        cis.append([_to_value_unbounded(unk, lo), _to_value_unbounded(unk, hi)])
    return cis, corr, loose


def autocorrelation_inflation(r: np.ndarray) -> float:
    """The factor by which correlated residuals widen a variance: (1 + rho) / (1 - rho),
    rho the residuals' lag-1 autocorrelation, the AR(1) ratio n / n_eff for regressors
    that vary slowly against the sampling (the model's sensitivities at 10 kHz do). White
    residuals give about 1; the noise of a real bench (filters, quantisation, unmodelled
    dynamics) is coloured, and n samples of it carry the information of fewer. A negative
    rho is taken as 0 (intervals are never narrowed); rho is capped at 0.99."""
    rho = min(max(lag1_correlation(r), 0.0), 0.99)
    return (1.0 + rho) / (1.0 - rho)


def lag1_correlation(r: np.ndarray) -> float:
    """The lag-1 autocorrelation of ``r`` about its mean (0 for a constant or fewer than
    three samples): about 0 for white residuals."""
    r = r - r.mean()
    rr = float(r @ r)
    if r.size < 3 or rr == 0.0:
        return 0.0
    return float(r[1:] @ r[:-1]) / rr


def _to_value_unbounded(unk: Unknown, x: float) -> float:
    """to_value outside the unit box too (an interval may reach beyond the bounds)."""
    try:
        return unk.to_value(x)
    except OverflowError:
        return math.inf


def identifiable(unknowns, cis, corr, loose) -> list[bool]:
    """False where the interval spans the whole box, is unbounded, or the unknown moves
    with another (|correlation| > CORRELATION_LIMIT)."""
    flags = []
    for i, unk in enumerate(unknowns):
        others = np.delete(np.nan_to_num(np.abs(corr[i]), nan=1.0), i)
        spans = cis[i][0] <= unk.lo and cis[i][1] >= unk.hi
        flags.append(not (loose[i] or spans or (others > CORRELATION_LIMIT).any()))
    return flags


# -- results -------------------------------------------------------------------------------
def _fit_quality(problem: Problem, values, rec: Recording) -> dict:
    model = problem.model(values, rec)
    out = {}
    for name, y in rec.outputs.items():
        r = model[name] - y
        rms = float(np.sqrt(np.mean(r**2)))
        span = float(np.ptp(y))
        out[name] = {"rms": rms, "nrmse": rms / span if span > 0 else None, "sigma": problem.sigma.get(name)}
        # the factor its s2 got in the intervals
        out[name]["autocorrelation_inflation"] = autocorrelation_inflation(r)
        out[name]["unexplained"] = unexplained(r / problem.sigma[name])
    return out


def write_ssv(path: Path, params: dict, version: str, name: str = "calibration") -> None:
    """The parameters as an SSP parameter-value file (SSV 1.0, no units: the FMU's own)."""
    from xml.sax.saxutils import quoteattr

    variables = _variables(version)
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"'
        f' version="1.0" name={quoteattr(name)}>',
        "  <ssv:Parameters>",
    ]
    for key, value in params.items():
        kind = variables[key].type
        if kind in _REAL:
            element = f'<ssv:Real value="{float(value)!r}"/>'
        elif kind == "Boolean":
            element = f'<ssv:Boolean value="{str(bool(value)).lower()}"/>'
        else:  # enumerations by their number, as the FMU takes them
            element = f'<ssv:Integer value="{int(value)}"/>'
        lines.append(f"    <ssv:Parameter name={quoteattr(key)}>{element}</ssv:Parameter>")
    lines += ["  </ssv:Parameters>", "</ssv:ParameterSet>", ""]
    path.write_text("\n".join(lines), encoding="utf-8")


def _json_number(x):
    return None if x is None or not math.isfinite(x) else float(x)


def _figure(path: Path, problem: Problem, before, after) -> None:
    from .plotting import pyplot, save_figure

    plt = pyplot()
    names = list(problem.rec.outputs)
    fig, axes = plt.subplots(2, len(names), figsize=(5 * len(names), 6), sharex=True, squeeze=False)
    t = problem.rec.time
    for j, name in enumerate(names):
        y = problem.rec.outputs[name]
        ax, axr = axes[0, j], axes[1, j]
        ax.plot(t, y, "k", lw=1, label="measured")
        ax.plot(t, before[name], "C1--", lw=1, label="model, start")
        ax.plot(t, after[name], "C0", lw=1, label="model, fitted")
        ax.set_title(name)
        ax.legend(fontsize=8)
        axr.plot(t, after[name] - y, "C0", lw=0.8)
        axr.set_ylabel(f"residual {name}")
        axr.set_xlabel("time [s]")
        for a in (ax, axr):
            a.grid(alpha=0.3)
    save_figure(fig, path)


@dataclass
class Fit:
    """What calibrate() returns; ``report`` is fit.json's content."""

    report: dict
    parameters: dict
    problem: Problem


def _parse_bounds(bounds) -> dict:
    out = {}
    for name, text in (bounds or {}).items():
        if isinstance(text, tuple | list):
            out[name] = (float(text[0]), float(text[1]))
            continue
        try:
            lo, hi = (float(s) for s in str(text).split(":"))
        except ValueError:
            raise CalibrationError(f"--bounds {name}={text}: expected LO:HI") from None
        out[name] = (lo, hi)
    return out


def _sigmas(sigma: dict, rec: Recording) -> dict:
    """--sigma NAME=VALUE checked: a measured output, a positive number."""
    out = {}
    for name, text in sigma.items():
        if name not in rec.outputs:
            raise CalibrationError(f"--sigma {name}: not a measured output of the recording")
        try:
            out[name] = float(text)
        except ValueError:
            raise CalibrationError(f"--sigma {name}={text}: not a number") from None
        if not (out[name] > 0 and math.isfinite(out[name])):
            raise CalibrationError(f"--sigma {name}={text}: must be positive and finite")
    return out


def prepare(
    data, fit, *, bounds=None, set_values=None, sigma=None, method="exact", version="fmi2", validate=None
) -> tuple[Problem, Recording | None]:
    """Every check, no simulation: the Problem to solve and the validation recording."""
    rec = read_recording(data, version)
    check = read_recording(validate, version) if validate is not None else None
    if check is not None and (set(check.outputs) != set(rec.outputs) or set(check.inputs) != set(rec.inputs)):
        raise CalibrationError(f"{check.source}: its columns differ from {rec.source}'s")
    fixed = resolve_set(dict(set_values or {}), version, method)
    for name in fixed:
        if name in rec.inputs:
            raise CalibrationError(f"--set {name}: an input the recording already gives as a column")
    if not fit:
        raise CalibrationError("--fit names nothing")
    unknowns = resolve_unknowns(list(fit), _parse_bounds(bounds), fixed, rec, version)
    sig = {name: noise_sigma(y) for name, y in rec.outputs.items()}
    sig.update(_sigmas(sigma or {}, rec))
    _warn_excitation(rec, unknowns)
    return Problem(version, fixed, unknowns, rec, sig), check


def calibrate(
    data,
    fit,
    *,
    out: Path | None = None,
    bounds=None,
    set_values=None,
    sigma=None,
    method="exact",
    version="fmi2",
    starts=4,
    seed=0,
    scheduler=None,
    workers=None,
    serial=False,
    validate=None,
    progress=True,
) -> Fit:
    """Fits ``fit`` (names: parameters, offset:OUTPUT, delay:OUTPUT) to the recording
    ``data``; writes fit.json, fit.ssv and fit.png into ``out`` when given. ``serial``: no
    dask (one process); else a LocalCluster of ``workers`` or the cluster ``scheduler``."""
    from . import cluster

    wall = time.perf_counter()
    problem, check = prepare(
        data,
        fit,
        bounds=bounds,
        set_values=set_values,
        sigma=sigma,
        method=method,
        version=version,
        validate=validate,
    )
    if starts < 1:
        raise CalibrationError(f"--starts {starts}: at least one")
    points = start_points(problem.unknowns, starts, seed)
    client = None if serial else cluster.client_for(scheduler, workers)
    try:
        results = _solve(problem, points, client, progress)
        results += _refine(problem, results, client, progress, starts, seed)
    finally:
        cluster.close(client)
    return _finish(problem, results, check, out, time.perf_counter() - wall)


def _start_entry(unknowns, result) -> dict:
    entry = {"start": [u.to_value(x) for u, x in zip(unknowns, result["start"], strict=True)]}
    entry["cost"] = _json_number(result["cost"])
    entry["evaluations"] = int(result["evaluations"])
    if "refine" in result:
        entry["refine"] = result["refine"]
    if "error" in result:
        entry["error"] = result["error"]
    return entry


def _names(unknowns) -> set[str]:
    return {u.name for u in unknowns}


def _finish(problem: Problem, results, check, out, wall) -> Fit:
    best = min(results, key=lambda r: r["cost"])
    if not math.isfinite(best["cost"]):
        raise RuntimeError("every start failed:\n" + "\n".join(r["error"] for r in results))
    unknowns = problem.unknowns
    values = [u.to_value(x) for u, x in zip(unknowns, best["u"], strict=True)]
    cis, corr, loose = intervals(unknowns, best["u"], best["jac"], best["fun"], len(problem.rec.outputs))
    flags = identifiable(unknowns, cis, corr, loose)
    report = {
        "parameters": {
            u.name: {
                "value": v,
                "start": u.to_value(best["start"][i]),
                "bounds": [u.lo, u.hi],
                "scale": "log" if u.log else "linear",
                "ci95": [_json_number(c) for c in cis[i]],
                "identifiable": flags[i],
            }
            for i, (u, v) in enumerate(zip(unknowns, values, strict=True))
        },
        "correlation": [[_json_number(c) for c in row] for row in corr],
        "outputs": _fit_quality(problem, values, problem.rec),
        "cost": best["cost"],
        "starts": [_start_entry(unknowns, r) for r in results],
        "evaluations": int(sum(r["evaluations"] for r in results)),
        "set": {k: v for k, v in problem.fixed.items() if k not in _names(unknowns)},
        "samples": len(problem.rec.time),
    }
    if check is not None:
        report["validation"] = {
            k: {"nrmse": v["nrmse"]} for k, v in _fit_quality(problem, values, check).items()
        }
    report["wall_s"] = wall
    fitted = problem.parameters(values)
    if out is not None:
        _write(Path(out), problem, report, fitted, values)
    return Fit(report, fitted, problem)


def _write(out: Path, problem: Problem, report: dict, fitted: dict, values) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "fit.json").write_text(json.dumps(report, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    write_ssv(out / "fit.ssv", fitted, problem.version)
    before = problem.model([u.start for u in problem.unknowns])
    _figure(out / "fit.png", problem, before, problem.model(values))


# -- command line ----------------------------------------------------------------------------
def _pairs(items, what: str) -> dict:
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise CalibrationError(f"{what} {item}: expected NAME=VALUE")
        out[name.strip()] = value.strip()
    return out


def parse_args(argv=None):
    ap = argparse.ArgumentParser(prog="python -m ehsv.calibrate", description=__doc__.splitlines()[0])
    ap.add_argument("data", help="recording: CSV or Parquet with a time column, FMU inputs and outputs")
    ap.add_argument("--fit", required=True, help="NAME[,NAME...]: parameters, offset:OUTPUT, delay:OUTPUT")
    ap.add_argument("--bounds", action="append", metavar="NAME=LO:HI")
    ap.add_argument("--set", action="append", metavar="NAME=VALUE", dest="set_values")
    ap.add_argument("--sigma", action="append", metavar="NAME=VALUE")
    ap.add_argument("--method", choices=("exact", "fixed_cost"), default="exact")
    ap.add_argument("--fmi3", action="store_true", help="use the FMI 3.0 archive")
    ap.add_argument("--starts", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0, help="seed of the Latin hypercube")
    ap.add_argument("--scheduler", help="address (tcp://host:port) or scheduler file of a dask cluster")
    ap.add_argument("--workers", type=int, help="LocalCluster workers (default: one per core)")
    ap.add_argument("--serial", action="store_true", help="run in this process, no dask")
    ap.add_argument("--validate", metavar="DATA2", help="a second recording to predict with the fitted set")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--out", type=Path, required=True)
    return ap.parse_args(argv)


def _summary(report: dict) -> str:
    lines = [f"{'parameter':28} {'value':>12} {'95 % interval':>27}  flag"]
    for name, p in report["parameters"].items():
        lo, hi = p["ci95"]
        ci = f"[{lo:.5g}, {hi:.5g}]" if lo is not None and hi is not None else "unbounded"
        flag = "" if p["identifiable"] else "NOT IDENTIFIABLE (value not precise)"
        lines.append(f"{name:28} {p['value']:12.6g} {ci:>27}  {flag}")
    for name, o in report["outputs"].items():
        lines.append(f"output {name}: rms {o['rms']:.4g}, nrmse {o['nrmse']}")
        if o["unexplained"]:
            lines.append(
                "  its residuals are correlated and above its noise (variance "
                f"x{o['autocorrelation_inflation']:.3g} in the intervals): the model does not "
                "reproduce it (a local minimum, or an effect it lacks)"
            )
    for name, o in report.get("validation", {}).items():
        lines.append(f"validation {name}: nrmse {o['nrmse']}")
    lines.append(f"{report['evaluations']} simulations, {report['wall_s']:.1f} s wall")
    return "\n".join(lines)


def main(argv=None) -> int:
    args = parse_args(argv)
    version = "fmi3" if args.fmi3 else "fmi2"
    try:
        sigma = _pairs(args.sigma, "--sigma")
        fit = calibrate(
            args.data,
            [s.strip() for s in args.fit.split(",") if s.strip()],
            out=args.out,
            bounds=_pairs(args.bounds, "--bounds"),
            set_values=_pairs(args.set_values, "--set"),
            sigma=sigma,
            method=args.method,
            version=version,
            starts=args.starts,
            seed=args.seed,
            scheduler=args.scheduler,
            workers=args.workers,
            serial=args.serial,
            validate=args.validate,
            progress=not args.no_progress,
        )
    except (CalibrationError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(_summary(fit.report))
    print(f"written: {args.out / 'fit.json'}, {args.out / 'fit.ssv'}, {args.out / 'fit.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
