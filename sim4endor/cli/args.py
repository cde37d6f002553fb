"""Argument types shared by the subcommands: argparse rejects a bad value with its name."""

from __future__ import annotations

import argparse

from sim4endor.rl.config import MAX_SEED


def positive_int(text: str) -> int:
    """An integer >= 1 (a count: frames, environments, trials, pixels)."""
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
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
