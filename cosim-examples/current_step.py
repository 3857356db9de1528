"""Demo: 0 -> 5 mA coil-current step through the op-amp PI driver (72 V supply).

Loads target/fmu/EhsvActuator-fmi2.fmu (--fmi3 for the FMI 3.0 archive) with fmpy, steps
it by hand every 1 us so the step instant is exact (i_ref changes at t = 0.1 ms), prints
the 2 % settling time of i_coil, how long u_driver stays at the +72 V rail and its final
value, and writes out/current_step.png (i_coil in mA and u_driver in V against ms).

    scripts/demo.sh            # builds the FMUs, then runs this
    .venv/bin/python cosim-examples/current_step.py [--fmi3] [--step-mA 5] [--out PATH]
"""

import sys
from pathlib import Path

import numpy as np

import ehsv
from ehsv import cli


def main(argv=None) -> int:
    ap = cli.parser(__doc__)
    ap.add_argument("--step-mA", type=float, default=5.0, help="i_ref step size in mA (default 5)")
    ap.add_argument("--supply", type=float, default=72.0, help="V_supply in V (default 72)")
    ap.add_argument("--out", type=Path, default=cli.OUT_DIR / "current_step.png")
    args = ap.parse_args(argv)

    version = cli.version(args)
    if cli.archive_missing(version):
        return 1

    h = 1e-6  # communication step = output interval, 1 us
    t_step = 0.1e-3  # the step happens 0.1 ms after the start
    t_stop = 1.5e-3
    i_step = args.step_mA * 1e-3
    r = ehsv.run_step(version, "opamp_pi", i_step, h=h, t_stop=t_stop, t_step=t_step, V_supply=args.supply)
    t, i, u = r["time"], r["i_coil"], r["u_driver"]

    ts = ehsv.settling_time(t, i, t_step, 0.02, y_final=i_step, y_initial=0.0)
    rail = args.supply  # V_drop = 0 by default
    at_rail = ehsv.time_at_rail(t, u, t_step, rail, tol=0.05)
    after = t >= t_step
    peak = float(np.max(u[after]))
    print(
        f"EhsvActuator ({version}), opamp_pi driver, V_supply = {args.supply:g} V, "
        f"i_ref 0 -> {args.step_mA:g} mA at t = {t_step * 1e3:g} ms, output every {h * 1e6:g} us"
    )
    print(f"  i_coil 2 % settling time : {ts * 1e3:.4f} ms after the step")
    print(f"  u_driver peak            : {peak:.3f} V")
    print(f"  u_driver at the rail     : {at_rail * 1e3:.4f} ms within 0.05 V of +{rail:g} V")
    print(f"  u_driver final (plateau) : {u[-1]:.4f} V   (R * i = {ehsv.NOMINAL['coil.R'] * i_step:.4f} V)")
    print(f"  i_coil final             : {i[-1] * 1e3:.6f} mA")

    plt = ehsv.pyplot()

    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    ms = t * 1e3
    ax1.plot(ms, i * 1e3, label="i_coil")
    ax1.axhline(args.step_mA, color="grey", lw=0.6, ls="--", label="i_ref after step")
    for f in (0.98, 1.02):
        ax1.axhline(args.step_mA * f, color="grey", lw=0.4, ls=":")
    ax1.axvline(
        (t_step + ts) * 1e3, color="tab:red", lw=0.8, ls="--", label=f"2 % settled: {ts * 1e3:.3f} ms"
    )
    ax1.set_ylabel("i_coil [mA]")
    ax1.legend(loc="lower right")
    ax1.grid(alpha=0.3)
    ax2.plot(ms, u, color="tab:orange", label="u_driver")
    ax2.axhline(rail, color="grey", lw=0.6, ls="--", label=f"+{rail:g} V rail")
    ax2.set_ylabel("u_driver [V]")
    ax2.set_xlabel("time [ms]")
    ax2.legend(loc="upper right")
    ax2.grid(alpha=0.3)
    fig.suptitle(
        f"EhsvActuator: 0 -> {args.step_mA:g} mA step, op-amp PI driver, {args.supply:g} V supply ({version})"
    )
    ehsv.save_figure(fig, args.out)
    print(f"  figure                   : {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
