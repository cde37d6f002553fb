"""Number types of the command lines: argparse rejects a bad value with its name.

Both the CLI (:mod:`sim4endor.cli.args`) and the vessel library's own command
(``sim4endor vessel generate``, :mod:`sim4endor.vessels.generators.command`) take them, so
they live below both: the library never imports the CLI built on it. The seed's range is the
configs' too (:mod:`sim4endor.rl.config`).
"""

from __future__ import annotations

import argparse
import math

#: Largest seed: torch, numpy and the collectors take seeds below 2**32, and the evaluation
#: and resumption offsets are added to it.
MAX_SEED = 2**31 - 1


def positive_int(text: str) -> int:
    """An integer >= 1 (a count: frames, environments, trials, pixels)."""
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return value


def non_negative_int(text: str) -> int:
    """An integer >= 0 (a count that may turn a group off)."""
    value = _int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (a length, a thickness)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def seed(text: str) -> int:
    """A random seed: an integer in [0, MAX_SEED]."""
    value = _int(text)
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be an integer in [0, {MAX_SEED}], got {text!r}")
    return value


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
