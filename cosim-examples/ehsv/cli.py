"""What the example commands share: the --fmi3 switch, the archive check, the out/ folder
and the line naming each figure written."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .paths import REPO, missing_fmu_message
from .plotting import save_figure

#: where the examples write their figures and tables unless told otherwise
OUT_DIR = REPO / "out"


def parser(doc: str) -> argparse.ArgumentParser:
    """An example's command line: the first line of its docstring ``doc`` and --fmi3."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--fmi3", action="store_true", help="use the FMI 3.0 archive")
    return ap


def version(args) -> str:
    """The FMI version --fmi3 chose: 'fmi3', else 'fmi2'."""
    return "fmi3" if args.fmi3 else "fmi2"


def archive_missing(version: str) -> bool:
    """True, after saying on stderr how to build it, when the archive is not built."""
    msg = missing_fmu_message(version)
    if msg:
        print(msg, file=sys.stderr)
    return msg is not None


def write_figure(fig, out: Path) -> None:
    """Writes ``fig`` to ``out`` and says where."""
    save_figure(fig, out)
    print(f"figure: {out}")
