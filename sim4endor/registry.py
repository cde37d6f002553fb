"""The one registry of sim4endor tasks: suite names, benchmark lists and gymnasium ids.

Every (domain, task) pair is declared once here, with its tags and its gymnasium id, so
:mod:`sim4endor.suite`, the gymnasium registration in :mod:`sim4endor.envs` and the training
benchmarks cannot disagree. Importing this module is cheap (no MuJoCo, no vessel loading);
the tasks themselves are built by :func:`sim4endor.suite.load`.

Example:
    >>> from sim4endor import registry
    >>> registry.ALL_TASKS[:2]
    (('simplified_phantom', 'task_a'), ('simplified_phantom', 'task_b'))
    >>> registry.find("simplified_phantom", "task_a").gym_id
    'Sim4EndoR/SimplifiedPhantom-TaskA-v0'
"""

from __future__ import annotations

from dataclasses import dataclass

from sim4endor.errors import Sim4EndoRError

#: Gymnasium namespace of every sim4endor id.
GYM_NAMESPACE = "Sim4EndoR"

TAG_BENCHMARKING = "benchmarking"
#: The paper's phantom tasks started down the wrong branch (see :data:`START_WRONG_BRANCH`).
TAG_REDIRECT = "redirect"
TAG_RANDOMISED = "randomised"
#: The paper's physical phantoms: flat trees in their x-y plane, not a patient's anatomy.
TAG_PHANTOM = "phantom"
#: Entries tagged so need task_kwargs (e.g. a vessel folder) and are not in ``ALL_TASKS``.
TAG_NEEDS_KWARGS = "needs_kwargs"


#: Where an episode starts: the paper's inlet start, or down a branch off the target's path
#: with the roll drawn over the full circle (``InitialStateConfig.off_path_depth``).
START_INLET = "inlet"
START_WRONG_BRANCH = "wrong_branch"


class UnknownTaskError(Sim4EndoRError, KeyError):
    """Raised for a domain or task name that is not registered; lists the valid ones."""

    def __str__(self) -> str:  # KeyError would quote the whole message.
        return str(self.args[0])


@dataclass(frozen=True)
class TaskEntry:
    """One registered task.

    Attributes:
        domain: Suite domain name, e.g. ``"simplified_phantom"``.
        task: Suite task name, e.g. ``"task_a"``.
        gym_id: Gymnasium id, e.g. ``"Sim4EndoR/SimplifiedPhantom-TaskA-v0"``.
        tags: Tags such as :data:`TAG_BENCHMARKING`.
        vessel: Vessel name loaded by the task (None when chosen per episode or via kwargs).
        target: Centerline label of the target node (None when chosen per episode or via kwargs).
        description: One line for listings and docs.
        start: :data:`START_INLET` or :data:`START_WRONG_BRANCH`.
    """

    domain: str
    task: str
    gym_id: str
    tags: frozenset[str]
    vessel: str | None
    target: str | None
    description: str
    start: str = START_INLET


def _phantom_entry(vessel: str, camel: str, target: str, description: str) -> TaskEntry:
    return TaskEntry(
        domain=vessel,
        task=f"task_{target.lower()}",
        gym_id=f"{GYM_NAMESPACE}/{camel}-Task{target}-v0",
        tags=frozenset({TAG_BENCHMARKING, TAG_PHANTOM}),
        vessel=vessel,
        target=target,
        description=description,
    )


def _redirect_entry(vessel: str, camel: str, target: str, phantom: str) -> TaskEntry:
    """The paper's task of ``target`` started down the wrong branch (``task_a_redirect``)."""
    return TaskEntry(
        domain=vessel,
        task=f"task_{target.lower()}_redirect",
        gym_id=f"{GYM_NAMESPACE}/{camel}-Task{target}Redirect-v0",
        tags=frozenset({TAG_REDIRECT, TAG_PHANTOM}),
        vessel=vessel,
        target=target,
        description=f"{phantom}: reach target {target} from a wire already down another "
                    "target's branch, rolled anywhere on the circle.",
        start=START_WRONG_BRANCH,
    )


ENTRIES: tuple[TaskEntry, ...] = (
    _phantom_entry("simplified_phantom", "SimplifiedPhantom", "A",
                   "Simplified phantom (one bifurcation): reach End Point A."),
    _phantom_entry("simplified_phantom", "SimplifiedPhantom", "B",
                   "Simplified phantom (one bifurcation): reach End Point B (curved branch)."),
    _phantom_entry("vascular_phantom", "VascularPhantom", "A",
                   "Vascular phantom (several bifurcations, tortuous): reach target A."),
    _phantom_entry("vascular_phantom", "VascularPhantom", "B",
                   "Vascular phantom (several bifurcations, tortuous): reach target B."),
    _redirect_entry("simplified_phantom", "SimplifiedPhantom", "A", "Simplified phantom"),
    _redirect_entry("simplified_phantom", "SimplifiedPhantom", "B", "Simplified phantom"),
    _redirect_entry("vascular_phantom", "VascularPhantom", "A", "Vascular phantom"),
    _redirect_entry("vascular_phantom", "VascularPhantom", "B", "Vascular phantom"),
    TaskEntry(
        domain="random_coronary",
        task="navigate",
        gym_id=f"{GYM_NAMESPACE}/RandomCoronary-v0",
        tags=frozenset({TAG_RANDOMISED}),
        vessel=None,
        target=None,
        description="A seeded random coronary tree and terminal target per episode "
                    "(workhorse wire, tip shaped 3 mm at 75°).",
    ),
    TaskEntry(
        domain="coronary",
        task="navigate",
        gym_id=f"{GYM_NAMESPACE}/Coronary-v0",
        tags=frozenset({TAG_RANDOMISED}),
        vessel=None,
        target=None,
        description="A left or right coronary tree of normal calibre behind a guide catheter, "
                    "and a distal branch end as target, per episode (workhorse wire).",
    ),
    TaskEntry(
        domain="vessel",
        task="navigate",
        gym_id=f"{GYM_NAMESPACE}/Vessel-v0",
        tags=frozenset({TAG_NEEDS_KWARGS}),
        vessel=None,
        target=None,
        description="Any built vessel folder: task_kwargs vessel=NAME_OR_PATH, target=LABEL.",
    ),
)

#: Every (domain, task) that loads without task_kwargs.
ALL_TASKS: tuple[tuple[str, str], ...] = tuple(
    (e.domain, e.task) for e in ENTRIES if TAG_NEEDS_KWARGS not in e.tags
)
#: The (domain, task) pairs of the paper's benchmark (Table I and the vascular phantom).
BENCHMARKING: tuple[tuple[str, str], ...] = tuple(
    (e.domain, e.task) for e in ENTRIES if TAG_BENCHMARKING in e.tags
)

#: The redirect variants of the paper's tasks, in registry order.
REDIRECT: tuple[tuple[str, str], ...] = tuple(
    (e.domain, e.task) for e in ENTRIES if TAG_REDIRECT in e.tags
)


def domains() -> tuple[str, ...]:
    """Returns the registered domain names, in registry order."""
    return tuple(dict.fromkeys(e.domain for e in ENTRIES))


def tasks_of(domain: str) -> tuple[str, ...]:
    """Returns the task names of ``domain``; raises :class:`UnknownTaskError` if unknown."""
    found = tuple(e.task for e in ENTRIES if e.domain == domain)
    if not found:
        raise UnknownTaskError(f"Unknown domain {domain!r}; valid domains: {list(domains())}.")
    return found


def find(domain: str, task: str) -> TaskEntry:
    """Returns the entry of (domain, task); the error lists the valid names."""
    for entry in ENTRIES:
        if entry.domain == domain and entry.task == task:
            return entry
    raise UnknownTaskError(
        f"Unknown task {task!r} for domain {domain!r}; valid tasks: {list(tasks_of(domain))}."
    )


def find_gym_id(gym_id: str) -> TaskEntry:
    """Returns the entry registered under a gymnasium id."""
    for entry in ENTRIES:
        if entry.gym_id == gym_id:
            return entry
    raise UnknownTaskError(
        f"Unknown gymnasium id {gym_id!r}; valid ids: {[e.gym_id for e in ENTRIES]}."
    )


def with_tag(tag: str) -> tuple[TaskEntry, ...]:
    """Returns the entries carrying ``tag``."""
    return tuple(e for e in ENTRIES if tag in e.tags)
