"""Runs an exported sim4endor policy with onnxruntime on one observation, as a robot would.

Usage: ``python experiments/export/run_onnx_policy.py EXPORT_DIR [--observation v1 ... vN]``

Only ``policy.onnx`` and ``policy.json`` (written by ``sim4endor export RUN --out EXPORT_DIR
--onnx``) are read: no sim4endor, torch or MuJoCo is needed on the robot's computer. The
observation is given in SI units in the order ``policy.json`` lists (default: all zeros, the
tip at the frame's origin at rest); the output is the step the driver applies this control
period, in metres and radians.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("export_dir", type=Path, help="folder with policy.onnx and policy.json")
    parser.add_argument("--observation", type=float, nargs="+", help="observation values (SI)")
    args = parser.parse_args()
    try:
        import onnxruntime
    except ImportError:
        parser.exit(2, "run_onnx_policy.py needs onnxruntime: pip install onnxruntime (or "
                       "'sim4endor[onnx]'); nothing else of sim4endor is needed here.\n")
    files = [args.export_dir / name for name in ("policy.json", "policy.onnx")]
    missing = [str(path) for path in files if not path.is_file()]
    if missing:
        parser.error(f"{', '.join(missing)} not found: export the run with "
                     "'sim4endor export RUN --out EXPORT_DIR --onnx' first")
    contract = json.loads((args.export_dir / "policy.json").read_text())
    size = contract["observation"]["shape"][-1]
    values = args.observation or [0.0] * size
    if len(values) != size:
        parser.error(f"--observation needs {size} values, got {len(values)}")
    session = onnxruntime.InferenceSession(str(args.export_dir / "policy.onnx"))
    observation = np.asarray([values], dtype=np.float32)
    (action,) = session.run(["action"], {"observation": observation})
    for entry in contract["observation"]["entries"] or []:
        start, stop = entry["slice"]
        print(f"{entry['name']:>17} = {values[start:stop]} {entry['unit']}")
    for entry in contract["action"]["entries"]:
        value = float(action[0, entry["index"]])
        step = value * entry["scale"]
        print(f"{entry['name']:>17} = {value:+.4f} -> {step:+.3e} {entry['unit']}")
    print(f"(one step every {contract['action']['control_period_s']} s)")


if __name__ == "__main__":
    main()
