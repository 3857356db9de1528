"""Frequency responses through the FMU (cosim-examples/ehsv/frequency.py), both archives.

* ideal_current and voltage, small signal: the measured response i_ref -> Q_valve (and
  i_ref -> i_coil for the voltage drive) equals the paper's eq. 3 / eq. 4 with the
  table's parameters within 0.1 dB and 1 degree from 5 to 500 Hz;
* the op-amp PI loop's small-signal current bandwidth exceeds the voltage drive's by the
  factor its loop gain predicts, Kp / R (160);
* the op-amp driver's large-signal limit: the frequency at which a sine of amplitude A
  first drives it to its rail, against (V - R A) / (2 pi L A) and the linear loop's own
  prediction.
"""

import math

import numpy as np
import pytest

import ehsv
from ehsv import frequency as fr

FREQS = (5.0, 20.0, 50.0, 100.0, 200.0, 500.0)
SMALL = 1e-4  # A


@pytest.mark.parametrize("driver", ["ideal_current", "voltage"])
def test_small_signal_equals_eq3_eq4(version, driver):
    outputs = ("Q_valve", "i_coil") if driver == "voltage" else ("Q_valve",)
    worst = []
    for f in FREQS:
        r = fr.sine_response(version, driver, f, SMALL)
        for o in outputs:
            expected = fr.eq3(f) if o == "Q_valve" else 1.0
            if driver == "voltage":
                expected = expected * fr.coil_lag(f)
            ratio = r.gains[o] / expected
            worst.append((abs(20 * math.log10(abs(ratio))), abs(math.degrees(np.angle(ratio))), f, o))
            assert not r.saturated
    db_err, deg_err = max(w[0] for w in worst), max(w[1] for w in worst)
    assert db_err <= 0.1 and deg_err <= 1.0, f"worst |dB|, |deg| = {db_err:.4f}, {deg_err:.4f}: {worst}"
    # teeth: over the range the response falls below half and turns past -90 degrees
    # (at 500 Hz eq. 3 gives -7.9 dB, -110 degrees; eq. 4 -28 dB, -194 degrees)
    g500 = fr.sine_response(version, driver, 500.0, SMALL).gains["Q_valve"] / ehsv.flow_gain()
    assert abs(g500) < 0.5 and math.cos(np.angle(g500)) < 0


def _f3_of_i_coil(version, driver, guess):
    """-3 dB frequency of i_ref -> i_coil (small signal), bisected within guess/2..2 guess."""
    below = lambda f: abs(fr.sine_response(version, driver, f, SMALL).gains["i_coil"]) < 1 / math.sqrt(2)  # noqa: E731
    assert not below(guess / 2) and below(2 * guess)
    return fr.refine(below, guess / 2, 2 * guess, 2e-3)


def test_opamp_bandwidth_exceeds_voltage_drive_by_the_loop_gain(version):
    """Voltage drive: i/i_cmd = 1/(1 + (L/R) s), -3 dB at R/(2 pi L) = 49.7 Hz. Op-amp PI
    with Ki/Kp = R/L: the loop gain is Kp/(L s), the closed loop Kp/(L s + Kp), -3 dB at
    Kp/(2 pi L) = 7958 Hz: the ratio is Kp/R = 160."""
    p = ehsv.NOMINAL
    r_total = p["coil.R"] + p["coil.R_sense"]
    volt = _f3_of_i_coil(version, "voltage", r_total / (2 * math.pi * p["coil.L"]))
    opamp = _f3_of_i_coil(version, "opamp_pi", p["driver.Kp"] / (2 * math.pi * p["coil.L"]))
    factor = p["driver.Kp"] / r_total
    assert volt == pytest.approx(r_total / (2 * math.pi * p["coil.L"]), rel=0.005)
    assert opamp / volt == pytest.approx(factor, rel=0.01), (
        f"{opamp:.1f} Hz / {volt:.3f} Hz, Kp/R = {factor:g}"
    )


@pytest.mark.parametrize("v_supply, amplitude", [(72.0, 5e-3), (24.0, 1e-3), (10.0, 5e-3)])
def test_large_signal_limit(version, v_supply, amplitude):
    """The onset of saturation against three predictions. (V - R A)/(2 pi L A) is where
    the rail's slope at the sine's peak current falls short of the sine's largest slope:
    a lower bound, since the sine needs its largest slope at zero current. The exact
    condition for a current that follows the sine is A sqrt(R^2 + (2 pi f L)^2) = V
    (rail_limit); the loop's own roll-off asks for a little less (loop_rail_limit)."""
    onset = fr.measure_onset({"version": version, "V_supply": v_supply, "amplitude": amplitude})["onset"]
    slew = fr.slew_limit(v_supply, amplitude)
    loop = fr.loop_rail_limit(v_supply, amplitude)
    msg = f"onset {onset:.1f} Hz, (V-RA)/(2 pi L A) {slew:.1f} Hz, loop {loop:.1f} Hz"
    assert onset >= slew, msg
    assert onset == pytest.approx(loop, rel=0.03), msg
    if ehsv.NOMINAL["coil.R"] * amplitude <= 0.07 * v_supply:  # R A small against V
        assert onset == pytest.approx(slew, rel=0.10), msg
