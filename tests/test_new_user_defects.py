"""What a new user hit (issue 78): each defect of the fresh-clone walk-through and the bad-input
audit, as that user met it, with the behaviour it has now."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium
import pytest
import trimesh
from cli_helpers import assert_refused, run_cli, snapshot
from guidewire_helpers import write_tube_vessel

from sim4endor import vessels
from sim4endor._atomic import exclusive_output
from sim4endor.envs.gym import NavigationEnv
from sim4endor.vessels import VesselFolderError
from sim4endor.vessels.centerline import CenterlineError
from sim4endor.vessels.manifest import ManifestError


@pytest.fixture()
def tube(tmp_path: Path) -> Path:
    """A small vessel folder (a capped tube with target A) to damage."""
    return write_tube_vessel(tmp_path / "tube").root


def _edit_json(path: Path, **changes: object) -> None:
    data = json.loads(path.read_text())
    data.update(changes)
    path.write_text(json.dumps(data))


def test_a_manifest_target_the_centerline_lacks_is_refused_where_the_folder_loads(
        tube: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = json.loads((tube / "manifest.json").read_text())
    _edit_json(tube / "manifest.json",
               targets={**manifest["targets"], "T3": manifest["targets"]["A"]})
    with pytest.raises(VesselFolderError, match=r"centerline.json.*\['T3'\]"):
        vessels.load(tube)
    before = snapshot(tube)
    # `vessel check` passed it, and `evaluate expert` then ended in KeyError: 'T3'.
    for args in (["vessel", "check", tube], ["evaluate", "expert", "--vessel", tube]):
        status, err = run_cli(args, capsys)
        assert_refused(status, err, "T3", str(tube))
    assert snapshot(tube) == before


@pytest.mark.parametrize(("file", "error"), [("manifest.json", ManifestError),
                                             ("centerline.json", CenterlineError)])
def test_a_folder_from_a_newer_layout_is_refused_naming_both_versions(
        tube: Path, file: str, error: type[Exception],
        capsys: pytest.CaptureFixture[str]) -> None:
    _edit_json(tube / file, schema_version=99)
    with pytest.raises(error, match=r"version 99, newer than the version 1"):
        vessels.load(tube)
    status, err = run_cli(["vessel", "check", tube], capsys)
    assert_refused(status, err, "99", "version 1", file)


def test_gymnasium_step_after_the_episode_ended_says_to_reset() -> None:
    env = NavigationEnv("simplified_phantom", "task_a", {"random": 0}, {"time_limit": 0.15})
    with pytest.raises(gymnasium.error.ResetNeeded, match=r"call reset\(\)"):
        env.step([1.0, 0.0])  # before the first reset
    env.reset(seed=0)
    ended = False
    for _ in range(5):
        _, _, terminated, truncated, _ = env.step([1.0, 0.0])
        ended = terminated or truncated
        if ended:
            break
    assert ended
    with pytest.raises(gymnasium.error.ResetNeeded, match=r"call reset\(\)"):
        env.step([1.0, 0.0])
    env.reset()
    env.step([1.0, 0.0])  # a new episode steps again


@pytest.mark.parametrize("command", ["train", "vessel build", "export", "train generalist"])
def test_a_second_writer_of_an_output_folder_is_refused_while_the_first_holds_it(
        tmp_path: Path, tube: Path, command: str, capsys: pytest.CaptureFixture[str]) -> None:
    # Two `train` runs into one --out both exited 0, and the run's logs held every row twice.
    out = tmp_path / "out"
    mesh = tmp_path / "tube.stl"
    trimesh.creation.cylinder(radius=1.5, height=20.0, sections=24).export(mesh)
    args = {
        "train": ["train", "sac", "--domain", "simplified_phantom", "--task", "task_a",
                  "--frames", "10", "--out", out],
        "vessel build": ["vessel", "build", mesh, "--name", "t", "--out", out, "--units", "mm",
                         "--no-progress"],
        "export": ["export", tube, "--out", out],
        "train generalist": ["train", "generalist", "--out", out],
    }[command]
    with exclusive_output(out):
        status, err = run_cli(args, capsys)
    assert_refused(status, err, str(out), "another sim4endor process")
    assert not out.exists() or not any(out.iterdir())
    assert not list(tmp_path.glob(".*.lock"))  # the first writer's lock is gone with it
