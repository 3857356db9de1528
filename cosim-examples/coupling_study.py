"""The coupling table: the actuator on a rigid mass M through its motion port, in the
plainest host loop, against the same system as one FMU (the load mass inside).

For every mass and communication step: the largest difference in x_piston as a fraction
of the motion, with and without the rod's acceleration given as an input derivative, and
the measured order of convergence between steps. Usage::

    python cosim-examples/coupling_study.py [--fmi 2] [--duration 0.2] [--method fixed_cost]

``--method`` sets the coupled FMU's solver.method; the reference stays exact.
"""

from __future__ import annotations

import argparse
import math

from ehsv.coupling import SIGNALS, difference, order, run_coupled, run_monolithic

MASSES = (2.0, 5.0, 20.0, 100.0, 1000.0)
STEPS = (1e-3, 1e-4, 1e-5)
#: The reference's communication step (the FMU integrates exactly in between: its result
#: depends on the step only through the load held over each step).
REFERENCE_STEP = 1e-5


def table(version: str, duration: float, signal_name: str, method: str = "exact") -> list[str]:
    signal = SIGNALS[signal_name]
    on = "" if method == "exact" else f", solver.method = {method}"
    lines = [
        f"{signal_name}, {duration} s, FMI {version[-1]}{on}: max |x_cosim - x_mono| / range(x_mono)",
        "| M (kg) | "
        + " | ".join(f"h = {h:g} s" for h in STEPS)
        + " | order | with input derivative | order |",
        "| ---: | " + " | ".join("---:" for _ in STEPS) + " | ---: | ---: | ---: |",
    ]
    for mass in MASSES:
        reference = run_monolithic(version, mass, REFERENCE_STEP, duration, signal)
        plain = [
            difference(run_coupled(version, mass, h, duration, signal, method=method), reference)
            for h in STEPS
        ]
        cells = [f"{e:.2e}" if math.isfinite(e) else "unstable" for e in plain]
        orders = " / ".join(f"{p:.2f}" for p in order(plain))
        extra = ""
        if version == "fmi2":
            with_a = [
                difference(
                    run_coupled(version, mass, h, duration, signal, input_derivatives=True, method=method),
                    reference,
                )
                for h in STEPS
            ]
            extra = (
                " / ".join(f"{e:.2e}" for e in with_a) + " | " + " / ".join(f"{p:.2f}" for p in order(with_a))
            )
        lines.append(f"| {mass:g} | " + " | ".join(cells) + f" | {orders} | {extra} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fmi", choices=("2", "3"), default="2")
    parser.add_argument("--duration", type=float, default=0.2)
    parser.add_argument("--signal", choices=sorted(SIGNALS), action="append")
    parser.add_argument(
        "--method", choices=("exact", "fixed_cost"), default="exact", help="coupled runs' solver.method"
    )
    args = parser.parse_args()
    for name in args.signal or sorted(SIGNALS):
        print("\n".join(table(f"fmi{args.fmi}", args.duration, name, args.method)))
        print()


if __name__ == "__main__":
    main()
