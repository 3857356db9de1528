"""solver.method = fixed_cost on hard runs, through the archives as users load them
(fmpy), 0.5 s at a 1e-4 s communication step, both FMI versions.

The runs: current squares at 100 Hz (+-5 mA) with the op-amp PI driver at 72 V and with
the H-bridge at 12 V (every half period a full reversal of the spool; the piston drifts
into its end stop within 0.3 s and is hammered there), a 2 Hz +-5 mA sine that drives the
piston into both end stops, and current steps that park it against a stop.

What each check would catch:

* every output finite at every step: a blow-up (fixed steps without error control have no
  rejection to save them);
* pressures between the cavitation floor (hydraulics.p_cavitation) and the relief
  envelope (hydraulics.p_tank + relief.p_crack + relief.dp_override): an overshoot of the
  floor on reversals (ROS2 without the floor clamp went 4 bar below it) or a pressure
  oscillation of the stiff chambers pumping itself up;
* no growth: an unstable mode grows geometrically from step to step, so its amplitude in
  the last 10 ms period exceeds that of the first periods many times over; the physics
  changes the amplitudes by at most a quarter (the piston reaching its stop);
* the same steady state as exact after a step: a bias of the fixed-cost fixed point (a
  contact force, a leakage or a clamp that acts at rest); at rest both methods solve the
  same equations f(y) = 0, so they agree to rounding.

Measured with fixed_cost's linearly implicit trapezoidal step at the default 50 us
(2026-11-28, fmi2): the pressures reach the floor (-0.9 bar; the step holds a pressure that
ends below it at the floor) and peak at 84.0 bar (op-amp) and 84.1 bar (H-bridge) under the
90 bar envelope; the last period's amplitude over the first periods' is at most 1.24
(v_piston, op-amp; 1.22 with the H-bridge, whose PWM fixed_cost takes by its periods'
means), the pressures' at most 1.09.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import ehsv

H = 1e-4  # s, communication step
T_END = 0.5  # s
OUTPUTS = ("i_coil", "u_driver", "Q_valve", "Q_A", "Q_B", "p_A", "p_B", "x_piston", "v_piston", "F_hydraulic")
MA = 1e-3
#: samples of one period of the 100 Hz squares
PERIOD = round(0.01 / H)
#: the first periods' largest amplitude is the reference of the growth check: the first
#: period alone starts from rest with a half-size step
FIRST_PERIODS = 5
#: allowed growth of an amplitude from the first periods to the last: the physics gives up
#: to 1.25 (the piston's velocity once it bounces on its stop); an instability far more
GROWTH = 1.5


def square(f: float, amplitude: float):
    """+amplitude for the first half of each period 1/f, -amplitude for the second (on
    the communication grid, so both methods see the same edges)."""
    half = round(0.5 / f / H)
    return lambda k: amplitude if (k // half) % 2 == 0 else -amplitude


def sine(f: float, amplitude: float):
    return lambda k: amplitude * math.sin(2 * math.pi * f * k * H)


def constant(value: float):
    return lambda k: value


#: name -> (driver, V_supply, i_ref at step k)
RUNS = {
    "opamp_pi square 100 Hz": ("opamp_pi", 72.0, square(100.0, 5 * MA)),
    "hbridge_pid square 100 Hz": ("hbridge_pid", 12.0, square(100.0, 5 * MA)),
    "opamp_pi sine 2 Hz into the stops": ("opamp_pi", 72.0, sine(2.0, 5 * MA)),
}
STEPS = {
    "opamp_pi +5 mA": ("opamp_pi", 72.0, constant(5 * MA)),
    "opamp_pi -5 mA": ("opamp_pi", 72.0, constant(-5 * MA)),
    "hbridge_pid +5 mA": ("hbridge_pid", 12.0, constant(5 * MA)),
}


def simulate(version: str, method: str, driver: str, v_supply: float, i_ref) -> dict[str, np.ndarray]:
    """One run through fmpy: i_ref(k) set before the k-th doStep, OUTPUTS recorded at
    every communication point."""
    fmu = ehsv.Ehsv(version)
    params = {"driver": ehsv.DRIVERS[driver], **ehsv.method_params(method)}
    fmu.initialize(0.0, T_END, **params, V_supply=v_supply, i_ref=i_ref(0))
    n = round(T_END / H)
    rec = np.empty((n + 1, len(OUTPUTS)))
    rec[0] = fmu.get(OUTPUTS)
    for k in range(n):
        fmu.set("i_ref", i_ref(k))
        fmu.do_step(k * H, H)
        rec[k + 1] = fmu.get(OUTPUTS)
    fmu.free()
    return {name: rec[:, j] for j, name in enumerate(OUTPUTS)}


_CACHE: dict = {}


def cached(version, method, spec):
    key = (version, method, spec)
    if key not in _CACHE:
        _CACHE[key] = simulate(version, method, *spec)
    return _CACHE[key]


def pressure_envelope() -> tuple[float, float]:
    """(floor, ceiling) of the chamber pressures, Pa, from the archive's parameters."""
    p = ehsv.NOMINAL
    ceiling = p["hydraulics.p_tank"] + p["relief.p_crack"] + p["relief.dp_override"]
    return p["hydraulics.p_cavitation"], ceiling


@pytest.mark.parametrize("name", list(RUNS))
def test_fixed_cost_stays_finite_and_inside_the_pressure_envelope(version, name):
    r = cached(version, "fixed_cost", RUNS[name])
    for out in OUTPUTS:
        assert np.isfinite(r[out]).all(), f"{out} left the numbers"
    floor, ceiling = pressure_envelope()
    for p in ("p_A", "p_B"):
        assert r[p].min() >= floor, f"{p} {r[p].min():.6g} Pa below the cavitation floor {floor:g}"
        assert r[p].max() <= ceiling, f"{p} {r[p].max():.6g} Pa above the relief envelope {ceiling:g}"
    # the runs are hard ones: both chambers go from the floor to near supply pressure
    for p in ("p_A", "p_B"):
        assert r[p].min() < floor + 1e5 and r[p].max() > ehsv.NOMINAL["relief.p_crack"] * 0.85, p


def test_the_sine_drives_the_piston_into_both_end_stops(version):
    """Guards the sine run above: it must reach the stops (x beyond +-stroke/2) with
    either method, or it would not test the contact."""
    half = ehsv.NOMINAL["cylinder.stroke"] / 2
    for method in ("exact", "fixed_cost"):
        x = cached(version, method, RUNS["opamp_pi sine 2 Hz into the stops"])["x_piston"]
        assert x.max() > half and x.min() < -half, (method, x.min(), x.max())


def _period_amplitudes(y: np.ndarray) -> np.ndarray:
    n = (len(y) - 1) // PERIOD
    return np.array([np.ptp(y[j * PERIOD : (j + 1) * PERIOD + 1]) for j in range(n)])


@pytest.mark.parametrize("name", [n for n in RUNS if "square" in n])
def test_fixed_cost_squares_do_not_grow(version, name):
    r = cached(version, "fixed_cost", RUNS[name])
    for out in ("i_coil", "u_driver", "Q_valve", "p_A", "p_B", "x_piston", "v_piston", "F_hydraulic"):
        amp = _period_amplitudes(r[out])
        first = amp[:FIRST_PERIODS].max()
        assert first > 0, out
        assert amp[-1] <= GROWTH * first, f"{out}: last period {amp[-1]:.4g}, first periods {first:.4g}"


@pytest.mark.parametrize("name", [*STEPS, "opamp_pi sine 2 Hz into the stops"])
def test_fixed_cost_reaches_the_steady_state_of_exact(version, name):
    """After a step (and after the sine's last swing, i_ref back near 0) the piston rests
    against an end stop; both methods end at the same state. Tolerances: 1 nm, 1 Pa,
    1 nA (the differences measured with the new fixed_cost are of rounding size: 3e-16 m,
    8e-8 Pa, 9e-19 A after the steps; 4e-16 m, 6e-6 Pa and 6e-20 A after the sine's last
    swing)."""
    spec = STEPS.get(name) or RUNS[name]
    exact, fixed = cached(version, "exact", spec), cached(version, "fixed_cost", spec)
    half = ehsv.NOMINAL["cylinder.stroke"] / 2
    assert abs(exact["x_piston"][-1]) > half, "the piston rests against a stop"
    assert abs(exact["v_piston"][-1]) < 1e-9, "at rest"
    assert fixed["x_piston"][-1] == pytest.approx(exact["x_piston"][-1], abs=1e-9)
    for p in ("p_A", "p_B"):
        assert fixed[p][-1] == pytest.approx(exact[p][-1], abs=1.0), p
    assert fixed["i_coil"][-1] == pytest.approx(exact["i_coil"][-1], abs=1e-9)
