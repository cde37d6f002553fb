"""The scripted centerline expert reaches every target of the shipped phantoms.

This is the phantoms' reachability check: a target the expert cannot reach is a defect of the
geometry (the vascular phantom's target B once was: the wire always fell into the other child
at bifurcation 1), and no amount of training would show it as anything but a low success rate.
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import math
from pathlib import Path

import numpy as np
import pytest
from dm_control.rl import control
from script_helpers import load_script

from sim4endor import suite, vessels
from sim4endor.tasks.expert import (
    FIXED_AIM,
    CenterlineExpert,
    ExpertConfig,
    ProbeConfig,
    ProbingExpert,
    PullBackEntry,
    lookahead,
    run_expert,
)

PHANTOM_TASKS = [(domain, task) for domain in ("simplified_phantom", "vascular_phantom")
                 for task in ("task_a", "task_b")]
#: Seeded episodes per target, and how many must reach it.
EPISODES, REACHED = 16, 10


@pytest.mark.parametrize(("domain", "task"), PHANTOM_TASKS)
def test_expert_reaches_every_phantom_target(domain: str, task: str) -> None:
    """Statistical over seeds, not one seed: whether one episode reaches the target depends
    on the last bits of floating-point arithmetic (another CPU, another numpy), because the
    wire's contacts chatter and the tip-force stop reads one sample of it. Measured over 40
    seeds (``expert_reachability.py --episodes 40``, 2026-11-27): 40/40 on both simplified
    targets, 39/40 on vascular A (a tip-force stop) and 40/40 on vascular B (39/40, a timeout,
    by the expert that keeps one aim). A geometry defect (a target out of the wire's
    reach) gives 0 of 16; at a true rate of 0.85 the chance of fewer than 10 is 0.6 %.
    """
    env = suite.load(domain, task, {"random": 0})
    outcomes = []
    for seed in range(EPISODES):
        env.task.reseed(seed)
        info = run_expert(env)
        outcomes.append("reached" if info["is_success"] else str(info["failure"] or "timeout"))
    reached = outcomes.count("reached")
    assert reached >= REACHED, (
        f"the expert reached {domain}/{task} in {reached} of {EPISODES} seeded episodes: "
        f"{collections.Counter(outcomes)}"
    )


def test_expert_actions_stay_in_the_action_box_and_reset_forgets_the_episode() -> None:
    env = suite.load("simplified_phantom", "task_a", {"random": 0})
    expert = CenterlineExpert()
    env.reset()
    for _ in range(40):
        action = expert(env.physics, env.task)
        assert action.shape == (2,) and np.all(np.abs(action) <= 1.0)
        env.step(action)
    # A new episode starts far behind the tip's best distance of the last one: an expert not
    # reset reads that as a wrong branch and pulls back, a reset one pushes.
    env.reset()
    assert expert(env.physics, env.task)[0] == -1.0
    expert.reset()
    assert expert(env.physics, env.task)[0] > 0.0


def test_the_expert_reads_the_tip_of_the_wire_in_the_physics() -> None:
    """The body axis is measured behind the wire's own pre-bent tip: 5 mm for the paper
    wire (as ExpertConfig's old fixed default), 2 mm for the workhorse shaped 2 mm at 45°."""
    for wire, tip in (("paper", 0.005), ({"preset": "workhorse", "tip": "2,45"}, 0.002)):
        env = suite.load("simplified_phantom", "task_a", {"random": 0, "wire": wire})
        env.reset()
        points = env.physics.wire_points()
        start = env.physics.tip_start_index()
        assert env.physics.shape_start_index() == start  # no secondary curve
        arc = np.linalg.norm(np.diff(points[start:], axis=0), axis=1).sum()
        assert arc == pytest.approx(tip, rel=1e-6)
    # With a secondary curve the shaped part reaches back to it (7 +- 1 mm from the end, on
    # the vertices of the segment grid there): the body axis is read behind it.
    env = suite.load("simplified_phantom", "task_a",
                     {"random": 0, "wire": {"preset": "workhorse", "tip": "2,60,7,40"}})
    env.reset()
    points = env.physics.wire_points()
    start = env.physics.shape_start_index()
    assert start < env.physics.tip_start_index()
    arc = np.linalg.norm(np.diff(points[start:], axis=0), axis=1).sum()
    assert 0.006 - 1e-9 <= arc <= 0.008 + np.linalg.norm(points[start] - points[start - 1])
    fixed = CenterlineExpert(ExpertConfig(tip_length=0.005))
    read = CenterlineExpert()
    env = suite.load("simplified_phantom", "task_b", {"random": 0})
    env.reset()
    for _ in range(30):
        action = read(env.physics, env.task)
        np.testing.assert_allclose(action, fixed(env.physics, env.task))
        env.step(action)


def test_a_blocked_carriage_makes_the_expert_pull_back() -> None:
    env = suite.load("simplified_phantom", "task_a", {"random": 0})
    env.reset()
    expert = CenterlineExpert()
    assert expert(env.physics, env.task)[0] > 0.0
    insertion, rotation = env.physics.driver_targets()
    # The servo target 3 mm ahead of the carriage: it pushes at its force limit.
    env.physics.set_driver_targets(insertion + 0.003, rotation)
    expert.reset()
    assert expert(env.physics, env.task)[0] < 0.0


def test_a_lookahead_on_copies_leaves_the_episode_alone_and_replays_exactly() -> None:
    """ProbingExpert's plans rest on this: the copy's rollout does not touch the real
    physics or task, and the real episode, given the copy's actions, ends where the copy did
    (bit for bit: MuJoCo is deterministic and the copy carries the solver's warm start)."""
    env = suite.load("vascular_phantom", "task_b", {"random": 3})
    env.reset()
    for _ in range(20):
        env.step(np.array([0.8, 0.3]))
    before = env.physics.data.qpos.copy(), env.physics.driver_targets()
    substeps = env.task.config.action.physics_steps(env.physics.timestep())
    reached, closest, actions = lookahead(env.physics, env.task, CenterlineExpert(), substeps,
                                           steps=30)
    np.testing.assert_array_equal(env.physics.data.qpos, before[0])
    assert env.physics.driver_targets() == before[1]
    assert actions and not reached
    for action in actions:
        env.step(action)
    assert env.task.step_info()["manifold_distance"] == closest


def test_a_stuck_probing_expert_follows_the_best_aim_of_its_probe() -> None:
    env = suite.load("vascular_phantom", "task_b", {"random": 3})
    env.reset()
    # stall_steps=0: stuck from the first step, so the first call probes.
    expert = ProbingExpert(probe=ProbeConfig(roll_offsets_deg=(0.0, 90.0), horizon=25,
                                             stall_steps=0, max_probes=1, pull_back=False))
    first = expert(env.physics, env.task)
    assert expert.probes == 1
    substeps = env.task.config.action.physics_steps(env.physics.timestep())
    plans = [lookahead(env.physics, env.task,
                        CenterlineExpert(dataclasses.replace(FIXED_AIM, roll_offset_deg=offset)),
                        substeps, 25)
             for offset in (0.0, 90.0)]
    best = min(plans, key=lambda plan: (not plan[0], plan[1]))
    np.testing.assert_array_equal(first, best[2][0])
    env.step(first)
    for expected in best[2][1:]:
        np.testing.assert_array_equal(expert(env.physics, env.task), expected)
        env.step(expected)
    # Once its one probe is spent it steers as the plain expert with a fixed aim does.
    expert._plan.clear()
    plain = CenterlineExpert(FIXED_AIM)
    plain._best, plain._backing_off = expert._best, expert._backing_off
    np.testing.assert_array_equal(expert(env.physics, env.task), plain(env.physics, env.task))


def test_the_screen_replaces_a_step_that_would_fail_by_the_first_safe_fallback() -> None:
    """The insertion limit half a push step ahead: the plain expert pushes into it, the
    screened expert holds the insertion and keeps the plain expert's roll."""
    kwargs = {"random": 0}
    free = suite.load("simplified_phantom", "task_b", kwargs)
    free.reset()
    start, _ = free.physics.driver_targets()
    step = free.task.config.action.max_insertion_step
    limit = {"termination": {"max_insertion": start + 0.5 * step}}
    env = suite.load("simplified_phantom", "task_b", {**kwargs, **limit})
    env.reset()
    plain = CenterlineExpert()(env.physics, env.task)
    assert plain[0] > 0.5  # its push would cross the limit
    unscreened = ProbingExpert(probe=ProbeConfig(screen=False))(env.physics, env.task)
    np.testing.assert_array_equal(unscreened, plain)
    screened = ProbingExpert()(env.physics, env.task)
    np.testing.assert_array_equal(screened, [0.0, plain[1]])
    env.step(screened)
    assert not env.task.step_info()["failure"]


def test_an_aim_offset_rolls_the_tip_away_from_the_path_turn() -> None:
    """ExpertConfig.roll_offset_deg: 0 (the default) leaves the plain expert's actions bit
    for bit; aimed 180 degrees off, the expert holds the insertion where the plain one,
    aligned, pushes, and rolls the other way (both with one fixed aim, no sweep)."""
    env = suite.load("vascular_phantom", "task_b", {"random": 0})
    env.reset()
    plain = CenterlineExpert(FIXED_AIM)
    zero = CenterlineExpert(dataclasses.replace(FIXED_AIM, roll_offset_deg=0.0))
    flipped = CenterlineExpert(dataclasses.replace(FIXED_AIM, roll_offset_deg=180.0))
    compared = 0
    for _ in range(30):
        action = plain(env.physics, env.task)
        np.testing.assert_array_equal(action, zero(env.physics, env.task))
        other = flipped(env.physics, env.task)
        if action[0] > 0.0 and action[1] != 0.0:  # aligned with the turn and rolling
            assert other[0] == 0.0 and np.sign(other[1]) == -np.sign(action[1])
            compared += 1
        env.step(action)
    assert compared >= 3


def test_an_expert_that_makes_no_progress_tries_the_next_aim() -> None:
    """ExpertConfig.retry_offsets_deg: on the same state, the first ``retry_steps`` calls aim
    as the plain expert does; once they brought the tip no closer, the next aim (180 degrees
    off here) takes over."""
    env = suite.load("vascular_phantom", "task_b", {"random": 0})
    env.reset()
    plain = CenterlineExpert(dataclasses.replace(FIXED_AIM, retry_offsets_deg=()))
    flipped = CenterlineExpert(dataclasses.replace(FIXED_AIM, retry_offsets_deg=(),
                                                   roll_offset_deg=180.0))
    for _ in range(30):
        action = plain(env.physics, env.task)
        if action[0] > 0.0 and action[1] != 0.0:  # aligned with the turn and rolling
            break
        env.step(action)
    else:
        pytest.fail("the expert never rolled while aligned in 30 steps")
    retrying = CenterlineExpert(dataclasses.replace(FIXED_AIM, retry_offsets_deg=(0.0, 180.0),
                                                    retry_steps=2))
    first, second, third = (retrying(env.physics, env.task) for _ in range(3))
    np.testing.assert_array_equal(first, action)
    np.testing.assert_array_equal(second, action)
    np.testing.assert_array_equal(third, flipped(env.physics, env.task))


def test_the_sweep_moves_the_aim_with_the_episode_time() -> None:
    """ExpertConfig.sweep_deg: on one state, where the fixed aim is met and the expert pushes,
    the sweeping expert acts as the fixed one where the sweep crosses zero, and a twelfth of
    the period after it or before its next zero rolls at full rate towards an aim 30 degrees
    off either way, still pushing: within ``sweep_deg`` of its moving aim it counts as
    aligned (a fixed aim 30 degrees off would not, beyond ``tolerance_deg``)."""
    env = suite.load("vascular_phantom", "task_b", {"random": 0})
    env.reset()
    fixed = CenterlineExpert(dataclasses.replace(FIXED_AIM, retry_offsets_deg=()))
    for _ in range(40):
        action = fixed(env.physics, env.task)
        if action[0] > 0.0 and 0.0 < abs(action[1]) < 1.0:  # aimed within one step's roll
            break
        env.step(action)
    else:
        pytest.fail("the expert never met its aim in 40 steps")
    sweep = ExpertConfig(retry_offsets_deg=(), sweep_deg=60.0, sweep_period=2.0)
    physics, task = env.physics, env.task
    actions = {}
    for phase in (0.0, 1 / 12, 7 / 12):  # of the period: the sweep at 0, +30 and -30 deg
        physics.data.time = phase * sweep.sweep_period  # the expert reads nothing else of it
        sweeping = CenterlineExpert(sweep)
        sweeping._best = fixed._best  # the same episode so far
        actions[phase] = sweeping(physics, task)
    np.testing.assert_allclose(actions[0.0], action, atol=1e-9)
    np.testing.assert_array_equal(actions[1 / 12], [action[0], -1.0])
    np.testing.assert_array_equal(actions[7 / 12], [action[0], 1.0])
    off = CenterlineExpert(dataclasses.replace(FIXED_AIM, retry_offsets_deg=(),
                                               roll_offset_deg=30.0))
    off._best = fixed._best
    np.testing.assert_array_equal(off(physics, task), [0.0, -1.0])


def _side_branch_env(random: int, tree: int = 300, target: str = "OM1") -> control.Environment:
    """A tuning tree's sideways branch (by default tree 300's first obtuse marginal), with the
    2 mm, 75 degree tip the reachability check uses, from start roll ``random``."""
    wire = {"preset": "workhorse", "tip": {"length": 2e-3, "angle": math.radians(75.0)}}
    return suite.load("coronary", "navigate", {"pool_seed": tree, "pool_size": 1, "wire": wire,
                                               "random": random, "target": target})


def test_the_pull_back_entry_passes_the_ostium_turns_the_tip_and_draws_the_wire_back() -> None:
    # Start roll 0: the tip passes the ostium pointing away from the branch, so the entry has
    # to turn it (on the same tree's diagonals it enters at once and never leaves "advance").
    env = _side_branch_env(random=0)
    env.reset()
    entry = PullBackEntry(ExpertConfig())
    distance = env.task.manifold_distance()
    phases: list[str] = []
    for _ in range(200):
        before = entry.phase
        action = entry(env.physics, env.task)
        d = distance(env.physics.tip_position())
        if entry.phase != before:
            junction = float(distance.node_distances[entry.junction])
            if entry.phase == "turn":  # past the branch, off the path, by the overshoot
                assert d - junction >= entry.overshoot
            if before == "draw":  # dropped into the branch, or slid back above it
                assert d < junction or d > junction + entry.give_up
        if entry.phase == "turn":
            assert action[0] == 0.0
        if entry.phase == "draw":
            assert action[0] == entry.pull
        if not phases or phases[-1] != entry.phase:
            phases.append(entry.phase)
        if entry.phase == "push":
            break
        env.step(action)
    assert phases == ["advance", "turn", "draw", "push"]


@pytest.mark.slow
def test_the_pull_back_entry_brings_the_wire_into_a_sideways_branch() -> None:
    """About 45 s: the entry, then the plain expert keeping one aim, reaches tuning tree 308's
    first obtuse marginal from at least one of starts 0-2. (Since the generator's second obtuse
    marginal and right ventricular branch, 2026-11-27, this replaces tree 302's second
    diagonal.) Which starts succeed flips on the last bits of the arithmetic from machine to
    machine, each success coming late (32-34 s of the 40): written when start 0 reached it; on
    the machine of 2026-12-03, evening, starts 1, 2 and 3 of 0-5 did and 0 did not. So the test
    holds the entry to reaching the branch at all, not to one episode."""
    one_aim = dataclasses.replace(FIXED_AIM, retry_offsets_deg=())

    def reaches(start: int) -> bool:
        env = _side_branch_env(start, 308, "OM1")
        timestep = env.reset()
        # One aim after the entry too: the tip creeps up the branch, and an expert that retries
        # takes 60 steps of that for a failed attempt, turns the tip 45 degrees off and times
        # out (the retrying plain expert alone reaches this branch, at 22 s).
        entry = PullBackEntry(one_aim)
        while not timestep.last():
            timestep = env.step(entry(env.physics, env.task))
        return bool(env.task.step_info()["is_success"])

    assert any(reaches(start) for start in range(3))


@pytest.mark.slow
def test_a_close_secondary_curve_takes_a_branch_off_the_inner_wall_of_the_parents_bend(
        tmp_path: Path) -> None:
    """About 30 s. Issue 15's second check as a user runs it: a tree of coronary calibre
    (radii 0.8-2 mm) built from its lumen mesh alone, the plain expert, the workhorse. T2 of
    tree 3130 (a 0.89 mm branch leaving the inner wall of its parent's bend at 88 degrees)
    took no tip before 2026-12-02, night: with 3 mm at 75 degrees and 40 degrees 7 mm back the
    shaft rides the outer wall and the tip flips back out of the ostium. Bent 2 mm at 90
    degrees with 60 degrees 5 mm back, it enters from both starts (docs/tasks/coronary.md)."""
    folder = _calibre_folder(tmp_path, 3130)
    assert not _expert_reaches(folder, "T2", "3,75,7,40", 0)
    assert _expert_reaches(folder, "T2", "2,90,5,60", 0)
    assert _expert_reaches(folder, "T2", "2,90,5,60", 1)


@pytest.mark.slow
def test_the_calibre_tip_shape_takes_the_targets_either_neighbouring_shape_misses(
        tmp_path: Path) -> None:
    """About a minute. The tip docs/tasks/coronary.md gives for folders of coronary calibre,
    3 mm at 75 degrees with 50 degrees 5 mm back, reached every target of 96 of them from at
    least one of two starts (2026-12-02, late night), where 40 degrees 7 mm back misses 3145's
    T3 and 60 degrees 5 mm back misses 3157's T4 from both, stalling 35-46 mm short."""
    for seed, target, missing in ((3145, "T3", "3,75,7,40"), (3157, "T4", "3,75,5,60")):
        folder = _calibre_folder(tmp_path / str(seed), seed)
        assert not _expert_reaches(folder, target, missing, 0), (seed, missing)
        assert any(_expert_reaches(folder, target, "3,75,5,50", start) for start in (0, 1)), seed


def _calibre_folder(tmp_path: Path, seed: int) -> Path:
    """The vessel folder of a coronary-calibre tree (radii 0.8-2 mm, two levels of branches)
    built from its lumen mesh alone, as the reachability runs of docs/tasks/coronary.md built
    it."""
    import trimesh

    from sim4endor.vessels.build import build_vessel
    from sim4endor.vessels.generators.command import generate_vessel

    generated = generate_vessel(
        "coronary_tree", out_dir=tmp_path / "generated", seed=seed, progress=False, cache=False,
        overrides=("root_radius=0.002", "min_radius=0.0008", "levels=2"))
    folder = tmp_path / "built"
    build_vessel(trimesh.load(tmp_path / "generated" / "lumen.stl"), name=f"t{seed}",
                 out_dir=folder, inlet=generated.inlet_position, targets=generated.targets,
                 progress=False, cache=False)
    return folder


def _expert_reaches(folder: Path, target: str, tip: str, start: int) -> bool:
    """Whether the plain expert with the workhorse shaped ``tip`` reaches ``target`` from the
    reachability benchmark's ``start``."""
    stride = _reachability_script().START_STRIDE  # the benchmark's starts, as documented
    env = suite.load("vessel", "navigate", {
        "vessel": str(folder), "target": target, "random": start * stride,
        "wire": {"preset": "workhorse", "tip": tip}})
    return bool(run_expert(env, CenterlineExpert())["is_success"])


@functools.cache  # loaded once: the calibre tests ask for its start stride every episode
def _reachability_script():
    """experiments/benchmarks/expert_reachability.py as a module."""
    return load_script("experiments/benchmarks/expert_reachability.py")


def test_reachability_starts_summary() -> None:
    """With several starts per target the benchmark reports the episode rate's Wilson
    interval and the targets reached from every start and from any."""
    rows = [{"tree": tree, "target": target, "start": start, "outcome": outcome}
            for tree, target, outcomes in (("left_1000", "D1", ("success", "timeout")),
                                           ("left_1000", "D2", ("success", "success")),
                                           ("right_1001", "AM", ("tip_force", "timeout")))
            for start, outcome in enumerate(outcomes)]
    summary = _reachability_script().starts_summary(rows)
    assert summary["targets"] == 3
    assert summary["targets_reached_every_start"] == 1  # D2
    assert summary["targets_reached_any_start"] == 2  # D1 and D2
    low, high = summary["success_rate_ci95"]
    # 3 of 6: the Wilson interval is 0.5 -+ 0.312 (z = 1.96), symmetric about the rate.
    assert low == pytest.approx(0.188, abs=1e-3) and high == pytest.approx(0.812, abs=1e-3)


def test_reachability_runs_the_phantoms_with_their_own_wire_or_the_one_given(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The phantoms' rows run each task's own wire unless a wire is given; a given one, a
    user-shaped workhorse here, reaches the simplified phantom's target A."""
    script = _reachability_script()
    loaded, real_load = [], suite.load

    def load(domain: str, task: str, task_kwargs: dict) -> control.Environment:
        loaded.append(task_kwargs)
        return real_load(domain, task, task_kwargs)

    monkeypatch.setattr(script.suite, "load", load)
    shaped = {"preset": "workhorse", "tip": "3,75,5,50"}
    row = script.reachability("simplified_phantom", "task_a", 1, CenterlineExpert(), shaped)
    own = script.reachability("simplified_phantom", "task_a", 1, CenterlineExpert())
    assert loaded == [{"random": 0, "wire": shaped}, {"random": 0}]
    assert row["wire"] == shaped and row["successes"] == 1
    assert own["wire"] is None and own["successes"] == 1


def test_reachability_runs_vessel_folders_as_a_user_loads_them() -> None:
    """``--domain vessel``: a case per target of the folder, loaded through the ``vessel``
    domain with the wire given; the expert reaches the simplified phantom's target A."""
    script = _reachability_script()
    folder = vessels.load("simplified_phantom").root
    cases = script.vessel_cases(folder, "paper")
    assert [case.task_kwargs["target"] for case in cases] == ["A", "B"]
    assert all(case.domain == "vessel" and case.task_kwargs["vessel"] == str(folder)
               and case.task_kwargs["wire"] == "paper" for case in cases)
    row = script.case_episode((cases[0], "centerline", 0))
    assert row["vessel"] == str(folder) and row["target"] == "A" and row["start"] == 0
    assert row["outcome"] == "success"
