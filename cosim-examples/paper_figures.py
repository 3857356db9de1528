"""The paper's figures redrawn from FMU runs with the numbers on the plots:

* fig4_valve_step.png: Q_valve after a current step, ideal current source (eq. 3)
  against voltage drive (eq. 4), FMU and exact solution, 5 % settling times,
* fig8_opamp_current.png: the op-amp PI driver at 72 V, 0 -> 5 and 0 -> 10 mA: coil
  current and driver voltage on its rail,
* fig10_11_flow_loop.png: the flow loop at 72 V and 10 V with the chamber pressures,
* fig14_16_drivers.png: the driver table (op-amp 72 V, H-bridge 12 V, industrial 24 V).

    .venv/bin/python cosim-examples/paper_figures.py [--fmi3] [--out-dir out]

The gallery (docs/studies.md "Gallery") is this command with --out-dir docs/gallery.
"""

from __future__ import annotations

import sys
from pathlib import Path

import ehsv
from ehsv import cli, paper_plots


def main(argv=None) -> int:
    ap = cli.parser(__doc__)
    ap.add_argument("--out-dir", type=Path, default=cli.OUT_DIR)
    args = ap.parse_args(argv)
    version = cli.version(args)
    if cli.archive_missing(version):
        return 1
    out = args.out_dir
    step = ehsv.PAPER_STEP

    linear = {d: ehsv.run_step(version, d, step, h=1e-5, t_stop=40e-3, outputs=("Q_valve",))
              for d in ("ideal_current", "voltage")}  # fmt: skip
    exact = {d: ehsv.linear_step_response_dense(d, step, 1e-5, 40e-3) for d in linear}
    figs = {
        "fig4_valve_step.png": paper_plots.fig4_valve_step(
            linear["ideal_current"], linear["voltage"], exact, version
        )
    }

    current = {i: ehsv.run_step(version, "opamp_pi", i, h=1e-6, t_stop=2e-3) for i in (5e-3, 10e-3)}
    figs["fig8_opamp_current.png"] = paper_plots.fig8_opamp_current(current, 72.0, version)
    figs["fig10_11_flow_loop.png"] = paper_plots.fig10_11_flow_loop(
        ehsv.compare_flow_supplies(version), version
    )
    figs["fig14_16_drivers.png"] = paper_plots.fig14_16_drivers(ehsv.compare_drivers(version), version)
    for name, fig in figs.items():
        cli.write_figure(fig, out / name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
