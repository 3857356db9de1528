"""How long a MuJoCo timestep the plugin actuators stand: the hydraulic leg (stand up,
squat, hop, land) and the quadruped (stand up, trot) on cosim-examples/mjcf/ with MuJoCo's
timestep 1e-4, 5e-4, 1e-3 and 2e-3 s, the plugin sub-stepping at 1e-4 s. Prints, for each
timestep, whether the robot stayed up and how far it departs from the 1e-4 s run: the
largest difference of the trunk height (mm), of the joint angles (deg) and of the rod
forces (N, and % of the 1e-4 s run's force range), on a common 1 kHz time grid (the
2e-3 s runs on their own 2 ms grid); dF: the largest change of a rod force between
successive 2 ms points while the robot stands still after standing up (chatter: a force
that alternates from step to step); and the wall time of each run.

    .venv/bin/python cosim-examples/host_timestep.py [--robot leg|quadruped|both]
        [--short] [--method exact|fixed_cost]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

import hydraulic_leg
import quadruped

TIMESTEPS = (1e-4, 5e-4, 1e-3, 2e-3)


def _on(t_ref, t, y):
    """y(t) (rows) interpolated onto t_ref, column by column."""
    y = np.asarray(y, dtype=float).reshape(len(t), -1)
    return np.column_stack([np.interp(t_ref, t, y[:, j]) for j in range(y.shape[1])])


def departures(ref, run) -> dict:
    """The largest differences of ``run`` from ``ref`` over the times both cover."""
    t = run.t[(run.t >= ref.t[0]) & (run.t <= min(ref.t[-1], run.t[-1]))]
    z = _on(t, ref.t, ref.rec["probe"][:, 0]) - _on(t, run.t, run.rec["probe"][:, 0])
    q = _on(t, ref.t, ref.rec["q"]) - _on(t, run.t, run.rec["q"])
    f_ref = _on(t, ref.t, ref.rec["F"])
    f = f_ref - _on(t, run.t, run.rec["F"])
    span = np.ptp(ref.rec["F"], axis=0).max()
    return {
        "z_mm": 1e3 * np.abs(z).max(),
        "q_deg": np.degrees(np.abs(q).max()),
        "F_N": np.abs(f).max(),
        "F_pct": 100 * np.abs(f).max() / span,
    }


def chatter(r, window: tuple[float, float]) -> float:
    """The largest change of a rod force between successive 2 ms points while the robot
    stands still (``window``, s): 0 for a smooth force, large where it alternates from step
    to step."""
    t = np.arange(window[0], window[1], 2e-3)
    f = _on(t, r.t, r.rec["F"])
    return float(np.abs(np.diff(f, axis=0)).max()) if len(t) > 1 else float("nan")


def hold_window(r) -> tuple[float, float]:
    """The stance after standing up, before the squat or the trot (the end if none)."""
    p = r.plan
    nxt = getattr(p, "squat", None) or getattr(p, "trot", None)
    end = nxt[0] if nxt else r.t_end
    return p.t_up[1] + 0.3 if end > p.t_up[1] + 0.4 else 0.3, end


def table(name: str, run, short: bool, method: str, stood) -> list[dict]:
    rows = []
    ref = None
    for h in TIMESTEPS:
        w0 = time.perf_counter()
        r = run(short=short, kind="plugin", render=False, method=method, timestep=h)
        wall = time.perf_counter() - w0
        ok = stood(r) and all(np.isfinite(r.rec["F"]).ravel())
        ref = ref or r
        row = {"robot": name, "h": h, "stable": ok, "wall": wall, **departures(ref, r)}
        row["chatter"] = chatter(r, hold_window(r))
        rows.append(row)
        print(
            f"{name:>10} {h:>7.0e} {'yes' if ok else 'NO':>7} {row['z_mm']:>9.2f} {row['q_deg']:>9.3f} "
            f"{row['F_N']:>9.1f} {row['F_pct']:>7.2f} {row['chatter']:>8.1f} {wall:>7.2f}",
            flush=True,
        )
    return rows


def leg_stood(r) -> bool:
    """The leg stood up and ends standing (on its plan's last command)."""
    end = r.window(r.t_end - 0.1, r.t_end + 1)
    return bool(np.abs(r.height[end] - r.height_cmd[end]).max() < 0.02)


def quad_stood(r) -> bool:
    return not r.fell


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robot", choices=("leg", "quadruped", "both"), default="both")
    ap.add_argument("--short", action="store_true", help="the tests' short runs (stand and hold)")
    ap.add_argument("--method", choices=("exact", "fixed_cost"), default="exact")
    args = ap.parse_args(argv)
    print(f"solver.method = {args.method}, plugin substep 1e-4 s; departures from the 1e-4 s run")
    head = ("robot", "h, s", "stable", "z, mm", "q, deg", "F, N", "F, %", "dF, N", "wall, s")
    print(" ".join(f"{h:>{w}}" for h, w in zip(head, (10, 7, 7, 9, 9, 9, 7, 8, 7), strict=True)))
    if args.robot in ("leg", "both"):
        table("leg", hydraulic_leg.run, args.short, args.method, leg_stood)
    if args.robot in ("quadruped", "both"):
        table("quadruped", quadruped.run, args.short, args.method, quad_stood)
    return 0


if __name__ == "__main__":
    sys.exit(main())
