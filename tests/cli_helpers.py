"""Running the command line in a test: its exit status, its one-line refusals, and what it
left on disk."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pytest

from sim4endor.cli import main


def run_cli(args: Sequence[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """Runs the command line in this process; returns (exit status, stderr)."""
    try:
        status = main([str(a) for a in args])
    except SystemExit as exc:  # argparse rejects a bad value by exiting
        status = int(exc.code or 0)
    return status, capsys.readouterr().err.strip()


def assert_refused(status: int, err: str, *names: str) -> None:
    """Exit status 2 and one line of error that names every one of ``names``."""
    assert status == 2, err
    assert len(err.splitlines()) == 1, err
    assert "Traceback" not in err
    for name in names:
        assert name in err, f"{name!r} not named in: {err}"


def snapshot(root: Path) -> dict[str, tuple[bytes, int]]:
    """Every file and folder under ``root`` (itself included) with its content and mode."""
    if not root.exists():
        return {}
    if root.is_file():
        return {".": (root.read_bytes(), root.stat().st_mode)}
    return {
        str(p.relative_to(root)): (p.read_bytes() if p.is_file() else b"", p.stat().st_mode)
        for p in sorted(root.rglob("*"))
    }
