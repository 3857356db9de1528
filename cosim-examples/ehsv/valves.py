"""Servo valves from their datasheets: the catalog (valves.toml beside this file) and the
datasheet's figures measured back through the FMU.

The catalog: ``[valves.NAME.parameters]`` holds the FMU's start values by variable name
(an enumeration by its item's name, e.g. ``"valve.parameterization" = "datasheet"``),
``[valves.NAME.source]`` the document and page the figures come from.

* ``names()``, ``entry(name)``, ``source(name)``: the catalog as written,
* ``start_values(name)``: the entry's start values for the FMU (enumerations as their
  numbers), ready for ``Ehsv.set``, fmpy's ``start_values`` or a scenario's ``params``,
* ``datasheet(...)``: the figures a set of start values gives the valve (``Datasheet``),
  the FMU's start values where the entry says nothing,
* ``derived(version, params)``: the calculated parameters ``valve.derived.*`` of an
  initialised instance,
* ``measure_response(spec)``: the small-signal Q_valve / i_ref of ``ideal_current``
  through the FMU (frequency.sine_response): a sweep, the DC gain from a step held to
  its steady state, and the -90 degree and -3 dB frequencies found by a bracketed root
  search on the measured phase and magnitude (``bracketed_root``: scipy's brentq), not
  read off the grid,
* ``measure_null(spec)``: the rod held at mid-stroke with its ports blocked: Q_supply at
  null (the null leakage) and the blocked-port pressure gain d(p_A - p_B)/di.

Every ``measure_*`` takes one picklable dict (a dask task, cluster.map_points).
"""

from __future__ import annotations

import cmath
import functools
import math
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from . import frequency as fr
from .contract import DRIVERS, NOMINAL, enumeration_value
from .fmu import model_description, pooled_instance
from .paths import require_fmu

#: the catalog shipped with the package
CATALOG = Path(__file__).with_name("valves.toml")

#: the calculated parameters of the valve (causality calculatedParameter)
DERIVED_PREFIX = "valve.derived."

#: small-signal amplitude, as a fraction of the valve's rated current
SMALL = 0.01


# --------------------------------------------------------------------------------------
# The catalog
# --------------------------------------------------------------------------------------


@functools.cache
def _load(path: Path) -> dict:
    with open(path, "rb") as f:
        data = tomllib.load(f)
    valves = data.get("valves")
    if not isinstance(valves, dict) or not valves:
        raise ValueError(f"{path}: no [valves.NAME] tables")
    for name, e in valves.items():
        if not isinstance(e.get("parameters"), dict):
            raise ValueError(f"{path}: valves.{name} has no [valves.{name}.parameters] table")
    return valves


def catalog(path: Path | None = None) -> dict[str, dict]:
    """Every entry of the catalog as written: name -> {"parameters": ..., "source": ...}."""
    return _load(Path(path or CATALOG))


def names(path: Path | None = None) -> list[str]:
    """The catalog's valve names, in the file's order."""
    return list(catalog(path))


def entry(name: str, path: Path | None = None) -> dict:
    """One entry as written; KeyError listing the names when there is no such valve."""
    valves = catalog(path)
    if name not in valves:
        raise KeyError(f"no valve {name!r} in the catalog; it has {', '.join(valves)}")
    return valves[name]


def source(name: str, path: Path | None = None) -> dict:
    """Where the entry's figures come from (document, page, ...)."""
    return dict(entry(name, path).get("source", {}))


def start_values(name: str, path: Path | None = None) -> dict[str, float | int]:
    """The entry's FMU start values: variable name -> number, an enumeration's item name
    replaced by its value the way DRIVERS maps driver names. A name the FMU does not have
    as a parameter, or an item its enumeration does not have, is a ValueError naming it."""
    out = {}
    for var, value in entry(name, path)["parameters"].items():
        if var not in NOMINAL:
            raise ValueError(f"valves.{name}: {var!r} is not a parameter of the FMU")
        if isinstance(value, str):
            try:
                value = enumeration_value(var, value)
            except ValueError as e:
                raise ValueError(f"valves.{name}: {var} = {value!r}: {e}") from None
        out[var] = value
    return out


@dataclass(frozen=True)
class Datasheet:
    """A valve's datasheet figures as the FMU reads them (SI units); None: not given."""

    Q_rated: float  # m3/s at i_rated and dp_rated
    i_rated: float  # A
    dp_rated: float  # Pa
    f_90: float  # Hz
    f_3dB: float | None  # Hz
    zeta: float
    lap: float  # m
    Q_leak_null: float | None  # m3/s at p_leak_ref
    p_leak_ref: float  # Pa
    pressure_gain: float | None  # Pa/A at p_leak_ref

    @property
    def flow_gain(self) -> float:
        """Q_rated / i_rated, m3/s per A: the small-signal DC gain."""
        return self.Q_rated / self.i_rated

    @property
    def lap_pressure_gain(self) -> float | None:
        """The blocked-port pressure gain that the null leakage gives when all of it flows
        through the lap: with x_r the rated stroke, K1/Kw = x_r/i_rated, K3 = Q_rated/x_r,
        the lap u = Q_leak / (2 K3 sqrt(p/dp_rated)) and the gain 2 p K1/(Kw u):
        4 p Q_rated sqrt(p/dp_rated) / (i_rated Q_leak), whatever x_r. None without leakage."""
        if not self.Q_leak_null:
            return None
        p = self.p_leak_ref
        return 4 * p * self.Q_rated * math.sqrt(p / self.dp_rated) / (self.i_rated * self.Q_leak_null)


def datasheet(params: Mapping) -> Datasheet:
    """The figures a set of start values (``start_values(name)`` or any params) gives,
    the FMU's start values where ``params`` says nothing."""
    p = {**NOMINAL, **params}
    return Datasheet(
        Q_rated=p["valve.Q_rated"],
        i_rated=p["valve.i_rated"],
        dp_rated=p["valve.dp_rated"],
        f_90=p["valve.f_90"],
        f_3dB=p["valve.f_3dB"] or None,
        zeta=p["valve.zeta"],
        lap=p["valve.lap"],
        Q_leak_null=p["valve.Q_leak_null"] or None,
        p_leak_ref=p["valve.p_leak_ref"],
        pressure_gain=p["valve.pressure_gain"] or None,
    )


# --------------------------------------------------------------------------------------
# Through the FMU
# --------------------------------------------------------------------------------------


def derived_names(version: str) -> list[str]:
    """The valve's calculated parameters in the archive ``version``."""
    md = model_description(require_fmu(version))
    return [
        v.name
        for v in md.modelVariables
        if v.causality == "calculatedParameter" and v.name.startswith(DERIVED_PREFIX)
    ]


def _instance(version: str, values: Mapping, inputs: Mapping | None = None):
    """This process's pooled instance with ``values`` and ``inputs`` set and initialised;
    a refusal raises RuntimeError with the FMU's log."""
    inst = pooled_instance(version)
    try:
        for k, v in {**values, **(inputs or {})}.items():
            inst.set(k, v)
        inst.initialize(start_time=0.0)
    except Exception as e:
        raise RuntimeError(f"{e}\nFMU log:\n{inst.log_text()}") from e
    return inst


def derived(version: str, params: Mapping) -> dict[str, float]:
    """``valve.derived.*`` of an instance initialised with ``params``: name without the
    prefix -> value (K1, Kw, K2, K3, f_n, tau, f_90, f_3dB, lap, Q_leak_null, ...)."""
    names_ = derived_names(version)
    inst = _instance(version, params)
    return {n[len(DERIVED_PREFIX) :]: v for n, v in zip(names_, inst.get(names_), strict=True)}


def transfer(d: Mapping, f) -> np.ndarray:
    """Q_valve / i (m3/s per A) of the valve whose derived parameters are ``d``, ideal
    current: K / (1 + tau s (s^2/wn^2 + 2 zeta s/wn + 1)), K = K3 K1/Kw."""
    s = 2j * math.pi * np.asarray(f, float)
    wn = 2 * math.pi * d["f_n"]
    k = d["K3"] * d["K1"] / d["Kw"]
    return k / (1 + d["tau"] * s * (s * s / wn**2 + 2 * d["zeta"] * s / wn + 1))


def settle_time(d: Mapping) -> float:
    """12 time constants of the slowest pole of ``transfer`` (the start transient below
    1e-5), s."""
    wn = 2 * math.pi * d["f_n"]
    poles = np.roots([d["tau"] / wn**2, 2 * d["zeta"] * d["tau"] / wn, d["tau"], 1.0])
    return 12.0 / float(np.min(-poles.real))


def bracketed_root(g: Callable[[float], float], f_lo: float, f_hi: float, rel: float = 1e-6) -> float:
    """The f in [f_lo, f_hi] where g(f) = 0, g(f_lo) and g(f_hi) of opposite signs: Brent's
    method (scipy.optimize.brentq) in log f, to ``rel`` of f."""
    log_root = brentq(lambda x: g(math.exp(x)), math.log(f_lo), math.log(f_hi), xtol=rel)
    return math.exp(log_root)


def _wrap_deg(x: float) -> float:
    return (x + 180.0) % 360.0 - 180.0


def _first_crossing(freqs, y, level) -> dict | None:
    """The grid bracket of y's first fall below ``level`` (bracketed_root's f_lo, f_hi),
    None if it never falls."""
    y = np.asarray(y, float)
    below = np.nonzero(y < level)[0]
    if len(below) == 0 or below[0] == 0:
        return None
    k = int(below[0])
    return {"f_lo": freqs[k - 1], "f_hi": freqs[k]}


def valve_params(spec: Mapping) -> dict:
    """The start values of a spec: its catalog entry's (``valve``), then its ``params``."""
    values = start_values(spec["valve"]) if spec.get("valve") else {}
    return {**values, **(spec.get("params") or {})}


def dc_gain(version: str, params: Mapping, amplitude: float, settle: float) -> float:
    """Q_valve / i_coil after a step of i_ref 0 -> ``amplitude`` (ideal current) held for
    two settling times."""
    inst = _instance(version, {**params, "driver": DRIVERS["ideal_current"]}, {"i_ref": 0.0})
    inst.set("i_ref", amplitude)
    n = 400
    h = 2 * settle / n
    for k in range(n):
        inst.do_step(k * h, h)
    q, i = inst.get(["Q_valve", "i_coil"])
    return q / i


def measure_response(spec: Mapping) -> dict:
    """The small-signal response Q_valve / i_ref of one valve through the FMU.

    ``spec``: version, valve (catalog name) and/or params (start values on top), freqs
    (the sweep, Hz, increasing), amplitude (A; default SMALL times the rated current),
    rel (the root search's tolerance, default 1e-6). Returns the spec with: datasheet,
    derived (valve.derived.*), settle (s), f and gains (the sweep, complex m3/s per A),
    dc_gain (m3/s per A), f_90 and f_3dB (Hz, nan if the sweep does not cross), and
    evaluations (sine runs in all)."""
    version = spec["version"]
    params = valve_params(spec)
    sheet = datasheet(params)
    d = {**derived(version, params), "zeta": sheet.zeta}
    settle = settle_time(d)
    amp = spec.get("amplitude") or SMALL * sheet.i_rated
    count = [0]

    def gain(f: float) -> complex:
        count[0] += 1
        r = fr.sine_response(
            version, "ideal_current", f, amp, outputs=("Q_valve",), params=params, settle=settle
        )
        return r.gains["Q_valve"]

    k_dc = dc_gain(version, params, amp, settle)
    freqs = [float(f) for f in spec["freqs"]]
    gains = [gain(f) for f in freqs]
    out = {**spec, "amplitude": amp, "datasheet": sheet, "derived": d, "settle": settle}
    out.update(f=freqs, gains=gains, dc_gain=k_dc)
    rel = spec.get("rel", 1e-6)
    level = 1 / math.sqrt(2)
    bracket = _first_crossing(freqs, np.abs(gains) / k_dc, level)
    out["f_3dB"] = (
        bracketed_root(lambda f: abs(gain(f)) / k_dc - level, rel=rel, **bracket) if bracket else math.nan
    )
    bracket = _first_crossing(freqs, fr.phase_deg(gains), -90.0)
    out["f_90"] = (
        bracketed_root(lambda f: _wrap_deg(math.degrees(cmath.phase(gain(f))) + 90.0), rel=rel, **bracket)
        if bracket
        else math.nan
    )
    out["evaluations"] = count[0]
    return out


#: the held rod of measure_null: motion port at mid-stroke, at rest, no cylinder leakage,
#: no relief valves (they must not open at a datasheet's 210 bar supply: the ports are
#: blocked, only the valve's flows are measured)
HELD_ROD = {
    "cylinder.port": "motion",
    "cylinder.C_leak": 0.0,
    "cylinder.C_leak_external": 0.0,
    "relief.p_crack": 0.0,
}


def _settle_blocked(inst, t: float, h: float, names, tol: float, t_max: float) -> tuple[float, list]:
    """Steps ``inst`` from ``t`` in chunks of 100 steps of ``h`` until no value of
    ``names`` moves more than ``tol`` (absolute, per name) over a chunk; returns the time
    and the values. RuntimeError if that takes longer than ``t_max`` more."""
    last = inst.get(names)
    t_end = t + t_max
    while t < t_end:
        for _ in range(100):
            inst.do_step(t, h)
            t += h
        now = inst.get(names)
        if all(abs(a - b) <= e for a, b, e in zip(now, last, tol, strict=True)):
            return t, now
        last = now
    raise RuntimeError(f"{names} still moving after {t_max:g} s: {last}")


def measure_null(spec: Mapping) -> dict:
    """The valve at null with its ports blocked (the rod held at mid-stroke: HELD_ROD,
    x_rod = v_rod = 0, ideal current, p_supply = valve.p_leak_ref).

    ``spec``: version, valve and/or params, di (A, the current step of the pressure gain;
    default: what moves p_A - p_B by 2 % of the supply at the valve's derived pressure
    gain, at most 2 % of the rated current). Returns the spec with: datasheet, derived,
    Q_supply (m3/s at i = 0: the null leakage), dp0 (Pa, p_A - p_B at i = 0), di and
    pressure_gain (Pa/A: (dp(+di) - dp(-di)) / (2 di), each held to its steady state);
    pressure_gain is nan where the valve's derived gain is 0 (no lap: unbounded) and no
    ``di`` was given."""
    version = spec["version"]
    params = valve_params(spec)
    sheet = datasheet(params)
    d = derived(version, params)
    held = {k: enumeration_value(k, v) if isinstance(v, str) else v for k, v in HELD_ROD.items()}
    values = {**params, **held, "driver": DRIVERS["ideal_current"]}
    p = sheet.p_leak_ref
    inputs = {"x_rod": 0.0, "v_rod": 0.0, "i_ref": 0.0, "p_supply": p}
    inst = _instance(version, values, inputs)
    names_ = ["Q_supply", "p_A", "p_B"]
    # the chambers start in the cylinder's force balance, not the bridge's: they settle
    # with the blocked ports' time constant (chamber compliance over the edges'
    # conductance, 0.3 s for 0.3 L/min), here to 1e-9 of the supply per 0.1 s
    tol = [1e-9 * max(d["Q_leak_null"], 1e-12), 1e-9 * p, 1e-9 * p]
    h, t_max = spec.get("h", 1e-3), spec.get("t_max", 100.0)
    t, (q0, pa, pb) = _settle_blocked(inst, 0.0, h, names_, tol, t_max)
    out = {**spec, "datasheet": sheet, "derived": d, "Q_supply": q0, "dp0": pa - pb, "t_settled": [t]}
    di = spec.get("di")
    if di is None and d.get("pressure_gain", 0.0) > 0:
        di = min(0.02 * p / d["pressure_gain"], 0.02 * sheet.i_rated)
    if not di:
        return {**out, "di": math.nan, "pressure_gain": math.nan}
    dp = []
    for i in (di, -di):
        inst.set("i_ref", i)
        t, (_, pa, pb) = _settle_blocked(inst, t, h, names_, tol, t_max)
        dp.append(pa - pb)
        out["t_settled"].append(t)
    return {**out, "di": di, "pressure_gain": (dp[0] - dp[1]) / (2 * di), "dp": dp}
