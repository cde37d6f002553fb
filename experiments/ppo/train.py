"""Train PPO on a sim4endor task (TorchRL sota-implementations style).

    python experiments/ppo/train.py --out runs/ppo [section.field=value ...]

The hyper-parameters are in config.yaml beside this script; arguments of the form
section.field=value override them (e.g. env.task=task_b collector.total_frames=20000).
The run folder gets config.yaml, resumable checkpoints, CSV logs and evaluations; rerun the
same command to resume. Same as: sim4endor train ppo --config experiments/ppo/config.yaml.
"""

import argparse
import json
from pathlib import Path

from sim4endor.rl.trainer import train_from_file


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("runs/ppo"), help="run folder")
    parser.add_argument("overrides", nargs="*", help="section.field=value overrides")
    args = parser.parse_args()
    config_path = Path(__file__).with_name("config.yaml")
    print(json.dumps(train_from_file(config_path, args.out, tuple(args.overrides))))


if __name__ == "__main__":
    main()
