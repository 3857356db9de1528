"""A HyQ-like hydraulic leg in MuJoCo: hip and knee each driven by an EhsvActuator cylinder.

The robot is cosim-examples/mjcf/hydraulic_leg.xml: a trunk on a vertical slide rail above
the ground, the leg hanging from it (hip flexion and knee hinges, a foot with friction),
each joint driven by one cylinder through a lever (the spatial tendon between its pivots),
the ehsv.actuator plugin's position loop on each rod. Everything the controller needs of
the robot is read from the loaded model (``Leg.of``): the levers, the link lengths and the
foot, the rail's lower stop (sitting) and the "stand" keyframe's trunk height. The
co-simulation steps at MuJoCo's timestep (1e-4 s in the file): mj_step1 -> the rods'
commands x_ref -> mj_step2 (the plugin steps the actuators inside it; with --actuator
fmu the FMUs step between, on the same tendons); the joint commands (the 2-link leg's
inverse kinematics for a trunk height, foot under the hip) at 1 kHz.

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
from ehsv.robot import Hydraulics, LeverSet, smooth

JOINTS = ("hip", "knee")
MJCF = mjplugin.MJCF_DIR / "hydraulic_leg.xml"


@dataclass(frozen=True)
class Leg:
    """What the controller and the reports need of the leg, read from the model."""

    kinematics: robot.LegKinematics
    levers: LeverSet  # joint angles -> rod positions, in JOINTS' order
    h_sit: float  # the rail's lower stop: the trunk's height sitting
    h_stand: float  # the "stand" keyframe's trunk height
    trunk_mass: float

    @staticmethod
    def of(model) -> Leg:
        rail = model.joint("rail")
        return Leg(
            kinematics=robot.LegKinematics.of(model, "trunk", "hip", "knee", "foot"),
            levers=robot.lever_set(model, JOINTS, mjplugin.length_mid(MJCF)),
            h_sit=float(rail.range[0]),
            h_stand=float(model.key("stand").qpos[rail.qposadr[0]]),
            trunk_mass=float(model.body("trunk").mass[0]),
        )

    def joint_command(self, height: float) -> tuple[float, float]:
        """Hip and knee angles that put the foot under the hip with the trunk at ``height``."""
        return self.kinematics.angles(height)


@dataclass(frozen=True)
class Plan:
    """The trunk height command over time (the phases' instants in s); the flight and the
    landing after the push-off are HopController's."""

    t_up: tuple[float, float]  # stand-up ramp
    squat: tuple[float, float] | None  # squat window (whole cycles of f_squat)
    hop: float | None  # start of the crouch before the hop
    h_sit: float  # the heights it starts from and stands at (the model's: Leg)
    h_stand: float
    f_squat: float = 1.5
    a_squat: float = 0.07  # height amplitude: from h_stand down to h_stand - 2 a and back
    h_crouch: float = 0.45
    t_push: float = 0.20  # push-off: the leg extends from h_crouch to h_push
    h_push: float = 0.58
    h_tuck: float = 0.50

    def height(self, t: float) -> float:
        h = smooth(t, *self.t_up, self.h_sit, self.h_stand)
        if self.squat and self.squat[0] <= t < self.squat[1]:
            # from the stance height down and back, zero speed at both ends
            h -= self.a_squat * (1 - math.cos(2 * math.pi * self.f_squat * (t - self.squat[0])))
        if self.hop is not None and t >= self.hop:
            t0 = self.hop
            h = smooth(t, t0, t0 + 0.3, self.h_stand, self.h_crouch)
            h = smooth(t, t0 + 0.4, t0 + 0.4 + self.t_push, h, self.h_push)
        return h

    @property
    def t_liftoff(self) -> float:
        return self.hop + 0.4 + self.t_push

    @staticmethod
    def full(duration: float, leg: Leg) -> Plan:
        squat = (2.0, 2.0 + 3 / 1.5) if duration >= 4.2 else None
        hop = 4.4 if duration >= 5.8 else None
        return Plan(t_up=(0.2, 1.2), squat=squat, hop=hop, h_sit=leg.h_sit, h_stand=leg.h_stand)

    @staticmethod
    def short(leg: Leg) -> Plan:
        return Plan(t_up=(0.02, 0.42), squat=None, hop=None, h_sit=leg.h_sit, h_stand=leg.h_stand)


class HopController:
    """The joint commands: the plan's height through the leg's inverse kinematics; after
    the push-off the leg tucks (h_tuck) until the foot touches down, then the height
    command leaves the touchdown height at the trunk's own speed and settles at h_stand as
    a critically damped second-order system (omega 12 rad/s), so the leg gives at the
    impact instead of stopping the trunk dead. No touchdown 1.5 s after the push: stand."""

    def __init__(self, plan: Plan, leg: Leg, rail_adr: int, rail_dof: int, foot_site: int):
        self.plan, self.leg, self.rail, self.rail_dof, self.foot = plan, leg, rail_adr, rail_dof, foot_site
        self.airborne = False
        self.touchdown: float | None = None
        self.h = self.v = 0.0
        self.t_prev = 0.0
        self.h_cmd = plan.h_sit

    def height(self, t: float, data) -> float:
        p = self.plan
        if p.hop is None or t < p.t_liftoff:
            return p.height(t)
        foot_z = data.site_xpos[self.foot, 2] - self.leg.kinematics.foot_radius
        if not self.airborne and foot_z > 0.01:
            self.airborne = True
        if self.touchdown is None:
            if self.airborne and foot_z < 0.002:
                self.touchdown = t
                self.h, self.v = float(data.qpos[self.rail]), float(data.qvel[self.rail])
            elif t > p.t_liftoff + 1.5:
                return smooth(t, p.t_liftoff + 1.5, p.t_liftoff + 2.0, p.h_tuck, p.h_stand)
            else:
                return smooth(t, p.t_liftoff, p.t_liftoff + 0.08, p.h_push, p.h_tuck)
        w = 12.0
        dt = t - self.t_prev
        self.v += dt * (w * w * (p.h_stand - self.h) - 2 * w * self.v)
        self.h += dt * self.v
        return self.h

    def __call__(self, t, data):
        self.h_cmd = self.height(t, data)
        self.t_prev = t
        return self.leg.joint_command(self.h_cmd)


@dataclass
class LegRun:
    """The run's records and summary (what the test asserts on)."""

    kind: str
    actuator_line: str
    rec: dict
    timing: robot.Timing
    plan: Plan
    leg: Leg
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
            s["hop_trunk_rise"] = float(self.height[w].max() - p.h_stand)
            s["hop_foot_clearance"] = float(self.rec["probe"][w, 2].max() - self.leg.kinematics.foot_radius)
            s["hop_apex_t"] = float(self.t[w][np.argmax(self.height[w])])
            after = self.window(s["hop_apex_t"], self.t_end)
            s["landing_low"] = float(self.height[after].min())
            end = self.window(self.t_end - 0.2, self.t_end)
            s["end_err"] = float(np.abs(self.height[end] - p.h_stand).max())
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

    config = {"solver.method": method}
    if substep is not None:
        config["substep"] = repr(substep)
    model = mjplugin.load_model(MJCF, kind, timestep, config)
    data = mujoco.MjData(model)
    leg = Leg.of(model)
    hyd = mjplugin.hydraulics(MJCF)
    plan = Plan.short(leg) if short else Plan.full(duration, leg)
    t_end = 0.6 if short else duration
    jid = {j: model.joint(j).qposadr[0] for j in ("rail", *JOINTS)}
    data.qpos[jid["rail"]] = leg.h_sit
    data.qpos[jid["hip"]], data.qpos[jid["knee"]] = leg.joint_command(leg.h_sit)
    mujoco.mj_forward(model, data)
    n = len(JOINTS)
    bank, line = None, f"actuators: {n} x ehsv.actuator MuJoCo plugin (solver.method = {method})"
    if kind == "fmu":
        bank, line = robot.make_bank("fmu", n, hyd, np.zeros(n), np.zeros(n), version, method)

    foot = model.site("foot").id
    ten_adr = [model.tendon(f"{j}_cyl").id for j in JOINTS]
    controller = HopController(plan, leg, jid["rail"], model.joint("rail").dofadr[0], foot)

    def probe(d):
        # the tendons' x_rod: MuJoCo's cylinder lengths, to check the levers against
        return (
            d.qpos[jid["rail"]],
            controller.h_cmd,
            d.site_xpos[foot, 2],
            *(d.ten_length[ten_adr] - leg.levers.length_mid),
        )

    sim = mjplugin.MjcfCosim(model, data, JOINTS, leg.levers, controller, bank)
    try:
        every = max(1, round(1e-3 / model.opt.timestep))
        sim.run(t_end, record_every=every, cmd_every=every, probe=probe)
    finally:
        if bank is not None:
            bank.close()
    rec = sim.rec.arrays()
    lever_x = np.array([leg.levers.rod(q)[0] for q in rec["q"]])
    tendon_error = float(np.abs(rec["probe"][:, 3:5] - lever_x).max())
    r = LegRun(sim.kind, line, rec, sim.timing, plan, leg, t_end, hyd, tendon_error, [], [], None)
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
    times = {0.0: "sitting", p.t_up[1] + 0.3: f"standing, {p.h_stand:g} m"}
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
    ax[0].plot(t, r.rec["probe"][:, 2] - r.leg.kinematics.foot_radius, lw=0.8, label="foot clearance")
    ax[0].set_ylabel("m")
    names = JOINTS
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
    arms = "/".join(f"{lv.r * 1e3:.0f}" for lv in r.leg.levers.levers)
    ax[0].set_title(
        f"Hydraulic leg in MuJoCo, {robot.KIND_LABEL[r.kind]} actuators: {r.leg.trunk_mass:g} kg trunk "
        f"on a rail, {r.hyd.p_supply / 1e6:g} MPa, {arms} mm levers",
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
        f"  trunk height held at {r.plan.h_stand} m: mean error {s['hold_err_mean'] * 1e3:+.2f} mm, "
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
            f"{s['end_err'] * 1e3:.1f} mm of {r.plan.h_stand} m at the end"
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
    print("  " + r.timing.line(r.t_end, len(JOINTS), r.kind))


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
