"""How often the truth lies inside ehsv.calibrate's 95 % intervals: bench recordings made
by bench_recording.py over N seeds (0.5 % noise, an offset on p_A and a delay on
x_piston, the hidden parameters of bench_recording.DEFAULT_TRUTH), each fitted as
docs/calibration.md says, on one dask LocalCluster.

    .venv/bin/python cosim-examples/calibration_coverage.py [--seeds 20] [--first 0] [--workers 2]
        [--starts 4] [--duration 0.2] [--noise-corr RHO] [--white] [--no-refine]
        [--json out/coverage.json]

Prints, per fitted quantity (and per block of 20 seeds where more are run), the seeds
whose interval holds the truth and the spread of the standardized errors
z = (value - truth) / sd (sd: the interval's half-width over the t quantile; an honest
interval has z of spread 1), per output the residuals' lag-1 autocorrelation at the
optimum (white residuals: about 0), and the seeds whose fit needed refinement rounds.
``--noise-corr`` colours the noise (bench_recording.coloured); ``--white`` computes the
intervals without ``calibrate.autocorrelation_inflation``; ``--no-refine`` fits without
calibrate's refinement rounds.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import bench_recording
from ehsv import calibrate as cal

NOISE, OFFSETS, DELAYS = 0.005, {"p_A": 2e4}, {"x_piston": 3e-4}
#: coverage is also counted per block of this many seeds (at least 18 of 20 is asked)
BLOCK = 20
TRUTH = {**bench_recording.DEFAULT_TRUTH, "offset:p_A": 2e4, "delay:x_piston": 3e-4}


def fit_seed(seed: int, *, duration: float = 0.2, rho: float = 0.0, **solve) -> dict:
    """One seed's recording fitted (``solve``: calibrate's starts, scheduler or serial);
    the truth's z and inside flag per quantity, the residuals' lag-1 autocorrelation per
    output, the refinement rounds run and whether the best start came from one."""
    df = bench_recording.recording(
        bench_recording.DEFAULT_TRUTH,
        duration=duration,
        noise=NOISE,
        offsets=OFFSETS,
        delays=DELAYS,
        seed=seed,
        noise_corr=rho,
    )
    fit = cal.calibrate(
        df,
        list(TRUTH),
        bounds={"delay:x_piston": "0:0.002"},
        set_values={"control_mode": "position"},
        progress=False,
        **solve,
    )
    params = fit.report["parameters"]
    rows = {name: _row(params[name], truth) for name, truth in TRUTH.items()}
    starts = fit.report["starts"]
    best = min(starts, key=lambda st: st["cost"])
    return {
        "seed": seed,
        "quantities": rows,
        "lag1": _lag1(fit),
        "refine_rounds": max((st.get("refine", 0) for st in starts), default=0),
        "best_from_refine": "refine" in best,
    }


def _row(p: dict, truth: float) -> dict:
    lo, hi = p["ci95"]
    # z on the value scale from the half-width on the side of the truth (log-scaled
    # intervals are asymmetric); the t quantile of a few thousand samples is 1.96
    half = (p["value"] - lo) if truth < p["value"] else (hi - p["value"])
    return {
        "value": p["value"],
        "ci95": [lo, hi],
        "inside": lo <= truth <= hi,
        "z": (p["value"] - truth) / (half / 1.96) if half > 0 else float("inf"),
    }


def _lag1(fit) -> dict:
    problem = fit.problem
    model = problem.model([fit.report["parameters"][u.name]["value"] for u in problem.unknowns])
    return {name: cal.lag1_correlation(model[name] - y) for name, y in problem.rec.outputs.items()}


def summarize(results: list[dict]) -> str:
    n = len(results)
    lines = [f"{'quantity':<20} {'inside':>8} {'z mean':>8} {'z sd':>6} {'max |z|':>8}"]
    for name in TRUTH:
        z = np.array([r["quantities"][name]["z"] for r in results])
        hits = sum(r["quantities"][name]["inside"] for r in results)
        lines.append(
            f"{name:<20} {hits:>4}/{n:<3} {z.mean():>8.2f} {z.std(ddof=1):>6.2f} {np.abs(z).max():>8.2f}"
        )
    if n > BLOCK:
        lines.append(f"per block of {BLOCK} seeds, the seeds whose interval holds the truth:")
        for first in range(0, n - BLOCK + 1, BLOCK):
            block = results[first : first + BLOCK]
            counts = [sum(r["quantities"][name]["inside"] for r in block) for name in TRUTH]
            lines.append(f"  seeds {block[0]['seed']}-{block[-1]['seed']}: " + " ".join(map(str, counts)))
    refined = [r["seed"] for r in results if r["refine_rounds"]]
    rescued = [r["seed"] for r in results if r["best_from_refine"]]
    lines.append(
        f"refinement rounds ran for seeds {refined or 'none'}; "
        f"the best start came from one for {rescued or 'none'}"
    )
    lag = {k: np.mean([r["lag1"][k] for r in results]) for k in results[0]["lag1"]}
    lines.append(
        "residual lag-1 autocorrelation (mean): " + ", ".join(f"{k} {v:+.3f}" for k, v in lag.items())
    )
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first", type=int, default=0, help="first seed")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--starts", type=int, default=4)
    ap.add_argument("--duration", type=float, default=0.2, help="s of each recording")
    ap.add_argument("--noise-corr", type=float, default=0.0, help="lag-1 correlation of the noise")
    ap.add_argument(
        "--white",
        action="store_true",
        help="intervals as if the residuals were white (without autocorrelation_inflation)",
    )
    ap.add_argument(
        "--no-refine",
        action="store_true",
        help="without calibrate's refinement rounds (a fit a basin off stays there)",
    )
    ap.add_argument("--json", type=Path, help="write the per-seed results here")
    a = ap.parse_args(argv)
    from dask.distributed import LocalCluster

    if a.white:  # the intervals are computed in this process, after the starts
        cal.autocorrelation_inflation = lambda r: 1.0
    if a.no_refine:
        cal.REFINE_ROUNDS = 0

    results = []
    with LocalCluster(n_workers=a.workers, threads_per_worker=1, dashboard_address=":0") as lc:
        for seed in range(a.first, a.first + a.seeds):
            solve = {"starts": a.starts, "scheduler": lc.scheduler_address}
            results.append(fit_seed(seed, duration=a.duration, rho=a.noise_corr, **solve))
            inside = [k for k, v in results[-1]["quantities"].items() if not v["inside"]]
            rounds = results[-1]["refine_rounds"]
            refine = f", {rounds} refinement rounds" if rounds else ""
            print(f"seed {seed}: truth outside for {inside or 'none'}{refine}", flush=True)
    print(summarize(results))
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
