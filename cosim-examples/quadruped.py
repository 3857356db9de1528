"""A HyQ-like hydraulic quadruped in MuJoCo: 12 joints, each driven by an EhsvActuator cylinder.

The robot is cosim-examples/mjcf/quadruped.xml: a trunk on a free joint, four legs (hip
abduction/adduction HAA, hip flexion HFE, knee KFE; front knees pointing back, hind knees
forward, as HyQ stands), each joint driven by one cylinder through a lever (the spatial
tendon between its pivots), the ehsv.actuator plugin's position loop on each rod.
Everything the controller needs of the robot is read from the loaded model
(``Quadruped.of``): the levers, each leg's hip position, link lengths, foot and knee
direction, the trunk's height in the file (the crouch it starts from) and in the "stand"
keyframe. The co-simulation steps at MuJoCo's timestep (1e-4 s in the file): mj_step1 ->
the 12 rods' commands x_ref -> mj_step2 (the plugin steps the actuators inside it; with
--actuator fmu the 12 FMUs step between, on the same tendons); the joint commands at
1 kHz.

The run: from the crouch stand up to the stance, hold it, trot in
place for 5 s (diagonal pairs LF+RH and RF+LH lift in alternation at 1.75 Hz, 5 cm foot
lift, 45 % swing), with a proportional attitude feedback that lengthens the legs on the low side,
then stand. Prints the base height and attitude, the rod force peaks, the real-time
factor and where the wall time goes (MuJoCo, the actuator calls, Python); writes
out/quadruped.png (base height, roll, pitch, the 12 rod forces) and, where a GL context
can be made, out/quadruped_render.png.

    .venv/bin/python cosim-examples/quadruped.py [--duration 8.5] [--short]
        [--actuator plugin|fmu] [--timestep 1e-4] [--method exact|fixed_cost|both] [--fmi3] [--no-render]

--method sets the FMU's solver.method; both runs the same scenario with exact, then
fixed_cost, and prints their real-time factors and figures side by side.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ehsv import cli, mjplugin, robot
from ehsv.robot import Hydraulics, LeverSet, smooth

LEGS = ("LF", "RF", "LH", "RH")
#: trot pairs: LF + RH swing together, then RF + LH
PAIR = {"LF": 0, "RH": 0, "RF": 1, "LH": 1}
JOINTS = tuple(f"{leg}_{j}" for leg in LEGS for j in ("haa", "hfe", "kfe"))
MJCF = mjplugin.MJCF_DIR / "quadruped.xml"


@dataclass(frozen=True)
class Quadruped:
    """What the controller and the reports need of the robot, read from the model."""

    legs: tuple[robot.LegKinematics, ...]  # in LEGS' order
    levers: LeverSet  # joint angles -> rod positions, in JOINTS' order
    h_crouch: float  # the trunk's height in the file: the pose a run starts from
    h_stand: float  # the "stand" keyframe's trunk height
    mass: float

    @staticmethod
    def of(model) -> Quadruped:
        trunk = model.body("trunk")
        z = model.joint("base").qposadr[0] + 2  # the free joint's position z
        return Quadruped(
            legs=tuple(
                robot.LegKinematics.of(model, "trunk", f"{n}_hfe", f"{n}_kfe", f"{n}_foot") for n in LEGS
            ),
            levers=robot.lever_set(model, JOINTS, mjplugin.length_mid(MJCF)),
            h_crouch=float(model.qpos0[z]),
            h_stand=float(model.key("stand").qpos[z]),
            mass=float(model.body_subtreemass[trunk.id]),
        )

    def stance(self, heights) -> np.ndarray:
        """Joint angles (JOINTS' order) with every foot under its hip, HAA at 0, leg i at
        trunk height ``heights[i]`` (one height for all: a level stance)."""
        q = np.zeros(len(JOINTS))
        for i, (leg, h) in enumerate(zip(self.legs, np.broadcast_to(heights, len(self.legs)), strict=True)):
            q[3 * i + 1 : 3 * i + 3] = leg.angles(float(h))
        return q


@dataclass(frozen=True)
class Plan:
    t_up: tuple[float, float]
    trot: tuple[float, float] | None
    h_crouch: float  # the heights it starts from and stands at (the model's: Quadruped)
    h_stand: float
    f_trot: float = 1.75
    lift: float = 0.05
    swing: float = 0.45  # fraction of the period a foot is in the air
    k_att: float = 1.0  # attitude feedback: leg length per (rad x m from the centre)

    @staticmethod
    def full(duration: float, quad: Quadruped) -> Plan:
        # whole cycles (both pairs' feet down at the end), 5 s or what the duration leaves
        cycles = math.floor(min(5.0, duration - 3.0) * Plan.f_trot + 0.5)
        trot = (2.5, 2.5 + cycles / Plan.f_trot) if cycles > 0 else None
        return Plan(t_up=(0.2, 1.2), trot=trot, h_crouch=quad.h_crouch, h_stand=quad.h_stand)

    @staticmethod
    def short(quad: Quadruped) -> Plan:
        """Standing from the start."""
        return Plan(t_up=(0.0, 0.0), trot=None, h_crouch=quad.h_crouch, h_stand=quad.h_stand)

    def height(self, t: float) -> float:
        return smooth(t, *self.t_up, self.h_crouch, self.h_stand)

    def foot_lift(self, t: float, pair: int) -> float:
        if self.trot is None or not (self.trot[0] <= t < self.trot[1]):
            return 0.0
        ph = ((t - self.trot[0]) * self.f_trot + 0.5 * pair) % 1.0
        if ph >= self.swing:
            return 0.0
        return self.lift * math.sin(math.pi * ph / self.swing) ** 2


def attitude(q: np.ndarray) -> tuple[float, float]:
    """Roll and pitch (rad) of the quaternion w, x, y, z."""
    w, x, y, z = q
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    return roll, pitch


class TrotController:
    """Joint commands at 1 kHz: each foot under its hip at the plan's height, the swing
    pair's feet lifted, and every leg lengthened by k (x_i pitch - y_i roll): a foot on
    the low side pushes the trunk level. (A derivative term on the body rates made the
    legs chatter: the rates carry the hydraulic resonances; the trot needs none.)"""

    def __init__(self, plan: Plan, quad: Quadruped):
        self.plan, self.quad = plan, quad
        self.h = plan.h_crouch

    def __call__(self, t, data) -> np.ndarray:
        p = self.plan
        roll, pitch = attitude(data.qpos[3:7])
        self.h = p.height(t)
        heights = [
            self.h - p.foot_lift(t, PAIR[name]) + p.k_att * (pitch * leg.hip[0] - roll * leg.hip[1])
            for name, leg in zip(LEGS, self.quad.legs, strict=True)
        ]
        return self.quad.stance(heights)


@dataclass
class QuadRun:
    kind: str
    actuator_line: str
    rec: dict
    timing: robot.Timing
    plan: Plan
    quad: Quadruped
    t_end: float
    hyd: Hydraulics
    fell: bool
    frames: list = field(default_factory=list)
    frame_labels: list = field(default_factory=list)
    render_error: str | None = None

    @property
    def t(self):
        return self.rec["t"]

    def window(self, t0, t1):
        return (self.t >= t0) & (self.t < t1)

    def summary(self) -> dict:
        pr = self.rec["probe"]
        z, hc, roll, pitch = pr[:, 0], pr[:, 1], pr[:, 2], pr[:, 3]
        s = {}
        p = self.plan
        stance = self.window(p.t_up[1] + 0.3, p.trot[0] if p.trot else self.t_end)
        s["stance_z"] = float(z[stance].mean()) if stance.any() else math.nan
        s["stance_err_max"] = float(np.abs(z[stance] - hc[stance]).max()) if stance.any() else math.nan
        s["stance_tilt_max"] = (
            float(np.degrees(np.maximum(np.abs(roll[stance]), np.abs(pitch[stance])).max()))
            if stance.any()
            else math.nan
        )
        w = self.window(*p.trot) if p.trot else np.zeros(0, bool)
        if w.any():
            s["trot_z"] = (float(z[w].min()), float(z[w].max()))
            s["trot_roll_max"] = float(np.degrees(np.abs(roll[w]).max()))
            s["trot_pitch_max"] = float(np.degrees(np.abs(pitch[w]).max()))
            s["trot_drift"] = float(np.hypot(*(pr[w, 4:6][-1] - pr[w, 4:6][0])))
        F = self.rec["F"]
        s["F_max"], s["F_min"] = float(F.max()), float(F.min())
        s["F_absmax_by_joint"] = {
            kind: float(np.abs(F[:, j::3]).max()) for j, kind in enumerate(("haa", "hfe", "kfe"))
        }
        s["p_max"] = float(max(self.rec["p_A"].max(), self.rec["p_B"].max()))
        s["x_rod_absmax"] = float(np.abs(self.rec["x_rod"]).max())
        s["rtf"] = self.t_end / self.timing.wall
        return s


def run(
    duration: float = 8.5,
    short: bool = False,
    kind: str = "plugin",
    version: str = "fmi2",
    render: bool = True,
    method: str = "exact",
    timestep: float | None = None,
    substep: float | None = None,
) -> QuadRun:
    """The run on MJCF (``MJCF``) with ``kind`` "plugin" actuators or "fmu" (the reference);
    ``timestep`` replaces MuJoCo's 1e-4 s (the plugin sub-steps at ``substep``)."""
    if render:
        robot.gl_backend()
    import mujoco

    config = {"solver.method": method}
    if substep is not None:
        config["substep"] = repr(substep)
    model = mjplugin.load_model(MJCF, kind, timestep, config)
    data = mujoco.MjData(model)
    quad = Quadruped.of(model)
    hyd = mjplugin.hydraulics(MJCF)
    plan = Plan.short(quad) if short else Plan.full(duration, quad)
    t_end = 0.4 if short else duration
    ctrl = initial_pose(model, data, plan, quad)
    n = len(JOINTS)
    bank, line = None, f"actuators: {n} x ehsv.actuator MuJoCo plugin (solver.method = {method})"
    if kind == "fmu":
        bank, line = robot.make_bank("fmu", n, hyd, np.zeros(n), np.zeros(n), version, method)

    def probe(d):
        roll, pitch = attitude(d.qpos[3:7])
        return (d.qpos[2], ctrl.h, roll, pitch, d.qpos[0], d.qpos[1])

    def fallen(d):
        return d.qpos[2] < 0.2 or abs(d.qpos[4]) > 0.5 or abs(d.qpos[5]) > 0.5

    sim = mjplugin.MjcfCosim(model, data, JOINTS, quad.levers, ctrl, bank)
    try:
        every = max(1, round(1e-3 / model.opt.timestep))
        sim.run(t_end, record_every=every, cmd_every=every, probe=probe, stop=fallen)
    finally:
        if bank is not None:
            bank.close()
    rec = sim.rec.arrays()
    fell = data.time < t_end - 1e-3
    r = QuadRun(sim.kind, line, rec, sim.timing, plan, quad, float(data.time), hyd, fell)
    if render:
        render_frames(model, r)
    return r


def initial_pose(model, data, plan: Plan, quad: Quadruped) -> TrotController:
    """Puts the robot in the plan's first pose (its height at t = 0, level, the
    controller's joint commands at t = 0); returns the controller."""
    import mujoco

    ctrl = TrotController(plan, quad)
    data.qpos[2] = plan.height(0.0)
    q0 = ctrl(0.0, data)
    for j, name in enumerate(JOINTS):
        data.qpos[model.joint(name).qposadr[0]] = q0[j]
    mujoco.mj_forward(model, data)
    return ctrl


def render_frames(model, r: QuadRun) -> None:
    cam = robot.Camera(model, 420, 560, lookat=(0, 0, 0.35), distance=2.4, azimuth=145, elev=-16)
    if cam.renderer is None:
        r.render_error = cam.error
        return
    p = r.plan
    times = {0.0: "crouch", p.t_up[1] + 0.5: "standing"}
    if p.trot:
        t0 = p.trot[0] + 2.0
        times[t0 + 0.25 * p.swing / p.f_trot * 2] = "trot, LF+RH up"
        times[t0 + (0.5 + 0.25 * p.swing * 2) / p.f_trot] = "trot, RF+LH up"
    # A run that fell ended early: no pictures of what it did not reach.
    reached = {t: label for t, label in times.items() if t <= r.t[-1]}
    cam.capture(model, r, reached, track_body=model.body("trunk").id)


def plot(r: QuadRun, out: Path) -> None:
    import ehsv

    plt = ehsv.pyplot()
    t = r.t
    pr = r.rec["probe"]
    fig, ax = plt.subplots(5, 1, sharex=True, figsize=(9, 11))
    ax[0].plot(t, pr[:, 0], label="base height")
    ax[0].plot(t, pr[:, 1], "--", lw=0.9, label="height command")
    ax[0].set_ylabel("m")
    ax[1].plot(t, np.degrees(pr[:, 2]), label="roll")
    ax[1].plot(t, np.degrees(pr[:, 3]), label="pitch")
    ax[1].set_ylabel("deg")
    F = r.rec["F"] / 1e3
    push, pull = r.hyd.stall_force()
    for a, j, kind in zip(ax[2:], range(3), ("HAA", "HFE", "knee"), strict=True):
        for i, (name, leg) in enumerate(zip(LEGS, r.quad.legs, strict=True)):
            a.plot(t, F[:, 3 * i + j], "-" if leg.bend < 0 else "--", lw=0.8, label=name)
        for f in (push, pull):
            a.axhline(f / 1e3, color="grey", lw=0.6, ls="--")
        a.set_ylabel(f"{kind} F_rod, kN")
    ax[-1].set_xlabel("time, s")
    if r.plan.trot:
        for a in ax:
            a.axvspan(*r.plan.trot, color="0.92", zorder=0)
    for a in ax:
        a.legend(fontsize=7, ncol=4, loc="upper right")
        a.grid(alpha=0.3)
    ax[0].set_title(
        f"Hydraulic quadruped in MuJoCo, {len(JOINTS)} {robot.KIND_LABEL[r.kind]} actuators "
        f"({r.quad.mass:.0f} kg, {r.hyd.p_supply / 1e6:g} MPa); trot shaded, -- stall",
        fontsize=10,
    )
    cli.write_figure(fig, out)
    plt.close(fig)


def report(r: QuadRun) -> None:
    s = r.summary()
    print(r.actuator_line)
    print(
        f"supply {r.hyd.p_supply / 1e6:g} MPa, relief {r.hyd.p_crack / 1e6:g} MPa, "
        f"position.Kp {r.hyd.Kp:g} A/m"
    )
    if r.fell:
        print(f"  FELL at t = {r.t_end:.2f} s")
    print(
        f"  stance: base at {s['stance_z']:.4f} m (command {r.plan.h_stand} m, largest error "
        f"{s['stance_err_max'] * 1e3:.1f} mm), tilt within {s['stance_tilt_max']:.2f} deg"
    )
    if "trot_z" in s:
        p = r.plan
        print(
            f"  trot {p.trot[1] - p.trot[0]:.1f} s at {p.f_trot} Hz, {p.lift * 1e3:.0f} mm lift: base "
            f"{s['trot_z'][0]:.3f} .. {s['trot_z'][1]:.3f} m, roll within {s['trot_roll_max']:.1f} deg, "
            f"pitch within {s['trot_pitch_max']:.1f} deg, drift {s['trot_drift'] * 1e3:.0f} mm"
        )
    fj = s["F_absmax_by_joint"]
    print(
        f"  rod force peaks |F|: HAA {fj['haa']:.0f} N, HFE {fj['hfe']:.0f} N, knee {fj['kfe']:.0f} N "
        f"(stall {r.hyd.stall_force()[0]:.0f} N push); chamber pressure peak {s['p_max'] / 1e6:.2f} MPa; "
        f"rods within +-{s['x_rod_absmax'] * 1e3:.1f} mm"
    )
    print("  " + r.timing.line(r.t_end, len(JOINTS), r.kind))


def figures(r: QuadRun) -> dict[str, str]:
    """The holding and tracking figures of ``report``, for the side-by-side table."""
    s = r.summary()
    out = {
        "fell": "yes" if r.fell else "no",
        "stance: base height, m": f"{s['stance_z']:.4f}",
        "stance: largest error, mm": f"{s['stance_err_max'] * 1e3:.1f}",
        "stance: tilt within, deg": f"{s['stance_tilt_max']:.2f}",
    }
    if "trot_z" in s:
        out["trot: base, m"] = f"{s['trot_z'][0]:.3f}..{s['trot_z'][1]:.3f}"
        out["trot: roll within, deg"] = f"{s['trot_roll_max']:.1f}"
        out["trot: pitch within, deg"] = f"{s['trot_pitch_max']:.1f}"
        out["trot: drift, mm"] = f"{s['trot_drift'] * 1e3:.0f}"
    out["pressure peak, MPa"] = f"{s['p_max'] / 1e6:.2f}"
    return out


def main(argv=None) -> int:
    ap = robot.parser(__doc__, 8.5, "0.4 s standing from the stance (the test's run)", "quadruped.png")
    runs = robot.run_example(ap.parse_args(argv), run, report, plot, figures)
    return 1 if runs is None or any(r.fell for r in runs.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
