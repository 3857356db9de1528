"""The paper's flow-loop comparison (Fig. 10/11, rows 8 and 9 of the figures table) through the FMU.

control_mode 1 (flow PID on Q_valve with the feed-forward Q_ref/(K3*K1/Kw)), driver
opamp_pi, Q_ref 0 -> 2e-4 m3/s at t = 0 from rest at mid-stroke, F_ext 0, outputs every
10 us, once with the high-voltage 72 V supply and once with a low-voltage 10 V supply
(ehsv.compare_flow_supplies, the same runs tests/python/test_cylinder.py
checks). Prints the 5 % settling times of Q_valve beside the paper's (3.3 ms and 6 ms)
and their ratio (paper: 181 %), and writes out/flow_loop.png: Q_valve, i_coil and the
piston position against time for both supplies.

    cargo run --release -p build-fmu      # the archives, once
    .venv/bin/python cosim-examples/flow_loop.py [--fmi3] [--out PATH]
"""

import argparse
import sys
from pathlib import Path

import ehsv

COLORS = {72.0: "tab:blue", 10.0: "tab:red"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmi3", action="store_true", help="use the FMI 3.0 archive")
    ap.add_argument("--out", type=Path, default=ehsv.REPO / "out" / "flow_loop.png")
    args = ap.parse_args(argv)

    version = "fmi3" if args.fmi3 else "fmi2"
    msg = ehsv.missing_fmu_message(version)
    if msg:
        print(msg, file=sys.stderr)
        return 1

    results = ehsv.compare_flow_supplies(version)
    print(
        f"EhsvActuator ({version}): control_mode 1 (flow loop), opamp_pi, Q_ref 0 -> "
        f"{ehsv.FLOW_STEP:g} m3/s at t = 0, output every {ehsv.FLOW_H * 1e6:g} us; "
        f"5 % settling time of Q_valve around Q_ref"
    )
    print(ehsv.flow_table(results))

    plt = ehsv.pyplot()

    fig, (ax1, ax2, ax3) = plt.subplots(3, 1, sharex=True, figsize=(9, 9))
    q_lmin = ehsv.FLOW_STEP * 6e4
    for spec in ehsv.PAPER_FLOW:
        res = results[spec.V_supply]
        r, c = res.run, COLORS[spec.V_supply]
        t_ms = r["time"] * 1e3
        label = f"{spec.V_supply:g} V: {res.settling * 1e3:.2f} ms (paper {spec.paper_ms:g} ms)"
        ax1.plot(t_ms, r["Q_valve"] * 6e4, color=c, lw=1.4, label=label)
        ax1.axvline(res.settling * 1e3, color=c, lw=0.8, ls="--")
        ax2.plot(t_ms, r["i_coil"] * 1e3, color=c, lw=1.4, label=f"{spec.V_supply:g} V")
        ax3.plot(t_ms, r["x_piston"] * 1e3, color=c, lw=1.4, label=f"{spec.V_supply:g} V")
    for f in (0.95, 1.05):
        ax1.axhline(q_lmin * f, color="grey", lw=0.5, ls=":")
    ax1.set_ylabel("Q_valve [L/min]")
    ax1.legend(loc="lower right", fontsize=8)
    ax1.grid(alpha=0.3)
    ax1.set_title("dashed: 5 % settling time; dotted: +-5 % band", fontsize=9)
    ax2.set_ylabel("i_coil [mA]")
    ax2.legend(loc="upper right", fontsize=8)
    ax2.grid(alpha=0.3)
    ax3.set_ylabel("x_piston [mm]")
    ax3.set_xlabel("time after the step [ms]")
    ax3.set_xlim(0, ehsv.FLOW_T_STOP * 1e3)
    ax3.legend(loc="lower right", fontsize=8)
    ax3.grid(alpha=0.3)
    fig.suptitle(
        f"EhsvActuator: flow step 0 -> {q_lmin:g} L/min, high- and low-voltage driver supply ({version})"
    )
    ehsv.save_figure(fig, args.out)
    print(f"figure: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
