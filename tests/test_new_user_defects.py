"""What a new user hit (issue 78): each defect of the fresh-clone walk-through and the bad-input
audit, as that user met it, with the behaviour it has now."""

from __future__ import annotations

import json
import shlex
from pathlib import Path

import gymnasium
import pytest
import trimesh
from cli_helpers import assert_refused, run_cli, snapshot
from guidewire_helpers import write_tube_vessel

from sim4endor import assets, suite, vessels
from sim4endor._atomic import exclusive_output
from sim4endor.cli import build_parser, main
from sim4endor.envs.gym import NavigationEnv
from sim4endor.rl.config import EnvConfig
from sim4endor.vessels import VesselFolderError
from sim4endor.vessels.centerline import CenterlineError
from sim4endor.vessels.manifest import ManifestError


@pytest.fixture(autouse=True)
def _private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


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


def test_render_runs_the_tasks_whole_episode_unless_told_otherwise(tube: Path) -> None:
    # `render` stopped at 400 steps (20 s), half a coronary wire's 40 s episode.
    from sim4endor.cli import render

    env = suite.load("vessel", "navigate", {"vessel": str(tube), "target": "A",
                                            "wire": "workhorse"})
    assert render.step_budget(env, None) == 800
    assert render.step_budget(env, 10) == 10
    phantom = suite.load("simplified_phantom", "task_a")
    assert render.step_budget(phantom, None) == 400 == render.step_budget(phantom, 1000)
    parser = build_parser()
    assert parser.parse_args(["render", "--out", "x.mp4"]).max_steps is None


def test_a_runs_policy_renders_in_another_domain_without_its_tree_pool(tmp_path: Path) -> None:
    # `render vessel navigate --vessel DIR --target T2 --policy generalist` failed: Unknown
    # task_kwargs ['pool_seed', 'pool_size'] for vessel/navigate.
    from sim4endor.cli.args import env_config
    from sim4endor.rl.runs import run_config

    base = run_config(assets.run_or_policy("generalist")).env
    assert base.pool_size is not None
    args = build_parser().parse_args(["render", "vessel", "navigate", "--vessel", "x",
                                      "--target", "T2", "--policy", "generalist"])
    env = env_config(args, base)
    assert (env.domain, env.vessel, env.target) == ("vessel", "x", "T2")
    assert env.pool_size is None and env.pool_seed is None and env.eval_pool_seed is None
    assert (env.observations, env.wire, env.tip) == (base.observations, base.wire, base.tip)


def test_the_documented_json_wire_is_taken_and_a_bad_one_refused_before_any_work(
        capsys: pytest.CaptureFixture[str]) -> None:
    wire = '{"preset": "paper", "chain_bodies": 6}'  # as docs/performance.md shows it
    env = EnvConfig(domain="vascular_phantom", task="task_a", wire=wire)
    assert env.task_kwargs(0)["wire"] == {"preset": "paper", "chain_bodies": 6}
    status, err = run_cli(["evaluate", "generalist", "--domain", "coronary", "--task",
                           "navigate", "--wire", '{"preset": "paper", "chain_bodys": 6}'],
                          capsys)
    assert_refused(status, err, "chain_bodys")


def test_vessel_check_speaks_in_words_and_a_built_folder_names_its_command(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mesh = tmp_path / "tube.stl"
    trimesh.creation.cylinder(radius=1.5, height=20.0, sections=24).export(mesh)
    out = tmp_path / "built"
    build = ["vessel", "build", str(mesh), "--name", "t", "--out", str(out), "--units", "mm",
             "--no-progress", "--workers", "1"]
    assert main(build) == 0
    # The README names the command, as `vessel check`'s advice to rebuild a folder assumes.
    assert shlex.join(["sim4endor", *build]) in (out / "README.md").read_text()
    capsys.readouterr()
    assert main(["vessel", "check", str(out)]) == 0
    line = capsys.readouterr().out.strip()
    assert "checked again: lumen open" in line and line.endswith("passed")
    assert "{" not in line and "-0.0" not in line


def test_an_unwritable_out_is_named_not_its_hidden_staging_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    # Root writes into a read-only folder, so the refusal is the operating system's, raised
    # where the staging file is made; it named the hidden temp path (.config.yaml.x1y2).
    import tempfile

    def refuse(*args: object, **kwargs: object) -> None:
        raise PermissionError(13, "Permission denied", str(tmp_path / "run" / ".config.yaml.x1"))

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    out = tmp_path / "run"
    status, err = run_cli(["train", "sac", "--domain", "simplified_phantom", "--task",
                           "task_a", "--frames", "10", "--out", out], capsys)
    assert_refused(status, err, str(out / "config.yaml"), "not writable")
    assert ".x1" not in err


def test_a_folder_passed_as_the_mesh_is_called_a_folder(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "segmentation"
    folder.mkdir()
    (folder / "lumen.stl").write_text("solid x\nendsolid x\n")
    status, err = run_cli(["vessel", "build", folder, "--name", "t", "--out", tmp_path / "o",
                           "--units", "mm"], capsys)
    assert_refused(status, err, str(folder), "is a folder", "lumen.stl")


def test_export_refuses_a_folder_of_other_files(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # train and vessel build refused a non-empty unrelated --out; export wrote into it.
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("years of work\n")
    before = snapshot(out)
    status, err = run_cli(["export", "generalist", "--out", out], capsys)
    assert_refused(status, err, str(out), "thesis.tex")
    assert snapshot(out) == before


def test_a_negative_list_is_a_value_not_an_option(capsys: pytest.CaptureFixture[str]) -> None:
    # `--tip -3,75` read as an unknown flag ("--tip: expected one argument"), and so did an
    # inlet below the origin.
    args = build_parser().parse_args(["vessel", "build", "m.stl", "--name", "v", "--inlet",
                                      "-10,0,2.5", "--target", "T1=-1e-3,-2,3"])
    assert list(args.inlet) == [-10.0, 0.0, 2.5]
    status, err = run_cli(["train", "sac", "--wire", "workhorse", "--tip", "-3,75", "--out",
                           "x"], capsys)
    assert_refused(status, err, "--tip", "'-3,75'", "1-5 mm")


def test_trainings_final_evaluation_shows_its_progress(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # `train` printed nothing for ~3 min during its final evaluation on a coronary task.
    from rl_testing import pendulum_env, tiny_config

    from sim4endor.rl.trainer import train

    config = tiny_config("sac")
    train(config, tmp_path / "run", make_env=pendulum_env, progress=True)
    err = capsys.readouterr().err
    assert "evaluate: 100%" in err and f"{config.eval.trials}/{config.eval.trials}" in err


def test_the_probing_experts_evaluation_shows_its_steps_and_probes(
        tube: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # 526 s for 6 episodes on a real tree with a bar that moved once per target: the probes
    # (look-ahead on copies of the physics) hold the episode for seconds at a time.
    assert main(["evaluate", "probing-expert", "--vessel", str(tube)]) == 0
    err = capsys.readouterr().err
    assert "tube: 100%" in err and "A: 100%" in err  # the targets, the target's episodes
    steps = [line for line in err.replace("\r", "\n").splitlines() if line.startswith("steps:")]
    assert steps and "probes=0/12, to_target=" in steps[-1]  # and the episode's steps


@pytest.mark.parametrize("baseline", ["insert", "random"])
def test_the_open_loop_baselines_run_on_a_vessel_folder_like_the_expert(
        tube: Path, baseline: str, capsys: pytest.CaptureFixture[str]) -> None:
    # They existed only inside --suite generalisation.
    status = main(["evaluate", baseline, "--vessel", str(tube), "--json", "--no-progress"])
    metrics = json.loads(capsys.readouterr().out)
    assert status == 0 and metrics["trials"] == 1 and set(metrics["targets"]) == {"A"}
    if baseline == "insert":  # the tube is straight: pushing reaches its end
        assert metrics["success_rate"] == 1.0


def test_onnx_export_says_only_what_it_wrote(tmp_path: Path,
                                             capfd: pytest.CaptureFixture[str]) -> None:
    # It printed four "torchvision is not installed" lines and a FutureWarning.
    out = tmp_path / "policy"
    assert main(["export", "generalist", "--out", str(out), "--onnx"]) == 0
    captured = capfd.readouterr()
    assert captured.out.split() == [str(out / name)
                                    for name in ("policy.pt", "policy.json", "policy.onnx")]
    assert "torchvision" not in captured.err and "Warning" not in captured.err
