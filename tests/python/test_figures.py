"""The published figures the FMU must reproduce (rows 1, 2, 3, 6, 7, 10), both archives.

Settling time: the last time the signal is outside +-2 % (currents) or +-5 % (flows) of
the step size around its final value, measured from the step (ehsv.settling_time). Every
step is 0 -> i_ref at t = 0 from rest, V_supply = 72 V, nominal parameters.
"""

import numpy as np
import pytest

import ehsv

MA = 1e-3
US = 1e-6  # output interval for the current-loop transients


@pytest.fixture(scope="module")
def pi_5ma(version, run):
    return run(version, "opamp_pi", 5 * MA, h=US, t_stop=2e-3)


def test_row1_opamp_pi_5mA_settles_in_0_25_ms(pi_5ma):
    # Final value = the command: the PI loop has no steady-state error. (After the rail
    # stretch the current creeps the last ~0.5 % in with the coil's L/R = 3.2 ms, the
    # mode the PI zero cancels, so the sample at 2 ms is not yet the final value.)
    ts = ehsv.settling_time(pi_5ma["time"], pi_5ma["i_coil"], 0.0, 0.02, y_final=5 * MA, y_initial=0.0)
    assert 0.225e-3 <= ts <= 0.275e-3, f"2 % settling time {ts * 1e3:.4f} ms"


def test_row2_driver_at_the_72V_rail_then_5V(pi_5ma):
    t, u = pi_5ma["time"], pi_5ma["u_driver"]
    at_rail = ehsv.time_at_rail(t, u, 0.0, 72.0, tol=0.05)
    assert at_rail >= 0.15e-3, f"u_driver within 0.05 V of +72 V for {at_rail * 1e3:.4f} ms only"
    assert np.max(u) <= 72.0 + 1e-9, "u_driver above the +72 V rail"
    # final: R * i = 1000 ohm * 5 mA
    assert u[-1] == pytest.approx(5.0, abs=0.01)


def test_row2_saturation_flag_follows_the_rail(pi_5ma):
    u, sat = pi_5ma["u_driver"], pi_5ma["driver_saturated"]
    k = int(round(0.1e-3 / US))  # 0.1 ms: deep in the rail stretch
    assert u[k] == pytest.approx(72.0, abs=0.05)
    assert sat[k] == 1.0
    assert sat[0] == 0.0 and sat[-1] == 0.0


def test_row3_opamp_pi_10mA_settles_in_0_5_ms(version, run):
    r = run(version, "opamp_pi", 10 * MA, h=US, t_stop=3e-3)
    ts = ehsv.settling_time(r["time"], r["i_coil"], 0.0, 0.02, y_final=10 * MA, y_initial=0.0)
    assert 0.45e-3 <= ts <= 0.55e-3, f"2 % settling time {ts * 1e3:.4f} ms"


def test_row6_ideal_current_flow_settles_in_3_29_ms(version, run):
    r = run(version, "ideal_current", 5 * MA, h=1e-5, t_stop=30e-3)
    ts = ehsv.settling_time(r["time"], r["Q_valve"], 0.0, 0.05)
    assert ts == pytest.approx(3.29e-3, rel=0.03), f"5 % settling time {ts * 1e3:.4f} ms"


def test_row7_voltage_driver_flow_settles_in_10_99_ms(version, run):
    r = run(version, "voltage", 5 * MA, h=1e-5, t_stop=80e-3)
    ts = ehsv.settling_time(r["time"], r["Q_valve"], 0.0, 0.05)
    assert ts == pytest.approx(10.99e-3, rel=0.03), f"5 % settling time {ts * 1e3:.4f} ms"


@pytest.mark.parametrize("driver", list(ehsv.DRIVERS))
def test_row10_steady_state_flow_gain(version, run, driver):
    i = 5 * MA
    exact = ehsv.flow_gain()  # K3 K1 / Kw: the paper's 4 gpm at 10 mA (0.025268 m3/s per A)
    assert exact == pytest.approx(0.025268, rel=1e-4)
    if driver in ehsv.PWM_DRIVERS:
        # The current carries the PWM ripple the spool filters out: the steady-state
        # relation holds for the means over one period (1 us samples, 60 ms: the slowest
        # mode, the PI offset decaying with L/R = 3.2 ms, is down to e^-19). The 50-sample
        # mean is exact to the aliasing of high harmonics (measured 1e-9 in
        # fmu-src/tests/physics.rs): 1e-7.
        r = run(version, driver, i, h=1e-6, t_stop=60e-3)
        n = round(ehsv.pwm_period() / 1e-6)
        gain = np.mean(r["Q_valve"][-n:]) / np.mean(r["i_coil"][-n:])
        assert gain == pytest.approx(exact, rel=1e-7), f"{gain * 1e-3:.8e} m3/s per mA"
        return
    r = run(version, driver, i, h=1e-4, t_stop=0.1)
    # steady state: nothing moves any more in the last 10 ms
    assert abs(r["Q_valve"][-1] - r["Q_valve"][-101]) <= 1e-6 * abs(r["Q_valve"][-1])
    assert r["i_coil"][-1] == pytest.approx(i, rel=1e-6)
    gain = r["Q_valve"][-1] / r["i_coil"][-1]  # m3/s per A
    # A linear valve at rest (slowest pole L/R = 3.2 ms, 0.1 s: e^-31): exact to rounding
    # (measured <= 1.5e-14 in fmu-src/tests/physics.rs).
    assert gain == pytest.approx(exact, rel=1e-12), f"{gain * 1e-3:.8e} m3/s per mA"
    assert r["Q_valve"][-1] == pytest.approx(ehsv.NOMINAL["valve.K3"] * r["x_spool"][-1], rel=1e-12)
