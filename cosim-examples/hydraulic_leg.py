"""A HyQ-like hydraulic leg in MuJoCo: hip and knee each driven by an EhsvActuator cylinder.

The trunk (20 kg) runs on a vertical slide rail above the ground; the leg hangs from it:
hip flexion and knee hinges, thigh and shank 0.35 m, a foot with friction. Each joint is
driven by one cylinder (bore 16 mm, rod 10 mm, stroke 80 mm) through a 45 mm lever
(ehsv.robot.Lever: the cylinder's base pivot 0.20 m / 0.25 m from the joint, the lever
perpendicular at mid-stroke), supply 16 MPa, relief 21 MPa, the FMU's position loop on
each rod. The co-simulation steps at 1e-4 s: mj_step1 -> rods' x, v from the joints
through the levers -> each actuator's doStep -> joint torques F_rod * dx/dq into
qfrc_applied -> mj_step2; the joint commands (the 2-link leg's inverse kinematics for a
trunk height, foot under the hip) at 1 kHz.

The run: sitting on the rail's stop, stand up to 0.55 m, hold, squat (three cycles at
1.5 Hz from 0.55 m down to 0.41 m and back), crouch and hop (a fast extension, the leg
tucked in flight), land (the height command gives way at touchdown) and stand.
Prints the trunk height error, squat amplitude, hop height, rod force peaks, pressures
and the real-time factor with the time split; writes out/hydraulic_leg.png (joint angles
and commands, rod forces, chamber pressures, coil currents) and, where a GL context can
be made (MUJOCO_GL=egl by default, or osmesa; scripts/setup-gl.sh installs them),
out/hydraulic_leg_render.png (frames of the run).

    .venv/bin/python cosim-examples/hydraulic_leg.py [--duration 6] [--short]
        [--actuator plugin|fmu] [--timestep 1e-4] [--method exact|fixed_cost|both] [--fmi3] [--no-render]

--method sets the FMU's solver.method; both runs the same scenario with exact, then
fixed_cost, and prints their real-time factors and figures side by side.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ehsv import cli, mjplugin, robot
from ehsv.robot import Hydraulics, Lever, LeverSet, smooth

L1 = L2 = 0.35  # thigh, shank (m)
FOOT_R = 0.025
M_TRUNK, M_THIGH, M_SHANK = 20.0, 2.0, 1.0
H_SIT = 0.30  # the rail's lower stop: trunk (hip) height when sitting
H_STAND = 0.55
HYD = Hydraulics(p_supply=16e6, p_crack=21e6)
LEVERS = (
    Lever(d=0.20, r=0.045, q_mid=math.radians(-45), sign=+1, base_angle=math.pi / 2),  # hip
    Lever(d=0.25, r=0.045, q_mid=math.radians(95), sign=-1, base_angle=0.0),  # knee
)
JOINTS = ("hip", "knee")
MJCF = mjplugin.MJCF_DIR / "hydraulic_leg.xml"


def mjcf() -> str:
    # the cylinders beside the links, on the camera's side (-y)
    hip_base, hip_end = robot.cylinder_sites("hip_cyl", LEVERS[0], "y", side=-0.05)
    knee_base, knee_end = robot.cylinder_sites("knee_cyl", LEVERS[1], "y", joint_pos=(0, 0, -L1), side=-0.045)
    head = robot.scene_head(
        "hydraulic_leg", texrepeat=8, light="0.5 -1.5 2.5", light_dir="-0.2 0.6 -1", floor=2
    )
    return f"""{head}
    <geom name="rail" type="cylinder" fromto="-0.16 0.06 0 -0.16 0.06 1.1" size="0.012"
          rgba=".5 .5 .5 1"/>
    <body name="trunk" pos="0 0 0">
      <joint name="rail" type="slide" axis="0 0 1" range="{H_SIT} 1.2" limited="true" damping="1"/>
      <geom name="trunk" type="box" pos="0.02 0 0.06" size="0.17 0.09 0.06" mass="{M_TRUNK}"
            rgba=".3 .32 .36 1"/>
      {hip_base}
      <body name="thigh" pos="0 0 0">
        <joint name="hip" type="hinge" axis="0 1 0" range="-2.0 0.7"/>
        <geom class="link" type="capsule" fromto="0 0 0 0 0 -{L1}" size="0.03" mass="{M_THIGH}"/>
        {hip_end}
        {knee_base}
        <body name="shank" pos="0 0 -{L1}">
          <joint name="knee" type="hinge" axis="0 1 0" range="0.05 2.6"/>
          <geom class="link" type="capsule" fromto="0 0 0 0 0 -{L2}" size="0.02" mass="{M_SHANK - 0.1}"/>
          {knee_end}
          <geom name="foot" type="sphere" pos="0 0 -{L2}" size="{FOOT_R}" mass="0.1"
                contype="1" conaffinity="1" friction="1 0.005 0.0001" rgba=".15 .15 .15 1"/>
          <site name="foot" pos="0 0 -{L2}" size="0.005"/>
        </body>
      </body>
    </body>
  </worldbody>
  <tendon>
    {robot.cylinder_tendon("hip_cyl")}
    {robot.cylinder_tendon("knee_cyl")}
  </tendon>
{mjplugin.actuator_block(JOINTS, LEVERS, HYD)}
{stand_key()}
</mujoco>"""


def stand_key() -> str:
    """The keyframe "stand": the trunk at H_STAND, the foot under the hip, the rods' commands
    holding it (open it in the viewer: Simulation > Key > Load)."""
    q = joint_command(H_STAND)
    x_ref = LeverSet(LEVERS).rod(np.array(q))[0]
    return mjplugin.keyframe("stand", (H_STAND, *q), x_ref)


@dataclass(frozen=True)
class Plan:
    """The trunk height command over time (the phases' instants in s); the flight and the
    landing after the push-off are HopController's."""

    t_up: tuple[float, float]  # stand-up ramp
    squat: tuple[float, float] | None  # squat window (whole cycles of f_squat)
    hop: float | None  # start of the crouch before the hop
    f_squat: float = 1.5
    a_squat: float = 0.07  # height amplitude: from H_STAND down to H_STAND - 2 a and back
    h_crouch: float = 0.45
    t_push: float = 0.20  # push-off: the leg extends from h_crouch to h_push
    h_push: float = 0.58
    h_tuck: float = 0.50

    def height(self, t: float) -> float:
        h = smooth(t, *self.t_up, H_SIT, H_STAND)
        if self.squat and self.squat[0] <= t < self.squat[1]:
            # from the stance height down and back, zero speed at both ends
            h -= self.a_squat * (1 - math.cos(2 * math.pi * self.f_squat * (t - self.squat[0])))
        if self.hop is not None and t >= self.hop:
            t0 = self.hop
            h = smooth(t, t0, t0 + 0.3, H_STAND, self.h_crouch)
            h = smooth(t, t0 + 0.4, t0 + 0.4 + self.t_push, h, self.h_push)
        return h

    @property
    def t_liftoff(self) -> float:
        return self.hop + 0.4 + self.t_push

    @staticmethod
    def full(duration: float) -> Plan:
        squat = (2.0, 2.0 + 3 / 1.5) if duration >= 4.2 else None
        return Plan(t_up=(0.2, 1.2), squat=squat, hop=4.4 if duration >= 5.8 else None)

    @staticmethod
    def short() -> Plan:
        return Plan(t_up=(0.02, 0.42), squat=None, hop=None)


class HopController:
    """The joint commands: the plan's height through the leg's inverse kinematics; after
    the push-off the leg tucks (h_tuck) until the foot touches down, then the height
    command leaves the touchdown height at the trunk's own speed and settles at H_STAND as
    a critically damped second-order system (omega 12 rad/s), so the leg gives at the
    impact instead of stopping the trunk dead. No touchdown 1.5 s after the push: stand."""

    def __init__(self, plan: Plan, rail_adr: int, rail_dof: int, foot_site: int):
        self.plan, self.rail, self.rail_dof, self.foot = plan, rail_adr, rail_dof, foot_site
        self.airborne = False
        self.touchdown: float | None = None
        self.h = self.v = 0.0
        self.t_prev = 0.0
        self.h_cmd = H_SIT

    def height(self, t: float, data) -> float:
        p = self.plan
        if p.hop is None or t < p.t_liftoff:
            return p.height(t)
        foot_z = data.site_xpos[self.foot, 2] - FOOT_R
        if not self.airborne and foot_z > 0.01:
            self.airborne = True
        if self.touchdown is None:
            if self.airborne and foot_z < 0.002:
                self.touchdown = t
                self.h, self.v = float(data.qpos[self.rail]), float(data.qvel[self.rail])
            elif t > p.t_liftoff + 1.5:
                return smooth(t, p.t_liftoff + 1.5, p.t_liftoff + 2.0, p.h_tuck, H_STAND)
            else:
                return smooth(t, p.t_liftoff, p.t_liftoff + 0.08, p.h_push, p.h_tuck)
        w = 12.0
        dt = t - self.t_prev
        self.v += dt * (w * w * (H_STAND - self.h) - 2 * w * self.v)
        self.h += dt * self.v
        return self.h

    def __call__(self, t, data):
        self.h_cmd = self.height(t, data)
        self.t_prev = t
        return joint_command(self.h_cmd)


def joint_command(height: float) -> tuple[float, float]:
    """Hip and knee angles that put the foot under the hip with the trunk at ``height``."""
    return robot.leg_ik(height - FOOT_R, 0.0, L1, L2, bend=+1)


@dataclass
class LegRun:
    """The run's records and summary (what the test asserts on)."""

    kind: str
    actuator_line: str
    rec: dict
    timing: robot.Timing
    plan: Plan
    t_end: float
    hyd: Hydraulics
    tendon_error: float  # largest |MuJoCo tendon length - lever L(q)| over the records (m)
    frames: list
    frame_labels: list
    render_error: str | None

    @property
    def t(self) -> np.ndarray:
        return self.rec["t"]

    @property
    def height(self) -> np.ndarray:
        return self.rec["probe"][:, 0]

    @property
    def height_cmd(self) -> np.ndarray:
        return self.rec["probe"][:, 1]

    def window(self, t0: float, t1: float) -> np.ndarray:
        return (self.t >= t0) & (self.t < t1)

    def summary(self) -> dict:
        p = self.plan
        s = {}
        hold = self.window(p.t_up[1] + 0.1, (p.squat[0] if p.squat else self.t_end) - 1e-9)
        err = self.height[hold] - self.height_cmd[hold]
        s["hold_err_mean"] = float(np.mean(err)) if hold.any() else math.nan
        s["hold_err_max"] = float(np.max(np.abs(err))) if hold.any() else math.nan
        if p.squat:
            w = self.window(*p.squat)
            s["squat_amp"] = float((self.height[w].max() - self.height[w].min()) / 2)
            s["squat_cmd_amp"] = float((self.height_cmd[w].max() - self.height_cmd[w].min()) / 2)
            # the lag of the fundamental: phases of height and command at f_squat
            e = np.exp(-2j * np.pi * p.f_squat * self.t[w])
            dphi = np.angle(np.sum(self.height_cmd[w] * e) / np.sum(self.height[w] * e))
            s["squat_lag_ms"] = float(dphi / (2 * np.pi * p.f_squat) * 1e3)
        if p.hop is not None:
            w = self.window(p.t_liftoff - 0.1, self.t_end)
            s["hop_trunk_rise"] = float(self.height[w].max() - H_STAND)
            s["hop_foot_clearance"] = float(self.rec["probe"][w, 2].max() - FOOT_R)
            s["hop_apex_t"] = float(self.t[w][np.argmax(self.height[w])])
            after = self.window(s["hop_apex_t"], self.t_end)
            s["landing_low"] = float(self.height[after].min())
            end = self.window(self.t_end - 0.2, self.t_end)
            s["end_err"] = float(np.abs(self.height[end] - H_STAND).max())
        F = self.rec["F"]
        s["F_max"] = F.max(axis=0).tolist()
        s["F_min"] = F.min(axis=0).tolist()
        s["p_max"] = float(max(self.rec["p_A"].max(), self.rec["p_B"].max()))
        s["p_min"] = float(min(self.rec["p_A"].min(), self.rec["p_B"].min()))
        s["i_peak"] = float(np.abs(self.rec["i_coil"]).max())
        s["x_rod_range"] = [self.rec["x_rod"].min(axis=0).tolist(), self.rec["x_rod"].max(axis=0).tolist()]
        s["rtf"] = self.t_end / self.timing.wall
        return s


def run(
    duration: float = 6.0,
    short: bool = False,
    kind: str = "plugin",
    version: str = "fmi2",
    render: bool = True,
    method: str = "exact",
    timestep: float | None = None,
    substep: float | None = None,
) -> LegRun:
    """The run on MJCF (``MJCF``) with ``kind`` "plugin" actuators or "fmu" (the reference:
    the FMU through the same tendons); ``timestep`` replaces MuJoCo's 1e-4 s (the plugin
    then sub-steps at ``substep``, default 1e-4 s)."""
    if render:
        robot.gl_backend()  # before mujoco's import
    import mujoco

    plan = Plan.short() if short else Plan.full(duration)
    t_end = 0.6 if short else duration
    config = {"solver.method": method}
    if substep is not None:
        config["substep"] = repr(substep)
    model = mjplugin.load_model(MJCF, kind, timestep, config)
    data = mujoco.MjData(model)
    levers = LeverSet(LEVERS)
    jid = {j: model.joint(j).qposadr[0] for j in ("rail", *JOINTS)}
    q0 = joint_command(H_SIT)
    data.qpos[jid["rail"]] = H_SIT
    data.qpos[jid["hip"]], data.qpos[jid["knee"]] = q0
    mujoco.mj_forward(model, data)
    bank, line = None, f"actuators: {len(LEVERS)} x ehsv.actuator MuJoCo plugin (solver.method = {method})"
    if kind == "fmu":
        zero = np.zeros(len(LEVERS))
        bank, line = robot.make_bank("fmu", len(LEVERS), HYD, zero, zero, version, method)

    foot = model.site("foot").id
    ten_adr = [model.tendon(n).id for n in ("hip_cyl", "knee_cyl")]
    L_mid = np.array([lv.L_mid for lv in LEVERS])
    controller = HopController(plan, jid["rail"], model.joint("rail").dofadr[0], foot)

    def probe(d):
        return (
            d.qpos[jid["rail"]],
            controller.h_cmd,
            d.site_xpos[foot, 2],
            *(d.ten_length[ten_adr] - L_mid),
        )

    sim = mjplugin.MjcfCosim(model, data, JOINTS, levers, controller, mjplugin.length_mid(MJCF), bank)
    try:
        every = max(1, round(1e-3 / model.opt.timestep))
        sim.run(t_end, record_every=every, cmd_every=every, probe=probe)
    finally:
        if bank is not None:
            bank.close()
    rec = sim.rec.arrays()
    pr = rec["probe"]
    q = rec["q"]
    lever_x = np.array([[lv.rod(float(qj))[0] for lv, qj in zip(LEVERS, row, strict=True)] for row in q])
    tendon_error = float(np.abs(pr[:, 3:5] - lever_x).max())
    r = LegRun(sim.kind, line, rec, sim.timing, plan, t_end, HYD, tendon_error, [], [], None)
    if render:
        render_frames(model, r)
    return r


def render_frames(model, r: LegRun) -> None:
    """Pictures of recorded instants: sitting, standing, squat bottom, crouch, hop apex."""
    cam = robot.Camera(model, 420, 400, lookat=(0.0, 0.0, 0.45), distance=1.5, azimuth=90, elev=-6)
    if cam.renderer is None:
        r.render_error = cam.error
        return
    p, s = r.plan, r.summary()
    times = {0.0: "sitting", p.t_up[1] + 0.3: "standing, 0.55 m"}
    if p.squat:
        times[p.squat[0] + 0.5 / p.f_squat] = "squat, bottom"
    if p.hop is not None:
        times[p.hop + 0.38] = "crouch"
        times[s["hop_apex_t"]] = "hop, apex"
    cam.capture(model, r, times)


def plot(r: LegRun, out: Path) -> None:
    import ehsv

    plt = ehsv.pyplot()
    t = r.t
    fig, ax = plt.subplots(5, 1, sharex=True, figsize=(9, 11))
    ax[0].plot(t, r.height, label="trunk height")
    ax[0].plot(t, r.height_cmd, "--", lw=0.9, label="command")
    ax[0].plot(t, r.rec["probe"][:, 2] - FOOT_R, lw=0.8, label="foot clearance")
    ax[0].set_ylabel("m")
    names = ("hip", "knee")
    for j, c in enumerate(("C0", "C1")):
        ax[1].plot(t, np.degrees(r.rec["q"][:, j]), c, label=names[j])
        ax[1].plot(t, np.degrees(r.rec["q_cmd"][:, j]), c + "--", lw=0.9, label=f"{names[j]} command")
        ax[2].plot(t, r.rec["F"][:, j] / 1e3, c, label=f"{names[j]} F_rod")
        ax[3].plot(t, r.rec["p_A"][:, j] / 1e6, c, label=f"{names[j]} p_A")
        ax[3].plot(t, r.rec["p_B"][:, j] / 1e6, c + ":", label=f"{names[j]} p_B")
        ax[4].plot(t, r.rec["i_coil"][:, j] * 1e3, c, label=f"{names[j]} i_coil")
    ax[1].set_ylabel("joint angle, deg")
    push, pull = r.hyd.stall_force()
    for f in (push, pull):
        ax[2].axhline(f / 1e3, color="grey", lw=0.6, ls="--")
    ax[2].set_ylabel("rod force, kN\n(-- stall)")
    ax[3].axhline(r.hyd.p_crack / 1e6, color="red", lw=0.6, ls="--", label="relief setting")
    ax[3].axhline(r.hyd.p_supply / 1e6, color="grey", lw=0.6, ls="--", label="supply")
    ax[3].set_ylabel("pressure, MPa")
    ax[4].set_ylabel("coil current, mA")
    ax[4].set_xlabel("time, s")
    for a in ax:
        a.legend(fontsize=7, ncol=3, loc="upper right")
        a.grid(alpha=0.3)
    ax[0].set_title(
        f"Hydraulic leg in MuJoCo, {robot.KIND_LABEL[r.kind]} actuators: 20 kg trunk on a rail, "
        "16 MPa, 45 mm levers",
        fontsize=10,
    )
    cli.write_figure(fig, out)
    plt.close(fig)


def report(r: LegRun) -> None:
    s = r.summary()
    print(r.actuator_line)
    push, pull = r.hyd.stall_force()
    print(
        f"supply {r.hyd.p_supply / 1e6:g} MPa, relief {r.hyd.p_crack / 1e6:g} MPa, position.Kp "
        f"{r.hyd.Kp:g} A/m; stall force +{push:.0f} / {pull:.0f} N"
    )
    print(
        f"  trunk height held at {H_STAND} m: mean error {s['hold_err_mean'] * 1e3:+.2f} mm, "
        f"largest {s['hold_err_max'] * 1e3:.2f} mm"
    )
    if "squat_amp" in s:
        print(
            f"  squat: amplitude {s['squat_amp'] * 1e3:.1f} mm of {s['squat_cmd_amp'] * 1e3:.1f} mm "
            f"commanded at {r.plan.f_squat} Hz, lag {s['squat_lag_ms']:.0f} ms"
        )
    if "hop_trunk_rise" in s:
        print(
            f"  hop: trunk rose {s['hop_trunk_rise'] * 1e3:.0f} mm above stance (apex at "
            f"{s['hop_apex_t']:.2f} s), foot cleared the ground by {s['hop_foot_clearance'] * 1e3:.0f} mm; "
            f"landing sank to {s['landing_low']:.3f} m, standing again within "
            f"{s['end_err'] * 1e3:.1f} mm of {H_STAND} m at the end"
        )
    for j, name in enumerate(JOINTS):
        print(
            f"  {name} rod force {s['F_min'][j]:.0f} .. {s['F_max'][j]:.0f} N, rod "
            f"{s['x_rod_range'][0][j] * 1e3:+.1f} .. {s['x_rod_range'][1][j] * 1e3:+.1f} mm"
        )
    print(
        f"  chamber pressures {s['p_min'] / 1e6:.2f} .. {s['p_max'] / 1e6:.2f} MPa, "
        f"coil current peak {s['i_peak'] * 1e3:.2f} mA"
    )
    print(f"  lever check: MuJoCo's tendon length vs the lever's L(q): {r.tendon_error * 1e6:.2f} um")
    print("  " + r.timing.line(r.t_end, len(LEVERS), r.kind))


def figures(r: LegRun) -> dict[str, str]:
    """The holding and tracking figures of ``report``, for the side-by-side table."""
    s = r.summary()
    out = {
        "hold: mean error, mm": f"{s['hold_err_mean'] * 1e3:+.2f}",
        "hold: largest error, mm": f"{s['hold_err_max'] * 1e3:.2f}",
    }
    if "squat_amp" in s:
        out["squat amplitude, mm"] = f"{s['squat_amp'] * 1e3:.1f}"
        out["squat lag, ms"] = f"{s['squat_lag_ms']:.0f}"
    if "hop_trunk_rise" in s:
        out["hop: trunk rise, mm"] = f"{s['hop_trunk_rise'] * 1e3:.0f}"
        out["hop: landing low, m"] = f"{s['landing_low']:.3f}"
        out["end: height error, mm"] = f"{s['end_err'] * 1e3:.1f}"
    out["pressures, MPa"] = f"{s['p_min'] / 1e6:.2f}..{s['p_max'] / 1e6:.2f}"
    out["coil current peak, mA"] = f"{s['i_peak'] * 1e3:.2f}"
    return out


def main(argv=None) -> int:
    ap = robot.parser(__doc__, 6.0, "0.6 s: stand up and hold (the test's run)", "hydraulic_leg.png")
    runs = robot.run_example(ap.parse_args(argv), run, report, plot, figures)
    return 1 if runs is None else 0


if __name__ == "__main__":
    sys.exit(main())
