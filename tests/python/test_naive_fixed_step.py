"""Why the FMU's fixed_cost method is not a plain fixed step (docs/solvers.md): at the
stiffest place of the model, a piston stalled in its end stop with the smaller chamber's
port open, explicit Euler at 1e-4 s on the same cylinder equations leaves the physical
range and never settles, where both of the FMU's methods stay above the cavitation floor
and settle where the oil stops moving."""

import numpy as np
import pytest

import ehsv
from ehsv.naive_step import retract_to_stop, settled_swing


@pytest.fixture(scope="module")
def runs(version):
    return retract_to_stop(version)


def test_the_piston_reaches_its_stop_in_every_run(runs):
    """The comparison is only about the integrator if all three reach the same place."""
    for name, r in runs.items():
        assert r["x_piston"][-1] == pytest.approx(runs["exact"]["x_piston"][-1], abs=1e-5), name


def test_explicit_euler_at_a_tenth_of_a_millisecond_leaves_the_physical_range(runs):
    floor = ehsv.parameters()["hydraulics.p_cavitation"]
    euler = runs["explicit_euler"]
    # Tens of bar below the floor (no oil can be there), and still swinging at the end.
    assert euler["p_A"].min() < floor - 10e5
    assert settled_swing(euler) > 10e5


@pytest.mark.parametrize("method", ["exact", "fixed_cost"])
def test_the_fmu_stays_physical_and_settles(runs, method):
    floor = ehsv.parameters()["hydraulics.p_cavitation"]
    r = runs[method]
    assert r["p_A"].min() >= floor - 1.0
    assert settled_swing(r) < 1.0  # Pa
    np.testing.assert_allclose(r["p_A"][-1], runs["exact"]["p_A"][-1], atol=1e3)
