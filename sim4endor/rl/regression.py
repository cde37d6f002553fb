"""Is a candidate policy worse than the one it would replace? Both on the generalisation suite.

A candidate and a reference policy run the same cases of :mod:`sim4endor.rl.generalisation`
(the same anatomies, targets and start seeds), so each of the candidate's episodes has a twin
of the reference's. Per group (each of ``GROUPS``, and with ``motion`` its moving twin) the
verdict compares:

* **successes**: the candidate is worse when it reaches fewer targets than the reference;
* **SPL** (success weighted by path length, per episode): worse when the mean of the paired
  differences (candidate − reference) is below −2 standard errors of those differences;
* **tip force** (each episode's largest step-mean tip force, N): worse when the mean paired
  difference is above +2 standard errors.

With one episode in a group the standard error is 0, so any drop in SPL or rise in tip force
counts. A candidate may replace the reference only when no group is worse (``ships``).

A student distilled from the reference (issue 77) is judged by another rule (``keeps``): in
every group it reaches at least :data:`STUDENT_SHARE` of its teacher's successes and ends no
more episodes in a tip-force stop.

Episodes run in ``jobs`` spawned processes, each task a few cases of one policy.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import multiprocessing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from sim4endor.errors import Sim4EndoRError
from sim4endor.rl import generalisation
from sim4endor.rl.metrics import Episode, episode_spl, largest_tip_force
from sim4endor.rl.runs import run_config

#: A paired difference counts when it is this many standard errors from zero.
STANDARD_ERRORS = 2.0
#: The share of its teacher's successes a student keeps in every group.
STUDENT_SHARE = 0.9
#: How an episode ends that pressed the tip too hard (a reason of ``sim4endor.tasks.FAILURES``).
TIP_FORCE_STOP = "tip_force"
#: Cases a worker runs per task.
CHUNK_CASES = 8


@dataclasses.dataclass(frozen=True)
class Paired:
    """One metric's paired differences (candidate − reference) over a group's episodes."""

    mean: float
    standard_error: float

    @classmethod
    def of(cls, candidate: Sequence[float], reference: Sequence[float]) -> Paired:
        """The mean of the differences and its standard error (0 for a single pair)."""
        diff = np.asarray(candidate, dtype=float) - np.asarray(reference, dtype=float)
        se = float(diff.std(ddof=1) / np.sqrt(len(diff))) if len(diff) > 1 else 0.0
        return cls(float(diff.mean()), se)

    def below(self) -> bool:
        """The candidate is lower beyond the trial noise."""
        return self.mean < -STANDARD_ERRORS * self.standard_error

    def above(self) -> bool:
        """The candidate is higher beyond the trial noise."""
        return self.mean > STANDARD_ERRORS * self.standard_error


@dataclasses.dataclass(frozen=True)
class GroupVerdict:
    """A candidate against the reference on one group of the suite."""

    group: str
    episodes: int
    successes: int
    reference_successes: int
    spl: Paired
    tip_force_n: Paired
    tip_force_stops: int
    reference_tip_force_stops: int

    @property
    def worse(self) -> tuple[str, ...]:
        """The metrics on which the candidate is worse (empty: not worse)."""
        return tuple(name for name, is_worse in (
            ("successes", self.successes < self.reference_successes),
            ("spl", self.spl.below()),
            ("tip_force", self.tip_force_n.above())) if is_worse)

    @property
    def short_of_teacher(self) -> tuple[str, ...]:
        """Where a student falls short of the reference as its teacher (empty: nowhere)."""
        return tuple(name for name, short in (
            ("successes", self.successes < STUDENT_SHARE * self.reference_successes),
            ("tip_force_stops", self.tip_force_stops > self.reference_tip_force_stops))
            if short)


def compare(groups: Mapping[str, str], candidate: Mapping[str, Sequence[Episode]],
            reference: Mapping[str, Sequence[Episode]]) -> list[GroupVerdict]:
    """The verdict per group (in :func:`generalisation.ordered_groups` order) of two
    policies' episodes on the same cases.

    Args:
        groups: each case label's group.
        candidate, reference: each case label's episodes, in the same start-seed order.
    """
    verdicts = []
    for group in generalisation.ordered_groups(groups.values()):
        labels = [label for label, of in groups.items() if of == group]
        if not labels:
            continue
        pairs = [pair for label in labels for pair in _pairs(label, candidate, reference)]
        verdicts.append(GroupVerdict(
            group=group, episodes=len(pairs),
            successes=sum(c.success for c, _ in pairs),
            reference_successes=sum(r.success for _, r in pairs),
            spl=Paired.of([episode_spl(c) for c, _ in pairs],
                          [episode_spl(r) for _, r in pairs]),
            tip_force_n=Paired.of([largest_tip_force(c) for c, _ in pairs],
                                  [largest_tip_force(r) for _, r in pairs]),
            tip_force_stops=sum(c.outcome == TIP_FORCE_STOP for c, _ in pairs),
            reference_tip_force_stops=sum(r.outcome == TIP_FORCE_STOP for _, r in pairs)))
    return verdicts


def ships(verdicts: Sequence[GroupVerdict]) -> bool:
    """Whether the candidate is worse on no group."""
    return not any(v.worse for v in verdicts)


def keeps(verdicts: Sequence[GroupVerdict]) -> bool:
    """Whether a student falls short of its teacher (the reference) in no group."""
    return not any(v.short_of_teacher for v in verdicts)


def regression(candidates: Sequence[Path], reference: Path,
               config: generalisation.SuiteConfig, *, jobs: int = 1,
               progress: bool = False) -> dict[str, Any]:
    """Runs the reference and every candidate on the suite's cases and judges each candidate.

    Returns:
        ``verdicts``: candidate name → its :class:`GroupVerdict` list;
        ``ships``: candidate name → whether it is worse on no group;
        ``keeps``: candidate name → whether, as a student of the reference, it falls short
        in no group;
        ``rows``: policy name → group → :func:`~sim4endor.rl.metrics.summarize` metrics;
        ``outcomes``: policy name → case label → each episode's outcome.
    """
    policies = [Path(reference), *map(Path, candidates)]
    names = [generalisation.policy_name(p) for p in policies]
    if len(set(names)) != len(names):
        raise Sim4EndoRError(f"The policies compared need distinct names, got {names}; give "
                             "each run folder (or the folder above policy/) its own name.")
    cases = {name: generalisation.policy_cases(run_config(path).env, config)
             for name, path in zip(names, policies, strict=True)}
    # The labels come from the config alone; a policy's cases differ only in its observation
    # set and trained tip, which it is judged with.
    groups = {case.label: case.group for case in cases[names[0]]}
    episodes = _episodes(policies, names, cases, config, jobs, progress)
    verdicts = {name: compare(groups, episodes[name], episodes[names[0]]) for name in names[1:]}
    rows = {name: generalisation.group_metrics(cases[name], episodes[name]) for name in names}
    return {"reference": names[0], "verdicts": verdicts,
            "ships": {name: ships(v) for name, v in verdicts.items()},
            "keeps": {name: keeps(v) for name, v in verdicts.items()}, "rows": rows,
            "outcomes": {name: {label: [e.outcome for e in runs] for label, runs in of.items()}
                         for name, of in episodes.items()}}


def markdown(result: Mapping[str, Any]) -> str:
    """One row per (candidate, group): successes against the reference's, the paired SPL and
    tip-force differences with their standard errors, and what is worse."""
    lines = [f"| candidate | group | episodes | successes (reference {result['reference']}) | "
             "SPL difference ± SE | tip-force difference ± SE (N) | worse on |",
             "|---|---|---|---|---|---|---|"]
    for name, verdicts in result["verdicts"].items():
        for v in verdicts:
            lines.append(
                f"| {name} | {v.group} | {v.episodes} | {v.successes} ({v.reference_successes}) "
                f"| {v.spl.mean:+.3f} ± {v.spl.standard_error:.3f} "
                f"| {v.tip_force_n.mean:+.3f} ± {v.tip_force_n.standard_error:.3f} "
                f"| {', '.join(v.worse) or '–'} |")
    for name, ok in result["ships"].items():
        lines.append(f"\n{name}: {'worse on no group' if ok else 'WORSE on a group: do not ship'}")
    return "\n".join(lines)


def student_markdown(result: Mapping[str, Any]) -> str:
    """One row per (student, group): its successes against :data:`STUDENT_SHARE` of its
    teacher's (the reference), and both policies' tip-force stops."""
    teacher = result["reference"]
    lines = [f"| student | group | episodes | successes | {teacher} | share | tip-force stops "
             f"({teacher}) | short on |", "|---|---|---|---|---|---|---|---|"]
    for name, verdicts in result["verdicts"].items():
        for v in verdicts:
            share = (f"{100 * v.successes / v.reference_successes:.0f} %"
                     if v.reference_successes else "–")
            lines.append(
                f"| {name} | {v.group} | {v.episodes} | {v.successes} | {v.reference_successes} "
                f"| {share} | {v.tip_force_stops} ({v.reference_tip_force_stops}) "
                f"| {', '.join(v.short_of_teacher) or '–'} |")
    for name, ok in result["keeps"].items():
        lines.append(f"\n{name}: " + (
            f"keeps {STUDENT_SHARE:.0%} of {teacher}'s successes and no more tip-force stops "
            "in every group" if ok else f"SHORT of {teacher} in a group"))
    return "\n".join(lines)


def _pairs(label: str, candidate: Mapping[str, Sequence[Episode]],
           reference: Mapping[str, Sequence[Episode]]) -> list[tuple[Episode, Episode]]:
    ours, theirs = candidate.get(label, ()), reference.get(label, ())
    if len(ours) != len(theirs) or not ours:
        raise Sim4EndoRError(f"Case {label!r}: {len(ours)} candidate and {len(theirs)} "
                             "reference episodes; the comparison pairs them one to one.")
    return list(zip(ours, theirs, strict=True))


def _episodes(policies: Sequence[Path], names: Sequence[str],
              cases: Mapping[str, Sequence[generalisation.Case]],
              config: generalisation.SuiteConfig, jobs: int, progress: bool
              ) -> dict[str, dict[str, list[Episode]]]:
    """Each policy's episodes per case label; ``jobs`` processes run chunks of
    :data:`CHUNK_CASES` cases (small enough for the bar to move and the load to balance)."""
    chunks = [(path, name, tuple(cases[name][i:i + CHUNK_CASES]))
              for path, name in zip(policies, names, strict=True)
              for i in range(0, len(cases[name]), CHUNK_CASES)]
    out: dict[str, dict[str, list[Episode]]] = {name: {} for name in names}
    bar = tqdm(total=sum(len(chunk) for *_, chunk in chunks), desc="regression", unit="case",
               disable=not progress)
    with bar:
        if jobs == 1:
            for path, name, chunk in chunks:
                out[name].update(_run_chunk(path, chunk, config))
                bar.update(len(chunk))
            return out
        context = multiprocessing.get_context("spawn")  # CoACD's OpenMP in builds: never fork
        with concurrent.futures.ProcessPoolExecutor(jobs, mp_context=context) as pool:
            futures = {pool.submit(_run_chunk, path, chunk, config): (name, len(chunk))
                       for path, name, chunk in chunks}
            for future in concurrent.futures.as_completed(futures):
                name, size = futures[future]
                out[name].update(future.result())
                bar.update(size)
    return out


def _run_chunk(path: Path, cases: Sequence[generalisation.Case],
               config: generalisation.SuiteConfig) -> dict[str, list[Episode]]:
    """One policy's episodes on some of its cases (a worker's task). Each case's environment
    is closed once its episodes are run: no other policy of this process meets it, and a
    coronary scene holds tens of MB."""
    actor = generalisation.run_actor(path)
    out = {}
    for case in cases:
        envs = generalisation.CaseEnvironments()
        try:
            out.update(generalisation.run_cases([case], actor, config, envs))
        finally:
            envs.close()
    return out
