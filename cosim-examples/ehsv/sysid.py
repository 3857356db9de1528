"""The ``ehsv.actuator`` plugin's config keys as ``mujoco.sysid`` parameters (the robot path
of the calibration, docs/calibration.md).

A plugin instance's config lives in the MjSpec as ``spec.plugins[i].config``, a dict of
strings; the plugin reads it when the spec compiles. So a parameter's modifier writes its
value, as text, into the config of each instance it names and ``mujoco.sysid`` recompiles
the spec for every rollout. A value the plugin refuses fails that compile with the
plugin's own message.

* ``config_parameter(key, nominal, lo, hi, instances)``: one ``mujoco.sysid.Parameter``
  for config key ``key`` of the named instances (all ``ehsv.actuator`` instances if None:
  one physical value shared by identical cylinders),
* ``config_parameters({key: (nominal, lo, hi)}, instances)``: a ``ParameterDict`` of them,
* ``set_config(spec, instances, {key: value})``: the same write without a Parameter (e.g.
  the hidden values of a synthetic recording).

``mujoco.sysid`` needs the ``mujoco[sysid]`` extras (pinned in requirements.txt).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

PLUGIN = "ehsv.actuator"


def plugin_instances(spec, instances: Sequence[str] | None = None) -> list:
    """The spec's ``ehsv.actuator`` instances named ``instances`` (all if None); a KeyError
    names one that is not there."""
    mine = {p.name: p for p in spec.plugins if p.plugin_name == PLUGIN}
    if instances is None:
        return list(mine.values())
    missing = [n for n in instances if n not in mine]
    if missing:
        raise KeyError(f"no {PLUGIN} instance named {missing} (the spec has {sorted(mine)})")
    return [mine[n] for n in instances]


def set_config(spec, instances: Sequence[str] | None, values: Mapping[str, float | str]) -> None:
    """Writes ``values`` into the config of the named instances. The binding returns a copy
    of the dict, so the new dict is assigned rather than edited in place."""
    for plugin in plugin_instances(spec, instances):
        config = dict(plugin.config)
        config.update({k: v if isinstance(v, str) else repr(float(v)) for k, v in values.items()})
        plugin.config = config


def config_parameter(
    key: str,
    nominal: float,
    lo: float,
    hi: float,
    instances: Sequence[str] | None = None,
    name: str | None = None,
    frozen: bool = False,
):
    """A ``mujoco.sysid.Parameter`` named ``name`` (default: the key) whose modifier writes
    its value into config key ``key`` of the named instances."""
    from mujoco import sysid

    targets = None if instances is None else tuple(instances)

    def modifier(spec, param) -> None:
        set_config(spec, targets, {key: float(param.value.item())})

    return sysid.Parameter(name or key, nominal, lo, hi, frozen=frozen, modifier=modifier)


def config_parameters(keys: Mapping[str, tuple[float, float, float]], instances: Sequence[str] | None = None):
    """A ``mujoco.sysid.ParameterDict`` of ``config_parameter`` for each key's
    (nominal, lo, hi)."""
    from mujoco import sysid

    params = sysid.ParameterDict()
    for key, (nominal, lo, hi) in keys.items():
        params.add(config_parameter(key, nominal, lo, hi, instances))
    return params
