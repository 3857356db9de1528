"""Every figure the FMU must reproduce (the paper's rows 1-11), measured through fmpy on
both archives, with its band and a verdict. The README's figures come from this command:

    .venv/bin/python cosim-examples/figures.py

Exits with status 1 if any row is outside its band. The scenarios are the shared ones of
ehsv_scenarios (the tests in tests/python check the same runs).
"""
import sys

import numpy as np

import ehsv_scenarios as ehsv

MA = 1e-3


def current_rows(version):
    """Rows 1-3: the op-amp driver's current steps at 72 V (1 us output)."""
    five = ehsv.run_step(version, "opamp_pi", 5 * MA, h=1e-6, t_stop=3e-3)
    ten = ehsv.run_step(version, "opamp_pi", 10 * MA, h=1e-6, t_stop=3e-3)
    t = five["time"]
    return {
        1: ehsv.settling_time(t, five["i_coil"], 0.0, 0.02, y_final=5 * MA, y_initial=0.0),
        2: (ehsv.time_at_rail(t, five["u_driver"], 0.0, 72.0), float(five["u_driver"][-1])),
        3: ehsv.settling_time(ten["time"], ten["i_coil"], 0.0, 0.02, y_final=10 * MA, y_initial=0.0),
    }


def valve_rows(version):
    """Rows 6, 7 and 10: Q_valve settling with the linear drivers, and the static gain."""
    rows = {}
    for row, driver, t_stop in ((6, "ideal_current", 40e-3), (7, "voltage", 60e-3)):
        r = ehsv.run_step(version, driver, 5 * MA, h=1e-5, t_stop=t_stop, outputs=("Q_valve",))
        rows[row] = ehsv.settling_time(r["time"], r["Q_valve"], 0.0, 0.05, y_initial=0.0)
    gains = []
    for driver in ehsv.DRIVERS:
        r = ehsv.run_step(version, driver, 4 * MA, h=1e-3, t_stop=0.1, outputs=("i_coil", "Q_valve"),
                          V_supply=24.0 if driver == "industrial" else 72.0)
        gains.append(r["Q_valve"][-1] / (r["i_coil"][-1] / MA))
    rows[10] = (min(gains), max(gains))
    return rows


def driver_rows(version):
    """Rows 4 and 5: the paper's driver table in one run."""
    results = ehsv.compare_drivers(version)
    return {4: results["industrial"].settling, 5: results["hbridge_pid"].settling}


def flow_rows(version):
    """Rows 8, 9 (flow loop at 72 V and 10 V) and 11 (steady flow on the cylinder)."""
    flows = ehsv.compare_flow_supplies(version)
    run = ehsv.run_scenario(version, h=1e-5, t_stop=0.1, params={"control_mode": ehsv.CONTROL_MODES["flow"]},
                            changes={"Q_ref": 2e-5})
    speed_error = abs(run["v_piston"][-1] - run["Q_A"][-1] / ehsv.CYLINDER.area_a) / abs(run["v_piston"][-1])
    balance = ehsv.volume_balance(run)
    return {8: flows[72.0].settling, 9: (flows[10.0].settling, flows[10.0].settling / flows[72.0].settling),
            11: (speed_error, abs(balance["residual_path"]))}


ROWS = [
    # row, what, format of the measured value, check
    (1, "opamp_pi 72 V, 0->5 mA: i_coil settling (2 %)", lambda v: f"{v * 1e3:.4f} ms",
     lambda v: 0.225e-3 <= v <= 0.275e-3, "0.225-0.275 ms"),
    (2, "same run: u_driver at +72 V, then final", lambda v: f"{v[0] * 1e3:.3f} ms, {v[1]:.4f} V",
     lambda v: v[0] >= 0.15e-3 and abs(v[1] - 5.0) < 0.05, ">= 0.15 ms, 5.0 V"),
    (3, "opamp_pi 72 V, 0->10 mA: i_coil settling (2 %)", lambda v: f"{v * 1e3:.4f} ms",
     lambda v: 0.45e-3 <= v <= 0.55e-3, "0.45-0.55 ms"),
    (4, "industrial 24 V, 0->5 mA: i_coil settling (2 %)", lambda v: f"{v * 1e3:.4f} ms",
     lambda v: 4.5e-3 <= v <= 5.5e-3, "4.5-5.5 ms"),
    (5, "hbridge_pid 12 V, 0->5 mA: period-mean i_coil (2 %)", lambda v: f"{v * 1e3:.4f} ms",
     lambda v: 1.7e-3 <= v <= 2.3e-3, "1.7-2.3 ms"),
    (6, "ideal_current, i_ref step: Q_valve settling (5 %)", lambda v: f"{v * 1e3:.4f} ms",
     lambda v: abs(v / 3.29e-3 - 1) <= 0.03, "3.29 ms +-3 %"),
    (7, "voltage, i_ref step: Q_valve settling (5 %)", lambda v: f"{v * 1e3:.4f} ms",
     lambda v: abs(v / 10.99e-3 - 1) <= 0.03, "10.99 ms +-3 %"),
    (8, "flow loop 72 V, Q_ref 0->2e-4: Q_valve (5 %)", lambda v: f"{v * 1e3:.4f} ms",
     lambda v: v <= 3.6e-3, "<= 3.6 ms"),
    (9, "same at 10 V, and its ratio to row 8", lambda v: f"{v[0] * 1e3:.4f} ms, {v[1] * 100:.0f} %",
     lambda v: 5.4e-3 <= v[0] <= 6.6e-3 and v[1] >= 1.6, "5.4-6.6 ms, >= 160 %"),
    (10, "all 5 drivers, steady: Q_valve/i_coil (m3/s per mA)", lambda v: f"{v[0]:.6e} .. {v[1]:.6e}",
     lambda v: all(abs(g / 2.5268e-5 - 1) <= 0.005 for g in v), "2.5268e-5 +-0.5 %"),
    (11, "flow loop, steady: |v - Q_A/A_A|/v; volume balance", lambda v: f"{v[0]:.1e}; {v[1]:.1e}",
     lambda v: v[0] <= 0.01 and v[1] <= 0.01, "<= 1 %; <= 1 %"),
]


def main() -> int:
    measured = {}
    for version in ehsv.VERSIONS:
        missing = ehsv.missing_fmu_message(version)
        if missing:
            print(missing)
            return 1
        measured[version] = {**current_rows(version), **valve_rows(version), **driver_rows(version), **flow_rows(version)}
    ok = True
    print(f"{'row':>3}  {'scenario':52} {'FMI 2.0':>24} {'FMI 3.0':>24}  band")
    for row, what, show, check, band in ROWS:
        verdicts = [check(measured[v][row]) for v in ehsv.VERSIONS]
        ok &= all(verdicts)
        values = [show(measured[v][row]) for v in ehsv.VERSIONS]
        print(f"{row:>3}  {what:52} {values[0]:>24} {values[1]:>24}  {band} {'ok' if all(verdicts) else 'OUTSIDE'}")
    print("all rows inside their bands" if ok else "SOME ROWS OUTSIDE THEIR BANDS")
    return 0 if ok else 1


if __name__ == "__main__":
    np.seterr(all="ignore")
    sys.exit(main())
