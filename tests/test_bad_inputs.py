"""The bad-input corpus: every case of the bad-input audit of issue 14, as a user would meet it.

Each case asserts the exit status (2 for a refused input, from the command line), a one-line
message that names the bad input, and that nothing outside the tool's own outputs changed
(a snapshot of the folder it was pointed at, taken before and compared after).
"""

from __future__ import annotations

import math
import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from cli_helpers import assert_refused, run_cli, snapshot

from sim4endor import suite
from sim4endor.cli import main
from sim4endor.envs.gym import NavigationEnv
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl.checkpoint import CHECKPOINT_DIR, REPLAY_FILE, STATE_FILE, CheckpointError
from sim4endor.rl.config import apply_overrides, default_config, save_config
from sim4endor.tasks.config import TaskConfigError
from sim4endor.tasks.navigation import InvalidActionError
from sim4endor.vessels.build import BuildParams, build_vessel
from sim4endor.vessels.centerline import CenterlineGraph
from sim4endor.vessels.checks import stray_openings
from sim4endor.vessels.generators.tubes import sweep_tube
from sim4endor.vessels.meshio import MeshInputError, boundary_loops, prepare_lumen
from sim4endor.vessels.walls import WallParams

REPO = Path(__file__).resolve().parents[1]
SERIAL = BuildParams(wall=WallParams(workers=1))


# ---------------------------------------------------------------------------------------------
# Helpers


BEND = 12e-3  # m, radius of the bend of the curved tube
TUBE_RADIUS = 1.5e-3  # m


def bend_axis(samples: int = 60) -> np.ndarray:
    """The axis of the curved tube: a 120-degree arc of radius BEND in the xy plane (m)."""
    angle = np.linspace(0.0, np.radians(120.0), samples)
    return np.column_stack([BEND * np.cos(angle), BEND * np.sin(angle), np.zeros(samples)])


def curved_tube(open_ends: bool = False) -> trimesh.Trimesh:
    """A tube along :func:`bend_axis` (m), capped or with its two ends open."""
    axis = bend_axis()
    segments = 24
    vertices, faces = sweep_tube(axis, np.full(len(axis), TUBE_RADIUS), segments)
    if open_ends:  # keep the faces between the axis rings, drop the two caps
        cap_rings = max(2, segments // 4) - 1
        first, last = cap_rings * segments, (cap_rings + len(axis)) * segments
        faces = faces[np.all((faces >= first) & (faces < last), axis=1)]
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.remove_unreferenced_vertices()
    return mesh


def with_side_window(mesh: trimesh.Trimesh, faces: int = 320) -> trimesh.Trimesh:
    """``mesh`` less the ``faces`` faces nearest a point on the outside of the bend."""
    window = BEND * np.array([np.cos(0.6), np.sin(0.6), 0.0]) * (1 + TUBE_RADIUS / BEND)
    nearest = np.argsort(np.linalg.norm(mesh.triangles_center - window, axis=1))
    holed = mesh.copy()
    holed.update_faces(np.setdiff1d(np.arange(len(mesh.faces)), nearest[:faces]))
    holed.remove_unreferenced_vertices()
    return holed


@pytest.fixture(autouse=True)
def _private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def tube_mesh(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small capped straight tube in mm, as a user's STL."""
    path = tmp_path_factory.mktemp("mesh") / "tube.stl"
    tube = trimesh.creation.cylinder(radius=1.5, height=20.0, sections=24).subdivide_to_size(1.2)
    tube.export(path)
    return path


def build_args(mesh: Path, out: Path, *extra: str) -> list[str]:
    return ["vessel", "build", str(mesh), "--name", "tube", "--out", str(out), "--units", "mm",
            "--workers", "1", "--no-progress", "--inlet", "0,0,-10", *extra]


@pytest.fixture(scope="module")
def tube_folder(tmp_path_factory: pytest.TempPathFactory, tube_mesh: Path) -> Path:
    """A vessel folder built from :func:`tube_mesh` (copy it before changing it)."""
    out = tmp_path_factory.mktemp("built") / "tube"
    os.environ.setdefault("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("cache")))
    assert main(build_args(tube_mesh, out, "--no-cache")) == 0
    return out


# ---------------------------------------------------------------------------------------------
# Silent data loss: a build never deletes what it did not write


def assert_build_refused(tmp_path: Path, mesh: Path, out: Path,
                         capsys: pytest.CaptureFixture[str], *names: str) -> None:
    """A build into ``out`` is refused naming ``out`` and ``names``; nothing under tmp_path
    changes."""
    before = snapshot(tmp_path)
    status, err = run_cli(build_args(mesh, out), capsys)
    assert_refused(status, err, str(out), *names)
    assert snapshot(tmp_path) == before


def test_build_refuses_a_folder_of_other_files(tmp_path: Path, tube_mesh: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("years of work\n")
    assert_build_refused(tmp_path, tube_mesh, out, capsys, "not a vessel folder", "thesis.tex")


def test_build_refuses_a_vessel_folder_with_files_added(
    tmp_path: Path, tube_mesh: Path, tube_folder: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "tube"
    shutil.copytree(tube_folder, out)
    (out / "notes.txt").write_text("my notes\n")
    assert_build_refused(tmp_path, tube_mesh, out, capsys, "notes.txt")


def test_build_replaces_a_vessel_folder_it_wrote(
    tmp_path: Path, tube_mesh: Path, tube_folder: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "tube"
    shutil.copytree(tube_folder, out)
    status, err = run_cli(build_args(tube_mesh, out), capsys)
    assert status == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cache", "tube"]  # no leftovers


def test_build_refuses_an_out_that_is_a_file(tmp_path: Path, tube_mesh: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "o_file"
    out.write_text("not a folder\n")
    # Nothing changes: no .o_file.old left behind either.
    assert_build_refused(tmp_path, tube_mesh, out, capsys, "not a folder")


def test_an_unwritable_cache_keeps_the_build(tmp_path: Path, tube_mesh: Path,
                                             monkeypatch: pytest.MonkeyPatch,
                                             caplog: pytest.LogCaptureFixture,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    # A cache "folder" that is a file cannot be written, even by root (a read-only folder can).
    blocked = tmp_path / "cache_is_a_file"
    blocked.write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))
    out = tmp_path / "tube"
    status, err = run_cli(build_args(tube_mesh, out), capsys)
    assert status == 0, err
    assert (out / "manifest.json").is_file() and (out / "tube.xml").is_file()
    assert "could not store the build in the cache" in caplog.text


def file_modes(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): stat.S_IMODE(p.stat().st_mode)
            for p in folder.rglob("*") if p.is_file()}


def ordinary_mode() -> int:
    umask = os.umask(0o022)
    os.umask(umask)
    return 0o666 & ~umask


def test_vessel_folder_files_get_ordinary_modes(tube_folder: Path) -> None:
    """manifest.json and centerline.json were written 0600 (tempfile's mode), the rest 0644."""
    assert set(file_modes(tube_folder).values()) == {ordinary_mode()}, file_modes(tube_folder)


def test_run_folder_files_get_ordinary_modes(tmp_path: Path) -> None:
    """config.yaml and evaluation.json were written 0600, the rest 0644."""
    from rl_testing import pendulum_env, tiny_config

    from sim4endor.rl.trainer import train

    train(tiny_config("sac"), tmp_path, make_env=pendulum_env, progress=False)
    modes = file_modes(tmp_path)
    assert {"config.yaml", "evaluation.json"} <= set(modes)
    assert set(modes.values()) == {ordinary_mode()}, modes


# ---------------------------------------------------------------------------------------------
# Silent wrong build: a hole in the side wall is an error, and the check probes for it


def test_a_side_wall_hole_on_a_bend_is_refused(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    mesh = tmp_path / "holed.stl"
    holed = with_side_window(curved_tube())
    holed.apply_scale(1e3)
    holed.export(mesh)
    out = tmp_path / "holed"
    status, err = run_cli(["vessel", "build", mesh, "--name", "holed", "--out", out,
                           "--workers", "1", "--no-progress"], capsys)
    assert_refused(status, err, str(mesh), "hole")
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name != "cache"] == ["holed.stl"]


def test_stray_openings_tell_a_side_hole_from_vessel_ends() -> None:
    """The shape test of prepare_lumen can take a hole on a bend for a cut end; the centerline
    cannot be fooled: an end is where the centerline ends."""
    axis = bend_axis()
    graph = CenterlineGraph(axis, np.full(len(axis), TUBE_RADIUS),
                            np.column_stack([np.arange(len(axis) - 1), np.arange(1, len(axis))]))
    ends = curved_tube(open_ends=True)
    assert len(boundary_loops(ends)) == 2
    assert stray_openings(np.asarray(ends.vertices), boundary_loops(ends), graph) == []
    holed = with_side_window(ends)
    stray = stray_openings(np.asarray(holed.vertices), boundary_loops(holed), graph)
    assert len(stray) == 1 and stray[0].perimeter > 10 * TUBE_RADIUS


def test_a_small_hole_on_a_bend_is_filled(tmp_path: Path) -> None:
    """A hole of a few faces (as a mesh union can leave) is filled, not refused: by the shape
    test of prepare_lumen, or by the centerline test where it looks like an end (the random
    coronary trees of test_suite have one such slit)."""
    holed = with_side_window(curved_tube(), faces=6)
    vessel = build_vessel(holed, name="slit", out_dir=tmp_path / "slit", params=SERIAL,
                          progress=False, cache=False, inlet=bend_axis()[0])
    assert vessel.manifest.build["repairs"]["filled_holes"] == 1
    assert trimesh.load(vessel.root / "lumen.stl", force="mesh").is_watertight


def test_vessel_check_finds_a_side_hole(tmp_path: Path, tube_folder: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    import json
    folder = tmp_path / "tube"
    shutil.copytree(tube_folder, folder)
    lumen = trimesh.load(folder / "lumen.stl", force="mesh")
    nearest = np.argsort(np.linalg.norm(lumen.triangles_center - [TUBE_RADIUS, 0, 0], axis=1))
    lumen.update_faces(np.setdiff1d(np.arange(len(lumen.faces)), nearest[:40]))
    lumen.export(folder / "lumen.stl")
    status = main(["vessel", "check", str(folder), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert status != 0 and report["passed"] is False and report["wall_holes"] >= 1


@pytest.mark.parametrize("damage", ["missing", "garbage"])
def test_vessel_check_names_a_bad_hull(tmp_path: Path, tube_folder: Path, damage: str,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "tube"
    shutil.copytree(tube_folder, folder)
    hull = sorted((folder / "hulls").glob("*.stl"))[0]
    if damage == "missing":
        hull.unlink()
    else:
        hull.write_bytes(b"solid garbage\n\x00\x01\x02")
    before = snapshot(folder)
    status, err = run_cli(["vessel", "check", folder], capsys)
    assert_refused(status, err, hull.name)
    assert snapshot(folder) == before


def test_a_micrometre_mesh_declared_mm_suggests_um() -> None:
    tube = trimesh.creation.cylinder(radius=1500.0, height=20000.0, sections=24)
    with pytest.raises(MeshInputError, match="--units um"):
        prepare_lumen(tube, units="mm")


# ---------------------------------------------------------------------------------------------
# Ctrl-C during a build exits promptly and leaves nothing half-written


@pytest.mark.slow
@pytest.mark.parametrize("delay_s", [1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0])
def test_ctrl_c_during_a_build_exits_promptly(tmp_path: Path, delay_s: float) -> None:
    mesh = tmp_path / "curved.stl"
    tube = curved_tube()
    tube.apply_scale(1e3)
    tube.export(mesh)
    out = tmp_path / "curved"
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")}
    process = subprocess.Popen(
        [sys.executable, "-m", "sim4endor", "vessel", "build", str(mesh), "--name", "curved",
         "--out", str(out), "--workers", "2", "--no-progress", "--no-cache"],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    time.sleep(delay_s)
    process.send_signal(signal.SIGINT)
    try:
        _, err = process.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        process.kill()
        pytest.fail(f"the build still ran 30 s after Ctrl-C at {delay_s} s")
    if process.returncode == 0:
        pytest.skip(f"the build finished before Ctrl-C at {delay_s} s")
    assert process.returncode == 130, err
    assert "Traceback" not in err, err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != "cache") == ["curved.stl"]


def test_ctrl_c_while_an_extension_initialises_is_an_interrupt(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Ctrl-C during a command's first `import mujoco` comes out of MuJoCo's initialisation as
    "ImportError: initialization failed", raised from the KeyboardInterrupt: the Ctrl-C test
    above met it at 1 s on a faster machine (exit 1 and a traceback). It is an interrupt."""
    import sim4endor.cli.vessel

    def interrupted_import(args: object) -> int:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as interrupt:
            raise ImportError("initialization failed") from interrupt

    monkeypatch.setattr(sim4endor.cli.vessel, "run_list", interrupted_import)
    assert main(["vessel", "list"]) == 130
    assert capsys.readouterr().err == "interrupted\n"

    def broken_import(args: object) -> int:
        raise ImportError("a missing library")

    monkeypatch.setattr(sim4endor.cli.vessel, "run_list", broken_import)
    with pytest.raises(ImportError, match="a missing library"):
        main(["vessel", "list"])


# ---------------------------------------------------------------------------------------------
# Command-line numbers


@pytest.mark.parametrize(
    ("args", "names"),
    [
        (["train", "sac", "--out", "RUN", "--seed", "-1"], ["--seed", "-1"]),
        (["train", "sac", "--out", "RUN", "--envs", "0"], ["--envs", "0"]),
        (["train", "sac", "--out", "RUN", "--frames", "0"], ["--frames", "0"]),
        (["train", "sac", "--out", "RUN", "--frames", "-5"], ["--frames", "-5"]),
        (["train", "sac", "--out", "RUN", "--set", "optim.lr=-1"], ["optim.lr", "-1"]),
        (["train", "sac", "--out", "RUN", "--set", "optim.lr=nan"], ["optim.lr", "nan"]),
        (["train", "sac", "--out", "RUN", "--set", "optim.batch_size=0"],
         ["optim.batch_size", "0"]),
        (["train", "ddpg", "--out", "RUN", "--config", str(REPO / "experiments/sac/config.yaml")],
         ["sac", "ddpg"]),
        (["evaluate", "RUN", "--seed", "-1"], ["--seed"]),
        (["render", "simplified_phantom", "task_a", "--out", "RUN/x.txt"], ["x.txt", ".mp4"]),
        (["render", "simplified_phantom", "task_a", "--out", "RUN/x.mp4", "--width", "0"],
         ["--width", "0"]),
        (["render", "simplified_phantom", "task_a", "--out", "RUN/x.mp4", "--height", "-10"],
         ["--height", "-10"]),
        (["view", "simplified_phantom", "task_a", "--seed", "-1"], ["--seed"]),
        (["vessel", "generate", "simplified_phantom", "--seed", "-1", "--out", "RUN"], ["--seed"]),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, list) and v and v[0] in (
        "train", "evaluate", "render", "view", "vessel") else None,
)
def test_bad_command_line_values_are_refused(args: list[str], names: list[str], tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    status, err = run_cli([a.replace("RUN", str(run)) for a in args], capsys)
    assert_refused(status, err, *names)
    assert not run.exists()  # no run folder, no evaluation.json of an untrained policy


# ---------------------------------------------------------------------------------------------
# Checkpoints that are truncated, emptied or garbage


def _sac_run(run: Path) -> list[str]:
    """A run folder's config.yaml as `sim4endor train sac --frames 200 --out run` writes it."""
    config = apply_overrides(default_config("sac"), ["collector.total_frames=200"])
    run.mkdir(parents=True)
    save_config(config, run / "config.yaml")
    return ["--frames", "200", "--out", str(run)]


def _damage(path: Path, how: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if how == "emptied":
        path.write_bytes(b"")
    elif how == "garbage":
        path.write_bytes(os.urandom(256))
    else:  # truncated: the first half of a real checkpoint
        buffer = {"progress": {"frames": 1}, "agent": {"w": torch.zeros(1000)}}
        torch.save(buffer, path)
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


@pytest.mark.parametrize("how", ["truncated", "emptied", "garbage"])
@pytest.mark.parametrize("command", ["evaluate", "train"])
def test_a_damaged_checkpoint_is_named(tmp_path: Path, how: str, command: str,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    flags = _sac_run(run)
    state = run / CHECKPOINT_DIR / STATE_FILE
    _damage(state, how)
    before = snapshot(run)
    args = ["evaluate", run, "--trials", "1"] if command == "evaluate" else [
        "train", "sac", *flags, "--no-progress"]
    status, err = run_cli(args, capsys)
    assert_refused(status, err, str(state), "checkpoint")
    assert snapshot(run) == before


def test_a_garbage_replay_buffer_is_named(tmp_path: Path) -> None:
    from rl_testing import pendulum_env, tiny_config

    from sim4endor.rl.algorithms import build_agent
    from sim4endor.rl.checkpoint import Progress, load_checkpoint, save_checkpoint

    config = tiny_config("sac")
    env = pendulum_env(0)
    agent = build_agent(config, env.observation_spec, env.action_spec)
    save_checkpoint(tmp_path, agent, Progress(frames=10), None)
    replay = tmp_path / CHECKPOINT_DIR / REPLAY_FILE
    replay.write_bytes(os.urandom(512))
    from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(100))
    with pytest.raises(CheckpointError, match=f"{replay}.*delete it"):
        load_checkpoint(tmp_path, agent, buffer)


def test_a_garbage_policy_file_is_named(tmp_path: Path) -> None:
    policy = tmp_path / "policy.pt"
    policy.write_bytes(os.urandom(300))
    from sim4endor.cli.render import PolicyLoadError, load_policy

    with pytest.raises(PolicyLoadError, match=str(policy)) as raised:
        load_policy(str(policy), seed=0)
    assert len(str(raised.value).splitlines()) == 1


# ---------------------------------------------------------------------------------------------
# task_kwargs and environment_kwargs


@pytest.mark.parametrize(
    ("task_kwargs", "name"),
    [
        ({"random": "abc"}, "random"),
        ({"random": -1}, "random"),
        ({"random": 1.5}, "random"),
        ({"random": True}, "random"),
        ({"reward": 5}, "reward"),
        ({"action": {"max_insertion_step": "fast"}}, "max_insertion_step"),
        ({"action": {"speed": 1.0}}, "speed"),
        ({"termination": "x"}, "termination"),
        ({"curvature_weight": math.nan}, "curvature_weight"),
        ({"observations": "rotation"}, "observations"),
    ],
    ids=str,
)
def test_bad_task_kwargs_are_named(task_kwargs: dict[str, object], name: str) -> None:
    with pytest.raises(Sim4EndoRError, match=name) as raised:
        suite.load("simplified_phantom", "task_a", task_kwargs=task_kwargs)
    assert len(str(raised.value).splitlines()) == 1


@pytest.mark.parametrize(
    "environment_kwargs",
    [{"time_limit": -1}, {"time_limit": 0}, {"time_limit": math.nan}, {"time_limit": "long"},
     {"control_timestep": 0}, {"n_sub_steps": 0}, {"timelimit": 5}],
    ids=str,
)
def test_bad_environment_kwargs_are_named(environment_kwargs: dict[str, object]) -> None:
    (name,) = environment_kwargs
    with pytest.raises(TaskConfigError, match=name):
        suite.load("simplified_phantom", "task_a", environment_kwargs=environment_kwargs)


# ---------------------------------------------------------------------------------------------
# Actions


@pytest.fixture(scope="module")
def env() -> suite.NavigationEnvironment:
    environment = suite.load("simplified_phantom", "task_a", task_kwargs={"random": 0})
    environment.reset()
    return environment


@pytest.mark.parametrize("action", [["a", "b"], ["1", "0"], [True, False], np.array([True, True]),
                                    [None, 0.0]], ids=str)
def test_actions_that_are_not_numbers_are_refused(env: suite.NavigationEnvironment,
                                                  action: object) -> None:
    with pytest.raises(InvalidActionError, match="two numbers"):
        env.step(action)


def test_gymnasium_refuses_text_actions_too() -> None:
    genv = NavigationEnv("simplified_phantom", "task_a")
    genv.reset(seed=0)
    with pytest.raises(InvalidActionError, match="two numbers"):
        genv.step(["1", "0"])
    genv.close()


def test_ctrl_c_wrapped_by_a_library_still_ends_as_interrupted(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    # TorchRL's collector turns a Ctrl-C into a RuntimeError raised while it unwound; MuJoCo's
    # extension, initialising, into an ImportError raised from it (issue 67).
    from sim4endor.cli import main, vessel

    def wrapped(args: object) -> int:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise RuntimeError("Converting a tensordict to boolean value is not permitted")  # noqa: B904

    monkeypatch.setattr(vessel, "run_list", wrapped)
    assert main(["vessel", "list"]) == 130
    assert capsys.readouterr().err.strip() == "interrupted"


def test_caused_by_interrupt_reads_causes_and_contexts() -> None:
    from sim4endor.errors import caused_by_interrupt

    try:
        raise ImportError("extension init") from KeyboardInterrupt()
    except ImportError as error:
        assert caused_by_interrupt(error)
    assert not caused_by_interrupt(RuntimeError("a plain failure"))
