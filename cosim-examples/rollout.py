"""N hydraulic quadrupeds (cosim-examples/mjcf/quadruped.xml, twelve ehsv.actuator plugin
actuators each) through ``mujoco.rollout``, in MuJoCo's C threads, no Python in the loop.

Each robot stands and squats with its own command (from the keyframe `stand`'s trunk
height down by 2 x 15 mm and back at 1 + 0.25 k Hz for robot k; the joint commands through
the legs' inverse kinematics and levers, read from the model, as x_ref of each rod), open
loop from one initial state.
Prints robot-seconds per wall-second with 1 thread and with one per core, then the same
for the quadruped with MuJoCo's own ``position`` actuators on the same tendons (nearly
free), and their ratio; the same per CPU-second (the process's CPU time over all threads:
on a machine shared with other work the wall figures and the scaling vary with its load,
the CPU ones much less); the lowest trunk height of all robots says they stood.

    .venv/bin/python cosim-examples/rollout.py [--n 8] [--duration 0.5] [--timestep 1e-4]
        [--substep 1e-4] [--method fixed_cost|exact|both]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

# numpy's BLAS threads would spin beside MuJoCo's rollout threads
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import numpy as np  # noqa: E402

import quadruped  # noqa: E402
from ehsv import mjplugin  # noqa: E402

#: MuJoCo's position actuator standing in for the cylinder (N/m, N s/m on the tendon)
POSITION_KP, POSITION_KV = 2e5, 2e3


def position_model(timestep: float):
    """The quadruped with a ``position`` actuator on each cylinder's tendon."""
    import mujoco

    text = mjplugin.mjcf_text(quadruped.MJCF, "fmu", timestep)
    text = text.replace('gainprm="1" ctrllimited="false"', f'kp="{POSITION_KP}" kv="{POSITION_KV}"')
    text = text.replace("<general ", "<position ")
    return mujoco.MjModel.from_xml_string(text)


#: the squat of robot k: down by 2 x SQUAT_DEPTH and back at SQUAT_F0 + k SQUAT_DF Hz
SQUAT_DEPTH, SQUAT_F0, SQUAT_DF = 0.015, 1.0, 0.25


def commands(quad: quadruped.Quadruped, n: int, nstep: int, h: float) -> np.ndarray:
    """x_ref of every rod of every robot at every step, (n, nstep, 12), held 1 ms: each
    robot squats from the stance (``quad``: the robot as its model has it)."""
    every = max(1, round(1e-3 / h))
    out = np.empty((n, nstep, len(quadruped.JOINTS)))
    for k in range(n):
        f = SQUAT_F0 + SQUAT_DF * k
        for i in range(0, nstep, every):
            height = quad.h_stand - SQUAT_DEPTH * (1 - np.cos(2 * np.pi * f * i * h))
            out[k, i : i + every] = quad.levers.rod(quad.stance(height))[0]
    return out


def initial_state(model):
    """The full physics state with the robot standing at rest (plugin state included)."""
    import mujoco

    data = mujoco.MjData(model)
    quad = quadruped.Quadruped.of(model)
    quadruped.initial_pose(model, data, quadruped.Plan.short(quad), quad)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    return state


def rate(model, state, control, threads: int, repeat: int = 1) -> tuple[float, float, np.ndarray]:
    """Robot-seconds per wall-second and per CPU-second (all threads' CPU time: what the
    machine's other load does not change) of the rollout (best of ``repeat``), and its
    states."""
    import mujoco
    from mujoco import rollout

    datas = [mujoco.MjData(model) for _ in range(threads)]
    n, nstep = control.shape[:2]
    best = cpu = np.inf
    out = None
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        out, _ = rollout.rollout(model, datas, state, control, nstep=nstep)
        best = min(best, time.perf_counter() - w0)
        cpu = min(cpu, time.process_time() - c0)
    simulated = n * nstep * model.opt.timestep
    return simulated / best, simulated / cpu, out


def run(n: int, duration: float, timestep: float, substep: float, method: str, threads: list[int]) -> dict:
    """Rates of the hydraulic and the position-actuator quadruped for each thread count."""
    config = {"solver.method": method, "substep": repr(substep)}
    hyd = mjplugin.load_model(quadruped.MJCF, "plugin", timestep, config)
    pos = position_model(timestep)
    nstep = round(duration / timestep)
    quad = quadruped.Quadruped.of(hyd)
    x_ref = commands(quad, n, nstep, timestep)
    # the position actuators' ctrl is the tendon's length, the plugin's the rod's position
    lmid = quad.levers.length_mid
    out = {}
    for nt in threads:
        r_h, c_h, states = rate(hyd, initial_state(hyd), x_ref, nt)
        r_p, c_p, _ = rate(pos, initial_state(pos), x_ref + lmid, nt, repeat=3)
        z = states[:, :, 1 + 2]  # state = time, qpos...: qpos[2] the trunk height
        out[nt] = (r_h, r_p, c_h, c_p, float(z.min()))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=8, help="robots (default 8)")
    ap.add_argument("--duration", type=float, default=0.5, help="simulated s per robot (default 0.5)")
    ap.add_argument("--timestep", type=float, default=1e-4, help="MuJoCo's timestep, s (default 1e-4)")
    ap.add_argument("--substep", type=float, default=1e-4, help="the plugin's longest internal step, s")
    ap.add_argument("--method", choices=("exact", "fixed_cost", "both"), default="fixed_cost")
    args = ap.parse_args(argv)
    cores = os.cpu_count() or 1
    threads = sorted({1, cores})
    print(
        f"{args.n} quadrupeds x {args.duration:g} s, timestep {args.timestep:g} s, "
        f"substep {args.substep:g} s, "
        f"{cores} cores; robot-s per wall-s (hydraulic = 12 ehsv.actuator plugins; position = MuJoCo's "
        f"position actuators, kp {POSITION_KP:g})"
    )
    print(f"{'':>18} {'per wall-second':>29} {'per CPU-second':>29}")
    rates = ("hydraulic", "position", "ratio")
    head = ("method", "threads", *rates, *rates, "lowest z, m")
    print(" ".join(f"{h:>{w}}" for h, w in zip(head, (10, 7, 10, 10, 7, 10, 10, 7, 12), strict=True)))
    methods = ("exact", "fixed_cost") if args.method == "both" else (args.method,)
    for method in methods:
        res = run(args.n, args.duration, args.timestep, args.substep, method, threads)
        for nt, (r_h, r_p, c_h, c_p, z) in res.items():
            print(
                f"{method:>10} {nt:>7} {r_h:>10.2f} {r_p:>10.1f} {r_h / r_p:>7.3f} "
                f"{c_h:>10.2f} {c_p:>10.1f} {c_h / c_p:>7.3f} {z:>12.3f}"
            )
        if len(res) > 1:
            print(f"{'':>10} scaling {threads[-1]} threads / 1: {res[threads[-1]][0] / res[1][0]:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
