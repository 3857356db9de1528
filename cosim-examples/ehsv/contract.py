"""The FMU's interface, read from its own modelDescription.xml (no copy kept here).

The variable table in fmu-src/variables/src/variables.rs renders both archives' XML; this module
reads the FMI 2.0 archive's with ``fmpy.read_model_description`` the first time a value
is asked for, so importing the package does not need a built FMU:

* ``DRIVERS``, ``CONTROL_MODES`` and ``SOLVER_METHODS``: the enumerations, name -> integer
  value; ``ENUMERATIONS``: every enumeration variable's items the same way (variable name
  -> {item name -> value}, e.g. ``ENUMERATIONS["valve.parameterization"]["datasheet"]``;
  ``enumeration_value(name, item)`` takes an item by name or number),
* ``INPUTS``: name -> (unit, start), ``OUTPUTS``: name -> unit (None for a Boolean),
* ``NOMINAL``: every parameter's default (start) value in SI units (float, int or bool),
* ``flow_gain()``: the valve's static gain Q_valve / i_coil = K3 K1 / Kw, m3/s per A.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

from .paths import require_fmu

#: the archive whose XML is read (both carry the same table; test_compliance.py checks it)
SOURCE_VERSION = "fmi2"

#: drivers whose output switches (PWM): the coil current carries a ripple at f_pwm, so
#: their figures are taken on the mean over one PWM period (measures.period_average)
PWM_DRIVERS = ("hbridge_pid",)


@dataclass(frozen=True)
class Interface:
    drivers: dict[str, int]
    control_modes: dict[str, int]
    solver_methods: dict[str, int]
    inputs: dict[str, tuple[str | None, float]]
    outputs: dict[str, str | None]
    parameters: dict[str, float | int | bool]
    enumerations: dict[str, dict[str, int]]


def _start(var):
    """A variable's start value as a Python number (Booleans as bool)."""
    if var.type == "Boolean":
        return str(var.start).lower() in ("true", "1")
    if var.type in ("Real", "Float64"):
        return float(var.start)
    return int(var.start)


def _items(var) -> dict[str, int]:
    return {item.name: int(item.value) for item in var.declaredType.items}


@functools.cache
def interface(version: str = SOURCE_VERSION) -> Interface:
    """The interface of the built archive ``version``."""
    from fmpy import read_model_description

    md = read_model_description(str(require_fmu(version)))
    vs = md.modelVariables
    by_name = {v.name: v for v in vs}
    return Interface(
        drivers=_items(by_name["driver"]),
        control_modes=_items(by_name["control_mode"]),
        solver_methods=_items(by_name["solver.method"]),
        inputs={v.name: (v.unit, float(v.start)) for v in vs if v.causality == "input"},
        outputs={v.name: (None if v.type == "Boolean" else v.unit) for v in vs if v.causality == "output"},
        parameters={v.name: _start(v) for v in vs if v.causality == "parameter"},
        enumerations={v.name: _items(v) for v in vs if v.type == "Enumeration"},
    )


class _FromArchive(Mapping):
    """A read-only mapping filled from the archive on first use."""

    def __init__(self, field: str):
        self._field = field

    def _data(self) -> Mapping:
        return getattr(interface(), self._field)

    def __getitem__(self, key):
        return self._data()[key]

    def __iter__(self) -> Iterator:
        return iter(self._data())

    def __len__(self) -> int:
        return len(self._data())

    def __repr__(self) -> str:
        return f"<{self._field} of the FMU: {dict(self._data())!r}>"


DRIVERS: Mapping[str, int] = _FromArchive("drivers")
CONTROL_MODES: Mapping[str, int] = _FromArchive("control_modes")
SOLVER_METHODS: Mapping[str, int] = _FromArchive("solver_methods")
INPUTS: Mapping[str, tuple[str | None, float]] = _FromArchive("inputs")
OUTPUTS: Mapping[str, str | None] = _FromArchive("outputs")
NOMINAL: Mapping[str, float | int | bool] = _FromArchive("parameters")
ENUMERATIONS: Mapping[str, dict[str, int]] = _FromArchive("enumerations")


def enumeration_value(name: str, item) -> int:
    """The value of enumeration variable ``name``'s item, given by its item name or its
    number (as the plugin's config takes them); a ValueError listing the items otherwise."""
    items = ENUMERATIONS.get(name)
    if items is None:
        raise ValueError("not an enumeration")
    text = str(item).strip()
    if text in items:
        return items[text]
    if text.lstrip("-").isdigit() and int(text) in items.values():
        return int(text)
    raise ValueError(f"not one of {', '.join(f'{k} ({v})' for k, v in items.items())}")


def parameters(overrides: Mapping | None = None) -> dict:
    """The default parameters with ``overrides`` applied."""
    return {**NOMINAL, **(overrides or {})}


def method_params(method: str) -> dict:
    """The parameter that selects the integrator ``method`` ('exact' or 'fixed_cost'), to
    merge into a run's parameters (structural: set before initialisation)."""
    return {"solver.method": SOLVER_METHODS[method]}


def flow_gain(params: Mapping | None = None) -> float:
    """Static valve gain Q_valve / i_coil = K3 K1 / Kw, m3/s per A (0.025268 nominal)."""
    p = parameters(params)
    return p["valve.K3"] * p["valve.K1"] / p["valve.Kw"]
