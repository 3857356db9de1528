"""Every config key of the ehsv.actuator plugin, one at a time, at hostile values: the ends
of its range, just inside and outside them, +-1e-300, +-1e300, 0, nan, +-inf and text (an
enumeration's items too). Each value is either refused when the model compiles, with a
message naming the key, or the model compiles and 20 mj_steps of 1e-3 s (the plugin
sub-steps them at ``substep``) finish. Issue 44: ``substep`` = 1e-300 was accepted and made
the first mj_step run forever.

The keys are the FMU's parameters and the inputs the host does not drive (read from the
built archive's modelDescription.xml, which the same table renders), plus the plugin's own
``substep`` and ``length_mid``. Each key is tried where it matters (an ``hbridge.*`` key
with the H-bridge driver, ``position.*`` in position control, ...), with a command that
moves the rod.

The cases run in one child process, each under an alarm: a case that hangs kills the
child (SIGALRM), is reported as hung, and a new child takes the cases after it, so a hang
fails the test instead of stalling CI. ``LIMIT_S`` is a robustness bound, not a speed
assertion (a case takes milliseconds).

Both solver methods (``solver.method`` itself and ``solver.h_internal`` once). By hand,
more values (each decade of the range) at three host timesteps (1e-4, 1e-3 and 1e-2 s),
50 steps each, with counts and the slowest cases:

    .venv/bin/python tests/python/test_mujoco_config_fuzz.py --many
"""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from dataclasses import dataclass

#: longest a case may take (compile and steps); it takes milliseconds
LIMIT_S = 20
#: a safety net behind the alarms: longest one child may run (the CI cases take seconds)
BATCH_LIMIT_S = 1800
#: MuJoCo steps after a successful compile, and the host's timestep (s)
STEPS = 20
TIMESTEP = 1e-3
#: inputs the host drives (the control, the transmission) or that the motion port ignores:
#: not config keys (docs/mujoco.md)
HOST_DRIVEN = ("i_ref", "Q_ref", "x_ref", "x_rod", "v_rod", "F_ext")
#: the plugin's default where it is not the FMU's start value: a MuJoCo actuator is the
#: motion port (1)
PLUGIN_DEFAULTS = {"cylinder.port": 1.0}
#: the plugin's own keys: (min, max, default); mujoco-plugin/src/config.rs
OWN_KEYS = {"substep": (1e-6, 0.01, 1e-4), "length_mid": (None, None, 0.0)}
#: what a key's prefix needs to matter: the driver or control mode it belongs to
CONTEXT = {
    "industrial": {"driver": "industrial"},
    "hbridge": {"driver": "hbridge_pid"},
    "flow": {"control_mode": "flow"},
    "loop": {"control_mode": "position"},
    "position": {"control_mode": "position"},
    "solver.h_internal": {"solver.method": "fixed_cost"},
}
#: the command (ctrl) that moves the rod in each control mode: 5 mA, 1e-4 m3/s, 5 mm
COMMAND = {"current": 5e-3, "flow": 1e-4, "position": 5e-3}
HOSTILE = [1e-300, -1e-300, 1e300, -1e300, 0.0, math.nan, math.inf, -math.inf, "wide"]

MODEL = """<mujoco><option timestep="{timestep}"/>
<extension><plugin plugin="ehsv.actuator"/></extension>
<worldbody><body><joint name="s" type="slide" axis="1 0 0"/>
<geom type="box" size=".1 .1 .1" mass="5"/></body></worldbody>
<actuator><plugin plugin="ehsv.actuator" joint="s">{config}</plugin></actuator></mujoco>"""


@dataclass(frozen=True)
class Key:
    name: str
    lo: float | None
    hi: float | None
    start: float
    #: an enumeration's item names (empty for reals and Booleans)
    items: tuple[str, ...] = ()


def config_keys() -> list[Key]:
    """The plugin's config keys with their ranges and defaults, in the table's order."""
    from fmpy import read_model_description

    from ehsv.paths import require_fmu

    keys = []
    for v in read_model_description(str(require_fmu("fmi2"))).modelVariables:
        if v.causality not in ("parameter", "input") or v.name in HOST_DRIVEN:
            continue
        if v.type == "Boolean":
            keys.append(Key(v.name, 0.0, 1.0, float(str(v.start).lower() in ("true", "1"))))
            continue
        items = tuple(i.name for i in v.declaredType.items) if v.type == "Enumeration" else ()
        lo, hi = (None if x is None else float(x) for x in (v.min, v.max))
        if items:
            lo, hi = 0.0, float(len(items) - 1)
        keys.append(Key(v.name, lo, hi, PLUGIN_DEFAULTS.get(v.name, float(v.start)), items))
    keys += [Key(name, lo, hi, start) for name, (lo, hi, start) in OWN_KEYS.items()]
    return keys


def values(key: Key, many: bool = False) -> list:
    """The values tried for ``key``: its default, the ends of its range and just beyond and
    within them, the hostile ones, an enumeration's items by name; with ``many`` also each
    decade of the range. Duplicates dropped."""
    out: list = [key.start, *HOSTILE, *key.items]
    for bound in (key.lo, key.hi):
        if bound is not None:
            nudge = 1e-9 * abs(bound) if bound else 1e-12
            out += [bound, bound - nudge, bound + nudge]
    if key.items:
        out += [0.5, len(key.items)]
    if many and key.lo is not None and key.hi is not None:
        lo, hi = max(abs(key.lo), 1e-12), max(abs(key.hi), 1e-12)
        out += [
            s * 10.0**k
            for k in range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1)
            for s in (1, -1)
        ]
        out += [0.5 * (key.lo + key.hi)]
    seen, unique = set(), []
    for v in out:
        text = v if isinstance(v, str) else repr(float(v))
        if text not in seen:
            seen.add(text)
            unique.append(text)
    return unique


def context(name: str) -> dict[str, str]:
    """The other keys that make ``name`` matter (its driver, control mode or method)."""
    out = {k: v for k, v in CONTEXT.get(name.split(".")[0], {}).items() if k != name}
    return {**out, **CONTEXT.get(name, {})}


def cases(keys: list[Key], many: bool = False) -> list[dict]:
    """One case per key, value and solver method (by hand, ``many``: more values, the host
    timesteps 1e-4, 1e-3 and 1e-2 s, 50 steps each; the limit grows with the time
    simulated)."""
    timesteps, steps = ((1e-4, 1e-3, 1e-2), 50) if many else ((TIMESTEP,), STEPS)
    out = []
    for key in keys:
        config = context(key.name)
        ctrl = COMMAND[config.get("control_mode", "current")]
        fixed = key.name == "solver.method" or "solver.method" in config
        for method in (None,) if fixed else ("exact", "fixed_cost"):
            method_config = config if method is None else {**config, "solver.method": method}
            for timestep in timesteps:
                for value in values(key, many):
                    case = {"key": key.name, "value": value, "config": {**method_config, key.name: value}}
                    limit = math.ceil(LIMIT_S * max(1.0, steps * timestep / (STEPS * TIMESTEP)))
                    out.append({**case, "ctrl": ctrl, "timestep": timestep, "steps": steps, "limit": limit})
    return out


def run_case(mujoco, case: dict) -> dict:
    """Compiles the case's model and, if it compiles, steps it: what happened."""
    config = "".join(f'<config key="{k}" value="{v}"/>' for k, v in case["config"].items())
    xml = MODEL.format(timestep=case["timestep"], config=config)
    t0 = time.perf_counter()
    try:
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
    except Exception as e:  # the compile refuses: ValueError with the plugin's message
        message = str(e)
        return {"outcome": "refused", "named": case["key"] in message, "message": message[:300]}
    warnings: list[str] = []
    mujoco.set_mju_user_warning(warnings.append)
    try:
        data.ctrl[0] = case["ctrl"]
        for _ in range(case["steps"]):
            mujoco.mj_step(model, data)
    finally:
        mujoco.set_mju_user_warning(None)
    return {
        "outcome": "stepped",
        "seconds": time.perf_counter() - t0,
        "refused_steps": sum("ehsv.actuator" in w for w in warnings),
        "warning": next((w[:300] for w in warnings if "ehsv.actuator" in w), ""),
        "other_warnings": sum("ehsv.actuator" not in w for w in warnings),
        "finite": bool(all(math.isfinite(x) for x in [*data.qpos, *data.actuator_force])),
    }


def worker() -> None:
    """The child: cases as JSON on stdin, one result line each on stdout, each case under
    an alarm whose default action ends the process (a hang inside MuJoCo or the plugin
    never returns to Python, so a handler could not run)."""
    import mujoco

    from ehsv import mjplugin

    mjplugin.load_plugin()
    signal.signal(signal.SIGALRM, signal.SIG_DFL)
    for i, case in json.load(sys.stdin):
        signal.alarm(case["limit"])
        result = run_case(mujoco, case)
        signal.alarm(0)
        print(json.dumps({"i": i, **result}), flush=True)


def run_all(all_cases: list[dict]) -> list[dict]:
    """Every case's result, in order; a case that killed its child by the alarm is "hung"
    (one that crashed it "crashed"), and a new child goes on after it."""
    results: dict[int, dict] = {}
    todo = list(enumerate(all_cases))
    while todo:
        proc = subprocess.run(
            [sys.executable, __file__, "--worker"],
            input=json.dumps(todo),
            capture_output=True,
            text=True,
            timeout=BATCH_LIMIT_S,
        )
        for line in proc.stdout.splitlines():
            result = json.loads(line)
            results[result.pop("i")] = result
        todo = [(i, c) for i, c in todo if i not in results]
        if todo:
            outcome = "hung" if proc.returncode == -signal.SIGALRM else "crashed"
            results[todo[0][0]] = {"outcome": outcome, "stderr": proc.stderr[-500:]}
            todo = todo[1:]
    return [{**case, **results[i]} for i, case in enumerate(all_cases)]


def failures(results: list[dict]) -> list[str]:
    """The cases that break the rule (a value is refused with a message naming its key, or
    the steps finish): refused without naming it, hung, crashed."""
    bad = []
    for r in results:
        what = f"{r['key']} = {r['value']} ({r['config']}, timestep {r['timestep']})"
        if r["outcome"] == "refused" and not r["named"]:
            bad.append(f"{what}: refused without naming the key: {r['message']}")
        elif r["outcome"] not in ("refused", "stepped"):
            bad.append(f"{what}: {r['outcome']} {r.get('stderr', '')}")
    return bad


def summary(results: list[dict]) -> str:
    stepped = [r for r in results if r["outcome"] == "stepped"]
    counts = {
        "cases": len(results),
        "refused": sum(r["outcome"] == "refused" for r in results),
        "stepped": len(stepped),
        "stepped with refused steps": sum(r["refused_steps"] > 0 for r in stepped),
        "stepped, not finite": sum(not r["finite"] for r in stepped),
        "hung": sum(r["outcome"] == "hung" for r in results),
        "crashed": sum(r["outcome"] == "crashed" for r in results),
    }
    slowest = sorted(stepped, key=lambda r: -r["seconds"])[:8]
    lines = [", ".join(f"{k} {v}" for k, v in counts.items()), "slowest stepped cases:"]
    lines += [
        f"  {r['seconds']:.3f} s  {r['key']} = {r['value']}  {r['config']}  dt {r['timestep']}"
        for r in slowest
    ]
    return "\n".join(lines)


def test_every_config_key_refuses_or_steps_at_hostile_values():
    import pytest

    from ehsv import mjplugin
    from ehsv.paths import missing_fmu_message

    missing = mjplugin.plugin_missing() or missing_fmu_message("fmi2")
    if missing:
        pytest.fail(missing, pytrace=False)
    keys = config_keys()
    results = run_all(cases(keys))
    bad = failures(results)
    assert not bad, "\n".join(bad[:30]) + "\n" + summary(results)
    defaults = {key.name: repr(key.start) for key in keys}
    for r in results:
        if r["value"] == defaults[r["key"]]:
            assert r["outcome"] == "stepped", f"{r['key']}'s default does not step: {r}"
        if r["value"] in ("nan", "inf", "-inf", "wide") or r["key"] == "substep" and r["value"] == "1e-300":
            assert r["outcome"] == "refused", f"{r['key']} = {r['value']} is accepted"
    print(summary(results))


if __name__ == "__main__":
    if sys.argv[1:] == ["--worker"]:
        worker()
    else:
        t0 = time.perf_counter()
        all_results = run_all(cases(config_keys(), many="--many" in sys.argv))
        print(summary(all_results))
        print("\n".join(failures(all_results)) or "no failures", f"({time.perf_counter() - t0:.0f} s)")
