"""The paper's figures redrawn from FMU runs, with the FMU's numbers and the paper's on
the plots: Fig. 4 (eq. 3 vs eq. 4 valve step), Fig. 8 (op-amp current and driver
voltage), Fig. 10/11 (flow loop at 72 V and 10 V with the chamber pressures) and the
driver table of Fig. 14-16. Each function takes the runs and returns the figure."""

from __future__ import annotations

from .bands import FLOW_STEP, PAPER_FLOW, PAPER_FLOW_RATIO, PAPER_STEP, PAPER_T_TORQUE
from .measures import pwm_period, settling_time, time_at_rail
from .plotting import pyplot
from .scenarios import DriverResult, FlowStepResult

DRIVER_COLORS = {"opamp_pi": "tab:blue", "hbridge_pid": "tab:orange", "industrial": "tab:green"}
SUPPLY_COLORS = {72.0: "tab:blue", 10.0: "tab:red"}


def _note(ax, text: str, loc: str = "center right") -> None:
    """A boxed text with the figure's numbers."""
    x, ha = (0.98, "right") if "right" in loc else (0.02, "left")
    y, va = (0.5, "center") if "center" in loc else ((0.04, "bottom") if "lower" in loc else (0.96, "top"))
    ax.text(x, y, text, transform=ax.transAxes, ha=ha, va=va, ma="left", fontsize=8, family="monospace",
            bbox={"boxstyle": "round", "fc": "white", "ec": "0.7", "alpha": 0.9})  # fmt: skip


def fig4_valve_step(ideal: dict, voltage: dict, exact: dict, version: str):
    """Q_valve after an i_ref step with an ideal current source (eq. 3) and a voltage
    drive (eq. 4): FMU runs, the exact linear solution, and the 5 % settling times."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 5.5))
    q_final = ideal["Q_valve"][-1]
    rows = []
    for name, r, color, paper in (("ideal_current (eq. 3)", ideal, "tab:green", "~3.6"),
                                  ("voltage (eq. 4)", voltage, "tab:red", "10.8")):  # fmt: skip
        ts = settling_time(r["time"], r["Q_valve"], 0.0, 0.05, y_initial=0.0)
        ax.plot(r["time"] * 1e3, r["Q_valve"] / q_final, color=color, lw=1.6, label=f"FMU {name}")
        ax.axvline(ts * 1e3, color=color, lw=0.8, ls="--")
        rows.append((name.split()[0], ts, paper))
    for name, e in exact.items():
        ax.plot(
            e["time"] * 1e3,
            e["Q_valve"] / q_final,
            "k:",
            lw=1,
            label=f"exact, {name}" if name == "voltage" else None,
        )
    for f in (0.95, 1.05):
        ax.axhline(f, color="grey", lw=0.5, ls=":")
    ratio = rows[1][1] / rows[0][1]
    _note(ax, "5 % settling    FMU      paper\n"
              + "\n".join(f"{n:<14} {t * 1e3:6.3f} ms {p:>5} ms" for n, t, p in rows)
              + f"\nratio          {ratio:6.2f}    ~3", "center right")  # fmt: skip
    ax.set_xlabel("time after the step [ms]")
    ax.set_ylabel("Q_valve / final value")
    ax.set_xlim(0, 20)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.suptitle(
        f"Fig. 4: servo-valve step response, ideal torque motor vs coil current dynamics ({version})"
    )
    return fig


def fig8_opamp_current(runs: dict, v_supply: float, version: str):
    """i_coil and u_driver of the op-amp driver for current steps (``runs``: step in A ->
    run_step record), with the 2 % settling times and the time on the rail."""
    plt = pyplot()
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(9, 7))
    lines = ["step    settling  on rail   paper"]
    for (step, r), color in zip(runs.items(), ("tab:purple", "tab:blue"), strict=False):
        t = r["time"]
        ts = settling_time(t, r["i_coil"], 0.0, 0.02, y_final=step, y_initial=0.0)
        rail = time_at_rail(t, r["u_driver"], 0.0, v_supply)
        paper = {5e-3: "0.25 ms (bench)", 10e-3: "0.5 ms (sim.)"}.get(step, "")
        ax1.plot(t * 1e3, r["i_coil"] * 1e3, color=color, lw=1.5, label=f"i_coil, 0 -> {step * 1e3:g} mA")
        ax1.axvline(ts * 1e3, color=color, lw=0.8, ls="--")
        ax2.plot(t * 1e3, r["u_driver"], color=color, lw=1.5, label=f"u_driver, 0 -> {step * 1e3:g} mA")
        lines.append(f"{step * 1e3:4g} mA {ts * 1e3:6.3f} ms {rail * 1e3:6.3f} ms  {paper}")
    ax1.set_ylabel("i_coil [mA]")
    ax1.grid(alpha=0.3)
    ax1.legend(loc="lower right", fontsize=8)
    _note(ax1, "\n".join(lines), "center right")
    ax2.axhline(v_supply, color="grey", lw=0.6, ls="--", label=f"+{v_supply:g} V rail")
    ax2.set_ylabel("u_driver [V]")
    ax2.set_xlabel("time after the step [ms]")
    ax2.set_xlim(0, 1.0)
    ax2.grid(alpha=0.3)
    ax2.legend(loc="upper right", fontsize=8)
    fig.suptitle(f"Fig. 8: op-amp PI driver at {v_supply:g} V, coil current and driver voltage ({version})")
    return fig


def fig10_11_flow_loop(results: dict[float, FlowStepResult], version: str):
    """The flow loop at both supplies: Q_valve with its settling time, i_coil, u_driver
    and the chamber pressures."""
    plt = pyplot()
    fig, axes = plt.subplots(4, 1, sharex=True, figsize=(9, 11))
    q_lmin = FLOW_STEP * 6e4
    lines = ["supply  FMU 5 %    paper"]
    for spec in PAPER_FLOW:
        res = results[spec.V_supply]
        r, c = res.run, SUPPLY_COLORS.get(spec.V_supply, "k")
        t_ms = r["time"] * 1e3
        v = f"{spec.V_supply:g} V"
        axes[0].plot(t_ms, r["Q_valve"] * 6e4, color=c, lw=1.4, label=f"{v}: {res.settling * 1e3:.2f} ms")
        axes[0].axvline(res.settling * 1e3, color=c, lw=0.8, ls="--")
        axes[1].plot(t_ms, r["i_coil"] * 1e3, color=c, lw=1.4, label=v)
        axes[2].plot(t_ms, r["u_driver"], color=c, lw=1.4, label=v)
        axes[3].plot(t_ms, r["p_A"] * 1e-5, color=c, lw=1.4, label=f"p_A, {v}")
        axes[3].plot(t_ms, r["p_B"] * 1e-5, color=c, lw=1.0, ls="--", label=f"p_B, {v}")
        lines.append(f"{spec.V_supply:4.0f} V {res.settling * 1e3:7.3f} ms {spec.paper_ms:5.1f} ms")
    hi, lo = (results[spec.V_supply].settling for spec in PAPER_FLOW)
    lines.append(f"ratio   {lo / hi * 100:7.0f} %   {PAPER_FLOW_RATIO * 100:4.0f} %")
    for f in (0.95, 1.05):
        axes[0].axhline(q_lmin * f, color="grey", lw=0.5, ls=":")
    _note(axes[0], "\n".join(lines), "center right")
    units = ("Q_valve [L/min]", "i_coil [mA]", "u_driver [V]", "chamber pressure [bar]")
    for ax, unit in zip(axes, units, strict=True):
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=7)
    axes[-1].set_xlabel("time after the step [ms]")
    axes[-1].set_xlim(0, 15)
    fig.suptitle(
        f"Fig. 10/11: flow loop, Q_ref 0 -> {q_lmin:g} L/min, high- and low-voltage driver ({version})"
    )
    return fig


def fig14_16_drivers(results: dict[str, DriverResult], version: str, t_max_ms: float = 8.0):
    """The three drivers of the paper's table: i_coil (H-bridge raw and period mean) and
    u_driver, the 2 % settling times as ms and % of T_torque beside the paper's."""
    plt = pyplot()
    t_max = t_max_ms * 1e-3
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(9, 7))
    lines = [f"{'driver':<12} supply   FMU        paper"]
    for name, res in results.items():
        c, s = DRIVER_COLORS[name], res.spec
        t = res.run["time"]
        keep = t <= t_max
        if s.averaged:
            ax1.plot(t[keep] * 1e3, res.run["i_coil"][keep] * 1e3, color=c, lw=0.5, alpha=0.45,
                     label=f"{name} raw (PWM ripple {res.ripple * 1e3:.3f} mA p-p)")  # fmt: skip
            ax2.plot(t[keep] * 1e3, res.run["u_driver"][keep], color=c, lw=0.3, alpha=0.35,
                     label=f"{name} raw (+-{s.V_supply:g} V PWM)")  # fmt: skip
            ka = res.t_avg <= t_max
            ax1.plot(res.t_avg[ka] * 1e3, res.i_avg[ka] * 1e3, color=c, lw=1.6,
                     label=f"{name} mean over {pwm_period() * 1e6:g} us")  # fmt: skip
            ax2.plot(res.t_avg[ka] * 1e3, res.u_avg[ka], color=c, lw=1.6, label=f"{name} period mean")
        else:
            ax1.plot(
                t[keep] * 1e3,
                res.run["i_coil"][keep] * 1e3,
                color=c,
                lw=1.4,
                label=f"{name} ({s.V_supply:g} V)",
            )
            ax2.plot(
                t[keep] * 1e3, res.run["u_driver"][keep], color=c, lw=1.4, label=f"{name} ({s.V_supply:g} V)"
            )
        ax1.axvline(res.settling * 1e3, color=c, lw=0.8, ls="--")
        fmu = f"{res.settling * 1e3:6.3f} ms {res.pct_of_t_torque:4.1f} %"
        lines.append(f"{name:<12} {s.V_supply:4.0f} V {fmu}  {s.paper_ms:4g} ms {s.paper_pct:2.0f} %")
    lines.append(f"(% of T_torque = {PAPER_T_TORQUE * 1e3:g} ms)")
    step_ma = PAPER_STEP * 1e3
    for f in (0.98, 1.02):
        ax1.axhline(step_ma * f, color="grey", lw=0.5, ls=":")
    ax1.set_ylabel("i_coil [mA]")
    ax1.set_ylim(0, step_ma * 1.15)
    ax1.legend(loc="lower right", fontsize=7)
    ax1.grid(alpha=0.3)
    _note(ax1, "\n".join(lines), "center right")
    ax2.set_ylabel("u_driver [V]")
    ax2.set_xlabel("time after the step [ms]")
    ax2.set_xlim(0, t_max_ms)
    ax2.legend(loc="upper right", fontsize=7)
    ax2.grid(alpha=0.3)
    fig.suptitle(f"Fig. 14-16: 0 -> {step_ma:g} mA current step, the paper's three drivers ({version})")
    return fig
