"""The regression verdict: a candidate against the policy it would replace, case by case."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest
from navigation_helpers import require_vessel

from sim4endor import assets, vessels
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl import reachability, regression
from sim4endor.rl.generalisation import SuiteConfig, suite_cases
from sim4endor.rl.metrics import Episode


def _episode(success: bool, travelled: float = 0.1, tip_force: float = 0.2) -> Episode:
    """An episode 0.1 m from its target that travelled ``travelled`` m (SPL 0.1 / travelled)."""
    return Episode(tip_positions=np.array([[0.0, 0.0, 0.0], [travelled, 0.0, 0.0]]),
                   success=success, duration_s=5.0, wall_forces=np.zeros(3),
                   shortest_path_m=0.1, tip_forces=np.array([0.0, tip_force, np.nan]))


def _verdict(candidate: list[Episode], reference: list[Episode]) -> regression.GroupVerdict:
    labels = {f"tree {i}": "held_out_trees" for i in range(len(candidate))}
    ours = {label: [e] for label, e in zip(labels, candidate, strict=True)}
    theirs = {label: [e] for label, e in zip(labels, reference, strict=True)}
    verdict, = regression.compare(labels, ours, theirs)
    return verdict


def test_a_single_pair_has_no_noise_so_any_drop_counts() -> None:
    paired = regression.Paired.of([0.5], [0.6])
    assert paired.standard_error == 0.0 and paired.below() and not paired.above()
    assert not regression.Paired.of([0.6], [0.6]).below()


def test_fewer_successes_make_a_candidate_worse() -> None:
    verdict = _verdict([_episode(True), _episode(False)], [_episode(True), _episode(True)])
    assert (verdict.successes, verdict.reference_successes, verdict.episodes) == (1, 2, 2)
    assert "successes" in verdict.worse


def test_spl_and_tip_force_count_only_beyond_two_standard_errors() -> None:
    reference = [_episode(True, 0.1, 0.2) for _ in range(4)]
    # Paths longer on half the targets, shorter nowhere: the drop is within its own noise.
    noisy = [_episode(True, t) for t in (0.1, 0.2, 0.1, 0.2)]
    assert _verdict(noisy, reference).worse == ()
    # Every path twice as long and every tip pressing harder: beyond the noise.
    longer = [_episode(True, t, f) for t, f in ((0.2, 0.3), (0.21, 0.31), (0.19, 0.3),
                                                (0.2, 0.29))]
    verdict = _verdict(longer, reference)
    assert verdict.worse == ("spl", "tip_force")
    assert verdict.spl.mean == pytest.approx(np.mean([0.1 / t - 1 for t in (0.2, 0.21, 0.19, 0.2)]))
    assert verdict.tip_force_n.mean == pytest.approx(0.1)  # the NaN step is ignored
    assert not regression.ships([verdict])


def test_a_student_keeps_nine_tenths_of_its_teachers_successes_and_no_more_tip_force_stops(
) -> None:
    from sim4endor.tasks import FAILURES

    assert regression.TIP_FORCE_STOP in FAILURES
    teacher = [_episode(True) for _ in range(10)]
    nine = [_episode(True) for _ in range(9)]
    missed = dataclasses.replace(_episode(False), failure="timeout")
    pressed = dataclasses.replace(_episode(False), failure=regression.TIP_FORCE_STOP)
    kept = _verdict([*nine, missed], teacher)
    assert (kept.successes, kept.tip_force_stops) == (9, 0)
    assert kept.short_of_teacher == () and regression.keeps([kept])
    assert "successes" in kept.worse  # as a replacement it would not ship
    stopped = _verdict([*nine, pressed], teacher)
    assert stopped.short_of_teacher == ("tip_force_stops",)
    eight = _verdict([*nine[:8], missed, missed], teacher)
    assert eight.short_of_teacher == ("successes",) and not regression.keeps([eight])
    table = regression.student_markdown({"reference": "teacher", "verdicts": {"s": [kept]},
                                         "keeps": {"s": True}})
    assert "| s | held_out_trees | 10 | 9 | 10 | 90 % | 0 (0) | – |" in table


def test_episodes_must_pair_one_to_one() -> None:
    with pytest.raises(Sim4EndoRError, match="'tree 0': 2 candidate and 1 reference"):
        regression.compare({"tree 0": "held_out_trees"},
                           {"tree 0": [_episode(True), _episode(True)]},
                           {"tree 0": [_episode(True)]})


def test_two_real_folders_of_one_vessel_are_refused() -> None:
    require_vessel("vascular_phantom")
    folder = vessels.load("vascular_phantom").root
    config = SuiteConfig(trees=0, wide_trees=0, implicit_trees=0, real=(folder, folder),
                         steve_dir=None)
    with pytest.raises(Sim4EndoRError, match="Two suite cases are labelled 'vascular_phantom"):
        suite_cases(config, "generalist")


@pytest.fixture
def shipped_and_copy(tmp_path: Path) -> tuple[Path, Path, SuiteConfig]:
    """The shipped policy, a copy of it under another name, and a suite of the phantoms'
    four targets cut to 8 steps an episode."""
    require_vessel("simplified_phantom")
    require_vessel("vascular_phantom")
    shipped = assets.run_or_policy("generalist")
    copy = shutil.copytree(shipped, tmp_path / "copy")
    return shipped, copy, SuiteConfig(trees=0, wide_trees=0, implicit_trees=0, steve_dir=None,
                                      max_steps=8)


def test_the_shipped_policy_against_a_copy_of_itself_differs_nowhere(
    shipped_and_copy: tuple[Path, Path, SuiteConfig]
) -> None:
    """Episodes are deterministic, and both policies meet the same cases: every paired
    difference is exactly zero, so the copy ships."""
    shipped, copy, config = shipped_and_copy
    result = regression.regression([copy], shipped, config)
    verdict, = result["verdicts"]["copy"]
    assert (verdict.group, verdict.episodes) == ("phantoms", 4)
    assert verdict.successes == verdict.reference_successes
    assert verdict.spl == verdict.tip_force_n == regression.Paired(0.0, 0.0)
    assert result["ships"] == {"copy": True}
    assert result["rows"]["copy"] == result["rows"]["generalist"]
    assert "| copy | phantoms | 4 |" in regression.markdown(result)
    with pytest.raises(Sim4EndoRError, match="distinct names"):
        regression.regression([shipped], shipped, config)


def test_a_policy_beside_the_evaluated_one_meets_the_same_cases(
    shipped_and_copy: tuple[Path, Path, SuiteConfig]
) -> None:
    """``--beside``: a row of its own after the evaluated policy's, on the same cases."""
    from sim4endor.rl.generalisation import evaluate_suite, markdown

    shipped, copy, config = shipped_and_copy
    result = evaluate_suite(copy, config, with_baselines=False, beside=(shipped,))
    assert list(result["rows"]) == ["policy (copy)", "policy (generalist)"]
    assert result["rows"]["policy (copy)"] == result["rows"]["policy (generalist)"]
    assert "| policy (generalist) | phantoms | " in markdown(result)


def test_a_real_target_out_of_reach_says_how_narrow_the_way_is() -> None:
    require_vessel("vascular_phantom")
    vessel = vessels.load("vascular_phantom")
    graph = vessel.centerline
    for target in vessel.targets:
        at_target, narrowest = reachability.route_calibre(vessel, target)
        assert at_target == graph.radii[graph.labels[target]]
        assert graph.radii.min() <= narrowest <= min(at_target, graph.radii[graph.labels["inlet"]])
    miss = reachability.Reach("tip_force", 0.25e-3, 0.2e-3, 1.234)
    assert not miss.reachable
    assert miss.reason() == ("tip_force (1.23 N); lumen 0.50 mm across at the target, 0.40 mm "
                             "at the narrowest")
    assert reachability.Reach("success", 1e-3, 1e-3, 0.1).reason() == ""


def test_the_suite_table_names_each_unreachable_real_target() -> None:
    from sim4endor.rl.generalisation import markdown

    reach = {"p T1": reachability.Reach("success", 1e-3, 1e-3, 0.1),
             "p T2": reachability.Reach("timeout", 0.12e-3, 0.12e-3, 0.0)}
    text = markdown({"rows": {}, "reachability": reachability.as_json(reach),
                     "real_reachable": {"successes": 1.0, "reachable": 1, "targets": 2}})
    assert "the policy reaches 1 of the 1 targets (of 2) the probing expert reaches" in text
    assert "- unreachable: p T2: timeout; lumen 0.24 mm across" in text
    assert "p T1" not in text


@pytest.mark.slow
def test_processes_give_the_same_verdict_as_one(
    shipped_and_copy: tuple[Path, Path, SuiteConfig]
) -> None:
    """Chunks of cases in spawned workers: the same episodes as in this process."""
    shipped, copy, config = shipped_and_copy
    alone = regression.regression([copy], shipped, config)
    spread = regression.regression([copy], shipped, config, jobs=2)
    assert spread["rows"] == alone["rows"] and spread["outcomes"] == alone["outcomes"]
