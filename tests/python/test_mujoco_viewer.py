"""The quadruped's MJCF with its ehsv.actuator plugins opens in MuJoCo's interactive viewer
(``mujoco.viewer``, the code behind ``python -m mujoco.viewer`` and the README's
command), on a virtual display (Xvfb, installed by scripts/setup-gl.sh; Mesa renders
without a GPU): the window opens, the robot stands in it from its ``stand`` keyframe, and
the steps taken with the viewer open are the steps taken without it, bit for bit (the
viewer only draws).

The viewer runs in a child process under ``xvfb-run``: it needs a display and its own GL
context, which a test process must not keep. The child closes the viewer before it exits
(tearing the window down at interpreter exit instead crashes some GL stacks).
"""

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from ehsv import mjplugin

mujoco = pytest.importorskip("mujoco", reason="mujoco is not installed (scripts/setup-venv.sh)")
quadruped = pytest.importorskip("quadruped", reason="cosim-examples is not on the path")

#: steps of 1e-4 s (the MJCF's timestep) taken with the viewer open, drawn every 10th
STEPS, DRAW_EVERY = 300, 10

CHILD = """
import json, sys, time
import mujoco, mujoco.viewer
mujoco.mj_loadPluginLibrary(sys.argv[1])
model = mujoco.MjModel.from_xml_path(sys.argv[2])
data = mujoco.MjData(model)
mujoco.mj_resetDataKeyframe(model, data, model.key("stand").id)
steps, every = int(sys.argv[3]), int(sys.argv[4])
viewer = mujoco.viewer.launch_passive(model, data)
drawn_while_running = 0
for k in range(steps):
    mujoco.mj_step(model, data)
    if k % every == 0:
        viewer.sync()
        drawn_while_running += viewer.is_running()
viewer.close()
time.sleep(0.5)
print(json.dumps({
    "drawn": drawn_while_running,
    "qpos": data.qpos.tolist(),
    "plugin_state": data.plugin_state.tolist(),
}))
"""


def _headless_run(model) -> mujoco.MjData:
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("stand").id)
    for _ in range(STEPS):
        mujoco.mj_step(model, data)
    return data


def test_the_quadruped_opens_in_the_viewer_and_stands():
    missing = mjplugin.plugin_missing()
    if missing:
        pytest.fail(missing, pytrace=False)
    if shutil.which("xvfb-run") is None:
        pytest.skip("no xvfb-run: scripts/setup-gl.sh installs Xvfb")
    mjplugin.load_plugin()
    command = [
        "xvfb-run", "-a", "-s", "-screen 0 800x600x24",
        sys.executable, "-c", CHILD,
        str(mjplugin.plugin_path()), str(quadruped.MJCF), str(STEPS), str(DRAW_EVERY),
    ]  # fmt: skip
    child = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert child.returncode == 0, child.stderr[-2000:]
    seen = json.loads(child.stdout.strip().splitlines()[-1])
    # The window was open for every frame drawn.
    assert seen["drawn"] == STEPS // DRAW_EVERY
    model = mujoco.MjModel.from_xml_path(str(quadruped.MJCF))
    stand = model.key("stand")
    qpos = np.array(seen["qpos"])
    # Standing: the trunk within 5 mm of its keyframe height after 30 ms on the cylinders.
    assert abs(qpos[2] - stand.qpos[2]) < 5e-3, qpos[2]
    headless = _headless_run(model)
    np.testing.assert_array_equal(qpos, headless.qpos)
    np.testing.assert_array_equal(np.array(seen["plugin_state"]), headless.plugin_state)
