"""``sim4endor view DOMAIN TASK [task arguments]``: the MuJoCo viewer with keyboard teleoperation.

Keys (the viewer window must have focus):

===========  ==========================================================
key          effect
===========  ==========================================================
Up / Down    insertion speed +/- one notch (4 notches = full speed)
Left/Right   rotation speed -/+ one notch
S            stop (both speeds 0)
R            reset the episode
===========  ==========================================================

The environment steps in real time at its control frequency with the current speeds as the
action. The target is a green sphere; the top-left text shows D (manifold distance), the
reward and the return. ``--record FILE`` saves the demonstration (observations, actions,
rewards, reward terms, episode boundaries) as a compressed ``.npz`` when the viewer closes.
"""

from __future__ import annotations

import argparse
import io
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sim4endor import assets
from sim4endor._atomic import atomic_write_bytes
from sim4endor.cli import args as arg_types
from sim4endor.cli.render import (
    TARGET_RGBA,
    Policy,
    add_sphere,
    load_policy,
    state_vector,
    status_text,
    top_down_pose,
)

if TYPE_CHECKING:
    from sim4endor.suite import NavigationEnvironment

# GLFW key codes, as passed to the viewer's key callback.
KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP = 262, 263, 264, 265
KEY_R, KEY_S = 82, 83
NOTCH = 0.25


@dataclass
class Recording:
    """A demonstration: one row per control step, episodes separated by ``episode``."""

    observations: list[np.ndarray] = field(default_factory=list)
    actions: list[np.ndarray] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)
    terms: list[tuple[float, float, float]] = field(default_factory=list)
    episode: list[int] = field(default_factory=list)

    def save(self, path: Path) -> None:
        """Writes ``path`` (.npz) atomically."""
        buffer = io.BytesIO()
        np.savez_compressed(
            buffer,
            observations=np.array(self.observations, dtype=np.float32),
            actions=np.array(self.actions, dtype=np.float64).reshape(-1, 2),
            rewards=np.array(self.rewards, dtype=np.float64),
            reward_terms=np.array(self.terms, dtype=np.float64).reshape(-1, 3),
            episode=np.array(self.episode, dtype=np.int64),
        )
        atomic_write_bytes(Path(path), buffer.getvalue())


class TeleopSession:
    """Keyboard commands -> actions -> environment steps, with an optional recording.

    The viewer only forwards key codes to :meth:`on_key` and calls :meth:`tick` once per
    control period, so the session works (and is tested) without a window.
    """

    def __init__(self, env: NavigationEnvironment, record: bool = False,
                 policy: Policy | None = None) -> None:
        """Starts the first episode; with ``policy`` it drives while no key command is set."""
        self.env = env
        self.policy = policy
        self.speed = np.zeros(2)
        self.recording = Recording() if record else None
        self._episode = 0
        self._reset_requested = False
        self.timestep = env.reset()
        self.total = 0.0
        self.last_reward = 0.0
        self.step = 0

    def on_key(self, keycode: int) -> None:
        """Updates the commanded speeds (or asks for a reset) from one key press."""
        if keycode == KEY_UP:
            self.speed[0] += NOTCH
        elif keycode == KEY_DOWN:
            self.speed[0] -= NOTCH
        elif keycode == KEY_RIGHT:
            self.speed[1] += NOTCH
        elif keycode == KEY_LEFT:
            self.speed[1] -= NOTCH
        elif keycode == KEY_S:
            self.speed[:] = 0.0
        elif keycode == KEY_R:
            self._reset_requested = True
        self.speed = np.clip(self.speed, -1.0, 1.0)

    def tick(self) -> None:
        """Advances one control step with the current speeds (or resets)."""
        if self._reset_requested or self.timestep.last():
            self._reset_requested = False
            self._episode += 1
            self.timestep = self.env.reset()
            self.total = self.last_reward = 0.0
            self.step = 0
            return
        observation = state_vector(self.timestep.observation)
        if self.policy is not None and self.policy_driving:
            action = np.asarray(self.policy(observation), dtype=float)
        else:
            action = self.speed.copy()
        self.timestep = self.env.step(action)
        self.step += 1
        self.last_reward = float(self.timestep.reward)
        self.total += self.last_reward
        if self.recording is not None:
            info = self.env.task.step_info()
            self.recording.observations.append(observation)
            self.recording.actions.append(action)
            self.recording.rewards.append(self.last_reward)
            self.recording.terms.append((float(info["reward_distance"]),
                                         float(info["reward_goal"]),
                                         float(info["reward_failure"])))
            self.recording.episode.append(self._episode)

    @property
    def policy_driving(self) -> bool:
        """Whether the policy acts now: a key command overrides it until S sets the speeds
        back to zero."""
        return self.policy is not None and not self.speed.any()

    def status(self) -> str:
        """Returns the status lines shown in the viewer."""
        if self.policy_driving:
            command = "policy driving (arrow keys take over, S hands back)"
        else:
            command = f"command insert {self.speed[0]:+.2f} rotate {self.speed[1]:+.2f}"
        return status_text(self.env, self.step, self.last_reward, self.total) + "\n" + command


def run_viewer(args: argparse.Namespace) -> int:
    """Opens the passive viewer and runs the teleoperation loop until it closes."""
    from sim4endor import _gl

    _gl.require_display("sim4endor view")
    import mujoco
    import mujoco.viewer

    from sim4endor import suite
    from sim4endor.rl.runs import run_config

    source = assets.run_or_policy(args.policy) if args.policy else None
    # A run or shipped policy brings its observation set (and wire, ...); the flags change it.
    base = run_config(source).env if source is not None and source.is_dir() else None
    config = arg_types.env_config(args, base)
    env = suite.load(config.domain, config.task, config.task_kwargs(args.seed))
    policy = load_policy(args.policy, args.seed, env) if args.policy else None
    session = TeleopSession(env, record=args.record is not None, policy=policy)
    physics = env.physics
    period = env.control_timestep()
    try:
        with mujoco.viewer.launch_passive(physics.model.ptr, physics.data.ptr,
                                          key_callback=session.on_key) as viewer:
            pose = top_down_pose(env.task.anatomy.vessel.centerline.nodes)
            viewer.cam.lookat[:] = pose["lookat"]
            viewer.cam.distance = pose["distance"]
            viewer.cam.azimuth, viewer.cam.elevation = pose["azimuth"], pose["elevation"]
            while viewer.is_running():
                started = time.monotonic()
                with viewer.lock():
                    session.tick()
                    viewer.user_scn.ngeom = 0
                    add_sphere(viewer.user_scn, env.task.target_position, 2.0e-3, TARGET_RGBA)
                # set_texts takes the viewer's lock itself: calling it under lock() deadlocks.
                viewer.set_texts((mujoco.mjtFontScale.mjFONTSCALE_150,
                                  mujoco.mjtGridPos.mjGRID_TOPLEFT, "sim4endor",
                                  session.status()))
                viewer.sync()
                time.sleep(max(0.0, period - (time.monotonic() - started)))
    finally:  # also after Ctrl+C: a demonstration is worth keeping
        if session.recording is not None:
            session.recording.save(args.record)
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Adds the ``view`` subcommand."""
    parser = subparsers.add_parser(
        "view", help="drive the wire by keyboard in the MuJoCo viewer",
        description=__doc__.split("\n\n")[0] if __doc__ else None,
    )
    parser.add_argument("domain", help="suite domain, e.g. simplified_phantom")
    parser.add_argument("task", help="suite task, e.g. task_a")
    parser.add_argument("--seed", type=arg_types.seed, default=0)
    parser.add_argument("--reward", choices=("manifold", "euclidean"),
                        help="progress distance (default: manifold)")
    arg_types.add_task_arguments(parser)
    parser.add_argument("--policy", default=None,
                        help="a policy that drives while no key command is set: 'expert', "
                             "'probing-expert', a "
                             "shipped policy's name (e.g. generalist), a run folder or an "
                             "exported .pt (as render --policy)")
    parser.add_argument("--record", type=Path, default=None,
                        help="save the demonstration to this .npz file")
    parser.set_defaults(func=run_viewer, renders=True)


def load_recording(path: Path) -> dict[str, Any]:
    """Reads a ``--record`` file back as a dict of arrays."""
    with np.load(path) as data:
        return {k: data[k] for k in data.files}
