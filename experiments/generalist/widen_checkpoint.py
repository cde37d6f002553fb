"""Widens a SAC checkpoint's networks for observation entries appended to its set.

A policy trained on one observation set can go on training with entries added at the end of
it (e.g. ``generalist_no_radius`` -> ``generalist_stall``): each first layer gets a zero
weight column per new number, so the widened networks compute exactly what the old ones
did until training moves those weights, and the Adam moments of those columns start at
zero. A new number's input scale is its entry's default factor
(``sim4endor.rl.config.OBSERVATION_SCALES``), as the trainer would build it.

Usage:
    python experiments/generalist/widen_checkpoint.py SOURCE_RUN NEW_RUN stall_time
    sim4endor train sac --config NEW_RUN/config.yaml --out NEW_RUN ...

``NEW_RUN`` gets ``checkpoint/state.pt`` only (no replay buffer: its transitions have the
old observation's size), so training resumes with an empty buffer at the old frame count.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from sim4endor.observations import OBSERVATION_UNITS
from sim4endor.rl.config import OBSERVATION_SCALES

#: Entries that can be appended: a fixed size (not ``wire_shape`` or ``pixels``) and an input
#: factor.
_SIZES = {name: size for name, (_, size) in OBSERVATION_UNITS.items()
          if size is not None and name in OBSERVATION_SCALES}
#: First-layer parameters of every network, by key ending: their last dimension is the
#: observation (followed by the action, for the critics).
_FIRST_LAYER = ("net.0.weight", ".scale")


def _widen(tensor: torch.Tensor, at: int, columns: torch.Tensor) -> torch.Tensor:
    """``tensor`` with ``columns`` (broadcast over its other dimensions) inserted before
    index ``at`` of its last dimension."""
    filler = columns.to(tensor.dtype).expand(*tensor.shape[:-1], len(columns))
    return torch.cat([tensor[..., :at], filler, tensor[..., at:]], dim=-1)


def widen_state(state: dict, scales: list[float]) -> dict:
    """Returns the checkpoint ``state`` with one observation number appended per entry of
    ``scales`` (its input factor)."""
    zeros, factors = torch.zeros(len(scales)), torch.tensor(scales)
    agent = state["agent"]
    loss = agent["loss"]
    actor_in = loss["actor_network_params.module.0.module.0.net.0.weight"].shape[-1]
    widths = {actor_in, loss["qvalue_network_params.module.net.0.weight"].shape[-1]}
    for params in (loss, agent["exploration"]):
        for key, value in list(params.items()):
            if key.endswith(_FIRST_LAYER) and value.shape[-1] in widths:
                params[key] = _widen(value, actor_in,
                                     factors if key.endswith(".scale") else zeros)
    # Adam's moments of the first layers have their weights' shapes (2-D and more; the
    # biases' moments keep theirs).
    for moments in agent["optimizer"]["state"].values():
        for name in ("exp_avg", "exp_avg_sq"):
            value = moments[name]
            if value.ndim >= 2 and value.shape[-1] in widths:
                moments[name] = _widen(value, actor_in, zeros)
    return state


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", type=Path, help="run folder with checkpoint/state.pt")
    parser.add_argument("destination", type=Path, help="new run folder (created)")
    parser.add_argument("entries", nargs="+", choices=sorted(_SIZES),
                        metavar="ENTRY", help="observation entries appended to the set, in order")
    args = parser.parse_args()
    scales = [OBSERVATION_SCALES[name] for name in args.entries
              for _ in range(_SIZES[name])]
    state = torch.load(args.source / "checkpoint" / "state.pt", weights_only=True)
    out = args.destination / "checkpoint"
    out.mkdir(parents=True, exist_ok=False)
    torch.save(widen_state(state, scales), out / "state.pt")
    print(f"{out / 'state.pt'}: {len(scales)} observation number(s) appended")


if __name__ == "__main__":
    main()
