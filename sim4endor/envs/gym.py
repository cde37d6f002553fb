"""Gymnasium adapter of the navigation suite."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, SupportsFloat

import gymnasium
import numpy as np
from gymnasium import spaces

from sim4endor import _gl, registry

#: Info keys holding numbers (the others: ``failure``, a string naming the failure state);
#: ``tip_position`` is (3,) m, in the reset's info too, so metrics such as the path length
#: work whatever the observation holds (the ``generalist`` set has no absolute position).
NUMERIC_INFO_KEYS: tuple[str, ...] = (
    "tip_position",
    "reward_distance",
    "reward_goal",
    "reward_failure",
    "distance",
    "manifold_distance",
    "wall_force",
    "tip_force",
    "lumen_excess",
    "is_success",
    "failure_code",
    "insertion_command",
    "rotation_command",
)


class NavigationEnv(gymnasium.Env[Any, np.ndarray]):
    """Steer a guidewire tip to a target in a 3D vessel (gymnasium API of ``sim4endor.suite``).

    Made by ``gymnasium.make("Sim4EndoR/SimplifiedPhantom-TaskA-v0")`` (ids in
    :mod:`sim4endor.registry`) or directly with a domain and task name.

    **Observation**: ``Box(float32)`` concatenating the suite's entries in order; by default
    the paper's state (6,):

    ===  ==================  ====  =========================================
    idx  entry               unit  meaning
    ===  ==================  ====  =========================================
    0-2  ``tip_position``    m     wire tip x, y, z in the vessel frame
    3-5  ``tip_velocity``    m/s   wire tip velocity x, y, z
    ===  ==================  ====  =========================================

    Opt-in entries (``task_kwargs={"observations": (...)}``) follow in the order given:
    ``target_position`` (3, m), ``wire_shape`` (3·(N+1), m), ``last_action`` (2),
    ``insertion`` (1, m), ``rotation`` (1, rad), ``manifold_distance`` (1, m), and the
    tip-frame entries (``path_ahead``, ``axis_offset``, ...; :mod:`sim4endor.suite`).
    ``task_kwargs={"observations": "generalist"}`` replaces the whole state by that named set
    (36 numbers, none of them an absolute position). With ``"pixels"`` the space is a
    ``Dict`` of ``"state"`` (the Box above) and ``"pixels"`` (``Box(uint8, (H, W, 1))``, a
    fluoroscopy-like top-down projection). The tip position is always in ``info``.

    **Action**: ``Box(-1, 1, (2,), float32)``:

    ===  =========  ================================  =====================
    idx  name       maps to (per 50 ms control step)  default maximum
    ===  =========  ================================  =====================
    0    insertion  Δd (m), positive inserts          1.5 mm (30 mm/s)
    1    rotation   Δθ (rad) about the wire axis      9° (180 °/s)
    ===  =========  ================================  =====================

    NaN/inf actions raise :class:`sim4endor.tasks.InvalidActionError`.

    **Reward** (each term also in ``info``):

    ===================  ======================================  ================================
    info key             value                                   when
    ===================  ======================================  ================================
    ``reward_distance``  (D_last − D_current)/100, D in mm       every step
    ``reward_goal``      +100                                    D <= 1 mm (terminated)
    ``reward_failure``   −100                                    failure state (terminated)
    ===================  ======================================  ================================

    D is the manifold (geodesic) distance along the centerline graph, or Euclidean with
    ``task_kwargs={"reward": "euclidean"}``. Failure states (``info["failure"]``):
    ``tip_force`` (tip section on the wall > 1 N), ``outside_lumen`` (tip > 0.5 mm outside),
    ``insertion_limit``, ``rotation_limit``, ``instability``, ``push_force`` (driver push
    > 1 N). ``info`` also holds ``distance`` and
    ``manifold_distance`` (m), ``wall_force`` and ``tip_force`` (N), ``lumen_excess`` (m),
    ``is_success`` and ``failure_code`` (0, or the failure's 1-based index in
    ``sim4endor.tasks.FAILURES``).

    **Episode end**: ``terminated`` on success or failure; ``truncated`` after 20 s of
    simulated time (400 steps).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}  # noqa: RUF012 (gymnasium API)

    def __init__(
        self,
        domain: str,
        task: str,
        task_kwargs: Mapping[str, Any] | None = None,
        environment_kwargs: Mapping[str, Any] | None = None,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 480,
    ) -> None:
        """Loads the suite task.

        Args:
            domain: Suite domain, e.g. ``"simplified_phantom"``.
            task: Suite task, e.g. ``"task_a"``.
            task_kwargs: See :func:`sim4endor.suite.load`.
            environment_kwargs: See :func:`sim4endor.suite.load`.
            render_mode: ``"rgb_array"`` or None.
            width: Width of rendered frames (pixels).
            height: Height of rendered frames (pixels).
        """
        from sim4endor import suite  # MuJoCo loads only when an environment is made

        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}.")
        if render_mode is not None:
            _gl.require_rendering()
        self.entry = registry.find(domain, task)
        self.render_mode = render_mode
        self._size = (height, width)
        self.dm_env = suite.load(domain, task, task_kwargs, environment_kwargs)
        obs_spec = self.dm_env.observation_spec()
        self._state_keys = tuple(k for k in obs_spec if k != "pixels")
        state_dim = sum(int(np.prod(obs_spec[k].shape)) for k in self._state_keys)
        state = spaces.Box(-np.inf, np.inf, shape=(state_dim,), dtype=np.float32)
        self._pixels = "pixels" in obs_spec
        if self._pixels:
            self.observation_space: spaces.Space[Any] = spaces.Dict(
                {"state": state,
                 "pixels": spaces.Box(0, 255, shape=obs_spec["pixels"].shape, dtype=np.uint8)}
            )
        else:
            self.observation_space = state
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._episode_over = True  # until the first reset

    def _observation(self, observation: Mapping[str, np.ndarray]) -> Any:
        state = np.concatenate(
            [np.asarray(observation[k], dtype=np.float32).ravel() for k in self._state_keys]
        )
        if self._pixels:
            return {"state": state, "pixels": observation["pixels"]}
        return state

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Starts an episode; ``seed`` reseeds the task's own generator."""
        super().reset(seed=seed)
        if seed is not None:
            self.dm_env.task.reseed(seed)
        timestep = self.dm_env.reset()
        self._episode_over = False
        return (self._observation(timestep.observation),
                {"tip_position": self.dm_env.physics.tip_position()})

    def step(
        self, action: np.ndarray
    ) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Applies one control step; returns (obs, reward, terminated, truncated, info).

        Raises:
            gymnasium.error.ResetNeeded: Before the first :meth:`reset` and after an episode
                ended (``terminated`` or ``truncated``), as gymnasium's own environments do.
        """
        if self._episode_over:
            raise gymnasium.error.ResetNeeded(
                "Cannot call step() before reset() nor after the episode ended (terminated or "
                "truncated): call reset() to start a new episode."
            )
        # Not cast here: the task rejects text and bools, which a float cast would accept.
        timestep = self.dm_env.step(action)
        terminated = bool(timestep.last() and timestep.discount == 0.0)
        truncated = bool(timestep.last() and not terminated)
        self._episode_over = bool(timestep.last())
        # Numbers as numpy scalars: TorchRL's info reader needs a dtype.
        info = {
            k: np.asarray(v) if k in NUMERIC_INFO_KEYS else v
            for k, v in self.dm_env.task.step_info().items()
        }
        return (
            self._observation(timestep.observation),
            float(timestep.reward),
            terminated,
            truncated,
            info,
        )

    def render(self) -> np.ndarray | None:
        """Returns an RGB frame of the scene (``render_mode="rgb_array"``)."""
        if self.render_mode is None:
            return None
        height, width = self._size
        return np.asarray(self.dm_env.physics.render(height=height, width=width, camera_id=-1))

    def close(self) -> None:
        """Frees the rendering context, if any."""
        self.dm_env.close()


def register_all() -> None:
    """Registers a gymnasium id per registry entry (idempotent)."""
    for entry in registry.ENTRIES:
        if entry.gym_id in gymnasium.registry:
            continue
        gymnasium.register(
            id=entry.gym_id,
            entry_point="sim4endor.envs.gym:NavigationEnv",
            kwargs={"domain": entry.domain, "task": entry.task},
        )
