"""``sim4endor export RUN_DIR --out DIR [--onnx]``: a trained policy for a robot's controller."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim4endor import assets


def register(subparsers: argparse._SubParsersAction) -> None:
    """Adds the ``export`` subcommand."""
    parser = subparsers.add_parser(
        "export",
        help="export a trained run's policy (TorchScript, optionally ONNX, with its contract)",
        description=(
            "Write the latest deterministic policy of RUN_DIR to OUT as policy.pt (TorchScript), "
            "policy.json (observation entries with their slices and units, action scales in m "
            "and rad, control period) and, with --onnx, policy.onnx. "
            "experiments/export/run_onnx_policy.py runs the ONNX file with onnxruntime."
        ),
    )
    parser.add_argument("run_dir", type=assets.run_or_policy, metavar="RUN_OR_POLICY",
                        help="folder written by `sim4endor train --out`, a shipped pretrained "
                             "policy's name, or an exported policy folder")
    parser.add_argument("--out", type=Path, required=True, help="folder to write the policy to")
    parser.add_argument("--onnx", action="store_true",
                        help="also write policy.onnx (needs the onnx extra)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Exports and prints the written files."""
    from sim4endor.rl.export import export_policy

    for path in export_policy(args.run_dir, args.out, onnx=args.onnx):
        print(path)  # noqa: T201
    return 0
