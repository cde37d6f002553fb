"""Draws wire tip shapes at rest, to scale, for docs/guidewire.md ("Shaping the tip").

    python experiments/figures/tip_shapes_figure.py --wire workhorse \\
        --tip 2,45 --tip 2,60,7,40 --tip 3,75,7,40 --tip 3,75,5,60 --tip 3,75,5,50 \\
        --out docs/figures/tip_shapes.png

Each panel is the distal ``--length`` of the shaped preset's rest shape (the vertices the
scene builds the wire from, ``guidewire.wire_vertices``), the shaft along +x and the bend in
the plane of the page, with the width the scene's tip rule compares with the room in the
lumen (``GuidewireConfig.tip_lateral_offset``) and the lumen diameters of coronary calibre
for scale.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sim4endor.models import wires
from sim4endor.models.guidewire import wire_vertices

#: Lumen diameters (mm) drawn as bands for scale: the narrowest and widest of the calibre
#: folders (radii 0.8-2 mm, docs/tasks/coronary.md).
LUMEN_DIAMETERS_MM = (1.6, 4.0)


def distal(vertices: np.ndarray, length: float) -> np.ndarray:
    """The vertices within ``length`` (m, along the wire) of the distal end, in mm, the first
    of them at the origin."""
    from_tip = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(vertices[::-1], axis=0),
                                                               axis=1))])[::-1]
    kept = vertices[from_tip <= length]
    return (kept - kept[0]) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--wire", default="workhorse", help="the catalogue preset")
    parser.add_argument("--tip", action="append", required=True,
                        help="a tip shape as the command line writes it (2,60 or 2,60,7,40 or "
                             "J); repeat for more panels")
    parser.add_argument("--length", type=float, default=12.0,
                        help="distal length drawn (mm)")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    args = parser.parse_args()
    try:
        shaped = [wires.preset(args.wire, tip=tip) for tip in args.tip]
    except wires.WireCatalogueError as err:
        parser.error(str(err))
    fig, axes = plt.subplots(1, len(shaped), figsize=(2.6 * len(shaped), 2.5), squeeze=False,
                             sharey=True)
    for ax, tip, wire in zip(axes[0], args.tip, shaped, strict=True):
        points = distal(wire_vertices(wire), args.length * 1e-3)
        # The wider lumen first, so the narrower one's darker band shows on top of it.
        for diameter, shade in zip(LUMEN_DIAMETERS_MM[::-1], ("0.92", "0.8"), strict=True):
            ax.axhspan(-wire.radius * 1e3, diameter - wire.radius * 1e3, color=shade, lw=0,
                       zorder=0)
        ax.plot(points[:, 0], points[:, 1], "r-", lw=2)
        ax.plot(*points[-1, :2], "bo", ms=4)
        ax.set(aspect="equal", xlim=(-0.5, args.length + 0.5), ylim=(-0.5, 6.0))
        ax.set_title(f"{tip}: {wire.tip_lateral_offset * 1e3:.2f} mm wide", fontsize=9)
        ax.set_xlabel("mm along the shaft", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0][0].set_ylabel("mm across", fontsize=8)
    low, high = LUMEN_DIAMETERS_MM
    fig.suptitle(f"{args.wire} tips at rest, distal {args.length:g} mm; grey bands: lumens "
                 f"{low:g} and {high:g} mm across, the shaft on one wall", fontsize=9)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=100)
    print(args.out)


if __name__ == "__main__":
    main()
