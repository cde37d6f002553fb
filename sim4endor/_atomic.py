"""Atomic output: a folder or file appears complete, or not at all, and one writer at a time.

Staging files and folders come from :mod:`tempfile`, which makes them private (0600 / 0700);
they get the permissions of ordinary new files (as the umask allows) before they are renamed
into place, so outputs written atomically look like every other output.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import inspect
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, ParamSpec, TypeVar

import filelock

from sim4endor.errors import Sim4EndoRError

_Params = ParamSpec("_Params")
_Result = TypeVar("_Result")


class OutputBusyError(Sim4EndoRError, RuntimeError):
    """Raised when another process is writing the output folder; the message names it."""


@contextlib.contextmanager
def exclusive_output(target: Path) -> Iterator[None]:
    """Holds ``target`` (an output folder) for this process: a second writer of it, while the
    first holds it, is refused at once with :class:`OutputBusyError` instead of interleaving
    its files with the first's (two runs into one folder doubled its logs' rows).

    The lock is a hidden file beside ``target`` (an operating-system lock, released when the
    process ends, however it ends), removed again when the first writer is done.
    """
    target = Path(target)
    path = target.parent / f".{target.name}.lock"
    lock = filelock.FileLock(path, timeout=0)
    try:
        with _naming(target):
            target.parent.mkdir(parents=True, exist_ok=True)
            lock.acquire()
    except filelock.Timeout:
        raise OutputBusyError(
            f"{target} is being written by another sim4endor process; wait for it to finish "
            "or choose another output folder."
        ) from None
    try:
        yield
    finally:
        # Removed before the release: a writer arriving now takes a lock of its own on a
        # new file, once this one has written everything.
        path.unlink(missing_ok=True)
        lock.release()


def holds_output(parameter: str) -> Callable[[Callable[_Params, _Result]],
                                            Callable[_Params, _Result]]:
    """Decorates a function that writes the folder passed as ``parameter``: it runs under
    :func:`exclusive_output` of that folder."""

    def decorate(function: Callable[_Params, _Result]) -> Callable[_Params, _Result]:
        signature = inspect.signature(function)

        @functools.wraps(function)
        def wrapper(*args: _Params.args, **kwargs: _Params.kwargs) -> _Result:
            target: Any = signature.bind(*args, **kwargs).arguments[parameter]
            with exclusive_output(Path(target)):
                return function(*args, **kwargs)

        return wrapper

    return decorate


@contextlib.contextmanager
def atomic_directory(target: Path, *, overwrite: bool = True) -> Iterator[Path]:
    """Yields a temporary folder beside ``target`` that replaces ``target`` on success.

    On an exception the temporary folder is removed and ``target`` is left untouched, so a
    failed build never leaves a half-written vessel folder behind.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    if target.exists() and not overwrite:
        raise FileExistsError(f"{target} already exists; pass overwrite=True to replace it.")
    if target.exists() and not target.is_dir():
        raise FileExistsError(f"{target} exists and is not a folder; it is not replaced.")
    with _naming(target):
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    backup = target.with_name(f".{target.name}.old")
    if target.exists():
        shutil.rmtree(backup, ignore_errors=True)
        target.rename(backup)
    staging.chmod(0o777 & ~_umask())
    staging.rename(target)
    shutil.rmtree(backup, ignore_errors=True)


def atomic_write_text(path: Path, text: str) -> None:
    """Writes ``text`` to ``path`` through a temporary file and a rename."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Writes ``data`` to ``path`` through a temporary file and a rename."""
    path = Path(path)
    with _naming(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def _naming(target: Path) -> Iterator[None]:
    """Turns a refusal to write where ``target`` goes into one that names ``target``, not
    the hidden staging or lock file the refusal came from."""
    try:
        yield
    except OSError as exc:
        if exc.errno not in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise
        raise PermissionError(
            exc.errno, f"cannot write {target}: {target.parent} is not writable ({exc.strerror})"
        ) from None


def _umask() -> int:
    # Reading the umask means setting it; set it straight back (no other way in the stdlib).
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
