"""Draws the tip-load test's force–deflection curves, for docs/guidewire.md ("Tip-load test").

    python experiments/figures/tip_load_figure.py --out docs/figures/tip_load_curves.png

One panel per rated catalogue preset: the plate force against the shortening of the 10 mm
column (``sim4endor.models.tip_load.force_deflection``), settled after every 0.05 mm step of
the clamp (the curve the rating is read on, at 5 %), the same with 10x less mass scaling, and
a push that never waits (each step read over the 50 ms that follow it), whose first contact
overshoots the rating many times. The rating and the 1.2x band are drawn across.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from sim4endor.models import tip_load, wires

#: Presets drawn: the catalogue's rated wires, softest first.
PRESETS = ("workhorse", "intermediate", "stiff")
#: Relative shortening at which the rating is read (tip_load.simulate_tip_load's default).
READ_OUT = 0.05


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    args = parser.parse_args()
    fig, axes = plt.subplots(1, len(PRESETS), figsize=(3.6 * len(PRESETS), 3.3))
    for ax, name in zip(axes, PRESETS, strict=True):
        entry = wires.entry(name)
        rated = entry.rated_tip_load_gf
        runs = (
            ("settled (the test)", entry.config, 1.0, "b-o"),
            ("settled, 10x less mass", dataclasses.replace(entry.config, mass_scale=1e3), 1.0,
             "c--"),
            ("never waiting", entry.config, 0.05, "r-"),
        )
        for label, wire, hold, style in runs:
            curve = tip_load.force_deflection(wire, hold=hold)
            forces = [tip_load.gram_force(f) for f in curve.force]
            if hold < 1.0:  # drawn off the axes: give its peak
                label += f", peak {max(forces):.0f} gf"
            ax.plot(100 * curve.shortening, forces, style, lw=1.3, ms=3, label=label)
        ax.axhline(rated, color="k", lw=0.8)
        ax.axhspan(rated, 1.2 * rated, color="0.85", lw=0)
        ax.axvline(100 * READ_OUT, color="0.5", lw=0.8, ls=":")
        ax.set_ylim(0, 3 * rated)
        ax.set_title(f"{name}: rated {rated:g} gf", fontsize=10)
        ax.set_xlabel("shortening of the 10 mm column (%)")
        ax.legend(fontsize=7, loc="upper right")
    axes[0].set_ylabel("plate force (gf)")
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=120)


if __name__ == "__main__":
    main()
