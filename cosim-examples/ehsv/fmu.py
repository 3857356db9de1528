"""One instance of the FMU through fmpy's low-level classes, by variable name."""

from __future__ import annotations

import atexit
import functools
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from .paths import require_fmu

_STATUS = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
_REAL = ("Real", "Float64")
_INTEGER = ("Integer", "Enumeration", "Int64", "Int32")


@functools.cache
def _unzip(path: Path) -> str:
    """Extracts an archive once per process (removed at exit)."""
    import fmpy

    unzipdir = fmpy.extract(str(path))
    atexit.register(shutil.rmtree, unzipdir, True)
    return unzipdir


@functools.cache
def model_description(path: Path):
    """fmpy's model description of an archive, read once per process."""
    from fmpy import read_model_description

    return read_model_description(str(path))


@dataclass
class LogRecord:
    status: int
    category: str
    message: str

    def __str__(self) -> str:
        label = _STATUS[self.status] if 0 <= self.status < len(_STATUS) else str(self.status)
        return f"[{label}] [{self.category}] {self.message}"


def _dec(b) -> str:
    if b is None:
        return ""
    return b.decode("utf-8", "replace") if isinstance(b, bytes) else str(b)


@dataclass
class Ehsv:
    """One instance of the FMU, by hand, through fmpy's FMU2Slave / FMU3Slave.

    The archive is extracted once per process and its model description read once, so
    many instances (one after another or at once) cost only the instantiation. Log
    messages of the FMU are kept in ``log`` (FMI 2: our own fmi2CallbackLogger; FMI 3:
    ``FMU3Slave.instantiate(logMessage=...)``).

    The FMI 2 logger is variadic (a printf format); this FMU passes its message as the
    format with every '%' doubled and no arguments, so the callback undoes the doubling.
    fmpy's native addLoggerProxy would format arguments too, but it keeps one logger for
    the whole process: every instance's messages would go to the callback of the
    instance made last, a dangling pointer once that one is collected (a segfault seen
    when a long-lived instance logged after others had come and gone).
    """

    version: str
    logging_on: bool = False
    instance_name: str = "ehsv"
    log: list[LogRecord] = field(default_factory=list)

    def __post_init__(self):
        path = require_fmu(self.version)
        self.md = model_description(path)
        self.variables = {v.name: v for v in self.md.modelVariables}
        args = dict(
            guid=self.md.guid,
            unzipDirectory=_unzip(path),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=self.instance_name,
        )
        if self.version == "fmi2":
            self.fmu = self._instantiate_fmi2(args)
        else:
            from fmpy.fmi3 import FMU3Slave

            def log_message(_env, status, category, message):
                self.log.append(LogRecord(int(status), _dec(category), _dec(message)))

            self.fmu = FMU3Slave(**args)
            self.fmu.instantiate(loggingOn=self.logging_on, logMessage=log_message)
        fmi2 = self.version == "fmi2"
        self._get_real = self.fmu.getReal if fmi2 else self.fmu.getFloat64
        self._set_real = self.fmu.setReal if fmi2 else self.fmu.setFloat64
        self._free = False

    def _instantiate_fmi2(self, args):
        from fmpy import calloc, free
        from fmpy.fmi2 import (
            FMU2Slave,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        def logger(_env, _instance, status, category, message):
            text = _dec(message).replace("%%", "%")
            self.log.append(LogRecord(int(status), _dec(category), text))

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._callbacks = cb  # keep alive as long as the instance
        fmu = FMU2Slave(**args)
        fmu.instantiate(callbacks=cb, loggingOn=self.logging_on)
        return fmu

    # -- values by name ----------------------------------------------------------------
    def vr(self, name: str) -> int:
        try:
            return self.variables[name].valueReference
        except KeyError:
            raise KeyError(f"the FMU has no variable {name!r}") from None

    def set(self, name: str, value) -> None:
        vr = self.vr(name)
        t = self.variables[name].type
        if t in _REAL:
            self._set_real([vr], [float(value)])
        elif t == "Boolean":
            self.fmu.setBoolean([vr], [bool(value)])
        elif t in _INTEGER:
            if self.version == "fmi2":
                self.fmu.setInteger([vr], [int(value)])
            elif t == "Int32":
                self.fmu.setInt32([vr], [int(value)])
            else:
                self.fmu.setInt64([vr], [int(value)])
        else:
            raise TypeError(f"{name}: unsupported type {t}")

    def get(self, names) -> list[float]:
        """Values of the named variables (Booleans as 0.0/1.0), in the given order."""
        reals = [n for n in names if self.variables[n].type in _REAL]
        real_vals = (
            dict(zip(reals, self._get_real([self.vr(n) for n in reals]), strict=True)) if reals else {}
        )
        out = []
        for n in names:
            if n in real_vals:
                out.append(float(real_vals[n]))
            elif self.variables[n].type == "Boolean":
                out.append(float(bool(self.fmu.getBoolean([self.vr(n)])[0])))
            elif self.version == "fmi2":
                out.append(float(self.fmu.getInteger([self.vr(n)])[0]))
            else:
                out.append(float(self.fmu.getInt64([self.vr(n)])[0]))
        return out

    # -- life cycle --------------------------------------------------------------------
    def initialize(self, start_time: float = 0.0, stop_time: float | None = None, **values) -> None:
        """Sets parameters/inputs (keyword names with '.' written as '__'), then
        enters and leaves initialisation mode."""
        for k, v in values.items():
            self.set(k.replace("__", "."), v)
        if self.version == "fmi2":
            self.fmu.setupExperiment(startTime=start_time, stopTime=stop_time)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=start_time, stopTime=stop_time)
        self.fmu.exitInitializationMode()

    def do_step(self, t: float, h: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)

    def reset(self) -> None:
        """Back to the instantiated state with every start value (fmi2Reset / fmi3Reset)."""
        self.fmu.reset()

    def free(self, terminate: bool = True) -> None:
        if self._free:
            return
        self._free = True
        try:
            if terminate:
                self.fmu.terminate()
        finally:
            self.fmu.freeInstance()

    def log_text(self) -> str:
        return "\n".join(str(r) for r in self.log)


_POOL: dict[str, Ehsv] = {}


def pooled_instance(version: str) -> Ehsv:
    """This process's reusable instance of ``version``, reset to its start values (state
    Instantiated, log emptied): many runs in one process (a dask worker, a sweep) cost
    one instantiation and one extraction of the archive. The FMU is deterministic, so a
    reset instance gives the same numbers as a new one (test_sweep.py checks it)."""
    inst = _POOL.get(version)
    if inst is not None:
        try:
            inst.reset()
            inst.log.clear()
            return inst
        except Exception:  # noqa: BLE001 -- an instance that cannot reset is replaced
            _POOL.pop(version, None)
    inst = _POOL[version] = Ehsv(version)
    return inst
