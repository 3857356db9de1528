"""The robot path of the calibration: the ehsv.actuator plugin's config keys as
``mujoco.sysid`` parameters (ehsv.sysid) and cosim-examples/calibrate_leg.py, which records
the hydraulic leg on a test stand with hidden values of both cylinders' bulk modulus and
Coulomb friction and recovers them with ``mujoco.sysid.optimize``.

* a Parameter's modifier writes the instances' config, which the compiled model carries
  (the pressures change with it); a value the plugin refuses fails the compile,
* the example, small (0.3 s of data): the hidden values recovered within 1 %, inside
  their 95 % intervals, sysid's HTML report and fit.json written.
"""

import json

import numpy as np
import pytest

from ehsv import mjplugin

mujoco = pytest.importorskip("mujoco", reason="mujoco is not installed (scripts/setup-venv.sh)")
# mujoco.sysid imports as an empty package when its extras are missing
if not hasattr(pytest.importorskip("mujoco.sysid"), "optimize"):
    pytest.skip("mujoco[sysid]'s extras are not installed (requirements.txt)", allow_module_level=True)
calibrate_leg = pytest.importorskip("calibrate_leg", reason="cosim-examples is not on the path")
from ehsv import sysid as ehsv_sysid  # noqa: E402 (after the skips)

# the plugin, loaded once for every test here (conftest.py)
pytestmark = pytest.mark.usefixtures("mujoco_plugin")


def _p_a_after(spec, steps=200) -> float:
    """The hip's p_A after ``steps`` steps of the spec's model from the stance."""
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, calibrate_leg.initial_state(model), mujoco.mjtState.mjSTATE_FULLPHYSICS)
    data.ctrl[:] = calibrate_leg.stance()[1] + 0.002
    for _ in range(steps):
        mujoco.mj_step(model, data)
    return float(mjplugin.outputs(model, data, "p_A", [model.actuator("hip").id])[0])


def test_a_parameter_writes_the_instances_config():
    params = ehsv_sysid.config_parameters({"cylinder.beta": (1e9, 2e8, 2e9)}, instances=["hip"])
    spec = calibrate_leg.leg_spec()
    base = _p_a_after(spec)
    params["cylinder.beta"].update_from_vector(np.array([4e8]))
    params["cylinder.beta"].apply_modifier(spec)
    assert float(ehsv_sysid.plugin_instances(spec, ["hip"])[0].config["cylinder.beta"]) == 4e8
    assert "cylinder.beta" not in ehsv_sysid.plugin_instances(spec, ["knee"])[0].config
    assert abs(_p_a_after(spec) - base) > 1e4  # the compiled model carries the new value


def test_a_refused_value_fails_the_compile_and_an_unknown_instance_is_named():
    spec = calibrate_leg.leg_spec()
    ehsv_sysid.set_config(spec, None, {"cylinder.beta": -1.0})
    with pytest.raises(ValueError, match="cylinder.beta"):
        spec.compile()
    with pytest.raises(KeyError, match="ankle"):
        ehsv_sysid.plugin_instances(spec, ["ankle"])


def test_the_leg_example_recovers_its_hidden_values(tmp_path):
    assert calibrate_leg.main(["--duration", "0.3", "--out", str(tmp_path)]) == 0
    fit = json.loads((tmp_path / "fit.json").read_text())
    for key, row in fit["parameters"].items():
        assert row["value"] != row["start"], key
        assert abs(row["error_pct"]) < 1.0, (key, row)
        lo, hi = row["ci95"]
        assert lo <= row["true"] <= hi, (key, row)
    assert "<html" in (tmp_path / "report.html").read_text()[:2000].lower()
