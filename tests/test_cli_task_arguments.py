"""Task arguments from the command line and YAML, evaluation splits, and the smaller CLI fixes."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from rl_testing import pendulum_env, tiny_config

from sim4endor import vessels
from sim4endor.cli import main
from sim4endor.models import wires
from sim4endor.rl import envs as rl_envs
from sim4endor.rl.config import ConfigError, EnvConfig, apply_overrides, default_config
from sim4endor.rl.export import ExportError, export_policy
from sim4endor.rl.plots import read_scalar, scalar_names
from sim4endor.rl.trainer import train


def test_env_config_gives_only_the_task_arguments_set() -> None:
    config = apply_overrides(default_config("sac"), [
        "env.domain=random_coronary", "env.task=navigate", "env.pool_seed=3",
        "env.pool_size=4", "env.eval_pool_seed=1000", "env.wire=workhorse",
    ]).env
    assert config.task_kwargs(7) == {"random": 7, "reward": "manifold", "observations": (),
                                     "wire": "workhorse", "pool_seed": 3, "pool_size": 4}
    assert config.task_kwargs(7, evaluation=True)["pool_seed"] == 1000
    assert EnvConfig().task_kwargs(0) == {"random": 0, "reward": "manifold", "observations": ()}


@pytest.mark.parametrize(("override", "message"), [
    ("env.pool_size=0", "env.pool_size must be > 0"),
    ("env.pool_seed=-1", "env.pool_seed must be >= 0"),
    ("env.eval_pool_seed=5", "env.eval_pool_seed needs env.pool_size"),
    ("env.target=[1]", "cannot read"),
])
def test_bad_task_arguments_name_the_field(override: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        apply_overrides(default_config("sac"), [override])


def test_training_evaluates_on_the_evaluation_split(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[dict[str, Any]] = []

    def fake(domain: str, task: str, task_kwargs: dict[str, Any]) -> Any:
        seen.append(task_kwargs)
        return pendulum_env(task_kwargs["random"])

    monkeypatch.setattr("sim4endor.envs.make_torchrl_env", fake)
    config = EnvConfig(domain="random_coronary", task="navigate", pool_seed=0, pool_size=8,
                       eval_pool_seed=100)
    rl_envs.env_factory(config)(1)
    rl_envs.env_factory(config, evaluation=True)(2)
    assert [(s["random"], s["pool_seed"]) for s in seen] == [(1, 0), (2, 100)]


def _cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    status = main(argv)
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_train_flags_reach_the_config_and_a_refused_argument_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    status, _, err = _cli(["train", "sac", "--vessel", "simplified_phantom", "--target", "A",
                           "--frames", "10", "--out", str(out), "--no-progress"], capsys)
    # The default domain (simplified_phantom) takes no vessel: refused by name, before any file.
    assert status == 2 and "Unknown task_kwargs ['target', 'vessel']" in err
    assert not out.exists()


def test_an_unknown_wire_preset_is_refused_by_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    status, _, err = _cli(["train", "sac", "--wire", "floppy", "--frames", "10", "--out",
                           str(out), "--no-progress"], capsys)
    assert status == 2 and "floppy" in err and "workhorse" in err
    assert not out.exists()


def test_a_tip_shape_reaches_the_task_and_a_bad_one_is_refused_by_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--tip LENGTH_MM,ANGLE_DEG|J`` shapes the ``--wire`` preset's tip in every command that
    takes task arguments, and a run stores it as written."""
    config = apply_overrides(default_config("sac"), ["env.wire=workhorse", "env.tip=1.5,60"])
    wire = wires.resolve(config.env.task_kwargs(0)["wire"])
    assert (wire.tip_length, wire.tip_angle) == pytest.approx((0.0015, math.radians(60)))
    assert wires.resolve(EnvConfig(wire="stiff", tip="j").task_kwargs(0)["wire"]).tip_angle \
        == pytest.approx(wires.J_ANGLE)
    curved = wires.resolve(EnvConfig(wire="workhorse", tip="2,60,7,40").task_kwargs(0)["wire"])
    assert (curved.secondary_distance, curved.secondary_angle) == pytest.approx(
        (0.007, math.radians(40)))
    with pytest.raises(ConfigError, match=r"env\.tip='3,75' shapes the tip of env\.wire"):
        EnvConfig(tip="3,75")
    with pytest.raises(ConfigError, match=r"env\.tip: Tip shape '3,95'.*30-90 deg"):
        EnvConfig(wire="workhorse", tip="3,95")
    out = tmp_path / "run"
    for tip, message in (("3x75", "(e.g. 2,60,7,40), or J; got '3x75'"),
                         ("6,60", "length must be 1-5 mm")):
        with pytest.raises(SystemExit) as exited:  # argparse's own refusal
            main(["train", "sac", "--wire", "workhorse", "--tip", tip, "--out", str(out)])
        err = capsys.readouterr().err
        assert exited.value.code == 2 and "argument --tip: " in err and message in err
    status, _, err = _cli(["train", "sac", "--tip", "3,75", "--frames", "10", "--out",
                           str(out), "--no-progress"], capsys)
    assert status == 2 and "name the wire preset too" in err
    assert not out.exists()


def test_render_needs_a_task_unless_the_policy_is_a_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    status, _, err = _cli(["render", "--policy", "insert", "--out", str(tmp_path / "a.mp4")],
                          capsys)
    assert status == 2 and "Name a DOMAIN and TASK" in err
    status, _, err = _cli(["render", "vessel", "--out", str(tmp_path / "a.mp4")], capsys)
    assert status == 2 and "Name both DOMAIN and TASK" in err


def test_reports_read_tensorboard_logs(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    train(tiny_config("sac", "logger.backend=tensorboard"), run_dir, make_env=pendulum_env,
          progress=False)
    assert not (run_dir / "logs" / "scalars").exists()
    frames, values = read_scalar(run_dir, "eval/success_rate")
    assert frames.tolist() == [100.0, 200.0] and values.shape == (2,)
    assert scalar_names([run_dir], "train/reward") == ["train/reward"]


def test_export_command_and_reexport_of_an_exported_policy(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run_dir = tmp_path / "run"
    train(tiny_config("sac"), run_dir, make_env=pendulum_env, progress=False)
    first = export_policy(run_dir, tmp_path / "first", make_env=pendulum_env)
    # The CLI takes the exported folder (or its policy.pt) and adds ONNX to a copy.
    status, out, _ = _cli(["export", str(first[0]), "--out", str(tmp_path / "again"),
                           "--onnx"], capsys)
    assert status == 0 and [Path(p).name for p in out.split()] == [
        "policy.pt", "policy.json", "policy.onnx"]
    contract = json.loads((tmp_path / "again" / "policy.json").read_text())
    # Pendulum's 3 inputs are no sim4endor observation: no invented entries.
    assert contract["observation"]["entries"] is None
    assert contract["observation"]["shape"][-1] == 3
    with pytest.raises(ExportError, match="neither a training run folder"):
        export_policy(tmp_path, tmp_path / "x")


def test_a_vessel_prints_in_one_line() -> None:
    text = repr(vessels.load("simplified_phantom"))
    assert "\n" not in text and len(text) < 300
    assert "hulls=481" in text and "targets=['A', 'B']" in text


def test_an_automatic_inlet_among_equal_ends_is_reported(tmp_path: Path) -> None:
    import numpy as np
    import trimesh

    from sim4endor.vessels.build import BuildParams, build_vessel
    from sim4endor.vessels.walls import WallParams

    fork = np.array([30.0, 0.0, 0.0])
    parts = [trimesh.creation.cylinder(radius=1.7, segment=[np.zeros(3), fork], sections=64),
             trimesh.creation.icosphere(subdivisions=4, radius=1.7).apply_translation(fork)]
    for side in (1, -1):
        end = fork + 25.0 * np.array([np.cos(0.6), side * np.sin(0.6), 0.0])
        parts.append(trimesh.creation.cylinder(radius=1.7, segment=[fork, end], sections=64))
    lumen = trimesh.boolean.union(parts, engine="manifold")
    params = BuildParams(wall=WallParams(use_coacd=False, workers=1))
    vessel = build_vessel(lumen, name="eq", out_dir=tmp_path / "eq", units="mm", params=params,
                          progress=False, cache=False)
    assert "another end is within 10 %" in vessel.manifest.build["inlet_choice"]
    given = build_vessel(lumen, name="eq", out_dir=tmp_path / "given", units="mm",
                         params=params, progress=False, cache=False, inlet=np.zeros(3))
    assert "inlet_choice" not in given.manifest.build
    assert np.linalg.norm(given.inlet_position) < 1e-3


def test_evaluate_on_another_task_prints_but_keeps_the_runs_evaluation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run_dir = tmp_path / "run"
    train(tiny_config("sac", "eval.max_steps=5", "eval.trials=1"), run_dir, progress=False)
    saved = (run_dir / "evaluation.json").read_text()
    status, out, err = _cli(["evaluate", str(run_dir), "--trials", "1", "--json", "--no-progress",
                             "--domain", "vascular_phantom", "--task", "task_b"], capsys)
    assert status == 0, err
    assert json.loads(out)["trials"] == 1
    assert (run_dir / "evaluation.json").read_text() == saved


def test_evaluate_runs_the_trees_named_not_the_runs_held_out_split(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # The shipped generalist evaluates on held-out trees 1000 on; --pool-seed 1003 once gave
    # tree 1000 ("has no target 'AM'").
    from sim4endor import assets
    from sim4endor.rl import runs

    seen: dict[str, object] = {}

    def fake_evaluate_run(run_dir: Path, **kwargs: object) -> dict[str, float]:
        seen.update(kwargs["task_arguments"])  # type: ignore[arg-type]
        return {"success_rate": 1.0}

    monkeypatch.setattr(runs, "evaluate_run", fake_evaluate_run)
    status, _, err = _cli(["evaluate", "generalist", "--domain", "coronary", "--task", "navigate",
                           "--pool-seed", "1003", "--pool-size", "1", "--target", "AM",
                           "--json", "--no-progress"], capsys)
    assert status == 0, err
    config = runs.evaluation_env(runs.run_config(assets.run_or_policy("generalist")).env, seen)
    assert config.pool_seed == 1003 and config.eval_pool_seed is None
    assert config.task_kwargs(0, evaluation=True)["pool_seed"] == 1003


def test_a_tree_pool_run_evaluates_on_a_phantom_domain(
    capsys: pytest.CaptureFixture[str]
) -> None:
    # The generalist's config names a coronary tree pool; a phantom takes no pool arguments.
    status, out, err = _cli(["evaluate", "generalist", "--domain", "simplified_phantom",
                             "--task", "task_a", "--trials", "1", "--json", "--no-progress"],
                            capsys)
    assert status == 0, err
    assert json.loads(out)["trials"] == 1


def test_training_on_the_generalist_observation_set(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--observations generalist`` trains, evaluates (path length from the info's tip
    position) and exports with every tip-frame entry named in the policy contract."""
    run = tmp_path / "run"
    budget = ["collector.total_frames=60", "collector.frames_per_batch=30",
              "collector.init_random_frames=30", "optim.updates_per_batch=4",
              "network.hidden_sizes=[16]", "eval.trials=1",
              "eval.max_steps=10", "eval.interval_frames=60", "logger.backend=csv"]
    args = ["train", "sac", "--observations", "generalist", "--out", str(run), "--no-progress"]
    for override in budget:
        args += ["--set", override]
    status, _, err = _cli(args, capsys)
    assert status == 0, err
    evaluation = json.loads((run / "evaluation.json").read_text())
    assert evaluation["mean_path_length_m"] > 0  # tips read from info, not the observation
    status, _, err = _cli(["export", str(run), "--out", str(tmp_path / "policy")], capsys)
    assert status == 0, err
    contract = json.loads((tmp_path / "policy" / "policy.json").read_text())
    entries = {e["name"]: e for e in contract["observation"]["entries"]}
    assert next(iter(entries)) == "path_ahead" and entries["path_ahead"]["slice"] == [0, 24]
    assert contract["observation"]["shape"][-1] == 36
    # The default input factors follow the set: one per number, the route ahead ×50.
    assert contract["observation"]["scale_inside_network"][:24] == [50.0] * 24
    assert len(contract["observation"]["scale_inside_network"]) == 36
    assert contract["environment"]["task_kwargs"]["observations"] == "generalist"


def test_extra_observations_extend_the_paper_set_only() -> None:
    with pytest.raises(ConfigError, match="extend the 'paper' set only"):
        EnvConfig(observations="generalist", extra_observations=("rotation",))
    with pytest.raises(ConfigError, match=r"env\.observations must be one of"):
        EnvConfig(observations="everything")


def test_generalisation_suite_on_a_tiny_budget(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    """``evaluate RUN --suite generalisation``: the policy and the reference rows per group,
    a per-target breakdown, and a missing stEVE folder skipped with a message."""
    run = tmp_path / "run"
    args = ["train", "sac", "--observations", "generalist", "--frames", "30", "--out", str(run),
            "--no-progress", "--set", "collector.frames_per_batch=30",
            "--set", "collector.init_random_frames=30", "--set", "network.hidden_sizes=[8]",
            "--set", "eval.trials=1", "--set", "eval.max_steps=3"]
    assert _cli(args, capsys)[0] == 0
    patient = vessels.load("simplified_phantom").root  # a built folder stands in for one
    status, out, err = _cli(["evaluate", str(run), "--suite", "generalisation", "--trees", "1",
                             "--wide-trees", "1", "--implicit-trees", "0", "--real",
                             str(patient), "--max-steps", "3", "--steve",
                             str(tmp_path / "none"), "--json", "--no-progress"], capsys)
    assert status == 0, err
    result = json.loads(out)
    rows = result["rows"]
    assert list(rows) == ["policy (run)", "scripted expert (privileged)", "constant push [1, 0]",
                          next(r for r in rows if r.startswith("best constant")),
                          "uniform random"]
    for groups in rows.values():
        # stEVE absent: skipped; no implicit trees asked for.
        assert list(groups) == ["held_out_trees", "wide_trees", "real", "phantoms"]
        assert {"success_rate", "spl", "max_tip_force_n"} <= set(groups["phantoms"])
    assert groups["phantoms"]["trials"] == 4
    assert "simplified_phantom task_a" in result["targets"]
    assert any(label.startswith("left_coronary_01000 ") for label in result["targets"])
    assert any(label.startswith("wide_left_coronary_01000 ") for label in result["targets"])
    assert "steve: skipped" in caplog.text
    # In 3 steps the probing expert reaches neither real target: both reported, with why.
    reach = result["reachability"]
    assert sorted(reach) == ["simplified_phantom A", "simplified_phantom B"]
    assert {r["outcome"] for r in reach.values()} == {"timeout"}
    assert all(r["reason"].startswith("timeout; lumen ") for r in reach.values())
    assert result["real_reachable"] == {"successes": 0, "reachable": 0, "targets": 2}


def test_a_shipped_policy_by_name_on_every_target_of_a_vessel_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A name under sim4endor/policies is a run folder: ``evaluate NAME --vessel DIR --json``
    runs every target and never writes into the package; render and export take the name."""
    from sim4endor import assets

    shelf = tmp_path / "policies"
    assert _cli(["train", "sac", "--observations", "generalist", "--frames", "30", "--out",
                 str(shelf / "tiny"), "--no-progress",
                 "--set", "collector.frames_per_batch=30",
                 "--set", "collector.init_random_frames=30", "--set", "network.hidden_sizes=[8]",
                 "--set", "eval.trials=1", "--set", "eval.max_steps=3"], capsys)[0] == 0
    (shelf / "tiny" / "evaluation.json").unlink()
    monkeypatch.setattr(assets, "policies_dir", lambda: shelf)
    assert assets.policy_names() == ("tiny",)
    vessel = str(vessels.load("simplified_phantom").root)
    status, out, err = _cli(["evaluate", "tiny", "--vessel", vessel, "--trials", "1",
                             "--json", "--no-progress"], capsys)
    assert status == 0, err
    metrics = json.loads(out)
    assert {"success_rate", "mean_completion_time_s", "max_tip_force_n"} <= set(metrics)
    assert sorted(metrics["targets"]) == ["A", "B"] and metrics["trials"] == 2
    status, _, err = _cli(["evaluate", "tiny", "--vessel", vessel, "--target", "A",
                           "--trials", "1", "--no-progress"], capsys)
    assert status == 0, err
    assert not (shelf / "tiny" / "evaluation.json").exists()  # the package is never written
    status, out, err = _cli(["export", "tiny", "--out", str(tmp_path / "exported")], capsys)
    assert status == 0 and (tmp_path / "exported" / "policy.json").is_file(), err


@pytest.mark.parametrize("expert", ["expert", "probing-expert"])
def test_a_scripted_expert_on_every_target_of_a_vessel_folder(
    expert: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """``evaluate expert|probing-expert --vessel DIR``: the reachability check of a user's own
    anatomy, with the metrics and per-target breakdown of a policy's; both experts reach both
    phantom targets (docs/tasks/index.md: 8/8 each)."""
    vessel = str(vessels.load("simplified_phantom").root)
    status, out, err = _cli(["evaluate", expert, "--vessel", vessel, "--wire", "workhorse",
                             "--trials", "1", "--json", "--no-progress"], capsys)
    assert status == 0, err
    metrics = json.loads(out)
    assert sorted(metrics["targets"]) == ["A", "B"] and metrics["trials"] == 2
    assert metrics["success_rate"] == 1.0
    assert metrics["max_tip_force_n"] > 0.0
    for extra in ([], ["--vessel", vessel, "--target", "A"]):
        status, _, err = _cli(["evaluate", expert, *extra, "--trials", "1"], capsys)
        assert status == 2 and f"'{expert}' runs on every target" in err


def test_the_suite_and_a_vessel_run_a_policy_with_the_tip_it_was_trained_with(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A run trained with ``--tip 5,60`` meets that tip in ``evaluate RUN --suite`` and
    ``--vessel`` unless ``--tip`` names another; an expert row keeps the preset's."""
    from sim4endor.rl import baselines, generalisation
    from sim4endor.rl.config import save_config

    run = tmp_path / "run"
    run.mkdir()
    save_config(apply_overrides(default_config("sac"), [
        "env.domain=coronary", "env.task=navigate", "env.observations=generalist",
        "env.wire=workhorse", "env.tip=5,60"]), run / "config.yaml")
    tips: list[str | None] = []

    def fake_run_cases(cases: list[generalisation.Case], *args: object,
                       **kwargs: object) -> dict[str, list[object]]:
        tips.extend(case.env.tip for case in cases)
        return {case.label: [] for case in cases}

    monkeypatch.setattr(generalisation, "run_cases", fake_run_cases)
    monkeypatch.setattr(generalisation, "summarize", lambda episodes: {"success_rate": 0.0})
    vessel = vessels.load("simplified_phantom").root
    config = generalisation.SuiteConfig(trees=1, steve_dir=None)
    generalisation.evaluate_suite(run, config, with_baselines=False)
    generalisation.evaluate_vessel(run, vessel, config)
    assert tips and set(tips) == {"5,60"}
    tips.clear()
    generalisation.evaluate_vessel(run, vessel, generalisation.SuiteConfig(tip="3,75"))
    generalisation.evaluate_vessel(baselines.ScriptedExpert(), vessel, config)
    assert tips == ["3,75", "3,75", None, None]
