"""OpenGL on machines without a display or without the GL library (sim4endor._gl).

The "no libOSMesa" machine is simulated in a subprocess by a ``sitecustomize`` that hides the
library from ctypes, the way PyOpenGL and MuJoCo look it up.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

HIDE_OSMESA = '''
import ctypes, ctypes.util
_find, _init = ctypes.util.find_library, ctypes.CDLL.__init__
def find_library(name):
    return None if "osmesa" in name.lower() else _find(name)
def init(self, name, *args, **kwargs):
    if name and "osmesa" in str(name).lower():
        raise OSError(f"{name}: cannot open shared object file")
    _init(self, name, *args, **kwargs)
ctypes.util.find_library, ctypes.CDLL.__init__ = find_library, init
'''


def _run(args: list[str], tmp_path: Path, hide_osmesa: bool = False,
         **env_vars: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY", "PYTHONPATH")}
    env.update(env_vars, XDG_CACHE_HOME=str(tmp_path / "cache"))
    if hide_osmesa:
        shim = tmp_path / "shim"
        shim.mkdir(exist_ok=True)
        (shim / "sitecustomize.py").write_text(HIDE_OSMESA)
        env["PYTHONPATH"] = str(shim)
    return subprocess.run([sys.executable, *args], env=env, capture_output=True, text=True,
                          timeout=300, cwd=tmp_path)


def test_loading_a_task_without_a_display_prints_no_gl_warning(tmp_path: Path) -> None:
    result = _run(["-c", "import sim4endor; from sim4endor import suite; "
                   "suite.load('simplified_phantom', 'task_a').reset()"], tmp_path)
    assert result.returncode == 0, result.stderr
    assert "GLFW" not in result.stderr and "Warning" not in result.stderr, result.stderr


def test_a_vessel_builds_with_mujoco_gl_osmesa_and_no_osmesa(tmp_path: Path) -> None:
    result = _run(["-m", "sim4endor", "vessel", "generate", "simplified_phantom", "--out",
                   str(tmp_path / "sp"), "--no-progress"], tmp_path, hide_osmesa=True,
                  MUJOCO_GL="osmesa")
    assert result.returncode == 0, result.stderr[-2000:]
    assert (tmp_path / "sp" / "manifest.json").is_file()


@pytest.mark.parametrize("backend", ["osmesa", None])
def test_render_without_osmesa_says_what_to_install(tmp_path: Path, backend: str | None) -> None:
    extra = {"MUJOCO_GL": backend} if backend else {}
    result = _run(["-m", "sim4endor", "render", "simplified_phantom", "task_a", "--out",
                   str(tmp_path / "x.gif")], tmp_path, hide_osmesa=True, **extra)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "apt-get install libosmesa6" in lines[0], result.stderr
    assert not (tmp_path / "x.gif").exists()


def test_view_without_a_display_points_to_render(tmp_path: Path) -> None:
    result = _run(["-m", "sim4endor", "view", "simplified_phantom", "task_a"], tmp_path)
    assert result.returncode == 2
    assert "needs a display" in result.stderr and "sim4endor render" in result.stderr


@pytest.mark.render
def test_gymnasium_rgb_array_exits_cleanly(tmp_path: Path) -> None:
    script = ("import gymnasium as gym, sim4endor\n"
              "env = gym.make('Sim4EndoR/SimplifiedPhantom-TaskA-v0', render_mode='rgb_array')\n"
              "env.reset(seed=0)\n"
              "assert env.render().shape == (480, 480, 3)\n")
    result = _run(["-c", script], tmp_path)
    assert result.returncode == 0, result.stderr
    # dm_control's exit hook used to print "cannot schedule new futures after shutdown".
    assert "Error" not in result.stderr, result.stderr


def test_a_command_run_in_process_leaves_the_backend_as_it_was(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A non-rendering command disables GL while it runs; a process that ran one from Python
    (a test, a notebook) must still render afterwards, and its children too (the last CI run
    failed on this: the notebook's `sim4endor render` inherited MUJOCO_GL=disable)."""
    from sim4endor.cli import main

    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    assert main(["vessel", "list"]) == 0
    assert os.environ["MUJOCO_GL"] == "osmesa"
    monkeypatch.delenv("MUJOCO_GL")
    assert main(["vessel", "list"]) == 0
    assert "MUJOCO_GL" not in os.environ
    capsys.readouterr()
