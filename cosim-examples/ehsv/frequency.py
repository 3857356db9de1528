"""Frequency responses: measured through the FMU by sine excitation, and the analytic
transfer functions of the paper (eq. 3: ideal current source, eq. 4: with the coil's
current dynamics) and of the PI current loop.

Method (``sine_response``). The FMU holds its inputs between communication points, so a
sine input is a staircase. Each step of length h = 1/(N f) holds the sine's value at the
step's midpoint; the fundamental of that staircase is exactly sinc(pi f h) times the sine,
with no phase shift (the half-step delay of sampling at the step start is gone). The
FMU is initialised at rest with the input at its offset, the sine starts at t = 0, the
run settles for ``settle`` seconds (a whole number of periods), then the outputs at the
communication points of the next K whole periods give the fundamental by a discrete
Fourier sum at f (exact for a sinusoid sampled over whole periods). The complex gain is
that fundamental over the staircase's fundamental. What remains is aliasing: the
staircase's images at (kN +- 1) f, each sinc-weighted (about 1/N), pass through the model
and fold onto f at the sampled outputs; with the steps below (N = 2048 per period, or
steps of 1 to 50 us) and the model rolling off, this stays below 1e-3 of the gain
(0.01 dB) for every curve here. Step sizes: see H_MIN, H_MAX.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .contract import CONTROL_MODES, DRIVERS, flow_gain, parameters
from .fmu import pooled_instance

#: samples (communication steps) per sine period, within the step limits below
SAMPLES_PER_PERIOD = 2048

#: shortest communication step, s (above 488 Hz there are fewer samples per period).
#: Outputs that follow the input within a step (the ideal current source's i_coil) see
#: the staircase itself, which lags the sine by h/2: -180 f h degrees, 0.09 degree at
#: 500 Hz, 3.6 degrees at 20 kHz. A high-gain loop also answers each stair with a kick of
#: Kp (2 pi f A h) volts; at 1 us that stays below 1 % of the rail for the onsets measured.
H_MIN = 1e-6

#: longest communication step, s (below 9.8 Hz), short against the 1.2 ms spool mode
H_MAX = 50e-6


# --------------------------------------------------------------------------------------
# Analytic transfer functions
# --------------------------------------------------------------------------------------


def eq3(f, params: dict | None = None):
    """The paper's eq. 3, Q_valve / i for an ideal current source (complex, m3/s per A):
    alpha / (A/wn^2 s^3 + A 2 zeta/wn s^2 + A s + beta), alpha = K1 K2 K3 / Kf,
    beta = Kw K2 / Kf, A the spool end area, s = j 2 pi f."""
    p = parameters(params)
    s = 2j * math.pi * np.asarray(f, float)
    wn = 2 * math.pi * p["valve.f_n"]
    a = p["valve.A_s"]
    alpha = p["valve.K1"] * p["valve.K2"] * p["valve.K3"] / p["valve.Kf"]
    beta = p["valve.Kw"] * p["valve.K2"] / p["valve.Kf"]
    return alpha / (a / wn**2 * s**3 + a * (2 * p["valve.zeta"] / wn) * s**2 + a * s + beta)


def coil_lag(f, params: dict | None = None):
    """i / i_cmd of the voltage drive u = R_t i_cmd: 1 / (1 + (L/R_t) s), R_t = R + R_sense."""
    p = parameters(params)
    s = 2j * math.pi * np.asarray(f, float)
    return 1.0 / (1.0 + p["coil.L"] / (p["coil.R"] + p["coil.R_sense"]) * s)


def eq4(f, params: dict | None = None):
    """The paper's eq. 4 with the voltage driver's u = R_t i_cmd: Q_valve / i_cmd =
    eq. 3 x 1 / (1 + (L/R_t) s) (complex, m3/s per A)."""
    return eq3(f, params) * coil_lag(f, params)


def pi_loop(f, params: dict | None = None, prefix: str = "driver"):
    """i / i_cmd of a continuous PI current loop around the coil, below its rails:
    (Kp s + Ki) / (L s^2 + (R_t + Kp) s + Ki); with Ki/Kp = R_t/L it is Kp / (L s + Kp).
    ``prefix`` "driver" (opamp_pi) or "industrial"."""
    p = parameters(params)
    s = 2j * math.pi * np.asarray(f, float)
    kp, ki = p[f"{prefix}.Kp"], p[f"{prefix}.Ki"]
    r = p["coil.R"] + p["coil.R_sense"]
    return (kp * s + ki) / (p["coil.L"] * s**2 + (r + kp) * s + ki)


def analytic(driver: str, output: str, f, params: dict | None = None):
    """Small-signal i_ref -> ``output`` ("i_coil" or "Q_valve") of the linear drivers
    (the PI drivers below their rails and slew limits); None for hbridge_pid."""
    current = {
        "ideal_current": lambda: np.ones_like(np.asarray(f, float), dtype=complex),
        "voltage": lambda: coil_lag(f, params),
        "opamp_pi": lambda: pi_loop(f, params, "driver"),
        "industrial": lambda: pi_loop(f, params, "industrial"),
    }.get(driver)
    if current is None:
        return None
    g = current()
    return g if output == "i_coil" else g * eq3(f, params)


def slew_limit(v_supply: float, amplitude: float, params: dict | None = None) -> float:
    """(V - R_t A) / (2 pi L A): the frequency above which a sine of amplitude A needs a
    current slope larger than the slope the rail gives at the sine's peak, Hz."""
    p = parameters(params)
    r = p["coil.R"] + p["coil.R_sense"]
    return (v_supply - r * amplitude) / (2 * math.pi * p["coil.L"] * amplitude)


def rail_limit(v_supply: float, amplitude: float, params: dict | None = None) -> float:
    """The frequency at which the voltage a sine current of amplitude A needs,
    A sqrt(R_t^2 + (2 pi f L)^2), reaches the rail V: sqrt((V/A)^2 - R_t^2) / (2 pi L), Hz.
    A driver that tracks the sine (its error small) starts to saturate there."""
    p = parameters(params)
    r = p["coil.R"] + p["coil.R_sense"]
    return math.sqrt(max((v_supply / amplitude) ** 2 - r**2, 0.0)) / (2 * math.pi * p["coil.L"])


# --------------------------------------------------------------------------------------
# Measurement through the FMU
# --------------------------------------------------------------------------------------


@dataclass
class SineResult:
    f: float  # Hz
    amplitude: float  # of the input, in its unit
    h: float  # s, communication step
    gains: dict = field(default_factory=dict)  # output -> complex gain (output unit per input unit)
    saturated: bool = False  # the driver touched a rail during the measured periods
    steps: int = 0


def settle_time(driver: str, params: dict | None = None, control_mode: str = "current") -> float:
    """How long the start transient needs to fade below 1e-5 (12 time constants of the
    slowest mode the sine excites), s."""
    p = parameters(params)
    r = p["coil.R"] + p["coil.R_sense"]
    spool = p["valve.A_s"] * p["valve.Kf"] / (p["valve.Kw"] * p["valve.K2"])
    coil = p["coil.L"] / r
    tau = {
        "ideal_current": spool,
        "voltage": max(spool, coil),
        "opamp_pi": max(spool, p["coil.L"] / p["driver.Kp"]),
        "industrial": max(spool, p["coil.L"] / p["industrial.Kp"]),
        "hbridge_pid": max(spool, coil),  # the digital PI cancels the coil pole only nearly
    }[driver]
    if control_mode != "current":
        tau = max(tau, coil)
    return 12 * tau


def sine_response(
    version: str,
    driver: str,
    f: float,
    amplitude: float,
    *,
    input: str = "i_ref",
    outputs=("i_coil", "Q_valve"),
    offset: float = 0.0,
    V_supply: float = 72.0,
    control_mode: str = "current",
    params: dict | None = None,
    samples: int = SAMPLES_PER_PERIOD,
    h_min: float = H_MIN,
    h_max: float = H_MAX,
    settle: float | None = None,
    min_window: float = 5e-3,
    min_periods: int = 1,
) -> SineResult:
    """Fundamental gain input -> each output at frequency f (module docstring: method).

    The step is period/samples, kept within [h_min, h_max]. ``settle`` defaults to settle_time();
    the measured window is the longer of ``min_periods`` periods and ``min_window``
    seconds, in whole periods."""
    period = 1.0 / f
    samples = min(max(samples, math.ceil(period / h_max)), max(2, math.floor(period / h_min)))
    h = period / samples
    settle = settle_time(driver, params, control_mode) if settle is None else settle
    n_settle = math.ceil(settle / h)
    n_fit = samples * max(min_periods, math.ceil(min_window / period))
    values = {"driver": DRIVERS[driver], "control_mode": CONTROL_MODES[control_mode]}
    values.update(params or {})
    inst = pooled_instance(version)
    for name, v in values.items():
        inst.set(name, v)
    inst.set("V_supply", V_supply)
    inst.set(input, offset)
    inst.initialize(start_time=0.0)
    w = 2 * math.pi * f
    names = tuple(outputs) + ("driver_saturated",)
    rec = np.empty((n_fit, len(names)))
    for k in range(n_settle + n_fit):
        # the midpoint of the step k*h .. (k+1)*h; times from integers (no drift)
        inst.set(input, offset + amplitude * math.sin(w * (k + 0.5) * h))
        inst.do_step(k * h, h)
        if k >= n_settle:
            rec[k - n_settle] = inst.get(names)
    t = (np.arange(n_fit) + n_settle + 1) * h
    phasor = np.exp(-1j * w * t)
    staircase = amplitude * np.sinc(f * h)  # numpy's sinc(x) = sin(pi x)/(pi x)
    gains = {}
    for j, name in enumerate(outputs):
        # y = Im(Y e^{jwt}) -> Y = j (2/M) sum y e^{-jwt}
        y = 1j * 2.0 / n_fit * np.sum(rec[:, j] * phasor)
        gains[name] = complex(y / staircase)
    return SineResult(f, amplitude, h, gains, bool(rec[:, -1].max() > 0), n_settle + n_fit)


def static_gain(output: str, input: str = "i_ref", params: dict | None = None) -> float:
    """DC gain of input -> output: the valve's K3 K1/Kw from current to flow, its inverse
    from flow to current, 1 from current to current and from flow to flow."""
    if output == "Q_valve" and input == "i_ref":
        return flow_gain(params)
    if output == "i_coil" and input == "Q_ref":
        return 1.0 / flow_gain(params)
    return 1.0


def crossing(f, y, level: float) -> float:
    """First frequency where y (sampled at increasing f) falls below ``level``, by linear
    interpolation in log f; nan if it never does."""
    f = np.asarray(f, float)
    y = np.asarray(y, float)
    below = np.nonzero(y < level)[0]
    if len(below) == 0 or below[0] == 0:
        return math.nan
    k = below[0]
    x0, x1 = math.log(f[k - 1]), math.log(f[k])
    frac = (y[k - 1] - level) / (y[k - 1] - y[k])
    return math.exp(x0 + frac * (x1 - x0))


def refine(measure, f_lo: float, f_hi: float, rel: float = 2e-3) -> float:
    """Bisection in log f of a monotone predicate ``measure(f)`` (False at f_lo, True at
    f_hi) to a relative bracket ``rel``; returns the bracket's geometric mean."""
    while f_hi / f_lo > 1 + rel:
        mid = math.sqrt(f_lo * f_hi)
        if measure(mid):
            f_hi = mid
        else:
            f_lo = mid
    return math.sqrt(f_lo * f_hi)


def phase_deg(g) -> np.ndarray:
    """Unwrapped phase in degrees (continuous from the lowest frequency)."""
    return np.degrees(np.unwrap(np.angle(np.asarray(g, complex))))


def db(g) -> np.ndarray:
    return 20 * np.log10(np.abs(np.asarray(g, complex)))


def drive_voltage(f, params: dict | None = None, prefix: str = "driver"):
    """u / i_cmd of the linear PI loop (complex, V/A): C / (1 + C P) with C = Kp + Ki/s,
    P = 1 / (L s + R_t): the voltage the driver must produce to make the current follow."""
    p = parameters(params)
    s = 2j * math.pi * np.asarray(f, float)
    kp, ki = p[f"{prefix}.Kp"], p[f"{prefix}.Ki"]
    r = p["coil.R"] + p["coil.R_sense"]
    return (kp * s + ki) * (p["coil.L"] * s + r) / (p["coil.L"] * s**2 + (r + kp) * s + ki)


def loop_rail_limit(v_supply: float, amplitude: float, params: dict | None = None) -> float:
    """The frequency at which the linear op-amp PI loop asks for the rail voltage,
    A |u/i_cmd| = V_supply - V_drop (drive_voltage; above rail_limit by the loop's own
    roll-off, which makes the current, hence the voltage, a little smaller), Hz."""
    p = parameters(params)
    rail = v_supply - p["driver.V_drop"]
    if amplitude * abs(drive_voltage(0.0, params)) >= rail:
        return 0.0
    if amplitude * p["driver.Kp"] <= rail:
        return math.inf  # |u/i_cmd| <= Kp at every frequency: the rail is never asked for
    return refine(lambda f: amplitude * abs(drive_voltage(f, params)) >= rail, 1e-3, 1e7, 1e-9)


# --------------------------------------------------------------------------------------
# Curves and their figures (one dask task each)
# --------------------------------------------------------------------------------------

CURRENT_OUTPUTS = ("i_coil", "Q_valve")


def measure_curve(spec: dict) -> dict:
    """One measured frequency response and its figures, for a dask worker.

    ``spec``: version, driver, V_supply, amplitude, input ("i_ref" or "Q_ref"),
    control_mode, freqs (Hz), refine (bool: locate the -3 dB and -90 degree crossings by
    bisection through the FMU instead of interpolating the grid), h_min (optional).
    Returns f, gains (output -> complex list, normalised by the static gain), saturated,
    f3 / f90 (output -> Hz, nan if not crossed) and delay_10hz (output -> s)."""
    kw = {
        "input": spec.get("input", "i_ref"),
        "outputs": CURRENT_OUTPUTS,
        "V_supply": spec["V_supply"],
        "control_mode": spec.get("control_mode", "current"),
        "h_min": spec.get("h_min", H_MIN),
    }
    version, driver, amp = spec["version"], spec["driver"], spec["amplitude"]
    norm = {o: static_gain(o, kw["input"]) for o in CURRENT_OUTPUTS}

    def gains_at(f):
        r = sine_response(version, driver, f, amp, **kw)
        return {o: r.gains[o] / norm[o] for o in CURRENT_OUTPUTS}, r.saturated

    freqs = [float(f) for f in spec["freqs"]]
    runs = [gains_at(f) for f in freqs]
    gains = {o: [g[o] for g, _ in runs] for o in CURRENT_OUTPUTS}
    out = {**spec, "f": freqs, "gains": gains, "saturated": [s for _, s in runs], "f3": {}, "f90": {}}
    for o in CURRENT_OUTPUTS:
        mag, ph = np.abs(gains[o]), phase_deg(gains[o])
        out["f3"][o] = _locate(
            freqs, mag, 1 / math.sqrt(2), spec.get("refine"), lambda f, o=o: abs(gains_at(f)[0][o])
        )
        out["f90"][o] = _locate(
            freqs, ph, -90.0, spec.get("refine"), lambda f, o=o: math.degrees(np.angle(gains_at(f)[0][o]))
        )
    ten = gains_at(10.0)[0]
    out["delay_10hz"] = {o: -np.angle(ten[o]) / (2 * math.pi * 10.0) for o in CURRENT_OUTPUTS}
    return out


def _locate(freqs, y, level, refine_on, measure) -> float:
    """The first crossing of ``level`` by y(f) from above: grid interpolation, then (if
    ``refine_on``) bisection of measure(f) < level inside the grid bracket to 0.2 %."""
    f = crossing(freqs, y, level)
    if math.isnan(f) or not refine_on:
        return f
    k = int(np.nonzero(np.asarray(y) < level)[0][0])
    return refine(lambda x: measure(x) < level, freqs[k - 1], freqs[k])


def measure_onset(spec: dict) -> dict:
    """The frequency at which a sine of amplitude A first drives the op-amp to its rail
    (driver_saturated during the measured periods), bisected through the FMU within
    +-15 % of loop_rail_limit, 1 us steps. ``spec``: version, V_supply, amplitude."""
    v, a = spec["V_supply"], spec["amplitude"]
    predicted = loop_rail_limit(v, a)

    def saturates(f):
        r = sine_response(spec["version"], "opamp_pi", f, a, V_supply=v, outputs=("i_coil",), h_max=H_MIN)
        return r.saturated

    lo, hi = 0.85 * predicted, 1.15 * predicted
    if saturates(lo) or not saturates(hi):
        return {**spec, "onset": math.nan}
    return {**spec, "onset": refine(saturates, lo, hi, 5e-3)}
