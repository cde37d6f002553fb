"""Coronary-calibre vessel folders built as a user builds them, from the lumen mesh alone.

For each seed S of ``--seeds A-B`` it generates a two-level random coronary tree at one of the
issue's two calibres (radii 0.8-2 mm) and then builds its ``lumen.stl`` again with ``sim4endor
vessel build``, the centreline extracted from the mesh, the inlet and the targets given at the
generated folder's manifest coordinates (metres)::

    sim4endor vessel generate coronary_tree --seed S --set levels=2 \
        --set root_radius=R --set min_radius=M --out TMP/gS
    sim4endor vessel build TMP/gS/lumen.stl --units m --name ubS --out OUT/ubS \
        --inlet X,Y,Z --target T1=X,Y,Z ...

``--calibre narrow`` is the issue's example calibre (root radius 1.6 mm, smallest 0.85 mm),
``--calibre wide`` its whole range (2 mm to 0.8 mm). Both commands run through the command
line's own entry point (:func:`sim4endor.cli.main`), in this process. It prints, per folder,
its hull count, lumen-open and wall-closed fractions and build time (the manifest's checks); a
seed whose folder already holds a manifest is not rebuilt. A build below the acceptance checks
writes nothing: its seed is named at the end (exit status 1), and ``--allow-below-acceptance``
keeps it as the command line's flag does (seed 3203, lumen open 0.9845). This is how the
calibre folders 3100-3195 of docs/tasks/coronary.md were made; run the expert on them with
``expert_reachability.py --domain vessel --vessels OUT/ub... --starts 2``.

Usage:
    python experiments/benchmarks/calibre_folders.py --seeds 3200-3211 --calibre narrow \
        --out /tmp/calibre [--tmp /tmp/calibre_generated]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from sim4endor import cli

#: ``--calibre``: the generator's (root_radius, min_radius) in metres.
CALIBRES: dict[str, tuple[float, float]] = {
    "narrow": (0.0016, 0.00085),
    "wide": (0.002, 0.0008),
}


def seed_range(text: str) -> range:
    """Parses ``A-B`` (inclusive) or a single seed ``A``.

    Raises:
        argparse.ArgumentTypeError: For anything else, or ``B < A``.
    """
    first, sep, last = text.partition("-")
    try:
        low = int(first)
        high = int(last) if sep else low
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected A-B (seeds), got {text!r}") from None
    if high < low:
        raise argparse.ArgumentTypeError(f"expected A <= B, got {text!r}")
    return range(low, high + 1)


def generate_command(seed: int, calibre: str, out: Path) -> list[str]:
    """Returns the ``sim4endor`` arguments that generate tree ``seed`` at ``calibre``."""
    root_radius, min_radius = CALIBRES[calibre]
    return ["vessel", "generate", "coronary_tree", "--seed", str(seed), "--set", "levels=2",
            "--set", f"root_radius={root_radius}", "--set", f"min_radius={min_radius}",
            "--out", str(out), "--no-progress"]


def build_command(generated: Path, name: str, out: Path, below_acceptance: bool = False
                  ) -> list[str]:
    """Returns the ``sim4endor`` arguments that build ``generated``'s lumen as a user would.

    The inlet and the targets are the generated folder's manifest coordinates (metres, so
    ``--units m`` takes them as they are); nothing else of that folder is passed on.
    ``below_acceptance`` adds ``--allow-below-acceptance``.
    """
    manifest = json.loads((generated / "manifest.json").read_text())
    point = ",".join(repr(float(v)) for v in manifest["inlet"]["position"])
    command = ["vessel", "build", str(generated / "lumen.stl"), "--units", "m", "--name", name,
               "--out", str(out), "--inlet", point, "--no-progress"]
    for target, position in sorted(manifest["targets"].items()):
        command += ["--target", f"{target}=" + ",".join(repr(float(v)) for v in position)]
    return command + (["--allow-below-acceptance"] if below_acceptance else [])


def folder_row(folder: Path, seconds: float | None) -> str:
    """Returns the line printed for a built folder: hulls, checks and build time."""
    manifest = json.loads((folder / "manifest.json").read_text())
    checks = manifest.get("checks", {})
    wall = "" if seconds is None else f", {seconds:.1f} s in all (generate + build)"
    return (f"{folder.name}: {manifest.get('hull_count')} hulls, lumen open "
            f"{checks.get('lumen_open', float('nan')):.4f}, wall closed "
            f"{checks.get('wall_closed', float('nan')):.4f}, build "
            f"{checks.get('build_time_s', float('nan')):.1f} s, targets "
            f"{sorted(manifest.get('targets', {}))}{wall}")


def main() -> None:
    """Generates and builds the folders of ``--seeds``, printing a line per folder."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=seed_range, required=True, metavar="A-B",
                        help="tree seeds, inclusive")
    parser.add_argument("--calibre", choices=tuple(CALIBRES), required=True,
                        help="narrow: radii 1.6-0.85 mm; wide: 2-0.8 mm")
    parser.add_argument("--out", type=Path, required=True,
                        help="where the built folders ubS go")
    parser.add_argument("--tmp", type=Path, default=None,
                        help="where the generated folders gS go (default: a new temporary "
                             "folder)")
    parser.add_argument("--allow-below-acceptance", action="store_true",
                        help="pass --allow-below-acceptance to the build (default: a folder "
                             "below the build's acceptance checks is not written, and its "
                             "seed is named at the end)")
    args = parser.parse_args()
    tmp = args.tmp or Path(tempfile.mkdtemp(prefix="calibre_generated_"))
    args.out.mkdir(parents=True, exist_ok=True)
    failed: list[int] = []
    for seed in args.seeds:
        folder = args.out / f"ub{seed}"
        if (folder / "manifest.json").is_file():
            print(folder_row(folder, None) + " (already built)", flush=True)
            continue
        start = time.perf_counter()
        generated = tmp / f"g{seed}"
        # A non-zero status: the command line printed its own one-line error (a build below
        # the acceptance checks exits 2).
        if not (generated / "manifest.json").is_file() and cli.main(
            generate_command(seed, args.calibre, generated)
        ):
            failed.append(seed)
            continue
        if cli.main(build_command(generated, folder.name, folder, args.allow_below_acceptance)):
            failed.append(seed)
            continue
        print(folder_row(folder, time.perf_counter() - start), flush=True)
    if failed:
        sys.exit(f"not built (see the errors above): seeds {failed}")


if __name__ == "__main__":
    main()
