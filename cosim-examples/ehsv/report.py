"""The FMU's figures beside the paper's, as text tables."""

from __future__ import annotations

from .bands import FLOW_RATIO_MIN, PAPER_FLOW, PAPER_FLOW_RATIO
from .scenarios import DriverResult, FlowStepResult


def driver_table(results: dict[str, DriverResult]) -> str:
    """The paper's table beside the FMU's figures, as text."""
    head = (
        f"{'driver':<12} {'paper name':<26} {'supply':>6} {'paper ms':>8} {'FMU ms':>8} "
        f"{'paper %':>7} {'FMU %':>6}  band (row)"
    )
    lines = [head, "-" * len(head)]
    for name, res in results.items():
        s = res.spec
        lines.append(
            f"{name:<12} {s.label:<26} {s.V_supply:>4.0f} V {s.paper_ms:>8.2f} "
            f"{res.settling * 1e3:>8.4f} {s.paper_pct:>6.0f}% {res.pct_of_t_torque:>5.1f}%  "
            f"{s.band[0] * 1e3:g}-{s.band[1] * 1e3:g} ms (row {s.row})"
        )
    return "\n".join(lines)


def flow_table(results: dict[float, FlowStepResult]) -> str:
    """Settling times of the flow step beside the paper's, and their ratio, as text."""
    head = f"{'supply':>6} {'paper ms':>8} {'FMU ms':>8}  band (row)"
    lines = [head, "-" * len(head)]
    for spec in PAPER_FLOW:
        res = results[spec.V_supply]
        band = (
            f"<= {spec.band[1] * 1e3:g} ms"
            if spec.band[0] == 0
            else f"{spec.band[0] * 1e3:g}-{spec.band[1] * 1e3:g} ms"
        )
        settling = f"{res.settling * 1e3:>8.4f}"
        lines.append(f"{spec.V_supply:>4.0f} V {spec.paper_ms:>8.2f} {settling}  {band} (row {spec.row})")
    hi, lo = (results[spec.V_supply].settling for spec in PAPER_FLOW)
    lines.append(
        f"ratio 10 V / 72 V: FMU {lo / hi * 100:.0f} %, paper {PAPER_FLOW_RATIO * 100:.0f} % "
        f"(row 9: >= {FLOW_RATIO_MIN * 100:.0f} %)"
    )
    return "\n".join(lines)
