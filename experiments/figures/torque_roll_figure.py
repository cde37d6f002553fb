"""Draws the S-tube roll test, free and gripped, for docs/guidewire.md ("Torque through two
bends").

    python experiments/figures/torque_roll_figure.py --out docs/figures/torque_roll.png

One panel per tapered catalogue preset, each shaped alike (``--tip``, default 2 mm at 45°) and
with the hydrophobic coat, so that only the core differs: the tip's lag behind the driver's
commanded roll (``sim4endor.benches.torque.roll_test``) against time, lying free in the bends
and gripped behind the tip by ``torque.GRIP``, with the free lag plus the wind-up the core's
integrated 1/G·J predicts for the grip, and in each title the lag the grip adds on average from
1 s to the turn's end (``torque.grip_windup_deg``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sim4endor.benches import torque
from sim4endor.models import wires

#: Presets drawn: the catalogue's tapered cores, softest first.
PRESETS = ("workhorse", "intermediate", "stiff")
#: Time between two readings of :func:`torque.roll_test` (its default ``window``, s).
WINDOW = 0.05


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--tip", default="2,45", help="the tip shape of every preset")
    parser.add_argument("--grip", type=float, default=torque.GRIP,
                        help="grip torque behind the tip (N.m)")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    args = parser.parse_args()
    if not args.grip > 0:
        parser.error(f"--grip must be positive, got {args.grip}")
    try:
        shaped = [wires.resolve({"preset": name, "coating": "hydrophobic", "tip": args.tip})
                  for name in PRESETS]
    except wires.WireCatalogueError as err:
        parser.error(str(err))
    fig, axes = plt.subplots(1, len(PRESETS), figsize=(3.6 * len(PRESETS), 3.3), sharey=True)
    for ax, name, wire in zip(axes, PRESETS, shaped, strict=True):
        free = torque.roll_test(wire)
        gripped = torque.roll_test(wire, grip=args.grip)
        time = np.arange(len(free.command_deg)) * WINDOW
        end = int(np.argmax(np.asarray(free.command_deg) >= 360.0 - 1e-9))  # the turn done
        ax.axvline(end * WINDOW, color="0.6", lw=0.8, ls=":")
        free_lag = np.asarray(free.command_deg) - np.asarray(free.tip_deg)
        ax.plot(time, free_lag, "b-", lw=1.5, label="free in the bends")
        ax.plot(time, np.asarray(gripped.command_deg) - np.asarray(gripped.tip_deg), "r-",
                lw=1.5, label=f"gripped, {args.grip * 1e6:g} µN·m")
        turn = slice(0, end + 1)
        ax.plot(time[turn], free_lag[turn] + gripped.predicted_windup_deg, "r:", lw=1.2,
                label="free + the core's 1/G·J wind-up")
        windup = torque.grip_windup_deg(free, gripped)
        ax.set_title(f"{name}\nthe grip adds {windup:.1f}° over the turn "
                     f"(1/G·J: {gripped.predicted_windup_deg:.1f}°)", fontsize=9)
        ax.set_xlabel("time (s)", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0].set_ylabel("lag: commanded minus tip roll (deg)", fontsize=8)
    axes[0].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"360° turn at 90°/s, then 2 s held (dotted: the turn's end), in the S tube "
                 f"of two 90° bends; tip {args.tip}, hydrophobic coat: only the core differs",
                 fontsize=9)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=100)
    print(args.out)


if __name__ == "__main__":
    main()
