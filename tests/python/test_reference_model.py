"""The test's own reference model, checked without the FMU.

These tests make sure the yardsticks used on the FMU are right: the numpy matrix
exponential, the settling-time measure, and that the exact solution of the linear valve
model reproduces the published figures (rows 6, 7 and 10). If one of these fails, the
FMU tests that rely on it mean nothing.
"""

import math

import numpy as np
import pytest

import ehsv


def test_expm_matches_eigendecomposition():
    for driver in ("ideal_current", "voltage"):
        a, _, _ = ehsv.linear_model(driver)
        for t in (1e-6, 1e-4, 1e-3, 1e-2):
            w, v = np.linalg.eig(a * t)
            ref = (v @ np.diag(np.exp(w)) @ np.linalg.inv(v)).real
            got = ehsv.expm(a * t)
            assert np.max(np.abs(got - ref)) <= 1e-9 * max(1.0, np.max(np.abs(ref))), (driver, t)


def test_expm_known_values():
    # rotation generator: expm([[0, -x], [x, 0]]) = [[cos x, -sin x], [sin x, cos x]]
    x = 2.5
    got = ehsv.expm(np.array([[0.0, -x], [x, 0.0]]))
    assert np.allclose(got, [[math.cos(x), -math.sin(x)], [math.sin(x), math.cos(x)]], rtol=0, atol=1e-14)
    # nilpotent: expm([[0, 1], [0, 0]]) = [[1, 1], [0, 1]]
    assert np.allclose(ehsv.expm(np.array([[0.0, 1.0], [0.0, 0.0]])), [[1, 1], [0, 1]], rtol=0, atol=1e-15)


def test_settling_time_of_first_order_lag():
    # y = 1 - exp(-t/tau) enters the 2 % band at tau*ln(50) and stays inside
    tau = 3.2e-3
    t = np.arange(0, 0.05, 1e-6)
    y = 1 - np.exp(-t / tau)
    ts = ehsv.settling_time(t, y, 0.0, 0.02, y_final=1.0, y_initial=0.0)
    assert ts == pytest.approx(tau * math.log(50), rel=1e-6)


def test_settling_time_counts_the_last_exit_not_the_first_entry():
    t = np.arange(0, 10.001, 0.001)
    y = np.ones_like(t)
    y[t < 1] = t[t < 1]
    y[(t > 4) & (t < 5)] = 1.5  # a late excursion outside the band
    assert ehsv.settling_time(t, y, 0.0, 0.05, y_final=1.0, y_initial=0.0) == pytest.approx(5.0, abs=2e-3)
    assert math.isinf(ehsv.settling_time(t, y + (t > 9.9), 0.0, 0.05, y_final=1.0, y_initial=0.0))


def test_exact_solution_reproduces_published_figures():
    i = 5e-3
    ideal = ehsv.linear_step_response_dense("ideal_current", i, 1e-6, 0.03)
    ts = ehsv.settling_time(ideal["time"], ideal["Q_valve"], 0.0, 0.05)
    assert ts == pytest.approx(3.29e-3, rel=0.005)  # row 6
    volt = ehsv.linear_step_response_dense("voltage", i, 1e-6, 0.08)
    ts = ehsv.settling_time(volt["time"], volt["Q_valve"], 0.0, 0.05)
    assert ts == pytest.approx(10.99e-3, rel=0.005)  # row 7
    # row 10: steady-state gain K3*K1/Kw = 0.025268 m3/s per A
    assert ehsv.flow_gain() == pytest.approx(0.025268, rel=1e-4)
    assert volt["Q_valve"][-1] / i == pytest.approx(ehsv.flow_gain(), rel=1e-6)
    # the voltage driver's coil current is the first-order L/R lag
    tau = ehsv.NOMINAL["coil.L"] / ehsv.NOMINAL["coil.R"]
    k = 3200  # 3.2 ms = one time constant
    assert volt["i_coil"][k] == pytest.approx(i * (1 - math.exp(-volt["time"][k] / tau)), rel=1e-9)


def test_direct_and_propagated_exact_solutions_agree():
    t = np.array([0.0, 1e-4, 1e-3, 5e-3, 1e-2])
    for driver in ("ideal_current", "voltage"):
        direct = ehsv.linear_step_response(driver, 5e-3, t)
        dense = ehsv.linear_step_response_dense(driver, 5e-3, 1e-5, 1e-2)
        idx = np.rint(t / 1e-5).astype(int)
        q_final = ehsv.flow_gain() * 5e-3
        assert np.max(np.abs(direct["Q_valve"] - dense["Q_valve"][idx])) <= 1e-10 * q_final


def test_eq3_eq4_polynomials_equal_the_state_space_models():
    """The paper's eq. 3 and eq. 4 written as polynomials (ehsv.frequency) and the state
    space of the valve (ehsv.linear_model) are two derivations of one model:
    C (sI - A)^-1 B with C = K3 on x_spool must equal them at every frequency."""
    from ehsv import frequency as fr

    for driver, poly in (("ideal_current", fr.eq3), ("voltage", fr.eq4)):
        a, b, names = ehsv.linear_model(driver)
        c = np.zeros(len(names))
        c[names.index("x_spool")] = ehsv.NOMINAL["valve.K3"]
        for f in (0.1, 10.0, 100.0, 814.0, 5000.0):
            s = 2j * math.pi * f
            ss = c @ np.linalg.solve(s * np.eye(len(a)) - a, b)
            assert ss == pytest.approx(poly(f), rel=1e-10), (driver, f)
    assert fr.eq3(0.0).real == pytest.approx(ehsv.flow_gain(), rel=1e-12)
