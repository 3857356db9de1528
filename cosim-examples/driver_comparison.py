"""Driver comparison: the paper's table of current settling times beside the FMU's.

Runs the three drivers of the paper's table through the FMU (ehsv.compare_drivers, the
same runs the pytest suite checks): i_ref 0 -> 5 mA at t = 0 from rest, outputs every
1 us; proposed op-amp PI driver at 72 V, H-bridge (bipolar 20 kHz PWM, digital PI) at
12 V, industrial linear PI amplifier (My-502 like) at 24 V. Prints the
paper's figures beside the FMU's 2 % settling times (the H-bridge's on the mean of i_coil
over one PWM period) and as % of T_torque = 10.8 ms, and writes
out/driver_comparison.png: i_coil (mA; H-bridge raw and period mean) and u_driver (V)
against time (ms).

    cargo run --release -p build-fmu      # the archives, once
    .venv/bin/python cosim-examples/driver_comparison.py [--fmi3] [--out PATH] [--t-max-ms 8]
"""

import sys
from pathlib import Path

import ehsv
from ehsv import cli, paper_plots


def main(argv=None) -> int:
    ap = cli.parser(__doc__)
    ap.add_argument("--out", type=Path, default=cli.OUT_DIR / "driver_comparison.png")
    ap.add_argument("--t-max-ms", type=float, default=8.0, help="time axis of the figure (default 8 ms)")
    args = ap.parse_args(argv)

    version = cli.version(args)
    if cli.archive_missing(version):
        return 1

    results = ehsv.compare_drivers(version)
    print(
        f"EhsvActuator ({version}): i_ref 0 -> {ehsv.PAPER_STEP * 1e3:g} mA at t = 0, "
        f"output every {ehsv.COMPARE_H * 1e6:g} us; 2 % settling time of i_coil "
        f"(H-bridge: mean over one {ehsv.pwm_period() * 1e6:g} us PWM period); "
        f"T_torque = {ehsv.PAPER_T_TORQUE * 1e3:g} ms"
    )
    print(ehsv.driver_table(results))
    hb = results["hbridge_pid"]
    print(f"H-bridge ripple at the end: {hb.ripple * 1e3:.4f} mA peak to peak")

    fig = paper_plots.fig14_16_drivers(results, version, args.t_max_ms)
    cli.write_figure(fig, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
