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
* the cylinder and the outer loops: a scenario with any inputs changed at one instant
  (``run_scenario``), the paper's flow-loop comparison at 72 V and 10 V (``PAPER_FLOW``,
  ``flow_step``, ``compare_flow_supplies``, ``flow_table``), the cylinder geometry
  (``CYLINDER``), chamber A's volume balance (``volume_balance``), the spring-mass
  end-stop penetration (``impact_estimate``) and an independent RK4 integration of the
  cylinder equations (``cylinder_reference``),
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

#: outer-loop enumeration (parameter ``control_mode``): which command drives the coil current
CONTROL_MODES = {"current": 0, "flow": 1, "position": 2}

#: inputs: name -> (unit, start)
INPUTS = {
    "i_ref": ("A", 0.0),
    "V_supply": ("V", 72.0),
    "p_supply": ("Pa", 6.8948e6),   # gauge; 1000 psi = valve.dp_rated
    "F_ext": ("N", 0.0),            # on the rod, + towards +x (extension)
    "Q_ref": ("m3/s", 0.0),         # control_mode 1
    "x_ref": ("m", 0.0),            # control_mode 2, 0 = mid-stroke
}

#: outputs: name -> unit (None for the Boolean)
OUTPUTS = {
    "i_coil": "A",
    "u_driver": "V",
    "driver_saturated": None,
    "x_flapper": "m",
    "x_spool": "m",
    "Q_valve": "m3/s",
    "Q_A": "m3/s",
    "Q_B": "m3/s",
    "p_A": "Pa",
    "p_B": "Pa",
    "x_piston": "m",
    "v_piston": "m/s",
    "F_hydraulic": "N",
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
    # cylinder, load and valve ports (fmu-src/src/hydraulics.rs has the model notes)
    "cylinder.bore": 0.016,         # m
    "cylinder.rod": 0.010,          # m         rod on the B side
    "cylinder.stroke": 0.080,       # m         end stops at +-stroke/2
    "cylinder.mass": 5.0,           # kg
    "cylinder.beta": 1.0e9,         # Pa
    "cylinder.V_dead": 2.0e-6,      # m3        per chamber
    "cylinder.b_viscous": 200.0,    # N s/m
    "cylinder.F_coulomb": 20.0,     # N
    "cylinder.F_static": 30.0,      # N
    "cylinder.v_stribeck": 0.01,    # m/s
    "cylinder.v_friction_smooth": 1.0e-4,  # m/s  tanh(v/v) in place of sign(v)
    "cylinder.k_endstop": 1.0e8,    # N/m
    "cylinder.c_endstop": 1.0e4,    # N s/m
    "valve.dp_rated": 6.8948e6,     # Pa        total rated drop (1000 psi)
    "valve.dp_laminar": 1.0e5,      # Pa
    "hydraulics.p_tank": 0.0,       # Pa gauge
    "hydraulics.p_cavitation": -0.9e5,  # Pa gauge (0.1 bar absolute)
    "hydraulics.dp_cavitation_band": 5.0e4,  # Pa
    "cylinder.C_leak": 0.0,         # m3/(s Pa)  internal leakage (none)
    "cylinder.C_leak_external": 0.0,  # m3/(s Pa)
    # outer loops (control_mode 1 and 2)
    "loop.f_sample": 20000.0,       # Hz
    "loop.i_max": 0.01,             # A         rated current
    # (the flow and position PID gains are tuned defaults, not the contract: the FMU's
    # variable table, documentation/index.html in each archive, has them)
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
    values = dict(params or {})
    values.setdefault("driver", DRIVERS[driver])
    return run_scenario(version, h=h, t_stop=t_stop, params=values,
                        initial={"i_ref": i_before, "V_supply": V_supply},
                        changes={"i_ref": i_step}, t_change=t_step, outputs=outputs)


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
# Cylinder, load and the outer loops (control_mode 1 flow, 2 position)
# --------------------------------------------------------------------------------------

#: outputs of the hydraulic runs
HYDRAULIC_OUTPUTS = ("i_coil", "u_driver", "x_spool", "Q_valve", "Q_A", "Q_B", "p_A", "p_B",
                     "x_piston", "v_piston", "F_hydraulic")


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
    def from_params(cls, params: dict | None = None) -> "Cylinder":
        p = {**NOMINAL, **(params or {})}
        return cls(p["cylinder.bore"], p["cylinder.rod"], p["cylinder.stroke"], p["cylinder.mass"],
                   p["cylinder.beta"], p["cylinder.V_dead"], p["cylinder.k_endstop"],
                   p["cylinder.c_endstop"], p["hydraulics.p_tank"], p["hydraulics.p_cavitation"])

    @property
    def area_a(self) -> float:
        return math.pi / 4 * self.bore ** 2

    @property
    def area_b(self) -> float:
        return self.area_a - math.pi / 4 * self.rod ** 2

    def stall_force(self, p_supply: float = INPUTS["p_supply"][1]) -> float:
        """Extension stall force (p_S - p_T) * A_A, N."""
        return (p_supply - self.p_tank) * self.area_a

    def volume_a(self, x):
        """Oil volume of chamber A at piston position x (0 = mid-stroke), m3."""
        return self.v_dead + self.area_a * (np.asarray(x, float) + self.stroke / 2)


CYLINDER = Cylinder.from_params()


def run_scenario(version: str, *, h: float, t_stop: float, params: dict | None = None,
                 initial: dict | None = None, changes: dict | None = None, t_change: float = 0.0,
                 outputs=HYDRAULIC_OUTPUTS) -> dict[str, np.ndarray]:
    """General form of run_step: ``params`` and the ``initial`` inputs are set before
    initialisation (the model starts in equilibrium with them), ``changes`` (input name ->
    value) are set just before the doStep that starts at ``t_change``; ``outputs`` are
    recorded at every communication point k*h up to t_stop (times from integers, so runs
    with different h share their grid points exactly)."""
    n = int(round(t_stop / h))
    k_change = int(round(t_change / h))
    if abs(k_change * h - t_change) > 1e-12 * max(1.0, t_change) or abs(n * h - t_stop) > 1e-9 * t_stop:
        raise ValueError("t_change and t_stop must be multiples of h")
    inst = Ehsv(version)
    try:
        for k, v in {**(params or {}), **(initial or {})}.items():
            inst.set(k, v)
        inst.initialize(start_time=0.0, stop_time=t_stop)
        rec = np.empty((n + 1, len(outputs)))
        rec[0] = inst.get(outputs)
        for k in range(n):
            if k == k_change:
                for name, v in (changes or {}).items():
                    inst.set(name, v)
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


# -- the flow loop: the paper's Fig. 10/11 (rows 8 and 9) ---------------------------------

FLOW_STEP = 2e-4        # m3/s, Q_ref 0 -> 2e-4 at t = 0 (rows 8 and 9)
FLOW_H = 1e-5           # s, output interval (the loop samples every 50 us)
FLOW_T_STOP = 30e-3     # s, five times the slower settling time


@dataclass(frozen=True)
class PaperFlowRun:
    """One supply of the paper's flow-loop comparison and its spec row."""
    V_supply: float     # V
    paper_ms: float     # the paper's 5 % settling time of the valve flow, ms
    row: int
    band: tuple         # (lo, hi) s of the spec row (lo 0: only an upper bound)


#: the paper's Fig. 10 (high-voltage driver, 3.3 ms) and Fig. 11 (low-voltage, 6 ms = 181 %)
PAPER_FLOW = (
    PaperFlowRun(72.0, 3.3, 8, (0.0, 3.6e-3)),
    PaperFlowRun(10.0, 6.0, 9, (5.4e-3, 6.6e-3)),
)
PAPER_FLOW_RATIO = 1.81   # the paper: low-voltage settling is 181 % of the high-voltage one
FLOW_RATIO_MIN = 1.6      # row 9: >= 1.6 x row 8


@dataclass
class FlowStepResult:
    V_supply: float
    h: float
    run: dict           # run_scenario's record (HYDRAULIC_OUTPUTS)
    settling: float     # s, 5 % settling time of Q_valve around Q_ref, from the step


def flow_step(version: str, v_supply: float, h: float = FLOW_H, *, t_stop: float = FLOW_T_STOP,
              q_step: float = FLOW_STEP, params: dict | None = None,
              outputs=HYDRAULIC_OUTPUTS) -> FlowStepResult:
    """Rows 8/9: opamp_pi, control_mode 1 (flow PID + feed-forward), Q_ref 0 -> q_step at
    t = 0 from the equilibrium at mid-stroke, F_ext 0, p_supply nominal. Settling time:
    last time Q_valve is outside +-5 % of the step around Q_ref (the PI loop has no
    steady-state error), from the step."""
    values = {"driver": DRIVERS["opamp_pi"], "control_mode": CONTROL_MODES["flow"], **(params or {})}
    r = run_scenario(version, h=h, t_stop=t_stop, params=values,
                     initial={"V_supply": v_supply, "Q_ref": 0.0}, changes={"Q_ref": q_step},
                     outputs=outputs)
    ts = settling_time(r["time"], r["Q_valve"], 0.0, 0.05, y_final=q_step, y_initial=0.0)
    return FlowStepResult(v_supply, h, r, ts)


def compare_flow_supplies(version: str, h: float = FLOW_H) -> dict[float, FlowStepResult]:
    """The flow step at both supplies of the paper (72 V, 10 V): {V_supply: result}."""
    return {spec.V_supply: flow_step(version, spec.V_supply, h) for spec in PAPER_FLOW}


def flow_table(results: dict[float, FlowStepResult]) -> str:
    """Settling times of the flow step beside the paper's, and their ratio, as text."""
    head = f"{'supply':>6} {'paper ms':>8} {'FMU ms':>8}  spec band (row)"
    lines = [head, "-" * len(head)]
    for spec in PAPER_FLOW:
        res = results[spec.V_supply]
        band = (f"<= {spec.band[1] * 1e3:g} ms" if spec.band[0] == 0
                else f"{spec.band[0] * 1e3:g}-{spec.band[1] * 1e3:g} ms")
        lines.append(f"{spec.V_supply:>4.0f} V {spec.paper_ms:>8.2f} {res.settling * 1e3:>8.4f}  {band} (row {spec.row})")
    hi, lo = (results[spec.V_supply].settling for spec in PAPER_FLOW)
    lines.append(f"ratio 10 V / 72 V: FMU {lo / hi * 100:.0f} %, paper {PAPER_FLOW_RATIO * 100:.0f} % "
                 f"(row 9: >= {FLOW_RATIO_MIN * 100:.0f} %)")
    return "\n".join(lines)


def volume_balance(run: dict, cyl: Cylinder = CYLINDER) -> dict[str, float]:
    """Volume balance of chamber A over a recorded run (no leakage):
    integral of Q_A dt = A_A * (x_end - x_0) + compressed volume.

    ``inflow``: trapezoid integral of Q_A over the samples; ``displaced``: A_A * dx;
    ``compressed``: V_A(x_end)/beta * (p_A_end - p_A_0) (the end-point form);
    ``compressed_path``: trapezoid integral of V_A/beta dp_A along the run (the exact form
    when V_A changes during the run); ``residual`` and ``residual_path``: inflow minus
    displaced minus each, relative to |inflow|."""
    t, q, x, p = run["time"], run["Q_A"], run["x_piston"], run["p_A"]
    inflow = float(np.sum(0.5 * (q[1:] + q[:-1]) * np.diff(t)))
    displaced = cyl.area_a * float(x[-1] - x[0])
    compressed = float(cyl.volume_a(x[-1]) / cyl.beta * (p[-1] - p[0]))
    va = cyl.volume_a(x)
    compressed_path = float(np.sum(0.5 * (va[1:] + va[:-1]) / cyl.beta * np.diff(p)))
    return {"inflow": inflow, "displaced": displaced, "compressed": compressed,
            "compressed_path": compressed_path,
            "residual": (inflow - displaced - compressed) / abs(inflow),
            "residual_path": (inflow - displaced - compressed_path) / abs(inflow)}


def impact_estimate(v_impact: float, cyl: Cylinder = CYLINDER, force: float = 0.0) -> float:
    """Peak end-stop penetration of a mass ``cyl.mass`` hitting the spring-damper stop
    (k_endstop, c_endstop) at ``v_impact`` with a constant ``force`` pressing it in:
    the linear damped oscillator x'' + 2 zeta w x' + w^2 x = F/m from x = 0, x' = v
    (the contact force k d + c d' stays positive until the peak, so the no-pull rule does
    not act before it). Ignores the change of the hydraulic force during the contact."""
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


# -- an independent reference for the cylinder: the model notes' equations, plain RK4 -----

def cylinder_derivatives(y, x_s: float, p_supply: float, f_ext: float, params: dict | None = None):
    """[p_A', p_B', x', v'] of the cylinder model as fmu-src/src/hydraulics.rs documents it
    (gauge pressures; critically centred ports with the signed square root made laminar
    below dp_laminar by the C1 odd cubic; cavitation floor by fading an emptying chamber's
    bulk modulus over dp_cavitation_band; smooth Stribeck friction with tanh; end stops as
    spring-dampers that never pull; no leakage), written again here in plain Python so
    the FMU's integrator can be checked against an independent one."""
    p = {**NOMINAL, **(params or {})}
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
    dry = p["cylinder.F_coulomb"] + (p["cylinder.F_static"] - p["cylinder.F_coulomb"]) * math.exp(-(v / p["cylinder.v_stribeck"]) ** 2)
    friction = dry * math.tanh(v / p["cylinder.v_friction_smooth"]) + p["cylinder.b_viscous"] * v
    if x > half:
        stop = -max(cyl.k_endstop * (x - half) + cyl.c_endstop * v, 0.0)
    elif x < -half:
        stop = max(cyl.k_endstop * (-half - x) - cyl.c_endstop * v, 0.0)
    else:
        stop = 0.0
    force = p_a * a_a - p_b * a_b - friction + f_ext + stop
    return (cyl.beta / vol_a * in_a * fade(p_a, in_a), cyl.beta / vol_b * in_b * fade(p_b, in_b),
            v, force / cyl.mass)


def cylinder_reference(y0, x_s: float, *, h: float, n: int, substeps: int, p_supply: float = INPUTS["p_supply"][1],
                       f_ext: float = 0.0, params: dict | None = None) -> np.ndarray:
    """Classical RK4 of cylinder_derivatives at a constant spool position from state y0
    = (p_A, p_B, x, v), ``substeps`` fixed steps per output interval h; returns the states
    at 0, h, ..., n*h (rows). With h/substeps = 0.25 us every eigenvalue of the model
    (the model notes list them down to -1.4e5 1/s; the contact mode is ~4.5e3 rad/s) has
    |lambda dt| < 0.04, far inside RK4's stability region."""
    dt = h / substeps
    y = np.array(y0, float)
    out = np.empty((n + 1, 4))
    out[0] = y

    def f(z):
        return np.array(cylinder_derivatives(z, x_s, p_supply, f_ext, params))

    for k in range(n):
        for _ in range(substeps):
            k1 = f(y)
            k2 = f(y + 0.5 * dt * k1)
            k3 = f(y + 0.5 * dt * k2)
            k4 = f(y + dt * k3)
            y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out[k + 1] = y
    return out


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
    p = {**NOMINAL, **(p or {})}
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


def linear_step_response_dense(driver: str, i_step: float, dt: float, t_stop: float,
                               p: dict | None = None) -> dict[str, np.ndarray]:
    """Like linear_step_response on the grid k*dt, propagated with one transition matrix
    (fast for fine grids; rounding grows ~1e-16 per step)."""
    p = {**NOMINAL, **(p or {})}
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


def save_figure(fig, out) -> None:
    """Lays out ``fig`` and writes it to ``out`` (a Path), creating the folder."""
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
