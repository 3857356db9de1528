"""The README's figures command runs and finds every row inside its band (exit 0)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_figures_command_reports_every_row_inside_its_band():
    proc = subprocess.run(
        [sys.executable, str(ROOT / "cosim-examples" / "figures.py")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = [line for line in proc.stdout.splitlines() if line[:3].strip().isdigit()]
    assert len(rows) == 11 and all(line.endswith(" ok") for line in rows), proc.stdout
