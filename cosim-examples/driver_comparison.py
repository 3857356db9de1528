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

import argparse
import sys
from pathlib import Path

import ehsv

COLORS = {"opamp_pi": "tab:blue", "hbridge_pid": "tab:orange", "industrial": "tab:green"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmi3", action="store_true", help="use the FMI 3.0 archive")
    ap.add_argument("--out", type=Path, default=ehsv.REPO / "out" / "driver_comparison.png")
    ap.add_argument("--t-max-ms", type=float, default=8.0, help="time axis of the figure (default 8 ms)")
    args = ap.parse_args(argv)

    version = "fmi3" if args.fmi3 else "fmi2"
    msg = ehsv.missing_fmu_message(version)
    if msg:
        print(msg, file=sys.stderr)
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

    plt = ehsv.pyplot()

    t_max = args.t_max_ms * 1e-3
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(9, 7))
    for name, res in results.items():
        c = COLORS[name]
        t = res.run["time"]
        keep = t <= t_max
        label = f"{name} ({res.spec.V_supply:g} V): {res.settling * 1e3:.3f} ms (paper {res.spec.paper_ms:g})"
        if res.spec.averaged:
            ax1.plot(
                t[keep] * 1e3,
                res.run["i_coil"][keep] * 1e3,
                color=c,
                lw=0.5,
                alpha=0.45,
                label=f"{name} raw (PWM ripple)",
            )
            ka = res.t_avg <= t_max
            ax1.plot(
                res.t_avg[ka] * 1e3,
                res.i_avg[ka] * 1e3,
                color=c,
                lw=1.6,
                label=f"{name} period mean: {res.settling * 1e3:.3f} ms (paper {res.spec.paper_ms:g})",
            )
            ax2.plot(
                t[keep] * 1e3,
                res.run["u_driver"][keep],
                color=c,
                lw=0.3,
                alpha=0.35,
                label=f"{name} raw (+-{res.spec.V_supply:g} V PWM)",
            )
            ax2.plot(res.t_avg[ka] * 1e3, res.u_avg[ka], color=c, lw=1.6, label=f"{name} period mean")
        else:
            ax1.plot(t[keep] * 1e3, res.run["i_coil"][keep] * 1e3, color=c, lw=1.4, label=label)
            ax2.plot(
                t[keep] * 1e3,
                res.run["u_driver"][keep],
                color=c,
                lw=1.4,
                label=f"{name} ({res.spec.V_supply:g} V)",
            )
        ax1.axvline(res.settling * 1e3, color=c, lw=0.8, ls="--")
    step_ma = ehsv.PAPER_STEP * 1e3
    for f in (0.98, 1.02):
        ax1.axhline(step_ma * f, color="grey", lw=0.5, ls=":")
    ax1.set_ylabel("i_coil [mA]")
    ax1.set_ylim(0, step_ma * 1.15)
    ax1.legend(loc="lower right", fontsize=8)
    ax1.grid(alpha=0.3)
    ax1.set_title("dashed: 2 % settling time; dotted: +-2 % band", fontsize=9)
    ax2.set_ylabel("u_driver [V]")
    ax2.set_xlabel("time after the step [ms]")
    ax2.set_xlim(0, args.t_max_ms)
    ax2.legend(loc="upper right", fontsize=8)
    ax2.grid(alpha=0.3)
    fig.suptitle(f"EhsvActuator: 0 -> {step_ma:g} mA current step, three coil drivers ({version})")
    ehsv.save_figure(fig, args.out)
    print(f"figure: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
