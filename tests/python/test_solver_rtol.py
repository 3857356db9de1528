"""solver.rtol, the cylinder integrator's relative tolerance, through both archives.

A looser tolerance trades the cylinder's accuracy for speed: the driver, coil and valve are
exact at any setting, so their outputs keep every bit; the cylinder's move away from a run
at 1e-10 by what the tolerance allows. Values outside [1e-12, 1e-3] are refused with an
Error that names the parameter.
"""

import numpy as np
import pytest

import ehsv

EXACT_SIDE = ("i_coil", "u_driver", "x_spool", "Q_valve")
CYLINDER = ("Q_A", "Q_B", "p_A", "p_B", "x_piston", "v_piston")


def _run(version, rtol):
    # 5 mA from rest: the piston starts, runs and reaches its stop within the 60 ms.
    return ehsv.run_step(
        version,
        "opamp_pi",
        5e-3,
        h=1e-4,
        t_stop=60e-3,
        params={"solver.rtol": rtol},
        outputs=EXACT_SIDE + CYLINDER,
    )


def _worst_off(run, reference):
    """Largest deviation of a cylinder output from the reference, as a fraction of its range."""
    return max(np.max(np.abs(run[n] - reference[n])) / np.ptp(reference[n]) for n in CYLINDER)


def test_a_looser_tolerance_moves_only_the_cylinder(version):
    reference, default, loose = (_run(version, rtol) for rtol in (1e-10, 1e-7, 1e-4))
    for name in EXACT_SIDE:
        assert np.array_equal(loose[name], reference[name]), f"{name} depends on solver.rtol"
    default_off, loose_off = _worst_off(default, reference), _worst_off(loose, reference)
    assert default_off <= 1e-5, f"the default 1e-7 is {default_off:.1e} of a range off"
    # The parameter reaches the integrator: 1e-4 is measurably, and boundedly, less accurate.
    assert 10 * default_off < loose_off <= 1e-2, f"1e-7: {default_off:.1e}, 1e-4: {loose_off:.1e}"


@pytest.mark.parametrize("value", [0.0, -1e-7, 1e-2, float("nan")])
def test_a_tolerance_out_of_range_is_refused_naming_it(version, value):
    inst = ehsv.Ehsv(version)
    try:
        with pytest.raises(Exception, match="failed"):
            inst.set("solver.rtol", value)
        assert any("solver.rtol" in r.message for r in inst.log), inst.log_text()
    finally:
        inst.free(terminate=False)
