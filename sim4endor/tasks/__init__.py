"""Navigation tasks: the paper's MDP on top of :class:`sim4endor.physics.GuidewirePhysics`."""

from sim4endor.tasks import fluoroscopy
from sim4endor.tasks.anatomy import Anatomy, AnatomyPool, AnatomySource, FixedAnatomy
from sim4endor.tasks.config import (
    DEFAULT_OBSERVATIONS,
    OBSERVATION_SETS,
    OPTIONAL_OBSERVATIONS,
    WRONG_BRANCH_START,
    ActionConfig,
    CathLabConfig,
    InitialStateConfig,
    NavigationConfig,
    PixelsConfig,
    TaskConfigError,
    TerminationConfig,
)
from sim4endor.tasks.navigation import FAILURES, InvalidActionError, NavigationTask

__all__ = [
    "DEFAULT_OBSERVATIONS",
    "FAILURES",
    "OBSERVATION_SETS",
    "OPTIONAL_OBSERVATIONS",
    "WRONG_BRANCH_START",
    "ActionConfig",
    "Anatomy",
    "AnatomyPool",
    "AnatomySource",
    "CathLabConfig",
    "FixedAnatomy",
    "InitialStateConfig",
    "InvalidActionError",
    "NavigationConfig",
    "NavigationTask",
    "PixelsConfig",
    "TaskConfigError",
    "TerminationConfig",
    "fluoroscopy",
]
