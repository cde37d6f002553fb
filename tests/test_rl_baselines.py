"""Open-loop baselines and the expert, evaluated as trained policies are (tiny budgets)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from navigation_helpers import require_vessel

from sim4endor import vessels
from sim4endor.rl.baselines import (
    CONSTANT_GRID,
    ConstantAction,
    RandomActions,
    ScriptedExpert,
    best_constant,
    evaluate_baseline,
)
from sim4endor.rl.metrics import METRIC_KEYS


@pytest.fixture(autouse=True)
def phantom() -> None:
    require_vessel("simplified_phantom")


def test_constant_push_reports_the_trained_policies_metrics() -> None:
    metrics = evaluate_baseline("simplified_phantom", "task_a", ConstantAction(1.0, 0.0),
                                episodes=1, seed=0)
    assert tuple(metrics) == METRIC_KEYS
    assert metrics["trials"] == 1
    assert metrics["outcomes"] == {"success": 1}  # the paper's task A falls to a push
    assert 0.0 < metrics["spl"] <= 1.0


def test_random_actions_are_seeded() -> None:
    def run(seed: int) -> dict[str, object]:
        return evaluate_baseline("simplified_phantom", "task_a", RandomActions(seed),
                                 episodes=1, seed=0, max_steps=5)

    assert run(1) == run(1)
    assert run(1)["mean_path_length_m"] != run(2)["mean_path_length_m"]
    assert run(1)["outcomes"] == {"timeout": 1}  # cut at max_steps


def test_the_expert_drives_through_the_torchrl_env() -> None:
    metrics = evaluate_baseline("simplified_phantom", "task_b", ScriptedExpert(),
                                episodes=1, seed=0)
    assert metrics["success_rate"] == 1.0


def test_best_constant_ranks_by_success_then_time() -> None:
    assert len(CONSTANT_GRID) == 14 and (1.0, 0.0) in CONSTANT_GRID
    chosen, tried = best_constant("simplified_phantom", "task_a", episodes=1, seed=0,
                                  grid=((0.5, 0.0), (1.0, 0.0)))
    assert chosen == ConstantAction(1.0, 0.0)  # both succeed; the faster push wins
    assert set(tried) == {ConstantAction(0.5, 0.0), ConstantAction(1.0, 0.0)}
    assert chosen.label == "constant [1, 0]"


def test_the_steve_anatomy_is_built_once_into_a_folder_named_after_its_inputs(
        steve_bench_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Before, every suite run rebuilt one fixed folder, replacing it under any other suite run
    # (a bench worker) that had it open.
    from sim4endor import vessels
    from sim4endor.rl.generalisation import steve_vessel
    from sim4endor.vessels import build

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    builds: list[Path] = []

    def fake_build(*args: object, out_dir: Path, **kwargs: object) -> None:
        builds.append(out_dir)  # a small shipped vessel stands in for the stEVE build
        shutil.copytree(vessels.resolve("simplified_phantom"), out_dir)

    monkeypatch.setattr(build, "build_vessel", fake_build)
    first = steve_vessel(steve_bench_dir)
    assert first is not None and len(builds) == 1
    assert first.root.parent == tmp_path / "sim4endor" / "steve"
    assert first.root.name.startswith("steve_dualdevicenav_")  # + a hash of the inputs
    built = {p: p.stat().st_mtime_ns for p in first.root.rglob("*")}
    second = steve_vessel(steve_bench_dir)
    assert second is not None and second.root == first.root and len(builds) == 1
    assert {p: p.stat().st_mtime_ns for p in second.root.rglob("*")} == built
    assert steve_vessel(tmp_path / "no_such_folder") is None


def test_the_suite_reports_wide_implicit_and_real_anatomy_as_their_own_groups() -> None:
    from sim4endor.rl.generalisation import GROUPS, SuiteConfig, suite_cases

    folder = vessels.load("vascular_phantom").root  # any built folder stands in for a patient's
    config = SuiteConfig(trees=1, wide_trees=1, implicit_trees=0, real=(folder,),
                         steve_dir=None)
    cases = suite_cases(config, "generalist")
    groups = list(dict.fromkeys(case.group for case in cases))
    assert groups == ["held_out_trees", "wide_trees", "real", "phantoms"]
    assert groups == [group for group in GROUPS if group in groups]  # the reported order
    wide = [case for case in cases if case.group == "wide_trees"]
    normal = [case for case in cases if case.group == "held_out_trees"]
    assert all(case.label.startswith("wide_left_coronary_01000 ") for case in wide)
    assert {case.env.anatomy for case in wide} == {"wide"}
    assert {case.env.anatomy for case in normal} == {None}
    real = [case for case in cases if case.group == "real"]
    assert [case.env.target for case in real] == sorted(vessels.load(folder).targets)
    assert {case.env.vessel for case in real} == {str(folder)}


def test_the_moving_heart_runs_every_group_but_the_phantoms_again_as_its_own_group() -> None:
    from sim4endor.rl.generalisation import MOVING, SuiteConfig, ordered_groups, suite_cases

    folder = vessels.load("vascular_phantom").root
    still = suite_cases(SuiteConfig(trees=1, wide_trees=0, implicit_trees=0, real=(folder,),
                                    steve_dir=None), "generalist")
    cases = suite_cases(SuiteConfig(trees=1, wide_trees=0, implicit_trees=0, real=(folder,),
                                    steve_dir=None, motion=True, randomise=True), "generalist")
    assert ordered_groups(case.group for case in cases) == [
        "held_out_trees", "held_out_trees moving", "real", "real moving", "phantoms"]
    moving = [case for case in cases if case.group.endswith(MOVING)]
    assert [case.label for case in moving] == [case.label + MOVING for case in still
                                               if case.group != "phantoms"]
    assert {case.env.motion for case in moving} == {True}
    assert {case.env.motion for case in cases if case not in moving} == {None}
    assert {case.env.randomise for case in cases} == {True}
    assert {case.env.randomise for case in still} == {None}


@pytest.mark.slow
def test_the_implicit_family_is_built_once_into_the_cache() -> None:
    from sim4endor.rl.generalisation import implicit_vessels

    first, = implicit_vessels(1)
    again, = implicit_vessels(1)
    assert again.root == first.root and first.name == "implicit_coronary_0"
    assert first.targets
