#!/usr/bin/env bash
# Installs what MuJoCo's offscreen renderer needs for the pictures of
# cosim-examples/hydraulic_leg.py and quadruped.py (mujoco.Renderer without a display), and
# the virtual display on which tests/python/test_mujoco_viewer.py opens MuJoCo's viewer:
#
#   apt: libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri   EGL on Mesa (llvmpipe: no GPU needed),
#                                                       MUJOCO_GL=egl, the examples' default
#        libosmesa6                                     OSMesa, the fallback: MUJOCO_GL=osmesa
#        xvfb xauth                                     Xvfb and xvfb-run: an X display
#                                                       in memory for the viewer's window
#
# Idempotent: a second run only checks. Needs root (or sudo) for apt-get on Debian.
# Without these the examples still run and write their plots; they print one line saying
# the picture was skipped and why (and the viewer test skips, saying to run this).
set -euo pipefail

"$(dirname "${BASH_SOURCE[0]}")/apt-install.sh" setup-gl \
    libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libosmesa6 xvfb xauth
echo "setup-gl: ready" >&2
