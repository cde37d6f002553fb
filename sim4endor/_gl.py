"""Which OpenGL backend MuJoCo and dm_control use, decided before either is imported.

Both read ``MUJOCO_GL`` once, at import. Left unset on a machine without a display, dm_control
tries GLFW first, which warns ``GLFWError ... DISPLAY environment variable is missing``; set to
``osmesa`` without libOSMesa installed, even ``import mujoco`` fails inside PyOpenGL
(``'NoneType' object has no attribute 'glGetError'``), whether or not anything is rendered.
So: code that never renders runs with rendering disabled, headless code gets a backend that is
installed, and code that renders checks first and says in one line what to install or set.
"""

from __future__ import annotations

import contextlib
import ctypes.util
import os
import sys
from collections.abc import Iterator

from sim4endor.errors import Sim4EndoRError

MUJOCO_GL = "MUJOCO_GL"
#: dm_control's switch for rendering on the calling thread. Our environments render from one
#: thread; the default offload thread is shut down before dm_control's exit hook frees its
#: contexts, which then prints ``RuntimeError: cannot schedule new futures after shutdown``.
NO_OFFLOADING = "DISABLE_RENDER_THREAD_OFFLOADING"
_DISABLED = ("off", "disable", "disabled", "false", "0")
_WINDOWED = ("", "glfw", "glx", "on", "enable", "enabled", "true", "1")
_INSTALL_HINT = (
    "install OSMesa (apt-get install libosmesa6) and set MUJOCO_GL=osmesa, or set MUJOCO_GL=egl "
    "on a machine with a GPU"
)


class RenderingUnavailableError(Sim4EndoRError, RuntimeError):
    """Raised before rendering when no OpenGL backend can work; says what to install or set."""


def _has_display() -> bool:
    return sys.platform != "linux" or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )


def choose_headless_backend() -> None:
    """Picks a backend that exists when none was chosen and there is no display.

    OSMesa when its library is installed, else rendering disabled (a render call then raises
    :class:`RenderingUnavailableError` naming the fix). A ``MUJOCO_GL`` the user set is kept.
    """
    os.environ.setdefault(NO_OFFLOADING, "1")
    if MUJOCO_GL in os.environ or _has_display():
        return
    os.environ[MUJOCO_GL] = "osmesa" if ctypes.util.find_library("OSMesa") else "disable"


@contextlib.contextmanager
def backend_for(renders: bool) -> Iterator[None]:
    """Within the block, a headless backend for code that renders and none for other code.

    Code that never renders (building vessels, training) then loads no GL library at all. The
    environment is restored afterwards, so a command run from Python (e.g. a test) leaves
    nothing behind for the processes started later.
    """
    saved = {k: os.environ.get(k) for k in (MUJOCO_GL, NO_OFFLOADING)}
    if renders:
        choose_headless_backend()
    else:
        os.environ[MUJOCO_GL] = "disable"
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def rendering_problem() -> str | None:
    """Returns why rendering cannot work in this process (one line), or None if it can."""
    backend = os.environ.get(MUJOCO_GL, "").strip().lower()
    if backend in _DISABLED:
        return (f"rendering is disabled (MUJOCO_GL={backend}, which sim4endor also chooses when "
                f"there is neither a display nor libOSMesa): {_INSTALL_HINT}.")
    if backend == "osmesa" and not ctypes.util.find_library("OSMesa"):
        return f"MUJOCO_GL=osmesa but libOSMesa is not installed: {_INSTALL_HINT}."
    if backend == "egl" and not ctypes.util.find_library("EGL"):
        return f"MUJOCO_GL=egl but libEGL is not installed: {_INSTALL_HINT}."
    if backend in _WINDOWED and not _has_display():
        return f"there is no display for MUJOCO_GL={backend or 'glfw'}: {_INSTALL_HINT}."
    return None


def require_display(command: str) -> None:
    """Raises :class:`RenderingUnavailableError` when there is no display for a window."""
    if not _has_display():
        raise RenderingUnavailableError(
            f"{command} opens a window and needs a display (DISPLAY or WAYLAND_DISPLAY is "
            "unset); on a headless machine write a video with `sim4endor render` instead."
        )


def require_rendering() -> None:
    """Raises :class:`RenderingUnavailableError` unless :func:`rendering_problem` is None."""
    problem = rendering_problem()
    if problem is not None:
        raise RenderingUnavailableError(f"Cannot render: {problem}")
