"""pytest configuration for the EhsvActuator FMU suite.

The archives are built before pytest runs (scripts/test.sh: `cargo run --release -p
build-fmu`); nothing here builds anything. Every FMU test runs for both archives
(fmi2 and fmi3). Expensive simulations are cached for the session so that several
tests can look at one run.
"""

import functools

import pytest

import ehsv


@pytest.fixture(scope="module", params=ehsv.VERSIONS)
def version(request):
    """'fmi2' or 'fmi3'; fails (not skips) when the archive has not been built."""
    msg = ehsv.missing_fmu_message(request.param)
    if msg:
        pytest.fail(msg, pytrace=False)
    return request.param


@pytest.fixture(scope="module")
def fmu(version):
    return ehsv.fmu_path(version)


@functools.cache
def _cached_run(version, driver, i_step, h, t_stop, outputs, method):
    params = None if method == "exact" else ehsv.method_params(method)
    result = ehsv.run_step(version, driver, i_step, h=h, t_stop=t_stop, outputs=outputs, params=params)
    for a in result.values():
        a.setflags(write=False)  # shared between tests: read-only
    return result


def cached_run(version, driver, i_step, *, h, t_stop, outputs=ehsv.DEFAULT_OUTPUTS, method="exact"):
    """run_step (step at t = 0 from rest, V_supply 72 V, nominal parameters but
    solver.method = ``method``), once per session for each distinct set of arguments."""
    return _cached_run(version, driver, float(i_step), float(h), float(t_stop), tuple(outputs), method)


@pytest.fixture(scope="session")
def run():
    return cached_run


@pytest.fixture(scope="module")
def mujoco_plugin():
    """The ehsv.actuator MuJoCo plugin, loaded once per module; fails (not skips) where the
    library was not built, with the command that builds it."""
    from ehsv import mjplugin

    missing = mjplugin.plugin_missing()
    if missing:
        pytest.fail(missing, pytrace=False)
    return mjplugin.load_plugin()
