"""Training agents on the navigation tasks with TorchRL (DDPG, SAC, PPO).

Modules: :mod:`~sim4endor.rl.config` (typed configuration, the paper's defaults),
:mod:`~sim4endor.rl.networks` and :mod:`~sim4endor.rl.algorithms` (actors, critics, losses,
target updates), :mod:`~sim4endor.rl.trainer` (collect/optimise loop, checkpoints, logging),
:mod:`~sim4endor.rl.evaluation` and :mod:`~sim4endor.rl.metrics` (success rate, completion
time, path length, SPL, wall force), :mod:`~sim4endor.rl.runs` (reading run folders back),
:mod:`~sim4endor.rl.table`, :mod:`~sim4endor.rl.plots` and :mod:`~sim4endor.rl.bench`
(Table I, learning curves, the benchmark grid) and :mod:`~sim4endor.rl.export` (TorchScript /
ONNX policies for a robot driver). Submodules import torch and torchrl, so this package
imports nothing itself.

Example:
    >>> from sim4endor.rl.config import default_config
    >>> from sim4endor.rl.trainer import train
    >>> metrics = train(default_config("sac"), "runs/sac-a")   # doctest: +SKIP
"""
