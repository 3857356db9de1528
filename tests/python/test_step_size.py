"""Step-size independence and the exact solution of the linear cases, both archives.

The FMU integrates exactly between communication points, so the outputs at shared time
points must not depend on the communication step (1e-6 ... 1e-3 s), and for the linear
drivers they must equal the exact solution of the linear ODE (ehsv.linear_step_response:
scipy's matrix exponential). Tolerance: 1e-6 of the step size of the signal, i.e. 5e-9 A for
a 5 mA step and 1e-6 of the final flow for Q_valve.
"""

import numpy as np
import pytest

import ehsv

I_STEP = 5e-3
T_STOP = 10e-3  # long enough to cover the transients, short enough for 10 000 steps at 1 us
STEPS = (1e-6, 1e-5, 1e-4, 1e-3)
OUTPUTS = ("i_coil", "u_driver", "Q_valve")
TOL = {"i_coil": 1e-6 * I_STEP, "Q_valve": 1e-6 * ehsv.flow_gain() * I_STEP}


def _shared(fine, coarse, h_fine, h_coarse):
    """Indices into the fine run at the coarse run's grid points."""
    ratio = int(round(h_coarse / h_fine))
    return np.arange(len(coarse["time"])) * ratio


@pytest.mark.parametrize("driver", list(ehsv.DRIVERS))
@pytest.mark.parametrize("h", STEPS[1:])
def test_outputs_do_not_depend_on_the_step_size(version, run, driver, h):
    fine = run(version, driver, I_STEP, h=STEPS[0], t_stop=T_STOP, outputs=OUTPUTS)
    coarse = run(version, driver, I_STEP, h=h, t_stop=T_STOP, outputs=OUTPUTS)
    idx = _shared(fine, coarse, STEPS[0], h)
    assert np.allclose(fine["time"][idx], coarse["time"], rtol=1e-12, atol=0)
    for name, tol in TOL.items():
        diff = np.abs(fine[name][idx] - coarse[name])
        k = int(np.argmax(diff))
        assert diff[k] <= tol, (
            f"{name}: |h=1e-6 run - h={h:g} run| = {diff[k]:.3e} at "
            f"t = {coarse['time'][k] * 1e3:.3f} ms (tolerance {tol:.1e})"
        )
    # the comparison has teeth: the signals did move over the run
    assert abs(coarse["Q_valve"][-1]) > 0.5 * ehsv.flow_gain() * I_STEP


CYLINDER_OUTPUTS = ("Q_A", "Q_B", "p_A", "p_B", "x_piston", "v_piston")


@pytest.mark.parametrize("driver", list(ehsv.DRIVERS))
@pytest.mark.parametrize("h", (1e-4, 1e-3))
def test_cylinder_outputs_do_not_depend_on_the_step_size(version, run, driver, h):
    """Between communication points the cylinder follows the spool's path, however far
    apart they are: within 1e-5 of each output's range over a run at 10 us steps. While one
    quintic of spool path spanned a whole 1 ms step, the ideal source was 3e-3 off."""
    h_fine = 1e-5
    fine = run(version, driver, I_STEP, h=h_fine, t_stop=T_STOP, outputs=CYLINDER_OUTPUTS)
    coarse = run(version, driver, I_STEP, h=h, t_stop=T_STOP, outputs=CYLINDER_OUTPUTS)
    idx = _shared(fine, coarse, h_fine, h)
    for name in CYLINDER_OUTPUTS:
        span = np.ptp(fine[name])
        assert span > 0, f"{name} did not move"
        off = np.abs(fine[name][idx] - coarse[name]) / span
        k = int(np.argmax(off))
        assert off[k] <= 1e-5, (
            f"{name}: |h=1e-5 run - h={h:g} run| = {off[k]:.2e} of its range at "
            f"t = {coarse['time'][k] * 1e3:.3f} ms"
        )


@pytest.mark.parametrize("driver", ["ideal_current", "voltage"])
@pytest.mark.parametrize("h", STEPS)
def test_linear_drivers_match_the_exact_solution(version, run, driver, h):
    got = run(version, driver, I_STEP, h=h, t_stop=T_STOP, outputs=OUTPUTS)
    ref = ehsv.linear_step_response_dense(driver, I_STEP, h, T_STOP)
    assert np.allclose(got["time"], ref["time"], rtol=1e-12, atol=0)
    # sample 0 is recorded before the step is applied: compare from the first step on
    for name, tol in TOL.items():
        diff = np.abs(got[name][1:] - ref[name][1:])
        k = int(np.argmax(diff))
        assert diff[k] <= tol, (
            f"{name}: |FMU - exact| = {diff[k]:.3e} at t = "
            f"{got['time'][k + 1] * 1e3:.4f} ms (tolerance {tol:.1e})"
        )


def test_ideal_current_follows_the_command_exactly(version, run):
    got = run(version, "ideal_current", I_STEP, h=1e-4, t_stop=T_STOP, outputs=OUTPUTS)
    # i = i_ref; allowed: rounding of the FMU's arithmetic (1e-12 of the command)
    assert np.max(np.abs(got["i_coil"][1:] - I_STEP)) <= 1e-12 * I_STEP


def test_voltage_driver_applies_R_times_command(version, run):
    got = run(version, "voltage", I_STEP, h=1e-4, t_stop=T_STOP, outputs=OUTPUTS)
    r_total = ehsv.NOMINAL["coil.R"] + ehsv.NOMINAL["coil.R_sense"]
    assert got["u_driver"][-1] == pytest.approx(r_total * I_STEP, rel=1e-12)
