"""Train DDPG on a sim4endor task (TorchRL sota-implementations style).

    python experiments/ddpg/train.py --out runs/ddpg [section.field=value ...]

The hyper-parameters are in config.yaml beside this script; arguments of the form
section.field=value override them (e.g. env.task=task_b collector.total_frames=20000).
The run folder gets config.yaml, resumable checkpoints, CSV logs and evaluations; rerun the
same command to resume. Same as: sim4endor train ddpg --config experiments/ddpg/config.yaml.
"""

from pathlib import Path

from sim4endor.cli.train import experiment_script

if __name__ == "__main__":
    experiment_script(Path(__file__).resolve().with_name("config.yaml"))
