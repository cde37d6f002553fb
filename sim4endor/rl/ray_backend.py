"""Ray: joining a cluster, and a collector whose environment workers are Ray actors.

The learner stays in the calling process. TorchRL's Ray collector (``Collector(backend=
"ray")``, :class:`~torchrl.collectors.distributed.RayCollector`) starts one actor per
environment, each an ordinary single-environment :class:`~torchrl.collectors.Collector`,
gathers an equal slice of every batch from each, and sends them the policy weights
(torch.distributed over Gloo, ranks set up through Ray) whenever the trainer calls
``update_policy_weights_``. Ray starts its workers as new processes, never forks, so a
vessel whose walls are decomposed (CoACD, OpenMP) while its environment is built is safe there.

Ray is optional (the ``ray`` extra): it is imported inside the functions that need it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import socket
from collections.abc import Callable, Iterator, Sequence
from types import ModuleType
from typing import Any

from tensordict.nn import TensorDictModuleBase
from torchrl.collectors import BaseCollector, Collector

from sim4endor.errors import Sim4EndoRError

_LOG = logging.getLogger(__name__)

#: Addresses ``ray.init`` resolves itself (no host and port to probe).
_NAMED_ADDRESSES = ("auto", "local")
#: A head node that accepts no TCP connection in this time counts as unreachable; ray.init
#: would instead retry for minutes, logging a warning every few seconds.
_PROBE_TIMEOUT_S = 5.0
#: The fix named by every error about reaching a cluster.
_START_A_CLUSTER = (
    "Start one with `ray start --head` and pass the address it prints with --ray-address "
    "(or RAY_ADDRESS), or leave both unset to start Ray on this machine."
)


class RayBackendError(Sim4EndoRError):
    """Ray is not installed, or no Ray cluster answers at the given address."""


def import_ray() -> ModuleType:
    """Returns the ``ray`` module, or raises an error saying how to install it."""
    try:
        import ray
    except ImportError as exc:
        raise RayBackendError(
            "--backend ray needs Ray: pip install 'sim4endor[ray]' (or use the local backend)."
        ) from exc
    return ray


@contextlib.contextmanager
def connected(address: str | None = None) -> Iterator[ModuleType]:
    """Joins the Ray cluster at ``address`` for the ``with`` block; yields the ``ray`` module.

    A process already connected (a notebook or test that called ``ray.init``) stays connected
    as it is and keeps its connection afterwards.

    Args:
        address: ``HOST:PORT`` of the cluster's head node (what ``ray start --head`` prints)
            or ``auto`` (the cluster started on this machine); ``None``: the ``RAY_ADDRESS``
            environment variable, else a new Ray instance on this machine.

    Raises:
        RayBackendError: Ray is not installed, or no cluster answers at the address.
    """
    ray = import_ray()
    if ray.is_initialized():
        yield ray
        return
    address = address or os.environ.get("RAY_ADDRESS") or None
    if address is not None and address not in _NAMED_ADDRESSES:
        _probe(address)
    try:
        ray.init(address=address)
    # e.g. `auto` with no cluster on this machine, or a port where something else listens
    except ConnectionError as exc:
        raise RayBackendError(f"{str(exc).rstrip('.')}. {_START_A_CLUSTER}") from exc
    try:
        yield ray
    finally:
        ray.shutdown()


def _probe(address: str) -> None:
    """Raises a one-line error unless the head node at ``address`` accepts a TCP connection."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        raise RayBackendError(
            f"Ray address {address!r} is not HOST:PORT (e.g. 10.0.0.5:6379). {_START_A_CLUSTER}"
        )
    try:
        socket.create_connection((host, int(port)), timeout=_PROBE_TIMEOUT_S).close()
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise RayBackendError(
            f"No Ray cluster answers at {address} ({reason}). {_START_A_CLUSTER}"
        ) from exc


class _EnvWorker(Collector):
    """One environment's collector as a Ray actor.

    Ray prefixes an actor's log lines with its ``repr``; a collector's own spans dozens of
    lines (environment and policy), so this names the worker instead.
    """

    def __repr__(self) -> str:
        return f"EnvWorker{self.worker_idx}"


def ray_collector(
    create_env_fns: Sequence[Callable[[], Any]],
    policy: TensorDictModuleBase,
    *,
    frames_per_batch: int,
    total_frames: int,
    init_random_frames: int,
) -> BaseCollector:
    """Returns a collector stepping each of ``create_env_fns`` in a Ray actor (one CPU each).

    Each batch stacks an equal slice from every actor (shape ``[actors, frames]``, as the local
    multi-process collector). The actors start with ``policy``'s current weights; the caller
    sends them new ones with ``update_policy_weights_()``. Needs a connected Ray
    (:func:`connected`).
    """
    import ray

    workers = len(create_env_fns)
    cpus = ray.cluster_resources().get("CPU", 0)
    if cpus < workers:  # an autoscaling cluster may still add nodes: warn, do not refuse
        _LOG.warning("the Ray cluster has %g CPUs; the %d environment workers (one CPU each) "
                     "wait until that many are free", cpus, workers)
    collector = Collector(
        list(create_env_fns),
        policy,
        backend="ray",
        sync=True,
        frames_per_batch=frames_per_batch,
        total_frames=total_frames,
        init_random_frames=init_random_frames,
        backend_options={
            "collector_class": _EnvWorker,
            # One CPU per simulation, and none of TorchRL's default 2 GiB memory reservation,
            # which a small node cannot grant.
            "remote_configs": {"num_cpus": 1},
            # Our policies need no env transforms (e.g. InitTracker); say so, silencing a warning.
            "collector_kwargs": {"auto_register_policy_transforms": False},
        },
    )
    # The actors hold the policy pickled at construction; this starts the weight channel the
    # trainer's later updates go through.
    collector.update_policy_weights_()
    return collector
