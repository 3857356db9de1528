"""A synthetic bench recording for ehsv.calibrate: the FMU in position mode with hidden
parameter values, driven by x_ref held at random levels, with optional sensor noise,
offsets and delays.

    .venv/bin/python cosim-examples/bench_recording.py --out out/bench.csv
    .venv/bin/python cosim-examples/bench_recording.py --duration 1 --noise 0.005 \\
        --offset p_A=2e4 --delay x_piston=3e-4 --set cylinder.beta=8e8 --out out/bench.parquet

The levels (+-1.5 mm, each held 20-60 ms) keep the piston well inside its stroke and
excite the oil column (bulk modulus, dead volume, mass) at every change and the friction
whenever the piston stops. ``--noise`` is noise as a fraction of each output's range:
white, or with ``--noise-corr RHO`` coloured (a first-order autoregression of lag-1
correlation RHO, the same variance), as a real bench's filtered sensors give.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from ehsv import calibrate as cal

DEFAULT_TRUTH = {"cylinder.beta": 8e8, "cylinder.mass": 7.0, "cylinder.F_coulomb": 26.0}
OUTPUTS = ("x_piston", "p_A", "p_B")


def levels(t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """x_ref: 0 for the first 10 ms, then random levels held 20-60 ms."""
    x_ref = np.zeros_like(t)
    t0 = 0.01
    while t0 < t[-1]:
        x_ref[t >= t0] = rng.uniform(-1.5e-3, 1.5e-3)
        t0 += rng.uniform(0.02, 0.06)
    return x_ref


def coloured(e: np.ndarray, rho: float) -> np.ndarray:
    """White unit noise ``e`` made AR(1) with lag-1 correlation ``rho``, unit variance."""
    if rho == 0.0:
        return e
    from scipy.signal import lfilter

    out = lfilter([math.sqrt(1.0 - rho * rho)], [1.0, -rho], e)
    out[0] = e[0]  # stationary from the first sample
    return out


def recording(
    truth: dict, *, duration=0.2, rate=1e4, noise=0.0, offsets=None, delays=None, seed=0, noise_corr=0.0
):
    """The recording as a DataFrame (time, x_ref, x_piston, p_A, p_B)."""
    t = np.arange(int(round(duration * rate)) + 1) / rate
    # levels and noise from two independent streams of the one seed (generators seeded
    # seed and seed + 1 would draw a recording's noise from the bits of the next one's levels)
    levels_rng, rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))
    df = pd.DataFrame({"time": t, "x_ref": levels(t, levels_rng), **{n: np.zeros_like(t) for n in OUTPUTS}})
    y = cal.simulate("fmi2", {"control_mode": 2, **truth}, cal.read_recording(df))
    for name in OUTPUTS:
        v = np.interp(t - (delays or {}).get(name, 0.0), t, y[name]) + (offsets or {}).get(name, 0.0)
        df[name] = v + noise * np.ptp(y[name]) * coloured(rng.standard_normal(len(t)), noise_corr)
    return df


def _floats(items) -> dict:
    return {k: float(v) for k, v in (s.split("=", 1) for s in items or [])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=0.2, help="s")
    ap.add_argument("--rate", type=float, default=1e4, help="samples per second")
    ap.add_argument("--noise", type=float, default=0.0, help="fraction of each output's range")
    ap.add_argument("--noise-corr", type=float, default=0.0, help="lag-1 correlation of the noise")
    ap.add_argument("--set", action="append", metavar="NAME=VALUE", help="hidden parameter values")
    ap.add_argument("--offset", action="append", metavar="OUTPUT=VALUE")
    ap.add_argument("--delay", action="append", metavar="OUTPUT=SECONDS")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, required=True, help=".csv or .parquet")
    args = ap.parse_args(argv)
    truth = {**DEFAULT_TRUTH, **_floats(args.set)}
    df = recording(
        truth,
        duration=args.duration,
        rate=args.rate,
        noise=args.noise,
        offsets=_floats(args.offset),
        delays=_floats(args.delay),
        seed=args.seed,
        noise_corr=args.noise_corr,
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if args.out.suffix == ".parquet":
        df.to_parquet(args.out, index=False)
    else:
        df.to_csv(args.out, index=False)
    print(f"{len(df)} samples, hidden {truth} -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
