"""The paper's figures and the bands the FMU must land in.

The eleven rows of the README's figures table (``ROWS``: what is measured, how it is
shown, its band) and the two tables of the paper they come from: the driver table of
Fig. 14-16 (``PAPER_DRIVERS``) and the flow loop of Fig. 10/11 (``PAPER_FLOW``).
docs/model.md explains each row. Settling time: the last time the signal is outside
+-2 % (currents) or +-5 % (flows) of the step size around its final value, from the step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from .contract import DRIVERS, PWM_DRIVERS, flow_gain

#: the paper's reference: valve settling with a voltage drive (T_torque, Fig. 4), s
PAPER_T_TORQUE = 10.8e-3

#: tolerance of the paper comparison: the FMU's settling time within +-10 % of the paper's
PAPER_TOLERANCE = 0.10

#: A, the driver table's current step (0 -> 5 mA)
PAPER_STEP = 5e-3

#: m3/s, the flow loop's step Q_ref 0 -> 2e-4 (the Moog 30's nominal flow; rows 8 and 9)
FLOW_STEP = 2e-4


@dataclass(frozen=True)
class PaperDriver:
    """One line of the paper's driver table and the figure row that pins it down."""

    driver: str  # name in DRIVERS
    label: str  # the paper's name for it
    V_supply: float  # V, supply of the row
    paper_ms: float  # the paper's 2 % current settling time, ms
    paper_pct: float  # the paper's figure as % of T_torque
    row: int  # figure row
    band: tuple  # (lo, hi) s: the row's band for the 2 % settling time

    @property
    def code(self) -> int:
        return DRIVERS[self.driver]

    @property
    def averaged(self) -> bool:
        """The settling time is that of the PWM-period mean of i_coil."""
        return self.driver in PWM_DRIVERS

    @property
    def paper_band(self) -> tuple:
        return (
            self.paper_ms * 1e-3 * (1 - PAPER_TOLERANCE),
            self.paper_ms * 1e-3 * (1 + PAPER_TOLERANCE),
        )


#: the paper's table, fastest first (op-amp < H-bridge < industrial); every step is
#: i_ref 0 -> 5 mA at t = 0 from rest with nominal parameters
PAPER_DRIVERS = (
    PaperDriver("opamp_pi", "proposed op-amp driver", 72.0, 0.25, 2.0, 1, (0.225e-3, 0.275e-3)),
    PaperDriver("hbridge_pid", "H-bridge topology", 12.0, 2.0, 18.0, 5, (1.7e-3, 2.3e-3)),
    PaperDriver("industrial", "My-502 industrial driver", 24.0, 5.0, 50.0, 4, (4.5e-3, 5.5e-3)),
)


@dataclass(frozen=True)
class PaperFlowRun:
    """One supply of the paper's flow-loop comparison and its figure row."""

    V_supply: float  # V
    paper_ms: float  # the paper's 5 % settling time of the valve flow, ms
    row: int
    band: tuple  # (lo, hi) s of the row (lo 0: only an upper bound)


#: the paper's Fig. 10 (high-voltage driver, 3.3 ms) and Fig. 11 (low-voltage, 6 ms = 181 %)
PAPER_FLOW = (
    PaperFlowRun(72.0, 3.3, 8, (0.0, 3.6e-3)),
    PaperFlowRun(10.0, 6.0, 9, (5.4e-3, 6.6e-3)),
)
PAPER_FLOW_RATIO = 1.81  # the paper: low-voltage settling is 181 % of the high-voltage one
FLOW_RATIO_MIN = 1.6  # row 9: >= 1.6 x row 8


@dataclass(frozen=True)
class Row:
    """One row of the figures table: what is measured, how it is printed, its band."""

    row: int
    what: str
    show: Callable
    check: Callable
    band: str


def _ms(v) -> str:
    return f"{v * 1e3:.4f} ms"


#: the figures the FMU reproduces (cosim-examples/figures.py measures them on both archives)
ROWS = (
    Row(1, "opamp_pi 72 V, 0->5 mA: i_coil settling (2 %)", _ms,
        lambda v: 0.225e-3 <= v <= 0.275e-3, "0.225-0.275 ms"),
    Row(2, "same run: u_driver at +72 V, then final", lambda v: f"{v[0] * 1e3:.3f} ms, {v[1]:.4f} V",
        lambda v: v[0] >= 0.15e-3 and abs(v[1] - 5.0) < 0.05, ">= 0.15 ms, 5.0 V"),
    Row(3, "opamp_pi 72 V, 0->10 mA: i_coil settling (2 %)", _ms,
        lambda v: 0.45e-3 <= v <= 0.55e-3, "0.45-0.55 ms"),
    Row(4, "industrial 24 V, 0->5 mA: i_coil settling (2 %)", _ms,
        lambda v: 4.5e-3 <= v <= 5.5e-3, "4.5-5.5 ms"),
    Row(5, "hbridge_pid 12 V, 0->5 mA: period-mean i_coil (2 %)", _ms,
        lambda v: 1.7e-3 <= v <= 2.3e-3, "1.7-2.3 ms"),
    Row(6, "ideal_current, i_ref step: Q_valve settling (5 %)", _ms,
        lambda v: abs(v / 3.29e-3 - 1) <= 0.03, "3.29 ms +-3 %"),
    Row(7, "voltage, i_ref step: Q_valve settling (5 %)", _ms,
        lambda v: abs(v / 10.99e-3 - 1) <= 0.03, "10.99 ms +-3 %"),
    Row(8, "flow loop 72 V, Q_ref 0->2e-4: Q_valve (5 %)", _ms,
        lambda v: v <= 3.6e-3, "<= 3.6 ms"),
    Row(9, "same at 10 V, and its ratio to row 8", lambda v: f"{v[0] * 1e3:.4f} ms, {v[1] * 100:.0f} %",
        lambda v: 5.4e-3 <= v[0] <= 6.6e-3 and v[1] >= 1.6, "5.4-6.6 ms, >= 160 %"),
    # Row 10: four drivers land on K3 K1/Kw (= the paper's 2.5268e-5 to 2e-5) to rounding;
    # the H-bridge's i_coil sample carries part of its PWM ripple (1.2e-4 at that phase).
    Row(10, "all 5 drivers, steady: Q_valve/i_coil (m3/s per mA)", lambda v: f"{v[0]:.6e} .. {v[1]:.6e}",
        lambda v: all(abs(g / (flow_gain() * 1e-3) - 1) <= 5e-4 for g in v), "K3 K1/Kw +-0.05 %"),
    # Row 11: exact in steady motion and in the equations; what is left is the integrator's
    # error (Rodas4 at rtol 1e-7, or fixed_cost's linearly implicit trapezoidal step, which
    # figures.py runs at a smaller solver.h_internal for this row: ROW11_H_INTERNAL), and
    # for the balance that and the trapezoids on 10 us samples.
    Row(11, "flow loop, steady: |v - Q_A/A_A|/v; volume balance", lambda v: f"{v[0]:.1e}; {v[1]:.1e}",
        lambda v: v[0] <= 1e-7 and v[1] <= 1e-9, "<= 1e-7; <= 1e-9"),
)  # fmt: skip
