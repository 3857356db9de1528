"""Draws model.png, the FMU's icon (committed; build-fmu packs it into both archives):
a torque-motor coil on a servo valve above a cylinder with its rod.

usage: .venv/bin/python modelDescription/icon/make_icon.py   (rewrites model.png beside it)
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyBboxPatch, Rectangle  # noqa: E402

OUT = Path(__file__).with_name("model.png")
STEEL, OIL, COPPER, INK = "#b8c2cc", "#f2b441", "#c8642a", "#1f2d3a"


def main():
    fig = plt.figure(figsize=(1.28, 1.28), dpi=100)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(0, 100)
    ax.set_ylim(0, 100)
    ax.axis("off")
    box = {"linewidth": 1.5, "edgecolor": INK}
    # Torque motor: coil windings on an armature.
    ax.add_patch(Rectangle((30, 80), 40, 14, facecolor=STEEL, **box))
    for x in range(33, 68, 5):
        ax.add_patch(Rectangle((x, 82), 3, 10, facecolor=COPPER, linewidth=0))
    # Valve body with the spool.
    ax.add_patch(FancyBboxPatch((18, 56), 64, 22, boxstyle="round,pad=1", facecolor=STEEL, **box))
    ax.add_patch(Rectangle((24, 63), 52, 8, facecolor="white", **box))
    for x in (30, 46, 62):
        ax.add_patch(Rectangle((x, 63), 8, 8, facecolor=INK, linewidth=0))
    # Ports A and B down to the cylinder.
    for x in (32, 62):
        ax.add_patch(Rectangle((x, 40), 6, 16, facecolor=OIL, **box))
    # Cylinder, piston and rod.
    ax.add_patch(Rectangle((8, 14), 70, 26, facecolor=OIL, **box))
    ax.add_patch(Rectangle((44, 14), 8, 26, facecolor=STEEL, **box))
    ax.add_patch(Rectangle((52, 23), 46, 8, facecolor=STEEL, **box))
    fig.savefig(OUT, dpi=100, transparent=True)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
