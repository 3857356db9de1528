"""The archives through fmpy's own master (fmpy.simulate_fmu), not our hand-stepped loop:
start values by name, an input table with a step, outputs on fmpy's grid."""

import numpy as np
import pytest
from fmpy import simulate_fmu

import ehsv


def test_simulate_fmu_ideal_current_step(fmu):
    i = 5e-3
    t_step = 1e-3
    # a repeated time row is a discontinuity: 0 before t_step, i after it
    inputs = np.array(
        [(0.0, 0.0), (t_step, 0.0), (t_step, i), (0.04, i)],
        dtype=[("time", np.float64), ("i_ref", np.float64)],
    )
    r = simulate_fmu(
        str(fmu),
        start_time=0.0,
        stop_time=0.04,
        step_size=1e-5,
        output_interval=1e-5,
        start_values={"driver": ehsv.DRIVERS["ideal_current"], "V_supply": 72.0},
        input=inputs,
        output=["i_coil", "Q_valve"],
    )
    t, q, cur = r["time"], r["Q_valve"], r["i_coil"]
    before = t < t_step - 1e-9
    assert np.all(q[before] == 0.0) and np.all(cur[before] == 0.0)
    assert cur[-1] == pytest.approx(i, rel=1e-12)
    assert q[-1] / cur[-1] == pytest.approx(0.025268, rel=0.005)  # row 10
    ts = ehsv.settling_time(t, q, t_step, 0.05, y_initial=0.0)
    # fmpy applies the step at a communication point within one step (1e-5 s) of t_step
    assert ts == pytest.approx(3.29e-3, rel=0.03)  # row 6


def test_initialised_in_equilibrium_for_the_start_input(fmu):
    # i_ref = 5 mA from the start: the valve starts (and stays) at its steady flow
    r = simulate_fmu(
        str(fmu),
        stop_time=0.01,
        step_size=1e-4,
        output_interval=1e-4,
        start_values={"i_ref": 5e-3},
        output=["i_coil", "Q_valve", "u_driver"],
    )
    q_ss = ehsv.flow_gain() * 5e-3
    assert np.max(np.abs(r["Q_valve"] - q_ss)) <= 1e-6 * q_ss
    assert np.max(np.abs(r["i_coil"] - 5e-3)) <= 1e-6 * 5e-3
    assert np.max(np.abs(r["u_driver"] - 5.0)) <= 1e-6 * 5.0
