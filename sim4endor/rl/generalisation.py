"""The generalisation suite: a policy, zero-shot, on anatomies it was not trained on.

Groups of (anatomy, target) cases, all with one wire preset (default ``workhorse``):

* ``held_out_trees``: every distal target of ``trees`` generated coronary trees, seeds
  ``first_seed`` on (1000 on by default, a range no training pool or test uses);
* ``wide_trees``: the same for ``wide_trees`` trees of the coronary domain's ``wide`` anatomy
  (tortuous, stenosed, narrower; the same seeds, other trees);
* ``implicit``: every target of ``implicit_trees`` trees of the evaluation-only family
  (:mod:`sim4endor.vessels.generators.implicit_coronary`, seeds 0 on), written apart from the
  training generators and built as a user's mesh is, each once into the cache;
* ``real``: every target of the vessel folders of real patients' meshes given (``real``);
* ``phantoms``: targets A and B of both shipped phantoms;
* ``steve``: every target of the real stEVE anatomy (``steve_dir``), built once into the
  cache; skipped with a message when its folder is absent.

With ``motion`` every case whose anatomy can move (all but the phantoms) runs a second time on
a beating and breathing heart (:mod:`sim4endor.models.motion`), reported as the group
``GROUP moving``; with ``randomise`` every case draws the domain randomisation
(:mod:`sim4endor.tasks.randomisation`). Other policies may run ``beside`` the evaluated one,
each on the same cases with its own observation set (a student beside its teacher).

Each case runs ``trials`` deterministic episodes. Besides the policy, reference rows run the
same cases (:mod:`sim4endor.rl.baselines`): the scripted expert, the constant push ``[1, 0]``,
the best constant action of the baselines' grid (chosen on other trees and start seeds than the
ones reported) and uniform random actions. Per group the rows give success, mean completion
time, SPL and the largest tip force.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tensordict.nn import TensorDictModuleBase
from torchrl.envs import EnvBase
from tqdm.auto import tqdm

from sim4endor import vessels
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl import baselines, reachability
from sim4endor.rl.config import EnvConfig
from sim4endor.rl.envs import sim4endor_env
from sim4endor.rl.evaluation import rollout_episodes
from sim4endor.rl.metrics import Episode, summarize
from sim4endor.vessels import Vessel

if TYPE_CHECKING:
    from sim4endor.tasks.coronary import Anatomies

_LOG = logging.getLogger(__name__)

#: The groups, in the order they are reported.
GROUPS: tuple[str, ...] = ("held_out_trees", "wide_trees", "implicit", "real", "phantoms",
                           "steve")
#: Appended to a group's name and its cases' labels when they run on a moving heart.
MOVING = " moving"
#: The folder of the stEVE anatomy when ``--steve`` is not given.
DEFAULT_STEVE_DIR = Path(os.environ.get("SIM4ENDOR_SHARED", "../shared")) / "data" / \
    "steve_bench_dualdevicenav"
#: The phantoms and tasks of the ``phantoms`` group.
PHANTOMS: tuple[str, ...] = ("simplified_phantom", "vascular_phantom")
PHANTOM_TASKS: tuple[str, ...] = ("task_a", "task_b")
#: First tree seed the best constant action is chosen on (apart from the reported trees).
SELECTION_FIRST_SEED = 2000

#: Builds the acting module of an environment (a policy's or a baseline's).
ActorFactory = Callable[[EnvBase], TensorDictModuleBase]


@dataclasses.dataclass(frozen=True)
class SuiteConfig:
    """What the suite runs.

    Attributes:
        trees: Generated coronary trees of the ``held_out_trees`` group.
        first_seed: Seed of the first of them.
        wire: Guidewire preset of every case.
        tip: Its tip shape (``EnvConfig.tip``: ``"LENGTH_MM,ANGLE_DEG"`` or ``"J"``).
            ``None``: the shape the evaluated run was trained with (:meth:`for_run`; the
            preset's own when the run named none), so a policy meets the tip whose response
            to a roll it learnt; the reference rows use the same wire.
        fidelity: The wire's numerical settings (``EnvConfig.fidelity``: ``converged`` or
            ``fast``; ``None``: the default, ``converged``).
        trials: Episodes per case.
        seed: Start-state seed of every case's episodes.
        max_steps: Step cap per episode (the coronary domain's 40 s at 20 Hz; the tasks'
            own time limits also apply).
        steve_dir: Folder of the stEVE anatomy (its mesh and centerlines); ``None`` or an
            absent folder skips that group.
        wide_trees: Trees of the ``wide_trees`` group (seeds from ``first_seed``).
        implicit_trees: Trees of the ``implicit`` group (seeds 0 on).
        real: Vessel folders of the ``real`` group (``sim4endor vessel build`` output).
        motion: Also run every case but the phantoms' on a beating and breathing heart.
        randomise: Every case with domain randomisation (``EnvConfig.randomise``).
        cathlab: The cath lab's sensors of every case (``EnvConfig.cathlab``). ``None``: those
            the evaluated run was trained with (:meth:`for_run`), so a student meets its own
            sensors.
    """

    trees: int = 20
    first_seed: int = 1000
    wire: str = "workhorse"
    tip: str | None = None
    fidelity: str | None = None
    trials: int = 1
    seed: int = baselines.REPORT_SEED
    max_steps: int = 800
    steve_dir: Path | None = DEFAULT_STEVE_DIR
    wide_trees: int = 10
    implicit_trees: int = 6
    real: tuple[Path, ...] = ()
    motion: bool = False
    randomise: bool = False
    cathlab: dict[str, Any] | None = None

    def for_run(self, run_env: EnvConfig) -> SuiteConfig:
        """This config with the run's tip shape and cath lab where it names none."""
        return dataclasses.replace(
            self, tip=run_env.tip if self.tip is None else self.tip,
            cathlab=run_env.cathlab if self.cathlab is None else self.cathlab)

    def base_env(self, observations: str) -> EnvConfig:
        """The environment every case derives from: ``observations``, the suite's wire and
        its randomisation (a policy trained with randomisation meets it only when asked)."""
        return EnvConfig(observations=observations, wire=self.wire, tip=self.tip,
                         fidelity=self.fidelity, randomise=self.randomise or None,
                         cathlab=self.cathlab)


@dataclasses.dataclass(frozen=True)
class Case:
    """One anatomy and target: the environment to build and its label in the breakdown."""

    group: str
    label: str
    env: EnvConfig


def tree_cases(first_seed: int, trees: int, base: EnvConfig, anatomy: Anatomies = "normal",
               group: str = "held_out_trees") -> list[Case]:
    """Every distal target of the coronary trees ``first_seed ... first_seed + trees - 1`` of
    ``anatomy`` (:data:`sim4endor.tasks.coronary.Anatomies`)."""
    from sim4endor.tasks.coronary import generator_config, tree_name
    from sim4endor.vessels.generators.coronary_arteries import coronary_arteries

    cases = []
    for seed in range(first_seed, first_seed + trees):
        tree = coronary_arteries(generator_config(seed, "both", anatomy), seed=seed)
        for target in sorted(tree.targets):
            env = dataclasses.replace(base, domain="coronary", task="navigate", pool_seed=seed,
                                      pool_size=1, target=target,
                                      anatomy=None if anatomy == "normal" else anatomy)
            cases.append(Case(group, f"{tree_name(seed, 'both', anatomy)} {target}", env))
    return cases


def vessel_cases(group: str, vessel: Vessel, base: EnvConfig) -> list[Case]:
    """Every target of a vessel folder, labelled ``NAME TARGET``."""
    return [Case(group, f"{vessel.name} {target}",
                 dataclasses.replace(base, domain="vessel", task="navigate",
                                     vessel=str(vessel.root), target=target))
            for target in sorted(vessel.targets)]


def suite_cases(config: SuiteConfig, observations: str) -> list[Case]:
    """The cases of every group for a policy observing ``observations``."""
    base = config.base_env(observations)
    cases = tree_cases(config.first_seed, config.trees, base)
    cases += tree_cases(config.first_seed, config.wide_trees, base, "wide", "wide_trees")
    for vessel in implicit_vessels(config.implicit_trees):
        cases += vessel_cases("implicit", vessel, base)
    for folder in config.real:
        cases += vessel_cases("real", vessels.load(folder), base)
    cases += [Case("phantoms", f"{phantom} {task}",
                   dataclasses.replace(base, domain=phantom, task=task))
              for phantom in PHANTOMS for task in PHANTOM_TASKS]
    steve = steve_vessel(config.steve_dir)
    if steve is None:
        _LOG.warning("steve: skipped, no stEVE anatomy at %s (set SIM4ENDOR_SHARED to the "
                     "shared/ folder or pass --steve DIR)", config.steve_dir)
    else:
        cases += vessel_cases("steve", steve, base)
    if config.motion:  # the phantoms' walls are fixed in their box
        cases += [Case(case.group + MOVING, case.label + MOVING,
                       dataclasses.replace(case.env, motion=True))
                  for case in cases if case.group != "phantoms"]
    labels = [case.label for case in cases]
    if len(set(labels)) != len(labels):  # each case's episodes and environment go by label
        twice = sorted({label for label in labels if labels.count(label) > 1})
        raise Sim4EndoRError(f"Two suite cases are labelled {twice[0]!r}: two --real folders "
                             "hold vessels of one name; give one of them.")
    return cases


def ordered_groups(groups: Iterable[str]) -> list[str]:
    """The groups named in ``groups``, in the reported order: each of :data:`GROUPS`
    followed by its moving twin."""
    present = set(groups)
    return [name for group in GROUPS for name in (group, group + MOVING) if name in present]


def policy_cases(run_env: EnvConfig, config: SuiteConfig) -> list[Case]:
    """The suite's cases for a run's policy (its ``config.yaml``'s ``env``): its observation
    set, and its tip shape and cath lab where ``config`` names none
    (:meth:`SuiteConfig.for_run`)."""
    return suite_cases(config.for_run(run_env), run_env.observations)


def implicit_vessels(trees: int) -> list[Vessel]:
    """Trees ``0 ... trees - 1`` of the evaluation-only family, each built once into the cache
    (a folder named after a hash of its surface and the build's code: 13-42 s a build)."""
    from sim4endor.tasks.anatomy import build_once, default_cache_dir
    from sim4endor.vessels.build import content_hash
    from sim4endor.vessels.generators import implicit_coronary as family

    built = []
    for seed in range(trees):
        tree = family.implicit_coronary(family.ImplicitCoronaryConfig(), seed)
        digest = content_hash(tree.lumen, inlet=tree.inlet, targets=tree.targets)[:12]
        folder = default_cache_dir("implicit_coronary") / f"implicit_coronary_{seed}_{digest}"
        built.append(vessels.load(build_once(
            folder, functools.partial(family.build_tree, tree, seed))))
    return built


def steve_vessel(folder: Path | None) -> Vessel | None:
    """The stEVE anatomy built into the cache, or None when ``folder`` lacks it.

    The cache folder is named after a hash of the inputs, so it is built once per machine
    and never rewritten while another suite run (a bench worker) has it open.
    """
    if folder is None or not (folder / "vessel_architecture_collision.obj").is_file():
        return None
    from sim4endor.tasks.anatomy import build_once, default_cache_dir
    from sim4endor.vessels.build import build_vessel, content_hash
    from sim4endor.vessels.meshio import read_mesh
    from sim4endor.vessels.register import RegistrationParams
    from sim4endor.vessels.slicer import read_slicer_centerline

    mesh = read_mesh(folder / "vessel_architecture_collision.obj")
    centerline = read_slicer_centerline([folder / "centerlines"])
    registration = RegistrationParams()
    license_text = (folder / "LICENSE").read_text()
    digest = content_hash(mesh, centerline=centerline, registration=registration,
                          license=license_text)[:12]

    def build(out_dir: Path) -> None:
        build_vessel(mesh, name="steve_dualdevicenav", out_dir=out_dir, units="mm",
                     centerline=centerline, registration=registration,
                     source="stEVE_bench dualdevicenav (lkarstensen/stEVE_bench)",
                     license_text=license_text, progress=False)

    return vessels.load(build_once(default_cache_dir("steve") / f"steve_dualdevicenav_{digest}",
                                   build))


class CaseEnvironments:
    """Each case's environment, built the first time a policy needs it and shared by every
    policy the suite runs (building a coronary case costs about half a second; an episode
    reseeds its environment, so sharing changes no result). ``close`` closes them all."""

    def __init__(self) -> None:
        self._envs: dict[str, EnvBase] = {}

    def __getitem__(self, case: Case) -> EnvBase:
        if case.label not in self._envs:
            self._envs[case.label] = sim4endor_env(case.env, 0, evaluation=True)
        return self._envs[case.label]

    def close(self) -> None:
        """Closes every environment built."""
        for env in self._envs.values():
            env.close()
        self._envs.clear()


def run_cases(cases: Sequence[Case], make_actor: ActorFactory, config: SuiteConfig,
              envs: CaseEnvironments, label: str = "", progress: bool = False
              ) -> dict[str, list[Episode]]:
    """Runs ``config.trials`` episodes of each case; returns the episodes per case label.
    ``progress`` shows a bar counting cases and, under it while a case runs, the bars of
    :func:`~sim4endor.rl.evaluation.rollouts` (its episodes, and the steps of the one under
    way)."""
    episodes: dict[str, list[Episode]] = {}
    for case in tqdm(cases, desc=label or "suite", unit="case", disable=not progress):
        env = envs[case]
        episodes[case.label] = rollout_episodes(
            env, make_actor(env), trials=config.trials, max_steps=config.max_steps,
            seed=config.seed, progress=progress, desc=case.label, leave=False)
    return episodes


def group_metrics(cases: Sequence[Case], episodes: dict[str, list[Episode]]
                  ) -> dict[str, dict[str, Any]]:
    """The :func:`~sim4endor.rl.metrics.summarize` metrics of each group that has episodes."""
    out = {}
    for group in ordered_groups(case.group for case in cases):
        runs = [e for case in cases if case.group == group for e in episodes[case.label]]
        if runs:
            out[group] = summarize(runs)
    return out


def best_constant_action(config: SuiteConfig, observations: str, envs: CaseEnvironments,
                         progress: bool = False) -> baselines.ConstantAction:
    """The constant action of :data:`baselines.CONSTANT_GRID` that succeeds most often on
    four trees (seeds from :data:`SELECTION_FIRST_SEED`) and the phantoms' targets, started
    from :data:`baselines.SELECTION_SEED`: cases and starts apart from the reported ones."""
    selection = dataclasses.replace(config, seed=baselines.SELECTION_SEED, trials=1)
    base = config.base_env(observations)
    cases = [Case("phantoms", f"{phantom} {task}",
                  dataclasses.replace(base, domain=phantom, task=task))
             for phantom in PHANTOMS for task in PHANTOM_TASKS]
    cases += tree_cases(SELECTION_FIRST_SEED, min(config.trees, 4), base)

    def successes(action: baselines.ConstantAction) -> int:
        runs = run_cases(cases, functools.partial(_baseline_actor, action), selection, envs,
                         label=action.label, progress=progress)
        return sum(e.success for episodes in runs.values() for e in episodes)

    tried = [baselines.ConstantAction(insert, rotate)
             for insert, rotate in baselines.CONSTANT_GRID]
    scores = {action: successes(action) for action in tried}
    return max(tried, key=lambda action: scores[action])  # ties: the first in grid order


def reference_rows(config: SuiteConfig, observations: str, cases: Sequence[Case],
                   envs: CaseEnvironments, progress: bool = False
                   ) -> dict[str, dict[str, dict[str, Any]]]:
    """The baselines' metrics per group: expert, constant push, best constant, random."""
    chosen = best_constant_action(config, observations, envs, progress)
    rows: dict[str, dict[str, dict[str, Any]]] = {}
    for baseline, label in (
        (baselines.ScriptedExpert(), baselines.ScriptedExpert().label),
        (baselines.ConstantAction(1.0, 0.0), "constant push [1, 0]"),
        (chosen, f"best constant ({chosen.label})"),
        (baselines.RandomActions(seed=config.seed), baselines.RandomActions().label),
    ):
        episodes = run_cases(cases, functools.partial(_baseline_actor, baseline), config, envs,
                             label=label, progress=progress)
        rows[label] = group_metrics(cases, episodes)
    return rows


def evaluate_suite(run_dir: Path, config: SuiteConfig, *, with_baselines: bool = True,
                   beside: Sequence[Path] = (), progress: bool = False) -> dict[str, Any]:
    """Runs a training run's deterministic policy (and the reference rows) on the suite.

    ``beside``: other runs or policies (e.g. a student's teacher), each run on the same cases
    with its own observation set and trained tip, a row after the run's.

    Returns:
        ``rows``: policy label → group → metrics (:func:`group_metrics`), the run first;
        ``targets``: the run's success rate per case label (the per-target breakdown);
        ``reachability``: with ``config.real``, each real target's probing-expert episode
        (:mod:`sim4endor.rl.reachability`: reachable, or why not) and ``real_reachable``, the
        run's successes over the reachable ones.
    """
    from sim4endor.rl.runs import run_config

    train_config = run_config(run_dir)
    run_suite = config.for_run(train_config.env)
    envs = CaseEnvironments()
    try:
        cases, episodes = _policy_episodes(run_dir, config, envs, progress)
        rows = {f"policy ({policy_name(run_dir)})": group_metrics(cases, episodes)}
        for other in beside:
            rows[f"policy ({policy_name(other)})"] = _beside_row(other, config, progress)
        if with_baselines:
            rows.update(reference_rows(run_suite, train_config.env.observations, cases, envs,
                                       progress))
        reach = probe_real(cases, run_suite, envs, progress)
    finally:
        envs.close()
    targets = {label: summarize(runs)["success_rate"] for label, runs in episodes.items()}
    result: dict[str, Any] = {"rows": rows, "targets": targets}
    if reach:
        reached, reachable = reachability.reachable_successes(reach, targets)
        result.update(reachability=reachability.as_json(reach),
                      real_reachable={"successes": reached, "reachable": reachable,
                                      "targets": len(reach)})
    return result


def _beside_row(run_dir: Path, config: SuiteConfig, progress: bool
                ) -> dict[str, dict[str, Any]]:
    """Another run's metrics per group on the suite's cases, in environments of its own
    (its observation set may differ from the evaluated run's)."""
    envs = CaseEnvironments()
    try:
        return group_metrics(*_policy_episodes(run_dir, config, envs, progress))
    finally:
        envs.close()


def _policy_episodes(run_dir: Path, config: SuiteConfig, envs: CaseEnvironments,
                     progress: bool) -> tuple[list[Case], dict[str, list[Episode]]]:
    """A run's cases (:func:`policy_cases`) and its episodes on them, in ``envs``."""
    from sim4endor.rl.runs import run_config

    run_env = run_config(run_dir).env
    cases = policy_cases(run_env, config)
    return cases, run_cases(cases, run_actor(run_dir), config.for_run(run_env), envs,
                            label=policy_name(run_dir), progress=progress)


def policy_name(path: Path) -> str:
    """A run's name in the tables: its folder, or the folder above a recipe's ``policy``."""
    path = Path(path)
    return path.parent.name if path.name == "policy" else path.name


def probe_real(cases: Sequence[Case], config: SuiteConfig, envs: CaseEnvironments,
               progress: bool = False) -> dict[str, reachability.Reach]:
    """The probing expert's :class:`~sim4endor.rl.reachability.Reach` on each ``real``
    case (one episode each)."""
    real = [case for case in cases if case.group == "real"]
    if not real:
        return {}
    expert = baselines.ScriptedExpert(probing=True)
    episodes = run_cases(real, functools.partial(_baseline_actor, expert),
                         dataclasses.replace(config, trials=1), envs, label=expert.label,
                         progress=progress)
    return {case.label: reachability.reach_of(episodes[case.label][0], str(case.env.vessel),
                                              str(case.env.target)) for case in real}


def evaluate_vessel(policy: Path | baselines.Baseline, vessel: str | Path, config: SuiteConfig,
                    progress: bool = False) -> dict[str, Any]:
    """Runs a run's deterministic policy, or a reference row's policy (the scripted expert:
    is every target of a new anatomy within the wire's reach?), ``config.trials`` times on
    every target of a vessel folder (``sim4endor vessel build`` output or a vessel name) with
    ``config.wire``.

    Returns:
        The :func:`~sim4endor.rl.metrics.summarize` metrics over all targets, plus
        ``targets``: the same metrics per target label.
    """
    from sim4endor.rl.runs import evaluation_env, run_config

    loaded = vessels.load(vessel)
    make_actor: ActorFactory
    if isinstance(policy, baselines.Baseline):
        run_env = EnvConfig()  # a reference row reads no observation
        make_actor = functools.partial(_baseline_actor, policy)
    else:
        run_env = run_config(policy).env
        make_actor = run_actor(policy)
    config = config.for_run(run_env)
    base = evaluation_env(run_env, {"domain": "vessel", "task": "navigate",
                                    "vessel": str(loaded.root), "wire": config.wire,
                                    "tip": config.tip, "fidelity": config.fidelity,
                                    "motion": config.motion or None,
                                    "randomise": config.randomise or None})
    cases = [Case("vessel", target, dataclasses.replace(base, target=target))
             for target in sorted(loaded.targets)]
    envs = CaseEnvironments()
    try:
        episodes = run_cases(cases, make_actor, config, envs, label=loaded.name,
                             progress=progress)
    finally:
        envs.close()
    every = [e for runs in episodes.values() for e in runs]
    return {**summarize(every),
            "targets": {label: summarize(runs) for label, runs in episodes.items()}}


def run_actor(run_dir: Path) -> ActorFactory:
    """The acting module of a run's latest policy, built for the first environment it is
    given and reused for the others (the networks depend only on the specs, which the cases
    of one observation set share)."""
    from sim4endor.rl.runs import load_agent_for, run_config

    train_config = run_config(run_dir)
    actors: list[TensorDictModuleBase] = []

    def actor(env: EnvBase) -> TensorDictModuleBase:
        if not actors:
            actors.append(load_agent_for(run_dir, train_config, env).env_actor)
        return actors[0]

    return actor


def _baseline_actor(baseline: baselines.Baseline, env: EnvBase) -> TensorDictModuleBase:
    return baselines.policy(baseline, env)


def markdown(result: dict[str, Any]) -> str:
    """:func:`evaluate_suite`'s result: one table row per (policy, group) with success, mean
    time, SPL and largest tip force; then, with real patients, the policy's successes over
    their reachable targets and why each other target is out of reach."""
    lines = [table(result["rows"])]
    if "real_reachable" in result:
        counts = result["real_reachable"]
        lines.append(f"\nreal: the policy reaches {counts['successes']:g} of the "
                     f"{counts['reachable']} targets (of {counts['targets']}) the probing "
                     "expert reaches")
        lines += [f"- unreachable: {label}: {reach['reason']}"
                  for label, reach in result["reachability"].items() if not reach["reachable"]]
    return "\n".join(lines)


def table(rows: dict[str, dict[str, dict[str, Any]]]) -> str:
    """One table row per (policy, group): success, mean time, SPL, largest tip force."""
    lines = ["| policy | group | success | mean time (s) | SPL | max tip force (N) |",
             "|---|---|---|---|---|---|"]
    for policy, groups in rows.items():
        for group, metrics in groups.items():
            trials = metrics["trials"]
            won = round(metrics["success_rate"] * trials)
            time = metrics["mean_completion_time_s"]
            lines.append(
                f"| {policy} | {group} | {won}/{trials} ({100 * won / trials:.0f} %) | "
                f"{'–' if time is None else f'{time:.2f}'} | {metrics['spl']:.2f} | "
                f"{metrics['max_tip_force_n']:.2f} |")
    return "\n".join(lines)
