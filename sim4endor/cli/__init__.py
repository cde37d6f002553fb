"""The ``sim4endor`` command line.

Each subcommand lives in its own module of this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a handler taking the
parsed arguments and returning an exit status, and ``renders=True`` if it draws with OpenGL.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import re
import shlex
import sys
from collections.abc import Sequence
from typing import Any, NoReturn

from sim4endor import _gl
from sim4endor.errors import Sim4EndoRError, caused_by_interrupt

# Subcommand modules, imported lazily so `sim4endor --help` stays fast.
_SUBCOMMAND_MODULES: tuple[str, ...] = (
    "vessel", "train", "evaluate", "export", "table", "bench", "view", "render",
)


#: A number, or a comma-separated list of them, as the options' values are written.
_NUMBER = r"-?\d*\.?\d+(?:[eE][-+]?\d+)?"


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line naming the argument, not the usage text."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # argparse takes "-3" for a value but "-3,75" or "-10,0,2" (a tip, a point below the
        # origin) for an unknown option, and then says the option before it expected one
        # argument; no option of ours looks like a number, so such lists are values too.
        self._negative_number_matcher = re.compile(rf"^-{_NUMBER[2:]}(?:,{_NUMBER})*$")

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """Returns the top-level parser with every subcommand registered."""
    parser = _Parser(
        prog="sim4endor",
        description="Guidewire navigation simulator for robot-assisted PCI (MuJoCo + RL).",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in _SUBCOMMAND_MODULES:
        importlib.import_module(f"sim4endor.cli.{name}").register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the command line; returns the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    # As a user would type it again (a vessel folder's README names the command that built it).
    args.command_line = shlex.join(["sim4endor", *(sys.argv[1:] if argv is None else argv)])
    # sim4endor's own progress lines at INFO; other libraries' (absl, PyOpenGL) only from
    # WARNING, unless -v asks for everything.
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    logging.getLogger("sim4endor").setLevel(logging.DEBUG if args.verbose else logging.INFO)
    try:
        # MuJoCo reads MUJOCO_GL when first imported, during the command: one that renders
        # gets an installed backend, every other one none (a missing GL library must not break
        # a vessel build).
        with _gl.backend_for(renders=getattr(args, "renders", False)):
            return int(args.func(args) or 0)
    # OSError: a file or folder the command cannot read or write; its message names the path.
    except (Sim4EndoRError, OSError) as exc:
        print(f"sim4endor {args.command}: error: {exc}", file=sys.stderr)  # noqa: T201
        return 2
    except KeyboardInterrupt:
        return _interrupted()
    except Exception as exc:
        # Ctrl-C deep in a library can come out as another exception (caused_by_interrupt).
        if caused_by_interrupt(exc):
            return _interrupted()
        raise


def _interrupted() -> int:
    """Says the command was interrupted; returns the shell's status for Ctrl-C."""
    print("interrupted", file=sys.stderr)  # noqa: T201
    return 130


if __name__ == "__main__":
    sys.exit(main())
