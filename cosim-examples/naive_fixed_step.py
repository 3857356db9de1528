"""Why not a plain fixed step: explicit Euler at 1e-4 s against the FMU's two methods.

The piston retracts into its end stop (opamp_pi, i_ref 0 -> -5 mA) and stalls there,
chamber A at its dead volume with its port to tank open: the stiffest place of the model
(-1.4e5 1/s). Prints each integrator's lowest p_A and the swing of p_A over the last 20 ms,
and writes out/naive_fixed_step.png (p_A against time, the cavitation floor marked).

    .venv/bin/python cosim-examples/naive_fixed_step.py [--fmi3] [--out PATH]
"""

from pathlib import Path

import ehsv
from ehsv import cli
from ehsv.naive_step import NAIVE_H, retract_to_stop, settled_swing

LABELS = {
    "exact": "FMU, solver.method = exact",
    "fixed_cost": "FMU, solver.method = fixed_cost",
    "explicit_euler": "explicit Euler, same equations",
}
#: drawn in this order (Euler below, so the FMU's two lines stay visible on top of it)
STYLES = {
    "explicit_euler": {"color": "tab:red", "lw": 0.8},
    "exact": {"color": "tab:blue", "lw": 2.5},
    "fixed_cost": {"color": "tab:orange", "lw": 1.2, "ls": "--"},
}


def plot(runs: dict, floor: float, out: Path) -> None:
    plt = ehsv.pyplot()
    fig, ax = plt.subplots(figsize=(8, 4))
    for name, style in STYLES.items():
        r = runs[name]
        ax.plot(r["time"] * 1e3, r["p_A"] * 1e-5, label=LABELS[name], **style)
    ax.axhline(floor * 1e-5, color="k", ls=":", lw=0.8, label="cavitation floor")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("p_A (bar)")
    ax.set_title(f"Piston retracted into its stop, every integrator at h = {NAIVE_H * 1e3:g} ms")
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    cli.write_figure(fig, out)


def main(argv=None) -> int:
    ap = cli.parser(__doc__)
    ap.add_argument("--out", type=Path, default=cli.OUT_DIR / "naive_fixed_step.png")
    args = ap.parse_args(argv)
    version = cli.version(args)
    if cli.archive_missing(version):
        return 1
    runs = retract_to_stop(version)
    floor = ehsv.parameters()["hydraulics.p_cavitation"]
    print(f"EhsvActuator ({version}), i_ref 0 -> -5 mA, h = {NAIVE_H:g} s")
    print(f"  cavitation floor {floor * 1e-5:.2f} bar")
    for name, r in runs.items():
        print(
            f"  {LABELS[name]:34s} lowest p_A {r['p_A'].min() * 1e-5:8.2f} bar, "
            f"p_A swing over the last 20 ms {settled_swing(r) * 1e-5:8.3f} bar"
        )
    plot(runs, floor, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
