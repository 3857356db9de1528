"""The paper's flow-loop comparison (Fig. 10/11, rows 8 and 9 of the figures table) through the FMU.

control_mode 1 (flow PID on Q_valve with the feed-forward Q_ref/(K3*K1/Kw)), driver
opamp_pi, Q_ref 0 -> 2e-4 m3/s at t = 0 from rest at mid-stroke, F_ext 0, outputs every
10 us, once with the high-voltage 72 V supply and once with a low-voltage 10 V supply
(ehsv.compare_flow_supplies, the same runs tests/python/test_cylinder.py
checks). Prints the 5 % settling times of Q_valve beside the paper's (3.3 ms and 6 ms)
and their ratio (paper: 181 %), and writes out/flow_loop.png: Q_valve, i_coil,
u_driver and the chamber pressures against time for both supplies.

    cargo run --release -p build-fmu      # the archives, once
    .venv/bin/python cosim-examples/flow_loop.py [--fmi3] [--out PATH]
"""

import sys
from pathlib import Path

import ehsv
from ehsv import cli, paper_plots


def main(argv=None) -> int:
    ap = cli.parser(__doc__)
    ap.add_argument("--out", type=Path, default=cli.OUT_DIR / "flow_loop.png")
    args = ap.parse_args(argv)

    version = cli.version(args)
    if cli.archive_missing(version):
        return 1

    results = ehsv.compare_flow_supplies(version)
    print(
        f"EhsvActuator ({version}): control_mode 1 (flow loop), opamp_pi, Q_ref 0 -> "
        f"{ehsv.FLOW_STEP:g} m3/s at t = 0, output every {ehsv.FLOW_H * 1e6:g} us; "
        f"5 % settling time of Q_valve around Q_ref"
    )
    print(ehsv.flow_table(results))

    fig = paper_plots.fig10_11_flow_loop(results, version)
    cli.write_figure(fig, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
