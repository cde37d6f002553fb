"""Draws the wire's convergence against its cost, for docs/guidewire.md ("Convergence").

    python experiments/benchmarks/guidewire_convergence.py --sweep --json > sweep.jsonl
    python experiments/figures/convergence_figure.py sweep.jsonl [more.jsonl ...] \\
        --out docs/figures/convergence.png

Each JSON line of ``guidewire_convergence.py`` (a ``--sweep`` setting, or one run of the
shipped or a ``--wire`` setting) is one point pair: the mean (filled) and the largest (open)
tip difference against its 10x lighter, half-step reference, over the coronary cases, at the
setting's cost in env steps per CPU second. The issue's targets are drawn across.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

#: Issue 66's targets (mm), as in guidewire_convergence.py.
MAX_TARGET_MM = 0.5
MEAN_TARGET_MM = 0.1


def label(result: dict[str, Any]) -> str:
    """A point's name: its mass scale and step, its fidelity, or the wire fields it changed."""
    if "mass_scale" in result:
        return f"x{result['mass_scale']:.0e}, {result['timestep_s'] * 1e3:g} ms".replace("e+0", "e")
    changed = result.get("wire") or {}
    if not changed and "fidelity" in result:  # runs since the fidelities (2026-12-06)
        return f"{result['fidelity'] or 'converged'} fidelity"
    if not changed:
        return "shipped until 2026-12-06 (x1e4)"
    short = {"integrator": "", "mass_scale": "x", "damping_time": "damping ",
             "armature_time": "armature ", "contact_margin": "margin ", "max_timestep": "dt "}
    return ", ".join(f"{short.get(k, k + ' ')}{v:g}" if isinstance(v, float | int)
                     else f"{v}" for k, v in changed.items() if k in short)


def coronary_only(result: dict[str, Any]) -> dict[str, Any]:
    """The result over its coronary cases alone (the sweep runs only those)."""
    rows = [row for row in result["cases"] if row["case"].startswith("coronary")]
    return {**result,
            "tip_mean_mm": float(np.mean([row["tip_mean_mm"] for row in rows])),
            "tip_max_mm": max(row["tip_max_mm"] for row in rows),
            "env_steps_per_cpu_s": float(np.mean([row["env_steps_per_cpu_s"] for row in rows]))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("results", type=Path, nargs="+",
                        help="JSON lines of guidewire_convergence.py --json")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    args = parser.parse_args()
    results = [coronary_only(json.loads(line)) for path in args.results
               for line in path.read_text().splitlines() if line.strip()]
    fig, ax = plt.subplots(figsize=(9.0, 4.6))
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(results)))
    for result, colour in zip(results, colours, strict=True):
        cost = result["env_steps_per_cpu_s"]
        ax.plot([cost, cost], [result["tip_mean_mm"], result["tip_max_mm"]], "-",
                color=colour, lw=1)
        ax.plot(cost, result["tip_mean_mm"], "o", color=colour, label=label(result))
        ax.plot(cost, result["tip_max_mm"], "o", mfc="none", color=colour)
    ax.axhline(MAX_TARGET_MM, color="r", ls="--", lw=0.8)
    ax.axhline(MEAN_TARGET_MM, color="r", ls=":", lw=0.8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("env steps per CPU second (coronary cases)")
    ax.set_ylabel("tip difference to the reference (mm)\nfilled: mean, open: largest")
    ax.set_title("Mass scale and step against a 10x lighter, half-step reference", fontsize=10)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=120)


if __name__ == "__main__":
    main()
