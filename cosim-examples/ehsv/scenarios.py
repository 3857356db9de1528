"""Scenarios run through the FMU: inputs changed at one instant, outputs recorded at every
communication point; the paper's driver table and flow-loop comparison.

* ``run_scenario``: any parameters and start inputs, any inputs changed at ``t_change``,
* ``run_step``: the current step i_ref -> i_step of one driver,
* ``driver_step`` / ``compare_drivers``: the paper's 0 -> 5 mA step for the three drivers
  of its table (Fig. 14-16), with the PWM-period mean for the H-bridge,
* ``flow_step`` / ``compare_flow_supplies``: the flow loop at 72 V and 10 V (Fig. 10/11).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bands import FLOW_STEP, PAPER_DRIVERS, PAPER_FLOW, PAPER_STEP, PAPER_T_TORQUE, PaperDriver
from .contract import CONTROL_MODES, DRIVERS
from .fmu import Ehsv, pooled_instance
from .measures import period_average, pwm_period, settling_time

#: outputs of the current-loop runs
DEFAULT_OUTPUTS = ("i_coil", "u_driver", "driver_saturated", "x_flapper", "x_spool", "Q_valve")

#: outputs of the hydraulic runs
HYDRAULIC_OUTPUTS = (
    "i_coil", "u_driver", "x_spool", "Q_valve", "Q_A", "Q_B", "p_A", "p_B",
    "x_piston", "v_piston", "F_hydraulic",
)  # fmt: skip

COMPARE_H = 1e-6  # s, output interval of the driver comparison (50 samples per PWM period)
COMPARE_T_STOP = 20e-3  # s, four times the slowest settling time
FLOW_H = 1e-5  # s, output interval of the flow step (the loop samples every 50 us)
FLOW_T_STOP = 30e-3  # s, five times the slower settling time


def run_scenario(
    version: str,
    *,
    h: float,
    t_stop: float,
    params: dict | None = None,
    initial: dict | None = None,
    changes: dict | None = None,
    t_change: float = 0.0,
    outputs=HYDRAULIC_OUTPUTS,
    reuse: bool = False,
) -> dict[str, np.ndarray]:
    """General form of run_step: ``params`` and the ``initial`` inputs are set before
    initialisation (the model starts in equilibrium with them), ``changes`` (input name ->
    value) are set just before the doStep that starts at ``t_change``; ``outputs`` are
    recorded at every communication point k*h up to t_stop (times from integers, so runs
    with different h share their grid points exactly). ``reuse``: run on this process's
    pooled instance (reset, not freed) instead of a new one."""
    n = int(round(t_stop / h))
    k_change = int(round(t_change / h))
    if abs(k_change * h - t_change) > 1e-12 * max(1.0, t_change) or abs(n * h - t_stop) > 1e-9 * t_stop:
        raise ValueError("t_change and t_stop must be multiples of h")
    inst = pooled_instance(version) if reuse else Ehsv(version)
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
        if not reuse:
            inst.free()
    except Exception as e:  # keep the FMU's own words with the exception
        if inst.log:
            raise RuntimeError(f"{e}\nFMU log:\n{inst.log_text()}") from e
        raise
    result = {"time": np.arange(n + 1) * h}
    for j, name in enumerate(outputs):
        result[name] = rec[:, j]
    return result


def run_step(
    version: str,
    driver: str,
    i_step: float,
    *,
    h: float,
    t_stop: float,
    t_step: float = 0.0,
    i_before: float = 0.0,
    V_supply: float = 72.0,
    params: dict | None = None,
    outputs=DEFAULT_OUTPUTS,
) -> dict[str, np.ndarray]:
    """Steps i_ref from ``i_before`` to ``i_step`` at ``t_step`` (a communication point)
    and records ``outputs`` at every communication point 0, h, 2h, ... up to t_stop.

    The model is initialised in equilibrium with i_ref = i_before; at t_step the input is
    set just before the doStep that starts there, so the recorded value at t_step is the
    one before the step and everything after it sees the new command. Times are k*h,
    computed from integers, so runs with different h share their grid points exactly.
    """
    values = dict(params or {})
    values.setdefault("driver", DRIVERS[driver])
    return run_scenario(
        version,
        h=h,
        t_stop=t_stop,
        params=values,
        initial={"i_ref": i_before, "V_supply": V_supply},
        changes={"i_ref": i_step},
        t_change=t_step,
        outputs=outputs,
    )


@dataclass
class DriverResult:
    """One driver's step response and figures, from ``compare_drivers``."""

    spec: PaperDriver
    run: dict  # run_step's record: time and DEFAULT_OUTPUTS
    t_avg: np.ndarray  # time of the PWM-period means (the run's time for linear drivers)
    i_avg: np.ndarray  # i_coil, period-averaged for the PWM driver, else the raw samples
    u_avg: np.ndarray  # u_driver likewise
    settling: float  # s, 2 % settling time of i_avg around the command, from the step
    ripple: float  # A, peak-to-peak of raw i_coil over the last PWM period (0 if linear)

    @property
    def pct_of_t_torque(self) -> float:
        return 100.0 * self.settling / PAPER_T_TORQUE


def driver_step(
    version: str,
    spec: PaperDriver,
    *,
    h: float = COMPARE_H,
    t_stop: float = COMPARE_T_STOP,
    params: dict | None = None,
) -> DriverResult:
    """The paper's 0 -> 5 mA step for one driver at its row's supply, with its figures.

    Settling time: last time i_coil (the PWM driver: its mean over one PWM period) is
    outside +-2 % of the 5 mA step around the command (the PI loops have no steady-state
    error), measured from the step at t = 0 (settling_time with y_final = command)."""
    r = run_step(version, spec.driver, PAPER_STEP, h=h, t_stop=t_stop, V_supply=spec.V_supply, params=params)
    t = r["time"]
    if spec.averaged:
        period = pwm_period(params)
        t_avg, i_avg = period_average(t, r["i_coil"], period)
        _, u_avg = period_average(t, r["u_driver"], period)
        n = int(round(period / h))
        ripple = float(np.ptp(r["i_coil"][-(n + 1) :]))
    else:
        t_avg, i_avg, u_avg, ripple = t, r["i_coil"], r["u_driver"], 0.0
    ts = settling_time(t_avg, i_avg, 0.0, 0.02, y_final=PAPER_STEP, y_initial=0.0)
    return DriverResult(spec, r, t_avg, i_avg, u_avg, ts, ripple)


def compare_drivers(
    version: str, *, h: float = COMPARE_H, t_stop: float = COMPARE_T_STOP, params: dict | None = None
) -> dict[str, DriverResult]:
    """Runs the three drivers of the paper's table in one go (PAPER_DRIVERS: op-amp at
    72 V, H-bridge at 12 V, industrial at 24 V; 0 -> 5 mA at t = 0, nominal parameters
    but ``params``, outputs every ``h``) and returns {driver name: DriverResult}, fastest
    first."""
    return {
        spec.driver: driver_step(version, spec, h=h, t_stop=t_stop, params=params) for spec in PAPER_DRIVERS
    }


@dataclass
class FlowStepResult:
    V_supply: float
    h: float
    run: dict  # run_scenario's record (HYDRAULIC_OUTPUTS)
    settling: float  # s, 5 % settling time of Q_valve around Q_ref, from the step


def flow_step(
    version: str,
    v_supply: float,
    h: float = FLOW_H,
    *,
    t_stop: float = FLOW_T_STOP,
    q_step: float = FLOW_STEP,
    params: dict | None = None,
    outputs=HYDRAULIC_OUTPUTS,
) -> FlowStepResult:
    """Rows 8/9: opamp_pi, control_mode 1 (flow PID + feed-forward), Q_ref 0 -> q_step at
    t = 0 from the equilibrium at mid-stroke, F_ext 0, p_supply nominal. Settling time:
    last time Q_valve is outside +-5 % of the step around Q_ref (the PI loop has no
    steady-state error), from the step."""
    values = {"driver": DRIVERS["opamp_pi"], "control_mode": CONTROL_MODES["flow"], **(params or {})}
    r = run_scenario(
        version,
        h=h,
        t_stop=t_stop,
        params=values,
        initial={"V_supply": v_supply, "Q_ref": 0.0},
        changes={"Q_ref": q_step},
        outputs=outputs,
    )
    ts = settling_time(r["time"], r["Q_valve"], 0.0, 0.05, y_final=q_step, y_initial=0.0)
    return FlowStepResult(v_supply, h, r, ts)


def compare_flow_supplies(
    version: str, h: float = FLOW_H, params: dict | None = None
) -> dict[float, FlowStepResult]:
    """The flow step at both supplies of the paper (72 V, 10 V), nominal parameters but
    ``params``: {V_supply: result}."""
    return {spec.V_supply: flow_step(version, spec.V_supply, h, params=params) for spec in PAPER_FLOW}
