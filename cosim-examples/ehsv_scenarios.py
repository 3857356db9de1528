"""Shared helpers for the EhsvActuator FMUs: the one place for each fact used by the
demo (cosim-examples/current_step.py) and the pytest suite (tests/python).

* where the built archives are (``fmu_path``),
* the interface contract: variable names, nominal parameters, driver enumeration,
* an instance wrapper over fmpy's FMU2Slave / FMU3Slave that sets and gets by
  variable name and captures the FMU's log messages (``Ehsv``),
* a step scenario stepped by hand so the step instant is exact (``run_step``),
* the settling-time measure (``settling_time``),
* the paper's driver table and its three-driver run (``PAPER_DRIVERS``,
  ``compare_drivers``), with the mean over one PWM period (``period_average``),
* the exact solution of the linear cases (ideal_current and voltage drivers):
  matrix exponential in plain numpy (``linear_step_response``).

Only numpy and fmpy are needed. Nothing here builds anything: the archives are made by
``cargo run --release -p build-fmu`` (scripts/test.sh and scripts/demo.sh do it first).
"""
from __future__ import annotations

import atexit
import json
import math
import os
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
#: where build-fmu writes the archives; EHSV_FMU_DIR overrides it (e.g. archives built from
#: a clean checkout of a commit while the working tree is being edited)
FMU_DIR = Path(os.environ.get("EHSV_FMU_DIR") or REPO / "target" / "fmu")
VERSIONS = ("fmi2", "fmi3")


def fmu_path(version: str) -> Path:
    """Archive built by build-fmu for 'fmi2' or 'fmi3'."""
    if version not in VERSIONS:
        raise ValueError(f"unknown FMI version {version!r}, expected one of {VERSIONS}")
    return FMU_DIR / f"EhsvActuator-{version}.fmu"


def missing_fmu_message(version: str) -> str | None:
    path = fmu_path(version)
    if path.is_file():
        return None
    return (f"{path} does not exist: build the FMUs first with "
            f"`cargo run --release -p build-fmu` (scripts/test.sh does this before pytest)")


# --------------------------------------------------------------------------------------
# Interface contract (names, units, nominal values). Written down here from the project
# brief; fmu-src/src/variables.rs is the FMU's own table and the tests compare the two.
# --------------------------------------------------------------------------------------

#: coil driver enumeration (parameter ``driver``)
DRIVERS = {"ideal_current": 0, "voltage": 1, "opamp_pi": 2, "industrial": 3, "hbridge_pid": 4}

#: drivers whose output switches (PWM): the coil current carries a ripple at f_pwm, so its
#: figures are taken on the mean over one PWM period (``period_average``)
PWM_DRIVERS = ("hbridge_pid",)

#: inputs: name -> (unit, start)
INPUTS = {"i_ref": ("A", 0.0), "V_supply": ("V", 72.0)}

#: outputs: name -> unit (None for the Boolean)
OUTPUTS = {
    "i_coil": "A",
    "u_driver": "V",
    "driver_saturated": None,
    "x_flapper": "m",
    "x_spool": "m",
    "Q_valve": "m3/s",
}

#: parameters and their default (start) values, SI units
NOMINAL = {
    "driver": 2,               # opamp_pi
    "control_mode": 0,         # i_ref is the current command
    "driver.Kp": 1.6e5,        # V/A
    "driver.Ki": 5.0e7,        # V/(A s)
    "driver.V_drop": 0.0,      # V
    "driver.slew_rate": 2.0e7,  # V/s (20 V/us)
    "coil.L": 3.2,             # H
    "coil.R": 1000.0,          # ohm
    "coil.R_sense": 0.0,       # ohm
    "coil.K_b": 0.0,           # V s/m
    "valve.K1": 2.82462,       # N m/A   torque-motor gain
    "valve.Kf": 511.545,       # N m/m   net flapper stiffness
    "valve.Kw": 74.2853,       # N m/m   feedback-wire stiffness
    "valve.K2": 0.0967740,     # m2/s    hydraulic-amplifier flow gain
    "valve.K3": 0.664515,      # m2/s    spool flow gain
    "valve.A_s": 1.67742e-5,   # m2      spool end area
    "valve.zeta": 0.4,         # -       first-stage damping ratio
    "valve.f_n": 814.0,        # Hz      first-stage natural frequency
    "industrial.Kp": 2500.0,        # V/A       industrial linear PI current amplifier (driver 3)
    "industrial.Ki": 781250.0,      # V/(A s)   Ki/Kp = R/L
    "industrial.slew_rate": 1.0e6,  # V/s       1 V/us
    "hbridge.f_pwm": 20000.0,       # Hz        bipolar centre-aligned PWM (driver 4)
    "hbridge.f_sample": 20000.0,    # Hz        digital PI sampling, one-sample delay
    "hbridge.Kp": 9000.0,           # V/A
    "hbridge.Ki": 2812500.0,        # V/(A s)   Ki/Kp = R/L
    # (hbridge.feedforward, a Boolean, defaults to true)
    "valve.x_flapper_max": 0.0,     # m         travel limits, 0 = none
    "valve.x_spool_max": 0.0,       # m
}

#: steady-state flow gain Q_valve / i_coil = K3*K1/Kw, m3/s per A (0.025268)
FLOW_GAIN = NOMINAL["valve.K3"] * NOMINAL["valve.K1"] / NOMINAL["valve.Kw"]


# --------------------------------------------------------------------------------------
# Instances
# --------------------------------------------------------------------------------------

_unzipped: dict[str, str] = {}


def _unzip(path: Path) -> str:
    """Extracts an archive once per process (removed at exit)."""
    import fmpy

    key = str(path)
    if key not in _unzipped:
        _unzipped[key] = fmpy.extract(str(path))
        atexit.register(shutil.rmtree, _unzipped[key], True)
    return _unzipped[key]


@dataclass
class LogRecord:
    status: int
    category: str
    message: str

    def __str__(self) -> str:
        label = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"][self.status] \
            if 0 <= self.status <= 5 else str(self.status)
        return f"[{label}] [{self.category}] {self.message}"


@dataclass
class Ehsv:
    """One instance of the FMU, by hand, through fmpy's low-level classes.

    Log messages of the FMU are kept in ``log`` (FMI 2: a fmi2CallbackFunctions struct
    with our own logger plus fmpy's native proxy that formats the variadic message;
    FMI 3: ``FMU3Slave.instantiate(logMessage=...)``).
    """

    version: str
    logging_on: bool = False
    instance_name: str = "ehsv"
    log: list[LogRecord] = field(default_factory=list)

    def __post_init__(self):
        from fmpy import read_model_description

        msg = missing_fmu_message(self.version)
        if msg:
            raise FileNotFoundError(msg)
        path = fmu_path(self.version)
        self.md = read_model_description(str(path))
        self.variables = {v.name: v for v in self.md.modelVariables}
        unzipdir = _unzip(path)
        args = dict(guid=self.md.guid, unzipDirectory=unzipdir,
                    modelIdentifier=self.md.coSimulation.modelIdentifier,
                    instanceName=self.instance_name)
        if self.version == "fmi2":
            from ctypes import byref
            from fmpy.fmi2 import (FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE,
                                   fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE)
            from fmpy import calloc, free
            from fmpy.logging import addLoggerProxy

            def logger(_env, _instance, status, category, message):
                self.log.append(LogRecord(int(status), _dec(category), _dec(message)))

            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(logger)
            cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            addLoggerProxy(byref(cb))  # formats the printf-style message in C
            self._callbacks = cb       # keep alive as long as the instance
            self.fmu = FMU2Slave(**args)
            self.fmu.instantiate(callbacks=cb, loggingOn=self.logging_on)
        else:
            from fmpy.fmi3 import FMU3Slave

            def log_message(_env, status, category, message):
                self.log.append(LogRecord(int(status), _dec(category), _dec(message)))

            self.fmu = FMU3Slave(**args)
            self.fmu.instantiate(loggingOn=self.logging_on, logMessage=log_message)
        self._free = False

    # -- values by name ----------------------------------------------------------------
    def vr(self, name: str) -> int:
        try:
            return self.variables[name].valueReference
        except KeyError:
            raise KeyError(f"the FMU has no variable {name!r}") from None

    def set(self, name: str, value) -> None:
        var = self.variables.get(name)
        if var is None:
            raise KeyError(f"the FMU has no variable {name!r}")
        t = var.type
        if t in ("Real", "Float64"):
            (self.fmu.setReal if self.version == "fmi2" else self.fmu.setFloat64)([var.valueReference], [float(value)])
        elif t == "Boolean":
            self.fmu.setBoolean([var.valueReference], [bool(value)])
        elif t in ("Integer", "Enumeration", "Int64", "Int32"):
            if self.version == "fmi2":
                self.fmu.setInteger([var.valueReference], [int(value)])
            elif t == "Int32":
                self.fmu.setInt32([var.valueReference], [int(value)])
            else:
                self.fmu.setInt64([var.valueReference], [int(value)])
        else:
            raise TypeError(f"{name}: unsupported type {t}")

    def get(self, names) -> list[float]:
        """Values of the named variables (Booleans as 0.0/1.0), in the given order."""
        out = []
        reals = [n for n in names if self.variables[n].type in ("Real", "Float64")]
        real_vals = dict(zip(reals, (self.fmu.getReal if self.version == "fmi2" else self.fmu.getFloat64)(
            [self.vr(n) for n in reals]))) if reals else {}
        for n in names:
            if n in real_vals:
                out.append(float(real_vals[n]))
            elif self.variables[n].type == "Boolean":
                out.append(float(bool(self.fmu.getBoolean([self.vr(n)])[0])))
            elif self.version == "fmi2":
                out.append(float(self.fmu.getInteger([self.vr(n)])[0]))
            else:
                out.append(float(self.fmu.getInt64([self.vr(n)])[0]))
        return out

    # -- life cycle --------------------------------------------------------------------
    def initialize(self, start_time: float = 0.0, stop_time: float | None = None, **values) -> None:
        """Sets parameters/inputs (keyword names with '.' written as '__'), then
        enters and leaves initialisation mode."""
        for k, v in values.items():
            self.set(k.replace("__", "."), v)
        if self.version == "fmi2":
            self.fmu.setupExperiment(startTime=start_time, stopTime=stop_time)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=start_time, stopTime=stop_time)
        self.fmu.exitInitializationMode()

    def do_step(self, t: float, h: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)

    def free(self, terminate: bool = True) -> None:
        if self._free:
            return
        self._free = True
        try:
            if terminate:
                self.fmu.terminate()
        finally:
            self.fmu.freeInstance()

    def log_text(self) -> str:
        return "\n".join(str(r) for r in self.log)


def _dec(b) -> str:
    if b is None:
        return ""
    return b.decode("utf-8", "replace") if isinstance(b, bytes) else str(b)


# --------------------------------------------------------------------------------------
# Scenarios
# --------------------------------------------------------------------------------------

DEFAULT_OUTPUTS = ("i_coil", "u_driver", "driver_saturated", "x_flapper", "x_spool", "Q_valve")


def run_step(version: str, driver: str, i_step: float, *, h: float, t_stop: float,
             t_step: float = 0.0, i_before: float = 0.0, V_supply: float = 72.0,
             params: dict | None = None, outputs=DEFAULT_OUTPUTS) -> dict[str, np.ndarray]:
    """Steps i_ref from ``i_before`` to ``i_step`` at ``t_step`` (a communication point)
    and records ``outputs`` at every communication point 0, h, 2h, ... up to t_stop.

    The model is initialised in equilibrium with i_ref = i_before; at t_step the input is
    set just before the doStep that starts there, so the recorded value at t_step is the
    one before the step and everything after it sees the new command. Times are k*h,
    computed from integers, so runs with different h share their grid points exactly.
    """
    n = int(round(t_stop / h))
    k_step = int(round(t_step / h))
    if abs(k_step * h - t_step) > 1e-12 * max(1.0, t_step) or abs(n * h - t_stop) > 1e-9 * t_stop:
        raise ValueError("t_step and t_stop must be multiples of h")
    values = dict(params or {})
    values.setdefault("driver", DRIVERS[driver])
    inst = Ehsv(version)
    try:
        for k, v in values.items():
            inst.set(k, v)
        inst.set("i_ref", i_before)
        inst.set("V_supply", V_supply)
        inst.initialize(start_time=0.0, stop_time=t_stop)
        rec = np.empty((n + 1, len(outputs)))
        rec[0] = inst.get(outputs)
        for k in range(n):
            if k == k_step:
                inst.set("i_ref", i_step)
            inst.do_step(k * h, h)
            rec[k + 1] = inst.get(outputs)
        inst.free()
    except Exception as e:  # keep the FMU's own words with the exception
        if inst.log:
            raise RuntimeError(f"{e}\nFMU log:\n{inst.log_text()}") from e
        raise
    result = {"time": np.arange(n + 1) * h}
    for j, name in enumerate(outputs):
        result[name] = rec[:, j]
    return result


def settling_time(t, y, t_step: float, band: float, y_final: float | None = None,
                  y_initial: float | None = None) -> float:
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


# --------------------------------------------------------------------------------------
# Driver comparison (the paper's table: current settling time of a 0 -> 5 mA step)
# --------------------------------------------------------------------------------------

#: the paper's reference: valve settling with a voltage drive (T_torque), s
PAPER_T_TORQUE = 10.8e-3

#: tolerance of the paper comparison: the FMU's settling time within +-10 % of the paper's
PAPER_TOLERANCE = 0.10


@dataclass(frozen=True)
class PaperDriver:
    """One line of the paper's driver table and the spec row that pins it down."""
    driver: str          # name in DRIVERS
    label: str           # the paper's name for it
    V_supply: float      # V, supply of the spec row
    paper_ms: float      # the paper's 2 % current settling time, ms
    paper_pct: float     # the paper's figure as % of T_torque
    row: int             # spec row
    band: tuple          # (lo, hi) s: the spec row's band for the 2 % settling time

    @property
    def code(self) -> int:
        return DRIVERS[self.driver]

    @property
    def averaged(self) -> bool:
        """The settling time is that of the PWM-period mean of i_coil."""
        return self.driver in PWM_DRIVERS

    @property
    def paper_band(self) -> tuple:
        return (self.paper_ms * 1e-3 * (1 - PAPER_TOLERANCE), self.paper_ms * 1e-3 * (1 + PAPER_TOLERANCE))


#: the paper's table, fastest first (op-amp < H-bridge < industrial); every step is
#: i_ref 0 -> 5 mA at t = 0 from rest with nominal parameters
PAPER_DRIVERS = (
    PaperDriver("opamp_pi", "proposed op-amp driver", 72.0, 0.25, 2.0, 1, (0.225e-3, 0.275e-3)),
    PaperDriver("hbridge_pid", "H-bridge topology", 12.0, 2.0, 18.0, 5, (1.7e-3, 2.3e-3)),
    PaperDriver("industrial", "My-502 industrial driver", 24.0, 5.0, 50.0, 4, (4.5e-3, 5.5e-3)),
)
PAPER_STEP = 5e-3      # A, the table's current step
COMPARE_H = 1e-6       # s, output interval of the comparison runs (50 samples per PWM period)
COMPARE_T_STOP = 20e-3  # s, four times the slowest settling time


def pwm_period(params: dict | None = None) -> float:
    """PWM period of the H-bridge driver, s (1/hbridge.f_pwm)."""
    return 1.0 / {**NOMINAL, **(params or {})}["hbridge.f_pwm"]


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


@dataclass
class DriverResult:
    """One driver's step response and figures, from ``compare_drivers``."""
    spec: PaperDriver
    run: dict            # run_step's record: time and DEFAULT_OUTPUTS
    t_avg: np.ndarray    # time of the PWM-period means (the run's time for linear drivers)
    i_avg: np.ndarray    # i_coil, period-averaged for the PWM driver, else the raw samples
    u_avg: np.ndarray    # u_driver likewise
    settling: float      # s, 2 % settling time of i_avg around the command, from the step
    ripple: float        # A, peak-to-peak of raw i_coil over the last PWM period (0 if linear)

    @property
    def pct_of_t_torque(self) -> float:
        return 100.0 * self.settling / PAPER_T_TORQUE


def driver_step(version: str, spec: PaperDriver, *, h: float = COMPARE_H,
                t_stop: float = COMPARE_T_STOP, params: dict | None = None) -> DriverResult:
    """The paper's 0 -> 5 mA step for one driver at its row's supply, with its figures.

    Settling time: last time i_coil (the PWM driver: its mean over one PWM period) is
    outside +-2 % of the 5 mA step around the command (the PI loops have no steady-state
    error), measured from the step at t = 0 (settling_time with y_final = command)."""
    r = run_step(version, spec.driver, PAPER_STEP, h=h, t_stop=t_stop, V_supply=spec.V_supply,
                 params=params)
    t = r["time"]
    if spec.averaged:
        period = pwm_period(params)
        t_avg, i_avg = period_average(t, r["i_coil"], period)
        _, u_avg = period_average(t, r["u_driver"], period)
        n = int(round(period / h))
        ripple = float(np.ptp(r["i_coil"][-(n + 1):]))
    else:
        t_avg, i_avg, u_avg, ripple = t, r["i_coil"], r["u_driver"], 0.0
    ts = settling_time(t_avg, i_avg, 0.0, 0.02, y_final=PAPER_STEP, y_initial=0.0)
    return DriverResult(spec, r, t_avg, i_avg, u_avg, ts, ripple)


def compare_drivers(version: str, *, h: float = COMPARE_H, t_stop: float = COMPARE_T_STOP) -> dict[str, DriverResult]:
    """Runs the three drivers of the paper's table in one go (PAPER_DRIVERS: op-amp at
    72 V, H-bridge at 12 V, industrial at 24 V; 0 -> 5 mA at t = 0, nominal parameters,
    outputs every ``h``) and returns {driver name: DriverResult}, fastest first."""
    return {spec.driver: driver_step(version, spec, h=h, t_stop=t_stop) for spec in PAPER_DRIVERS}


def driver_table(results: dict[str, DriverResult]) -> str:
    """The paper's table beside the FMU's figures, as text."""
    head = (f"{'driver':<12} {'paper name':<26} {'supply':>6} {'paper ms':>8} {'FMU ms':>8} "
            f"{'paper %':>7} {'FMU %':>6}  spec band (row)")
    lines = [head, "-" * len(head)]
    for name, res in results.items():
        s = res.spec
        lines.append(f"{name:<12} {s.label:<26} {s.V_supply:>4.0f} V {s.paper_ms:>8.2f} "
                     f"{res.settling * 1e3:>8.4f} {s.paper_pct:>6.0f}% {res.pct_of_t_torque:>5.1f}%  "
                     f"{s.band[0] * 1e3:g}-{s.band[1] * 1e3:g} ms (row {s.row})")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------
# Exact solution of the linear cases
# --------------------------------------------------------------------------------------

def expm(a: np.ndarray) -> np.ndarray:
    """Matrix exponential: scaling and squaring with a Taylor series (numpy only).

    The matrix is scaled by 2**-s so its 1-norm is below 1/2; 30 Taylor terms are then far
    below double rounding (0.5**30/30! ~ 4e-42), and s squarings undo the scaling.
    """
    a = np.asarray(a, float)
    norm = np.linalg.norm(a, 1)
    s = max(0, int(math.ceil(math.log2(norm / 0.5)))) if norm > 0.5 else 0
    b = a / (2.0 ** s)
    result = np.eye(len(a))
    term = np.eye(len(a))
    for k in range(1, 31):
        term = term @ b / k
        result = result + term
    for _ in range(s):
        result = result @ result
    return result


def linear_model(driver: str, p: dict | None = None):
    """State-space (A, B, names) of the linear cases with the coil current command as the
    single input u = i_ref (held constant between communication points).

    First stage (flapper): x_f'' + 2 zeta wn x_f' + wn^2 x_f = wn^2 (K1 i - Kw x_s) / Kf,
    spool: x_s' = (K2 / A_s) x_f, flow: Q = K3 x_s, wn = 2 pi f_n.
    ideal_current: i = i_ref, states (x_f, v_f, x_s).
    voltage: u = (R + R_sense) i_ref (below the rails), L i' = u - (R + R_sense) i,
    states (i, x_f, v_f, x_s).
    """
    p = {**NOMINAL, **(p or {})}
    wn = 2 * math.pi * p["valve.f_n"]
    z = p["valve.zeta"]
    g = wn * wn / p["valve.Kf"]
    c_spool = p["valve.K2"] / p["valve.A_s"]
    valve = np.array([
        [0.0, 1.0, 0.0],
        [-wn * wn, -2 * z * wn, -g * p["valve.Kw"]],
        [c_spool, 0.0, 0.0],
    ])
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


def linear_step_response(driver: str, i_step: float, t, p: dict | None = None) -> dict[str, np.ndarray]:
    """Exact response to i_ref stepping from 0 to i_step at t = 0 (from rest), at times t.

    For a constant input the augmented system [[A, B], [0, 0]] has the state (x, u), so
    x(t) is the top of expm(M t) (0, ..., 0, u). Each time is evaluated directly (no
    accumulated rounding). Returns i_coil, x_flapper, x_spool and Q_valve.
    """
    p = {**NOMINAL, **(p or {})}
    a, b, names = linear_model(driver, p)
    n = len(a)
    m = np.zeros((n + 1, n + 1))
    m[:n, :n] = a
    m[:n, n] = b
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


def linear_step_response_dense(driver: str, i_step: float, dt: float, t_stop: float,
                               p: dict | None = None) -> dict[str, np.ndarray]:
    """Like linear_step_response on the grid k*dt, propagated with one transition matrix
    (fast for fine grids; rounding grows ~1e-16 per step)."""
    p = {**NOMINAL, **(p or {})}
    a, b, names = linear_model(driver, p)
    n = len(a)
    m = np.zeros((n + 1, n + 1))
    m[:n, :n] = a
    m[:n, n] = b
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


# --------------------------------------------------------------------------------------
# Bad input cases (run in a child process by the tests: a crash cannot take pytest down)
# --------------------------------------------------------------------------------------

BAD_INPUT_CASES = ("nan_input", "negative_step", "coil_L_negative")


def bad_input_case(version: str, case: str) -> dict:
    """Runs one bad-input case; returns what happened: the exception text (fmpy raises
    FMICallException for Error/Fatal), its FMI status, the captured log, and whether the
    instance could still be freed afterwards."""
    from fmpy.fmi1 import FMICallException

    inst = Ehsv(version, logging_on=False)
    result = {"case": case, "version": version, "exception": None, "status": None,
              "function": None, "log": [], "freed": False}
    try:
        if case == "coil_L_negative":
            inst.set("coil.L", -1.0)
            inst.initialize()
        else:
            inst.initialize()
            if case == "nan_input":
                inst.set("i_ref", float("nan"))
                inst.do_step(0.0, 1e-4)
            elif case == "negative_step":
                inst.do_step(0.0, -1e-4)
            else:
                raise ValueError(f"unknown case {case}")
    except FMICallException as e:
        result.update(exception=str(e), status=e.status, function=e.function)
    except Exception as e:  # anything else is reported, not swallowed
        result.update(exception=f"{type(e).__name__}: {e}")
    result["log"] = [[r.status, r.category, r.message] for r in inst.log]
    inst.free(terminate=False)  # after Error only freeInstance/reset are allowed
    result["freed"] = True
    return result


if __name__ == "__main__":
    # python ehsv_scenarios.py bad-input fmi2 nan_input  -> one JSON line
    if len(sys.argv) == 4 and sys.argv[1] == "bad-input":
        print(json.dumps(bad_input_case(sys.argv[2], sys.argv[3])))
    else:
        sys.exit("usage: ehsv_scenarios.py bad-input {fmi2|fmi3} {" + "|".join(BAD_INPUT_CASES) + "}")
