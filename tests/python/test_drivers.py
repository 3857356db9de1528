"""The paper's driver comparison (rows 1, 4, 5), the H-bridge PWM at two communication
steps, and the optional effects (travel limits, output-stage drop, slew limit), both
archives.

Every figure comes from ehsv.compare_drivers / ehsv.driver_step (cosim-examples/
ehsv/scenarios.py), the same code that cosim-examples/driver_comparison.py prints from:
i_ref 0 -> 5 mA at t = 0 from rest, outputs every 1 us, each driver at its row's supply
(op-amp 72 V, H-bridge 12 V, industrial 24 V). Settling time: last time i_coil is outside
+-2 % of the step around the command, from the step; for the H-bridge the signal is the
mean of i_coil over one PWM period (50 us = 50 intervals of 1 us, ehsv.period_average).
"""

import numpy as np
import pytest

import ehsv

MA = 1e-3
SPEC = {s.driver: s for s in ehsv.PAPER_DRIVERS}
N = ehsv.NOMINAL
#: final spool travel of the 5 mA step, K1*i/Kw (0.19 mm)
X_SPOOL_FINAL = N["valve.K1"] * ehsv.PAPER_STEP / N["valve.Kw"]


@pytest.fixture(scope="module")
def paper(version):
    """The three drivers of the paper's table, run once per archive."""
    return ehsv.compare_drivers(version)


def _ms(x):
    return f"{x * 1e3:.4f} ms"


def test_row4_industrial_24V_settles_in_5_ms(paper):
    res = paper["industrial"]
    lo, hi = SPEC["industrial"].band
    assert lo <= res.settling <= hi, f"row 4: 2 % settling time {_ms(res.settling)}, band {_ms(lo)}-{_ms(hi)}"
    u = res.run["u_driver"]
    assert np.max(np.abs(u)) <= 24.0 + 1e-9, "u_driver beyond the 24 V rails"
    # the amplifier's 1 V/us slew limit holds on the 1 us samples
    slope = np.max(np.abs(np.diff(u))) / ehsv.COMPARE_H
    assert slope <= N["industrial.slew_rate"] * (1 + 1e-9), f"|du/dt| up to {slope:.6g} V/s"


def test_row5_hbridge_12V_period_mean_settles_in_2_ms(paper):
    res = paper["hbridge_pid"]
    lo, hi = SPEC["hbridge_pid"].band
    assert lo <= res.settling <= hi, (
        f"row 5: 2 % settling time of the period mean {_ms(res.settling)}, band {_ms(lo)}-{_ms(hi)}"
    )
    # the mean over the last period is the command (PI loop, no steady-state error)
    assert res.i_avg[-1] == pytest.approx(ehsv.PAPER_STEP, rel=1e-3)


def test_row1_opamp_72V_settles_in_a_quarter_ms(paper):
    res = paper["opamp_pi"]
    lo, hi = SPEC["opamp_pi"].band
    assert lo <= res.settling <= hi, f"row 1: 2 % settling time {_ms(res.settling)}"


def test_three_drivers_against_the_paper(paper):
    """One run of the paper's table: each driver within +-10 % of the paper's settling
    time, and op-amp < H-bridge < industrial."""
    assert list(paper) == ["opamp_pi", "hbridge_pid", "industrial"]
    report = "\n" + ehsv.driver_table(paper)
    for name, res in paper.items():
        lo, hi = res.spec.paper_band
        assert lo <= res.settling <= hi, (
            f"{name}: {_ms(res.settling)} vs paper {res.spec.paper_ms} ms +-10 %{report}"
        )
    ts = [res.settling for res in paper.values()]
    assert ts[0] < ts[1] < ts[2], report
    # the ratios the paper's percentages of T_torque express: H-bridge ~8x, industrial
    # ~20x the op-amp driver (paper: 2 / 0.25 and 5 / 0.25); each within 20 %
    assert ts[1] / ts[0] == pytest.approx(2.0 / 0.25, rel=0.2), report
    assert ts[2] / ts[0] == pytest.approx(5.0 / 0.25, rel=0.2), report


# --------------------------------------------------------------------------------------
# H-bridge PWM
# --------------------------------------------------------------------------------------


def test_pwm_results_do_not_depend_on_the_communication_step(paper, version):
    """Row 5's run at 1e-6 s against the same run at 1e-4 s, at the shared time points.

    i_coil and x_spool are continuous: within 1e-6 of their step sizes (5 mA; the final
    spool travel K1*i/Kw). u_driver is piecewise constant (+-V_supply), switching at time
    events on an absolute clock (k/f_pwm, k/f_sample, and the duty edges inside each
    period), not at communication points. Both runs end a doStep at every shared point,
    the state there is the same (exact integration), and a time event that falls on the
    point is fired by the step that ends there in both runs (the FMU gives the step end a
    1e-9 relative slack). So u_driver must be equal at every shared point, exactly -- also
    where a switching instant coincides with it (the shared points are every second PWM
    period boundary; the end of the 100 % duty stretch is such an instant)."""
    fine = paper["hbridge_pid"].run
    coarse = ehsv.run_step(
        version,
        "hbridge_pid",
        ehsv.PAPER_STEP,
        h=1e-4,
        t_stop=ehsv.COMPARE_T_STOP,
        V_supply=SPEC["hbridge_pid"].V_supply,
    )
    idx = np.arange(len(coarse["time"])) * 100
    assert np.allclose(fine["time"][idx], coarse["time"], rtol=1e-12, atol=0)
    for name, scale in (("i_coil", ehsv.PAPER_STEP), ("x_spool", X_SPOOL_FINAL)):
        diff = np.abs(fine[name][idx] - coarse[name])
        k = int(np.argmax(diff))
        assert diff[k] <= 1e-6 * scale, (
            f"{name}: |h=1e-6 - h=1e-4| = {diff[k]:.3e} at "
            f"t = {coarse['time'][k] * 1e3:.2f} ms (tolerance {1e-6 * scale:.1e})"
        )
    u_f, u_c = fine["u_driver"][idx], coarse["u_driver"]
    bad = np.nonzero(u_f != u_c)[0]
    # shared points where the fine run switched in the microsecond before the point
    on_edge = int(np.count_nonzero(fine["u_driver"][idx[1:] - 1] != u_f[1:]))
    assert len(bad) == 0, (
        f"u_driver differs at {len(bad)} shared points, first at "
        f"t = {coarse['time'][bad[0]] * 1e3:.2f} ms: {u_f[bad[0]]} vs {u_c[bad[0]]} "
        f"({on_edge} shared points follow a switching instant within 1 us)"
    )
    assert np.array_equal(fine["driver_saturated"][idx], coarse["driver_saturated"])
    # teeth: the spool did travel, and the bridge did switch between the shared points
    assert fine["x_spool"][-1] == pytest.approx(X_SPOOL_FINAL, rel=1e-3)
    assert np.count_nonzero(np.diff(fine["u_driver"])) > 100


def test_pwm_ripple_is_real(paper):
    """Bipolar PWM: u_driver is +-V_supply only; at 12 V the coil current ripple at the end
    (peak to peak, raw 1 us samples over the last 5 PWM periods) is ~V/L*T/2 scaled by the
    duty: far above rounding, 0.05-0.2 mA."""
    res = paper["hbridge_pid"]
    v = SPEC["hbridge_pid"].V_supply
    u = res.run["u_driver"]
    assert set(np.unique(u)) <= {-v, v}, np.unique(u)
    n = int(round(ehsv.pwm_period() / ehsv.COMPARE_H))
    tail = res.run["i_coil"][-5 * n :]
    ripple = float(np.ptp(tail))
    assert 0.05 * MA < ripple < 0.2 * MA, f"ripple {ripple * 1e3:.4f} mA p-p"
    assert ripple > 1e4 * 1e-6 * ehsv.PAPER_STEP
    assert res.ripple == pytest.approx(ripple, rel=0.05)  # every period alike at the end
    # at the periodic steady state the period mean of u_driver is R * i (5 V): L di/dt
    # averages out. The samples place each of the two edges of a period only within 1 us,
    # so the sampled mean is right within 2 edges * 2V * (h/2) / T (0.48 V at 12 V).
    tol = 2 * 2 * v * (ehsv.COMPARE_H / 2) / ehsv.pwm_period()
    assert res.u_avg[-1] == pytest.approx(N["coil.R"] * ehsv.PAPER_STEP, abs=tol)


# --------------------------------------------------------------------------------------
# Optional effects through fmpy
# --------------------------------------------------------------------------------------

X_SPOOL_MAX = 0.1e-3  # m; 10 mA would drive the spool to K1*i/Kw = 0.38 mm
X_FLAPPER_MAX = 10e-6  # m; 10 mA through the op-amp driver peaks at ~56 um free


@pytest.mark.parametrize("sign", [1, -1], ids=["+10mA", "-10mA"])
@pytest.mark.parametrize("driver", list(SPEC))
def test_spool_travel_limit_holds_and_saturates_the_flow(version, driver, sign):
    r = ehsv.run_step(
        version,
        driver,
        sign * 10 * MA,
        h=1e-5,
        t_stop=20e-3,
        V_supply=SPEC[driver].V_supply,
        params={"valve.x_spool_max": X_SPOOL_MAX},
    )
    xs, q = r["x_spool"], r["Q_valve"]
    q_max = N["valve.K3"] * X_SPOOL_MAX
    worst = float(np.max(np.abs(xs)))
    assert worst <= X_SPOOL_MAX * (1 + 1e-12), (
        f"|x_spool| up to {worst * 1e3:.4f} mm, limit {X_SPOOL_MAX * 1e3} mm"
    )
    assert np.max(np.abs(q)) <= q_max * (1 + 1e-12)
    # at the stop for the last 5 ms, the flow saturated at K3 * x_spool_max
    tail = r["time"] >= 15e-3
    assert np.all(np.abs(sign * xs[tail] - X_SPOOL_MAX) <= 1e-12 * X_SPOOL_MAX)
    assert sign * q[-1] == pytest.approx(q_max, rel=1e-12)


@pytest.mark.parametrize("h", [1e-6, 1e-5, 1e-4])
@pytest.mark.parametrize("driver", list(SPEC))
def test_flapper_travel_limit_holds_and_releases(version, driver, h):
    """10 mA with the flapper stop at 10 um: the flapper never passes the stop, leaves it
    once the feedback wire takes the torque back, and the spool ends at K1*i/Kw as
    without the stop (x_flapper returns to 0: the spool integrates it), at any step."""
    r = ehsv.run_step(
        version,
        driver,
        10 * MA,
        h=h,
        t_stop=20e-3,
        V_supply=SPEC[driver].V_supply,
        params={"valve.x_flapper_max": X_FLAPPER_MAX},
    )
    xf, xs = r["x_flapper"], r["x_spool"]
    assert np.max(np.abs(xf)) <= X_FLAPPER_MAX * (1 + 1e-12)
    final = N["valve.K1"] * 10 * MA / N["valve.Kw"]
    at_stop = r["time"][xf >= X_FLAPPER_MAX * (1 - 1e-12)]
    stuck = (
        f"flapper at its stop from {at_stop[0] * 1e3:.3f} to {at_stop[-1] * 1e3:.3f} ms"
        if len(at_stop)
        else "never at its stop"
    )
    assert xs[-1] == pytest.approx(final, rel=1e-4), (
        f"x_spool ends at {xs[-1] * 1e3:.4f} mm, expected {final * 1e3:.4f} mm; {stuck}"
    )
    assert abs(xf[-1]) <= 1e-3 * X_FLAPPER_MAX, stuck
    # free, the flapper peaks at ~56 um (op-amp), ~14 um (H-bridge), ~23 um (industrial)
    assert len(at_stop) > 0, "the stop was never reached: the test has no teeth"


def test_output_stage_drop_lowers_the_rail(version):
    """driver.V_drop = 2 V: the op-amp output saturates at 72 - 2 = 70 V."""
    r = ehsv.run_step(
        version, "opamp_pi", 5 * MA, h=1e-6, t_stop=2e-3, V_supply=72.0, params={"driver.V_drop": 2.0}
    )
    u = r["u_driver"]
    assert np.max(u) <= 70.0 + 1e-9
    assert ehsv.time_at_rail(r["time"], u, 0.0, 70.0, tol=1e-9) > 0.1e-3
    assert r["driver_saturated"].max() == 1.0


def test_slew_limit_bounds_du_dt(version):
    """driver.slew_rate = 1 V/us (default 20 V/us): |du/dt| on 1 us samples never above it,
    and reached; the slower output stretches the current settling beyond row 1's band."""
    rate = 1e6
    r = ehsv.run_step(
        version, "opamp_pi", 5 * MA, h=1e-6, t_stop=2e-3, V_supply=72.0, params={"driver.slew_rate": rate}
    )
    slope = np.abs(np.diff(r["u_driver"])) / 1e-6
    assert np.max(slope) <= rate * (1 + 1e-9)
    assert np.max(slope) >= rate * (1 - 1e-6)
    ts = ehsv.settling_time(r["time"], r["i_coil"], 0.0, 0.02, y_final=5 * MA, y_initial=0.0)
    assert ts > SPEC["opamp_pi"].band[1]
