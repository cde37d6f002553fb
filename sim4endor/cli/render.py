"""``sim4endor render [DOMAIN TASK] --policy ... --out episode.mp4``: a video, headless.

Rendering uses an offscreen OpenGL context: ``MUJOCO_GL`` defaults to ``osmesa`` here (set
``MUJOCO_GL=egl`` for a GPU). The camera looks straight down on the vessel (the phantoms lie
in the x–y plane), the target is marked by a green sphere and the top-left text shows the
step, the manifold distance D and the reward.
"""

from __future__ import annotations

import argparse
import itertools
import math
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sim4endor import assets
from sim4endor.cli import args as arg_types
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl.config import EnvConfig

if TYPE_CHECKING:
    import mujoco

    from sim4endor.suite import NavigationEnvironment

Policy = Callable[[np.ndarray], np.ndarray]
BUILTIN_POLICIES = arg_types.REFERENCE_POLICIES
TARGET_RGBA = np.array([0.1, 0.9, 0.2, 0.8], dtype=np.float32)
#: The wire overlay of videos and figures: 0.5 mm radius, 3 px across at 640 px per phantom.
WIRE_RADIUS = 0.5e-3
WIRE_RGBA = np.array([0.35, 0.75, 1.0, 1.0], dtype=np.float32)
#: Video formats the writer (imageio: ffmpeg, Pillow) produces, by file suffix.
VIDEO_SUFFIXES = (".mp4", ".gif")
#: Largest frame side (pixels): the offscreen buffer is allocated at this size.
MAX_FRAME_SIZE = 4096


class PolicyLoadError(Sim4EndoRError, ValueError):
    """Raised when ``--policy`` is neither a built-in name nor a loadable policy file."""


class RenderArgumentError(Sim4EndoRError, ValueError):
    """Raised for an output file or frame size the renderer cannot write."""


def load_policy(spec: str, seed: int, env: NavigationEnvironment | None = None) -> Policy:
    """Returns an observation-vector -> action function.

    Args:
        spec: ``"insert"`` (push straight in), ``"random"`` (uniform actions), ``"expert"``
            (:class:`sim4endor.tasks.expert.CenterlineExpert`, which reads ``env``'s wire and
            centerline rather than the observation), ``"probing-expert"``
            (:class:`sim4endor.tasks.expert.ProbingExpert`: the same with lookahead on a copy
            of the simulation where it is stuck, the reachability check), a training run
            folder (its latest
            deterministic policy, as ``sim4endor evaluate`` runs it) or the path of a
            TorchScript policy exported by ``sim4endor.rl.export`` (observation (6,) float32
            -> action (2,) in [-1, 1]).
        seed: Seed of the random policy.
        env: The environment the policy acts in (needed by the experts).
    """
    if spec in arg_types.EXPERT_POLICIES:
        if env is None:
            raise PolicyLoadError(f"--policy {spec} needs the environment it acts in.")
        from sim4endor.tasks.expert import CenterlineExpert, ProbingExpert

        expert = ProbingExpert() if spec == arg_types.PROBING_EXPERT else CenterlineExpert()
        previous = [math.inf]  # simulated time of the last call

        def steer(_obs: np.ndarray) -> np.ndarray:
            # The policy sees no episode boundary; `view` resets the env on R or at an
            # episode's end. The time going back marks a new episode, which the expert must
            # start afresh (its best distance, back-off and probes are the last episode's).
            now = env.physics.time()
            if now < previous[0]:
                expert.reset()
            previous[0] = now
            return expert(env.physics, env.task)

        return steer
    if spec == "insert":
        return lambda _obs: np.array([1.0, 0.0])
    if spec == "random":
        rng = np.random.default_rng(seed)
        return lambda _obs: rng.uniform(-1.0, 1.0, size=2)
    path = assets.run_or_policy(spec)
    if path.is_dir():
        return _run_policy(path)
    if not path.is_file():
        raise PolicyLoadError(
            f"--policy {spec!r} is neither {list(BUILTIN_POLICIES)}, a training run folder nor "
            "an existing file; export a trained run with sim4endor.rl.export (TorchScript .pt)."
        )
    import torch

    try:
        module = torch.jit.load(str(path), map_location="cpu")
    except RuntimeError as exc:  # torch's message runs over several lines: keep the first
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else "unreadable"
        raise PolicyLoadError(f"{path} is not a TorchScript policy ({reason}).") from None
    return _torch_policy(module.eval())


def _run_policy(run_dir: Path) -> Policy:
    """The deterministic policy of a training run folder's latest checkpoint."""
    from sim4endor.rl.export import deterministic_policy
    from sim4endor.rl.runs import load_agent

    config, agent = load_agent(run_dir)
    return _torch_policy(deterministic_policy(config, agent))


def _torch_policy(module: Callable[..., Any]) -> Policy:
    import torch

    def act(observation: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            obs = torch.as_tensor(observation, dtype=torch.float32)
            return np.asarray(module(obs).numpy(), dtype=np.float64)

    return act


def _append_geom(scene: mujoco.MjvScene, kind: int, size: np.ndarray, position: np.ndarray,
                 rgba: np.ndarray) -> mujoco.MjvGeom | None:
    """Appends a visual-only geom to an abstract scene; None when the scene is full."""
    import mujoco

    # dm_control hands its wrapper of the scene; the viewer the raw mujoco.MjvScene.
    scene = getattr(scene, "ptr", scene)
    if scene.ngeom >= scene.maxgeom:
        return None
    # Grow first: dm_control's scene wrapper only exposes geoms[:ngeom].
    scene.ngeom += 1
    geom = scene.geoms[scene.ngeom - 1]
    mujoco.mjv_initGeom(geom, kind, size, np.asarray(position, dtype=np.float64),
                        np.eye(3).ravel(), rgba)
    return geom


def add_sphere(scene: mujoco.MjvScene, position: np.ndarray, radius: float,
               rgba: np.ndarray) -> None:
    """Appends a visual-only sphere to an abstract scene (target marker)."""
    import mujoco

    _append_geom(scene, mujoco.mjtGeom.mjGEOM_SPHERE, np.array([radius, 0.0, 0.0]), position,
                 rgba)


def add_wire(scene: mujoco.MjvScene, points: np.ndarray) -> None:
    """Appends a visual-only capsule chain through the wire's ``points``, drawn thicker.

    The real wire (0.36 mm across) is about one pixel wide in a view of a whole phantom, and
    the lumen surface in front of it dims it further; the overlay shows where it is.
    """
    import mujoco

    capsule = mujoco.mjtGeom.mjGEOM_CAPSULE
    for start, end in itertools.pairwise(np.asarray(points, dtype=np.float64)):
        geom = _append_geom(scene, capsule, np.zeros(3), np.zeros(3), WIRE_RGBA)
        if geom is None:
            return
        mujoco.mjv_connector(geom, capsule, WIRE_RADIUS, start, end)
        geom.emission = 0.6  # bright through the translucent lumen whatever the lighting


def top_down_pose(points: np.ndarray, fovy_deg: float = 45.0) -> dict[str, Any]:
    """Returns a free-camera pose looking down -z that frames ``points`` (m) with a margin."""
    low, high = points.min(axis=0), points.max(axis=0)
    half = 0.5 * float(np.max(high[:2] - low[:2]))
    # The frame is fitted at the top of the points' box, half their height above the centre.
    distance = 1.15 * half / np.tan(np.radians(fovy_deg) / 2) + 0.5 * float(high[2] - low[2])
    return {"lookat": 0.5 * (low + high), "distance": distance, "azimuth": 90.0,
            "elevation": -90.0}


def status_text(env: NavigationEnvironment, step: int, reward: float, total: float) -> str:
    """Returns the live status lines: step, D (mm), reward, return, failure/success."""
    info = env.task.step_info() if step else {}
    distance = info.get("manifold_distance")
    lines = [
        f"step {step}  t {env.physics.time():.2f} s",
        "D  --" if distance is None else f"D  {float(distance) * 1e3:.1f} mm",
        f"reward {reward:+.3f}  return {total:+.2f}",
    ]
    if info.get("is_success"):
        lines.append("SUCCESS")
    elif info.get("failure"):
        lines.append(f"FAILURE: {info['failure']}")
    return "\n".join(lines)


def state_vector(observation: Any) -> np.ndarray:
    """Concatenates the non-image observation entries, as the gymnasium adapter does."""
    return np.concatenate(
        [np.asarray(v, dtype=np.float32).ravel() for k, v in observation.items() if k != "pixels"]
    )


def render_episode(args: argparse.Namespace) -> int:
    """Runs one episode with the policy and writes the video atomically."""
    from sim4endor import _gl

    out = Path(args.out)
    if out.suffix.lower() not in VIDEO_SUFFIXES:
        raise RenderArgumentError(
            f"--out {out}: the video format is chosen by the suffix; use one of "
            f"{', '.join(VIDEO_SUFFIXES)}."
        )
    if max(args.width, args.height) > MAX_FRAME_SIZE:
        raise RenderArgumentError(
            f"--width {args.width} --height {args.height}: frames are at most "
            f"{MAX_FRAME_SIZE} pixels on a side."
        )
    _gl.require_rendering()
    import imageio.v2 as imageio
    from dm_control.mujoco import MovableCamera, TextOverlay
    from tqdm.auto import tqdm

    from sim4endor import suite

    config = _env_config(args)
    env = suite.load(config.domain, config.task, config.task_kwargs(args.seed))
    policy = load_policy(args.policy, args.seed, env)
    timestep = env.reset()

    def mark_target(_physics: Any, scene: mujoco.MjvScene) -> None:
        add_wire(scene, env.physics.wire_points())
        target, motion = env.task.target_position, env.physics.wall_motion
        if motion is not None:
            target = motion.from_rest(target, env.physics.time())
        add_sphere(scene, target, 2.0e-3, TARGET_RGBA)

    # The offscreen buffer is allocated from the model's size when the first frame renders.
    buffer = env.physics.model.vis.global_
    buffer.offwidth, buffer.offheight = (max(buffer.offwidth, args.width),
                                         max(buffer.offheight, args.height))
    camera = MovableCamera(env.physics, height=args.height, width=args.width,
                           scene_callback=mark_target)
    camera.set_pose(**top_down_pose(env.task.anatomy.vessel.centerline.nodes))

    # A moving wall is its hulls (group 3): the lumen's display mesh (group 1) stands still.
    option = wall_view() if env.physics.wall_motion is not None else None
    frames: list[Any] = []
    total, step = 0.0, 0
    max_steps = step_budget(env, args.max_steps)
    bar = tqdm(total=max_steps, unit="steps", desc=f"render {config.domain}/{config.task}",
               disable=args.no_progress)
    while True:
        reward = 0.0 if timestep.reward is None else float(timestep.reward)
        total += reward
        overlay = TextOverlay(body=status_text(env, step, reward, total))
        # render reuses its buffer
        frames.append(np.array(camera.render(overlays=[overlay], scene_option=option)))
        if timestep.last() or step >= max_steps:
            break
        timestep = env.step(policy(state_vector(timestep.observation)))
        step += 1
        bar.update()
    bar.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        staging = Path(tmp) / f"partial{out.suffix}"
        imageio.mimwrite(staging, frames, fps=args.fps)
        staging.replace(out)
    print(f"{out}: {episode_outcome(env, timestep, step)}, return {total:+.2f}")  # noqa: T201
    env.physics.free()  # release the GL context now, not in dm_control's atexit hook
    return 0


def wall_view() -> Any:
    """Scene options that draw the wall's collision hulls instead of the lumen's mesh."""
    from dm_control.mujoco import wrapper

    option = wrapper.core.MjvOption()
    option.geomgroup[1], option.geomgroup[3] = 0, 1
    return option


def step_budget(env: NavigationEnvironment, requested: int | None) -> int:
    """The control steps an episode of ``env`` may take: its task's time limit (800 on a
    coronary tree or a coronary wire's vessel folder, 400 on the phantoms), or fewer if
    ``requested``."""
    limit = round(env.task.config.termination.time_limit / env.control_timestep())
    return limit if requested is None else min(requested, limit)


def episode_outcome(env: NavigationEnvironment, timestep: Any, steps: int) -> str:
    """How an episode ended, in words: success, the failure's reason, time limit or step cap."""
    info = env.task.step_info() if steps else {}
    seconds = f"{steps} steps ({env.physics.time():.2f} s)"
    if info.get("is_success"):
        return f"success after {seconds}"
    if info.get("failure"):
        return f"failure ({info['failure']}) after {seconds}"
    if timestep.last():
        return f"time limit after {seconds}"
    return f"stopped at --max-steps after {seconds}"


def _env_config(args: argparse.Namespace) -> EnvConfig:
    """The environment to render: the flags', on top of the run's when --policy is a run."""
    from sim4endor.rl.runs import run_config

    if (args.domain is None) != (args.task is None):
        raise RenderArgumentError("Name both DOMAIN and TASK, or neither (with a run folder "
                                  "as --policy, whose task is then rendered).")
    policy = assets.run_or_policy(args.policy)
    base = run_config(policy).env if policy.is_dir() else None
    if args.domain is None and base is None:
        raise RenderArgumentError(f"Name a DOMAIN and TASK to render --policy {args.policy} "
                                  "in (only a run folder brings its own).")
    return arg_types.env_config(args, base)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Adds the ``render`` subcommand."""
    parser = subparsers.add_parser(
        "render", help="write a video of one episode (headless)",
        description="Run one episode with a policy and write a top-down video (mp4 or gif); "
                    "prints the file and how the episode ended.",
    )
    parser.add_argument("domain", nargs="?",
                        help="suite domain, e.g. simplified_phantom (default with a run folder "
                             "as --policy: the run's)")
    parser.add_argument("task", nargs="?", help="suite task, e.g. task_a")
    parser.add_argument("--policy", default="insert",
                        help="'insert' (the default), 'random', 'expert' (scripted, reads the "
                             "wire and centerline), 'probing-expert' (the same with lookahead "
                             "where it is stuck), a shipped pretrained policy's name (e.g. "
                             "generalist), a training run folder (its latest policy) or "
                             "an exported TorchScript policy (.pt: a program, load only trusted "
                             "files; a run folder loads weights only)")
    parser.add_argument("--out", type=Path, default=Path("episode.mp4"), help="video file")
    parser.add_argument("--seed", type=arg_types.seed, default=0,
                        help="task and random-policy seed")
    parser.add_argument("--reward", choices=("manifold", "euclidean"),
                        help="progress distance (default: manifold, or the run's)")
    arg_types.add_task_arguments(parser)
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--max-steps", type=arg_types.positive_int, default=None,
                        help="stop after this many steps (default: the task's own time limit)")
    parser.add_argument("--width", type=arg_types.positive_int, default=640)
    parser.add_argument("--height", type=arg_types.positive_int, default=480)
    parser.add_argument("--fps", type=arg_types.positive_int, default=20,
                        help="20 = real time at 20 Hz control")
    parser.set_defaults(func=render_episode, renders=True)
