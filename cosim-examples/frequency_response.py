"""Frequency responses of the actuator through the FMU, per driver: i_ref -> i_coil,
i_ref -> Q_valve and, in the flow loop, Q_ref -> Q_valve; small signal (0.1 mA) and
large signal (1, 5, 10 mA) at supplies of 72, 24 and 10 V.

    .venv/bin/python cosim-examples/frequency_response.py [--quick] [--fmi3] [--serial]
        [--scheduler ADDRESS] [--workers N] [--out-dir out] [--valve NAME|all ...]

Method: sine excitation, settle, fundamental over whole periods (ehsv/frequency.py says
how the held inputs are accounted for). Prints

1. the small-signal table: -3 dB and -90 degree frequencies and the delay at 10 Hz
   (-phase / (2 pi 10 Hz)) per driver and supply, beside the paper's eq. 3 and eq. 4,
   and the op-amp loop's bandwidth over the voltage drive's against Kp / R,
2. the large-signal -3 dB frequency of i_coil per driver, supply and amplitude,
3. the slew limit of the op-amp driver: the frequency at which a sine of amplitude A
   first drives it to its rail, against (V - R A) / (2 pi L A),

and writes bode_small_signal.png, bode_large_signal.png and slew_limit.png. Every
curve is one task on dask.distributed (LocalCluster by default, one worker per core).

``--valve NAME`` (a valve of the catalog cosim-examples/ehsv/valves.toml, repeatable, or
``all``) measures that valve instead: its small-signal Q_valve / i_ref with the ideal
current source (1 % of its rated current) over a sweep, the DC gain from a step held to
steady state, the -90 degree and -3 dB frequencies by a root search on the measured phase
and magnitude inside the sweep's bracket (ehsv/valves.py), and, with the rod held at
mid-stroke and its ports blocked at the datasheet's supply, Q_supply at null and the
pressure gain. It prints each figure of the datasheet beside the FMU's, and writes
bode_valve_NAME.png: the measured points, the model's line from its derived gains, the
datasheet's points marked (Q_rated/i_rated, -3 dB at f_3dB, -90 degrees at f_90).
"""

from __future__ import annotations

import math
import sys
import textwrap
from pathlib import Path

import numpy as np

import ehsv
from ehsv import cli, cluster
from ehsv import frequency as fr
from ehsv import valves as vv

SUPPLIES = (72.0, 24.0, 10.0)
SMALL = 1e-4  # A, small-signal amplitude
LARGE = (1e-3, 5e-3, 10e-3)  # A
LOOP_DRIVERS = ("opamp_pi", "industrial", "hbridge_pid")  # closed current loops: the supply matters
COLORS = {
    "ideal_current": "tab:green",
    "voltage": "tab:red",
    "opamp_pi": "tab:blue",
    "industrial": "tab:purple",
    "hbridge_pid": "tab:orange",
    "flow loop": "tab:brown",
}


def report_failures(results: list[dict]) -> bool:
    """Prints the tasks that failed (their "error"); whether any did."""
    failed = [r for r in results if "error" in r]
    for r in failed:
        print(f"failed: {r['error']}", file=sys.stderr)
    return bool(failed)


def feasible(v_supply: float, amplitude: float) -> bool:
    """A current of this amplitude needs at least R A volts at DC."""
    return ehsv.NOMINAL["coil.R"] * amplitude < v_supply


def small_signal_specs(version, freqs) -> list[dict]:
    """ideal_current and voltage once (the supply only clamps |R i| > V), the closed loops
    at every supply, and the flow loop Q_ref -> Q_valve at 72 V and 10 V."""
    base = {"version": version, "amplitude": SMALL, "freqs": freqs, "refine": True}
    specs = [{**base, "driver": d, "V_supply": 72.0} for d in ("ideal_current", "voltage")]
    specs += [{**base, "driver": d, "V_supply": v} for d in LOOP_DRIVERS for v in SUPPLIES]
    q_small = ehsv.flow_gain() * SMALL
    specs += [
        {
            **base,
            "driver": "opamp_pi",
            "V_supply": v,
            "input": "Q_ref",
            "control_mode": "flow",
            "amplitude": q_small,
        }
        for v in (72.0, 10.0)
    ]
    return specs


def large_signal_specs(version, freqs) -> list[dict]:
    return [
        {"version": version, "driver": d, "V_supply": v, "amplitude": a, "freqs": freqs, "refine": False}
        for d in LOOP_DRIVERS
        for v in SUPPLIES
        for a in LARGE
        if feasible(v, a)
    ]


def label(c: dict) -> str:
    return "flow loop" if c.get("control_mode") == "flow" else c["driver"]


def ms(x: float) -> str:
    return f"{x * 1e3:8.3f}"


def hz(x: float) -> str:
    return f"{x:9.1f}" if math.isfinite(x) else f"{'-':>9}"


def analytic_figures(driver: str) -> dict:
    """-3 dB, -90 degree frequencies and the 10 Hz delay of the analytic responses."""
    f = np.geomspace(0.1, 1e6, 20001)
    out = {}
    for o in fr.CURRENT_OUTPUTS:
        g = fr.analytic(driver, o, f) / fr.static_gain(o)
        g10 = fr.analytic(driver, o, 10.0) / fr.static_gain(o)
        out[o] = (
            fr.crossing(f, np.abs(g), 1 / math.sqrt(2)),
            fr.crossing(f, fr.phase_deg(g), -90.0),
            -np.angle(g10) / (2 * math.pi * 10),
        )
    return out


def small_signal_table(curves: list[dict]) -> str:
    head = (
        f"{'response':<26} {'supply':>6}  {'i_coil -3dB':>11} {'-90deg':>9}  "
        f"{'Q_valve -3dB':>12} {'-90deg':>9}  {'10 Hz delay i, Q [ms]':>21}"
    )
    lines = [
        f"small signal ({SMALL * 1e3:g} mA; flow loop: the same flow), measured through the FMU [Hz]",
        head,
    ]
    lines.append("-" * len(head))
    for c in curves:
        name = label(c) if label(c) != "flow loop" else "flow loop (Q_ref->Q_valve)"
        supply = "any" if c["driver"] in ("ideal_current", "voltage") else f"{c['V_supply']:.0f} V"
        d = c["delay_10hz"]
        lines.append(
            f"{name:<26} {supply:>6}  {hz(c['f3']['i_coil']):>11} {hz(c['f90']['i_coil'])}  "
            f"{hz(c['f3']['Q_valve']):>12} {hz(c['f90']['Q_valve'])}  {ms(d['i_coil'])} {ms(d['Q_valve'])}"
        )
    for driver, name in (("ideal_current", "eq. 3 (ideal current)"), ("voltage", "eq. 4 (voltage drive)")):
        a = analytic_figures(driver)
        lines.append(
            f"{name:<26} {'':>6}  {hz(a['i_coil'][0]):>11} {hz(a['i_coil'][1])}  "
            f"{hz(a['Q_valve'][0]):>12} {hz(a['Q_valve'][1])}  {ms(a['i_coil'][2])} {ms(a['Q_valve'][2])}"
        )
    return "\n".join(lines)


def loop_gain_line(curves: list[dict]) -> str:
    """The op-amp loop's small-signal current bandwidth over the voltage drive's."""
    by = {(c["driver"], c["V_supply"], c.get("control_mode")): c for c in curves}
    opamp = by[("opamp_pi", 72.0, None)]["f3"]["i_coil"]
    volt = by[("voltage", 72.0, None)]["f3"]["i_coil"]
    p = ehsv.NOMINAL
    predicted = p["driver.Kp"] / (p["coil.R"] + p["coil.R_sense"])
    return (
        f"current bandwidth, op-amp PI / voltage drive at 72 V: {opamp:.1f} / {volt:.2f} Hz = "
        f"{opamp / volt:.1f}; loop gain Kp / R = {predicted:.1f} "
        f"(closed loop Kp / (L s + Kp) against the coil's R / (L s + R))"
    )


def large_signal_table(curves: list[dict]) -> str:
    lines = ["large signal: i_coil -3 dB frequency [Hz] (grid-interpolated)"]
    head = f"{'driver':<12} {'supply':>6}" + "".join(f" {a * 1e3:>8g} mA" for a in LARGE)
    lines += [head, "-" * len(head)]
    by = {(c["driver"], c["V_supply"], c["amplitude"]): c for c in curves}
    for d in LOOP_DRIVERS:
        for v in SUPPLIES:
            cells = [
                hz(by[(d, v, a)]["f3"]["i_coil"]) if (d, v, a) in by else f"{'(R A > V)':>9}" for a in LARGE
            ]
            lines.append(f"{d:<12} {v:>4.0f} V" + "".join(f" {c:>11}" for c in cells))
    return "\n".join(lines)


def onset_table(onsets: list[dict]) -> str:
    head = (
        f"{'supply':>6} {'A mA':>5} {'onset Hz':>9} {'loop':>8} {'ratio':>6} {'rail':>8} "
        f"{'(V-RA)/2piLA':>13} {'ratio':>6}"
    )
    lines = [
        "op-amp slew limit: frequency at which a sine of amplitude A first drives the output to its rail",
        "(loop: A |u/i_ref| of the linear PI loop reaches the rail; rail: A sqrt(R^2 + (2 pi f L)^2) = V)",
        head,
        "-" * len(head),
    ]
    for o in onsets:
        v, a = o["V_supply"], o["amplitude"]
        loop, rail, slew = fr.loop_rail_limit(v, a), fr.rail_limit(v, a), fr.slew_limit(v, a)
        lines.append(
            f"{v:>4.0f} V {a * 1e3:>5g} {hz(o['onset'])} {loop:8.1f} {o['onset'] / loop:6.3f} {rail:8.1f} "
            f"{slew:13.1f} {o['onset'] / slew:6.3f}"
        )
    return "\n".join(lines)


def bode_figure(curves: list[dict], out: Path, version: str) -> None:
    plt = ehsv.pyplot()
    fig, axes = plt.subplots(2, 2, sharex=True, figsize=(13, 8))
    fa = np.geomspace(min(curves[0]["f"]), max(curves[0]["f"]), 400)
    for col, o in enumerate(fr.CURRENT_OUTPUTS):
        mag, ph = axes[0, col], axes[1, col]
        for c in curves:
            if c["V_supply"] != 72.0:
                continue
            g = np.asarray(c["gains"][o])
            name = label(c)
            if name == "flow loop" and o == "i_coil":
                continue
            f3 = c["f3"][o]
            text = f"{name}: -3 dB {f3:.0f} Hz" if math.isfinite(f3) else name
            mag.semilogx(c["f"], fr.db(g), "o", ms=3, color=COLORS[name], label=text)
            ph.semilogx(c["f"], fr.phase_deg(g), "o", ms=3, color=COLORS[name])
        overlays = [("eq. 3 (ideal current)", fr.analytic("ideal_current", o, fa), "g-")]
        overlays.append(("eq. 4 (voltage drive)", fr.analytic("voltage", o, fa), "r--"))
        overlays.append(("PI loop, analytic", fr.analytic("opamp_pi", o, fa), "b:"))
        for text, g, style in overlays:
            g = g / fr.static_gain(o)
            mag.semilogx(fa, fr.db(g), style, lw=1, label=text)
            ph.semilogx(fa, fr.phase_deg(g), style, lw=1)
        mag.set_ylim(-60 if o == "Q_valve" else -40, 5)
        mag.axhline(-3, color="grey", lw=0.5, ls=":")
        ph.axhline(-90, color="grey", lw=0.5, ls=":")
        ph.set_ylim(-300 if o == "Q_valve" else -180, 10)
        flow = " (flow loop: Q_ref -> Q_valve)" if o == "Q_valve" else ""
        mag.set_title(f"i_ref -> {o}{flow}, 72 V, 0.1 mA", fontsize=9)
        mag.set_ylabel("gain / static gain [dB]")
        ph.set_ylabel("phase [deg]")
        ph.set_xlabel("frequency [Hz]")
        mag.legend(fontsize=7, loc="lower left")
        for ax in (mag, ph):
            ax.grid(alpha=0.3, which="both")
    fig.suptitle(f"EhsvActuator small-signal frequency response, points: FMU ({version}), lines: analytic")
    ehsv.save_figure(fig, out)


def large_figure(curves: list[dict], out: Path, version: str) -> None:
    plt = ehsv.pyplot()
    fig, axes = plt.subplots(1, len(SUPPLIES), sharey=True, figsize=(15, 5))
    styles = dict(zip(LARGE, ("-", "--", ":"), strict=True))
    for ax, v in zip(axes, SUPPLIES, strict=True):
        for c in curves:
            if c["V_supply"] != v:
                continue
            f3 = c["f3"]["i_coil"]
            ax.semilogx(
                c["f"], fr.db(c["gains"]["i_coil"]), styles[c["amplitude"]], marker="o", ms=3,
                color=COLORS[c["driver"]], label=f"{c['driver']} {c['amplitude'] * 1e3:g} mA: {f3:.0f} Hz",
            )  # fmt: skip
        ax.axhline(-3, color="grey", lw=0.5, ls=":")
        ax.set_title(f"V_supply {v:g} V", fontsize=10)
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylim(-30, 3)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="lower left")
    axes[0].set_ylabel("i_coil / i_ref fundamental [dB]")
    fig.suptitle(
        f"EhsvActuator large-signal current response (-3 dB frequency in the legend), FMU ({version})"
    )
    ehsv.save_figure(fig, out)


def onset_figure(onsets: list[dict], out: Path) -> None:
    plt = ehsv.pyplot()
    fig, ax = plt.subplots(figsize=(8, 5))
    amps = np.geomspace(0.5e-3, 12e-3, 200)
    for v, color in zip(SUPPLIES, ("tab:blue", "tab:orange", "tab:red"), strict=True):
        a = amps[[feasible(v, x) for x in amps]]
        for limit, style, what in (
            (fr.loop_rail_limit, "-", "PI loop at the rail"),
            (fr.slew_limit, ":", "(V - R A)/(2 pi L A)"),
        ):
            ax.loglog(a * 1e3, [limit(v, x) for x in a], style, color=color, lw=1, label=f"{v:g} V: {what}")
        pts = [o for o in onsets if o["V_supply"] == v]
        ax.loglog(
            [o["amplitude"] * 1e3 for o in pts],
            [o["onset"] for o in pts],
            "o",
            color=color,
            label=f"{v:g} V: FMU",
        )
        for o in pts:
            xy = (o["amplitude"] * 1e3, o["onset"])
            ax.annotate(f"{o['onset']:.0f} Hz", xy, textcoords="offset points", xytext=(5, 4), fontsize=7)
    ax.set_xlabel("current amplitude A [mA]")
    ax.set_ylabel("highest frequency without reaching the rail [Hz]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.suptitle("op-amp PI driver: large-signal (slew) limit of the coil current")
    ehsv.save_figure(fig, out)


# --------------------------------------------------------------------------------------
# --valve NAME: a catalog valve's datasheet figures through the FMU
# --------------------------------------------------------------------------------------

L_MIN = 60000.0  # L/min per m3/s


def valve_sweep(name: str, per_decade: int) -> list[float]:
    """From a twentieth of the lower datasheet frequency to 8 f_90, ``per_decade`` points
    a decade."""
    sheet = vv.datasheet(vv.start_values(name))
    lo, hi = min(sheet.f_90, sheet.f_3dB or sheet.f_90) / 20, 8 * sheet.f_90
    return list(np.geomspace(lo, hi, int(round(per_decade * math.log10(hi / lo))) + 1))


def _cell(x, scale: float = 1.0, fmt: str = "{:12.7g}") -> str:
    return fmt.format(x * scale) if x is not None and math.isfinite(x) else f"{'-':>12}"


def _err(measured, expected) -> str:
    if expected is None or not expected or not math.isfinite(measured):
        return f"{'':>10}"
    return f"{(measured / expected - 1) * 100:+9.4f}%"


def valve_table(name: str, resp: dict, null: dict) -> str:
    """Each datasheet figure of the valve beside the FMU's derived one and the measured."""
    sheet, d = resp["datasheet"], resp["derived"]
    where = vv.source(name).get("document", "no source document named")
    p_bar = sheet.p_leak_ref / 1e5
    gain_expected = sheet.pressure_gain or sheet.lap_pressure_gain
    rows = [
        ("DC gain Q_rated/i_rated", "L/min per mA", sheet.flow_gain, d["K3"] * d["K1"] / d["Kw"],
         resp["dc_gain"], L_MIN / 1e3),
        ("-90 degree frequency f_90", "Hz", sheet.f_90, d["f_90"], resp["f_90"], 1.0),
        ("-3 dB frequency f_3dB", "Hz", sheet.f_3dB, d["f_3dB"], resp["f_3dB"], 1.0),
        (f"null leakage at {p_bar:g} bar", "L/min", sheet.Q_leak_null, d["Q_leak_null"],
         null["Q_supply"], L_MIN),
        (f"pressure gain at {p_bar:g} bar", "bar per mA", gain_expected, d["pressure_gain"] or None,
         null["pressure_gain"], 1e-8),
    ]  # fmt: skip
    head = (
        f"{'figure':<30} {'unit':<13} {'datasheet':>12} {'FMU derived':>12} {'measured':>12} {'vs sheet':>10}"
    )
    lines = [f"valve {name} ({where})", head, "-" * len(head)]
    for what, unit, sheet_v, derived_v, measured, scale in rows:
        lines.append(
            f"{what:<30} {unit:<13} {_cell(sheet_v, scale)} {_cell(derived_v, scale)} "
            f"{_cell(measured, scale)} {_err(measured, sheet_v)}"
        )
    if not sheet.pressure_gain and gain_expected:
        lines.append("  (pressure gain not on the sheet: the one its null leakage gives through the lap)")
    runs = f"  {len(resp['f'])} sweep points, {resp['evaluations'] - len(resp['f'])} runs for the crossings"
    amp = f"{resp['amplitude'] * 1e3:g} mA"
    if math.isfinite(null["di"]):
        lines.append(f"{runs}, {amp}; pressure gain from +-{null['di'] * 1e3:.3g} mA")
    else:
        lines.append(f"{runs}, {amp}; no lap: pressure gain unbounded")
    return "\n".join(lines)


def valve_figure(name: str, resp: dict, out: Path, version: str) -> None:
    """Bode plot of Q_valve / i_ref over Q_rated/i_rated: measured points, the model's line
    (derived gains), the datasheet's points and the measured crossings."""
    plt = ehsv.pyplot()
    sheet, d = resp["datasheet"], resp["derived"]
    k = sheet.flow_gain
    fig, (mag, ph) = plt.subplots(2, 1, sharex=True, figsize=(8, 7))
    g = np.asarray(resp["gains"]) / k
    fa = np.geomspace(min(resp["f"]), max(resp["f"]), 400)
    ga = vv.transfer(d, fa) / k
    mag.semilogx(resp["f"], fr.db(g), "o", ms=4, color="tab:blue", label="FMU, measured (sine fits)")
    ph.semilogx(resp["f"], fr.phase_deg(g), "o", ms=4, color="tab:blue")
    mag.semilogx(fa, fr.db(ga), "-", lw=1, color="tab:blue", alpha=0.5, label="model, derived gains")
    ph.semilogx(fa, fr.phase_deg(ga), "-", lw=1, color="tab:blue", alpha=0.5)
    dc_db = 20 * math.log10(resp["dc_gain"] / k)
    mag.plot([min(resp["f"])], [0.0], "rs", ms=9, mfc="none", label="datasheet Q_rated/i_rated (0 dB)")
    mag.plot([min(resp["f"])], [dc_db], "k+", ms=9, label=f"measured DC gain ({dc_db:+.4f} dB)")
    if sheet.f_3dB:
        mag.plot(
            [sheet.f_3dB], [-3.0103], "rD", ms=9, mfc="none", label=f"datasheet f_3dB {sheet.f_3dB:g} Hz"
        )
    if math.isfinite(resp["f_3dB"]):
        mag.plot(
            [resp["f_3dB"]], [-3.0103 + dc_db], "kx", ms=8, label=f"measured -3 dB: {resp['f_3dB']:.4g} Hz"
        )
    ph.plot([sheet.f_90], [-90.0], "rD", ms=9, mfc="none", label=f"datasheet f_90 {sheet.f_90:g} Hz")
    if math.isfinite(resp["f_90"]):
        ph.plot([resp["f_90"]], [-90.0], "kx", ms=8, label=f"measured -90 deg: {resp['f_90']:.4g} Hz")
    for ax, level in ((mag, -3.0103), (ph, -90.0)):
        ax.axhline(level, color="grey", lw=0.5, ls=":")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="lower left")
    mag.set_ylabel("|Q_valve / i| over Q_rated/i_rated [dB]")
    ph.set_ylabel("phase [deg]")
    ph.set_xlabel("frequency [Hz]")
    doc = textwrap.shorten(vv.source(name).get("document", ""), 110, placeholder=" ...")
    fig.suptitle(
        f"valve {name}: small-signal Q_valve / i_coil, ideal current, {resp['amplitude'] * 1e3:g} mA, "
        f"FMU ({version})" + (f"\n{doc}" if doc else ""),
        fontsize=9,
    )
    cli.write_figure(fig, out)


def valve_main(args, version: str) -> int:
    """--valve: measure each named valve (one dask task per measurement), print its
    table, draw its Bode plot."""
    chosen = vv.names() if "all" in args.valve else args.valve
    unknown = [n for n in chosen if n not in vv.names()]
    if unknown:
        print(
            f"no valve {', '.join(unknown)} in the catalog; it has {', '.join(vv.names())}", file=sys.stderr
        )
        return 2
    per_decade = 4 if args.quick else 10
    responses = [{"version": version, "valve": n, "freqs": valve_sweep(n, per_decade)} for n in chosen]
    nulls = [{"version": version, "valve": n} for n in chosen]
    client = None if args.serial else cluster.client_for(args.scheduler, args.workers)
    try:
        progress = not args.no_progress
        resp = cluster.map_points(
            vv.measure_response, responses, client=client, progress=progress, desc="valves"
        )
        null = cluster.map_points(vv.measure_null, nulls, client=client, progress=progress, desc="null")
    finally:
        cluster.close(client)
    if report_failures(resp + null):
        return 1
    print(f"EhsvActuator ({version}): catalog valves, datasheet against the FMU")
    for name, r, n in zip(chosen, resp, null, strict=True):
        print()
        print(valve_table(name, r, n))
        valve_figure(name, r, args.out_dir / f"bode_valve_{name}.png", version)
    return 0


def main(argv=None) -> int:
    ap = cli.parser(__doc__)
    ap.add_argument("--quick", action="store_true", help="fewer frequencies (a smoke run)")
    ap.add_argument("--scheduler", help="address or scheduler file of a running dask cluster")
    ap.add_argument("--workers", type=int, help="LocalCluster workers (default: one per core)")
    ap.add_argument("--serial", action="store_true", help="run in this process, no dask")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--out-dir", type=Path, default=cli.OUT_DIR)
    ap.add_argument(
        "--valve", action="append", metavar="NAME", help="a catalog valve's datasheet figures (or 'all')"
    )
    args = ap.parse_args(argv)
    version = cli.version(args)
    if cli.archive_missing(version):
        return 1
    if args.valve:
        return valve_main(args, version)

    per_decade = 2 if args.quick else 4
    small_f = list(np.geomspace(5.0, 20000.0, int(round(per_decade * math.log10(4000))) + 1))
    large_f = list(np.geomspace(20.0, 10000.0, int(round(per_decade * math.log10(500))) + 1))
    small, large = small_signal_specs(version, small_f), large_signal_specs(version, large_f)
    onset_amps = (1e-3, 5e-3) if args.quick else (1e-3, 2e-3, 5e-3, 10e-3)
    onsets = [
        {"version": version, "V_supply": v, "amplitude": a}
        for v in SUPPLIES
        for a in onset_amps
        if feasible(v, a)
    ]

    client = None if args.serial else cluster.client_for(args.scheduler, args.workers)
    try:
        progress = not args.no_progress
        curves = cluster.map_points(
            fr.measure_curve, small + large, client=client, progress=progress, desc="curves"
        )
        onset_results = cluster.map_points(
            fr.measure_onset, onsets, client=client, progress=progress, desc="onsets"
        )
    finally:
        cluster.close(client)
    if report_failures(curves + onset_results):
        return 1
    small_curves, large_curves = curves[: len(small)], curves[len(small) :]
    print(f"EhsvActuator ({version}) frequency responses")
    print(small_signal_table(small_curves))
    print(loop_gain_line(small_curves))
    print()
    print(large_signal_table(large_curves))
    print()
    print(onset_table(onset_results))
    out = args.out_dir
    bode_figure(small_curves, out / "bode_small_signal.png", version)
    large_figure(large_curves, out / "bode_large_signal.png", version)
    onset_figure(onset_results, out / "slew_limit.png")
    print(
        f"figures: {out / 'bode_small_signal.png'}, {out / 'bode_large_signal.png'}, {out / 'slew_limit.png'}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
