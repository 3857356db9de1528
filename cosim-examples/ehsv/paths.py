"""Where the built archives are."""

from __future__ import annotations

import os
from pathlib import Path

#: the repository root (cosim-examples/ehsv/paths.py is three levels below it)
REPO = Path(__file__).resolve().parents[2]

#: where build-fmu writes the archives; EHSV_FMU_DIR overrides it (e.g. archives built from
#: a clean checkout of a commit while the working tree is being edited)
FMU_DIR = Path(os.environ.get("EHSV_FMU_DIR") or REPO / "target" / "fmu")

VERSIONS = ("fmi2", "fmi3")


def fmu_path(version: str) -> Path:
    """Archive built by build-fmu for 'fmi2' or 'fmi3'."""
    if version not in VERSIONS:
        raise ValueError(f"unknown FMI version {version!r}, expected one of {VERSIONS}")
    return FMU_DIR / f"EhsvActuator-{version}.fmu"


def missing_fmu_message(version: str) -> str | None:
    """None if the archive exists, else what to do about it."""
    path = fmu_path(version)
    if path.is_file():
        return None
    return (
        f"{path} does not exist: build the FMUs first with "
        f"`cargo run --release -p build-fmu` (scripts/test.sh does this before pytest)"
    )


def require_fmu(version: str) -> Path:
    """The archive's path; FileNotFoundError saying how to build it when it is missing."""
    msg = missing_fmu_message(version)
    if msg:
        raise FileNotFoundError(msg)
    return fmu_path(version)
