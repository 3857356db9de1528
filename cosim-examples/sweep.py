"""Parameter study of the FMU on dask.distributed, one FMU run per design point.

Every metric goes in one tidy table (Parquet), and a figure shows the study.

    .venv/bin/python cosim-examples/sweep.py                      # default study, ~36 runs
    .venv/bin/python cosim-examples/sweep.py --points 40          # finer: 120 runs
    .venv/bin/python cosim-examples/sweep.py --scenario flow_step --design lhs --points 64 \\
        --vary driver=opamp_pi --vary V_supply=10:72 --vary flow.Kp=0.5:8:log
    .venv/bin/python cosim-examples/sweep.py --scenario current_step --design lhs --points 200 \\
        --vary valve.K3=5% --vary valve.f_n=10% --vary valve.zeta=20%      # valve tolerances
    .venv/bin/python cosim-examples/sweep.py --scheduler tcp://10.0.0.5:8786   # an existing cluster
    .venv/bin/python cosim-examples/sweep.py --throughput         # runs/s: serial, 1 and 2 workers

Default study: the 0 -> 5 mA current step (i_ref at t = 0 from rest, 20 ms at 2 us)
for the paper's three drivers (op-amp PI, H-bridge, industrial) with V_supply from 12 to
72 V. Each worker process extracts the archive once and reuses one FMU instance, reset
between runs. A point whose run fails is recorded with its error; the others go on.
Without --scheduler the runs go to an in-process LocalCluster with one worker per core
(--workers N to choose, --serial for a plain loop in this process).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pandas as pd

import ehsv
from ehsv import cli, cluster, study

DEFAULT_VARY = ["driver=opamp_pi,hbridge_pid,industrial", "V_supply=12:72"]
DEFAULT_POINTS = 12


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", choices=sorted(study.SCENARIOS), default="current_step")
    ap.add_argument(
        "--vary",
        action="append",
        metavar="FACTOR",
        help="name=lo:hi[:log], name=a,b,c or name=P%% (repeat; default: " + " ".join(DEFAULT_VARY) + ")",
    )
    ap.add_argument("--design", choices=("grid", "lhs"), default="grid")
    ap.add_argument(
        "--points",
        type=int,
        default=DEFAULT_POINTS,
        help="values per range (grid) or samples per level combination (lhs)",
    )
    ap.add_argument("--seed", type=int, default=1, help="seed of the Latin hypercube")
    ap.add_argument(
        "--metrics",
        default=",".join(study.METRICS),
        help="comma-separated, from: " + ", ".join(study.METRICS),
    )
    ap.add_argument("--h", type=float, help="communication step, s (scenario default)")
    ap.add_argument("--t-stop", type=float, help="simulated time, s (scenario default)")
    ap.add_argument("--fmi3", action="store_true", help="use the FMI 3.0 archive")
    ap.add_argument("--scheduler", help="address (tcp://host:port) or scheduler file of a dask cluster")
    ap.add_argument("--workers", type=int, help="LocalCluster workers (default: one per core)")
    ap.add_argument("--serial", action="store_true", help="run in this process, no dask")
    ap.add_argument(
        "--throughput",
        action="store_true",
        help="time the design serially, on 1 and on 2 LocalCluster workers",
    )
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--out", type=Path, default=cli.OUT_DIR / "sweep.parquet")
    ap.add_argument("--figure", type=Path, default=cli.OUT_DIR / "sweep.png")
    return ap.parse_args(argv)


def study_points(args) -> list[dict]:
    metrics = [m.strip() for m in args.metrics.split(",") if m.strip()]
    return study.points(
        args.vary or DEFAULT_VARY,
        args.points,
        kind=args.design,
        seed=args.seed,
        scenario=args.scenario,
        version=cli.version(args),
        metrics=metrics,
        h=args.h,
        t_stop=args.t_stop,
    )


def run(points, *, scheduler=None, workers=None, serial=False, progress=True) -> list[dict]:
    client = None if serial else cluster.client_for(scheduler, workers)
    try:
        return cluster.map_points(study.run_point, points, client=client, progress=progress)
    finally:
        cluster.close(client)


def throughput(points, progress: bool) -> None:
    """Runs per second of the same design: serially in this process, then on a
    LocalCluster of 1 and of 2 workers (cluster start-up and one warm-up run per worker
    not counted)."""
    print(f"throughput of {len(points)} runs ({points[0]['_scenario']}):")
    print(f"{'':12} {'runs/s':>8} {'wall s':>8}")
    for label, workers in (("serial", 0), ("1 worker", 1), ("2 workers", 2)):
        client = None if workers == 0 else cluster.local_cluster_client(workers)
        try:
            warm = [points[0]] * max(1, workers)
            cluster.map_points(study.run_point, warm, client=client, progress=False)
            start = time.perf_counter()
            cluster.map_points(study.run_point, points, client=client, progress=progress, desc=label)
            wall = time.perf_counter() - start
        finally:
            cluster.close(client)
        print(f"{label:12} {len(points) / wall:8.2f} {wall:8.2f}")


def figure(df: pd.DataFrame, metric: str, out: Path) -> None:
    """The study's first metric against its first range factor, one curve per level of
    the first level factor; the paper's three drivers marked when the study is theirs."""
    plt = ehsv.pyplot()
    numeric = [
        c for c in df.columns if c not in ("point", "error", *study.RUN_COLUMNS) and c not in study.METRICS
    ]
    x = next((c for c in numeric if pd.api.types.is_float_dtype(df[c])), None)
    group = next((c for c in numeric if c != x and not pd.api.types.is_float_dtype(df[c])), None)
    if x is None:
        return
    fig, ax = plt.subplots(figsize=(8, 5))
    scale = 1e3 if metric.startswith(("settling", "rise")) else 1.0
    for name, part in df.groupby(group) if group else [(None, df)]:
        part = part.sort_values(x)
        ax.plot(part[x], part[metric] * scale, "o-", ms=3, label=str(name) if name is not None else metric)
    if metric == "settling_i" and x == "V_supply" and group == "driver":
        for spec in ehsv.PAPER_DRIVERS:
            ax.plot(spec.V_supply, spec.paper_ms, "k*", ms=12)
            right = spec.V_supply > df[x].mean()
            ax.annotate(
                f"paper: {spec.driver} {spec.paper_ms:g} ms at {spec.V_supply:g} V",
                (spec.V_supply, spec.paper_ms),
                textcoords="offset points",
                xytext=(-8 if right else 8, 8),
                ha="right" if right else "left",
                fontsize=8,
            )
        ax.set_yscale("log")
    unit = "ms" if scale == 1e3 else ""
    ax.set_xlabel(x)
    ax.set_ylabel(f"{metric} [{unit}]" if unit else metric)
    ax.set_title(study.METRICS[metric][0].rsplit(",", 1)[0], fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.suptitle(f"EhsvActuator parameter study: {len(df)} runs")
    ehsv.save_figure(fig, out)


def main(argv=None) -> int:
    args = parse_args(argv)
    version = cli.version(args)
    if cli.archive_missing(version):
        return 1
    points = study_points(args)
    progress = not args.no_progress
    if args.throughput:
        throughput(points, progress)
        return 0
    start = time.perf_counter()
    results = run(
        points, scheduler=args.scheduler, workers=args.workers, serial=args.serial, progress=progress
    )
    wall = time.perf_counter() - start
    df = study.results_table(points, results)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    df.to_parquet(args.out, index=False)
    failed = df["error"].notna().sum()
    print(f"{len(df)} runs in {wall:.1f} s ({len(df) / wall:.1f} runs/s), {failed} failed -> {args.out}")
    with pd.option_context("display.width", 160, "display.max_rows", 20):
        print(df.drop(columns=list(study.RUN_COLUMNS)).to_string(max_rows=20))
    metric = points[0]["_metrics"][0]
    figure(df, metric, args.figure)
    print(f"figure: {args.figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
