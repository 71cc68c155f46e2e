"""Record rollouts of a policy: an mp4 (or a GIF, for docs) of every frame the env renders.

The env runs with ``render_mode="rgb_array_list"``, so these are the env's own video frames:
one per control step; for a one-strike env the whole strike in slow motion (at least a second
at the env's ``render_fps``, a frame at each contact instant, with its overlays). Each
episode's last frame is held for ``hold`` seconds (a strike's last frame sums it up: ghost
poses, every impulse). ``grid=True`` plays the episodes side by side, in lockstep, each holding
its last frame until the slowest is done.
"""

from __future__ import annotations

import math
import operator
from collections import deque
from pathlib import Path

import gymnasium as gym
import numpy as np

from spinstrike import envs, physics
from spinstrike.envs.recording import VideoWriter, tile

__all__ = ["record"]


class _Episode:
    """One episode of a policy, rendered frame by frame (stepped whenever its frames run out)."""

    def __init__(self, policy, env_id: str, seed: int, kwargs: dict) -> None:
        self.env = gym.make(env_id, render_mode="rgb_array_list", **kwargs)
        self.policy = policy
        self.obs, _ = self.env.reset(seed=seed)
        self.frames: deque[np.ndarray] = deque(self.env.render())
        self.done = False
        self.total = 0.0
        self.last: np.ndarray | None = None

    def next_frame(self) -> np.ndarray | None:
        """The episode's next frame (None once it is over and every frame was shown)."""
        while not self.frames and not self.done:
            self.obs, r, term, trunc, _ = self.env.step(self.policy(self.env, self.obs))
            self.total += float(r)
            self.done = bool(term or trunc)
            self.frames.extend(self.env.render())
        if self.frames:
            self.last = self.frames.popleft()
            return self.last
        return None

    def close(self) -> None:
        self.env.close()


def _check_size(size) -> tuple[int, int]:
    from spinstrike.envs.config import size_problem

    try:
        w, h = (operator.index(side) for side in size)
    except (TypeError, ValueError):
        raise ValueError(f"size: must be (width, height) in pixels (got {size!r})") from None
    problem = size_problem((w, h))
    if problem:
        raise ValueError(f"size: {problem}")
    return w, h


def _check_grid(episodes: int, columns: int, size) -> None:
    """A grid's frame within the sides a frame may have (4096 px: ``--grid --size 4096x4096``
    wrote an 8192 x 8192 H.264 that players refuse; 50 episodes at 720 x 480, 5760 x 3360)."""
    from spinstrike.envs.config import FRAME_SIZES, ConfigError

    w, h = columns * size[0], math.ceil(episodes / columns) * size[1]
    if max(w, h) > FRAME_SIZES[1]:
        raise ConfigError(f"grid: {episodes} episodes of {size[0]}x{size[1]} tile to {w}x{h}, "
                          f"beyond {FRAME_SIZES[1]} pixels a side (what players take); give "
                          f"fewer episodes or a smaller size")


def record(policy, env_id: str, path: str | Path, episodes: int = 3, seed: int = 2000,
           env_kwargs: dict | None = None, size: tuple[int, int] | None = None,
           grid: bool = False, hold: float = 0.5) -> dict:
    """Write ``episodes`` rollouts of ``policy(env, obs)`` (seeds ``seed``, ``seed + 1``...)
    to one video at ``path`` (``.mp4``, or ``.gif``).

    Args:
        size: (width, height) of an episode's frames (default: the env's ``render_size``).
        grid: tile the episodes in one frame (``ceil(sqrt(episodes))`` columns), played
            together; else one after the other.
        hold: seconds each episode's last frame is held.

    Returns:
        ``{"path", "frames", "fps", "returns", "size"}`` (``size``: the video's width, height).
    """
    kwargs = dict(env_kwargs or {})
    if size is not None:
        kwargs["render_size"] = _check_size(size)
    # a policy with memory of its env or its episode (``for_episode``: the planner's warm
    # start, the random policy's stream) gets one of its own per episode: a grid's episodes,
    # stepped in turn, handed one planner a new env each step, and it started every decision
    # afresh (half the return, silently); a random grid's episodes drew another policy's
    # actions than the same seeds filmed one after the other
    runs = [_Episode(policy.for_episode(k) if hasattr(policy, "for_episode") else policy,
                     env_id, seed + k, kwargs) for k in range(episodes)]
    fps = runs[0].env.metadata["render_fps"]
    held = int(round(hold * fps))
    columns = math.ceil(math.sqrt(episodes))
    try:
        if grid:
            _check_grid(episodes, columns, runs[0].env.unwrapped.cfg.render_size)
        writer = VideoWriter(path, fps)
    except BaseException:
        for run in runs:
            run.close()
        raise
    try:
        if grid:
            while True:
                frames = [run.next_frame() for run in runs]
                if all(f is None for f in frames):
                    break
                writer.write(tile([f if f is not None else run.last
                                   for f, run in zip(frames, runs, strict=True)], columns))
            final = tile([run.last for run in runs], columns)
            for _ in range(held):
                writer.write(final)
        else:
            for run in runs:
                while (frame := run.next_frame()) is not None:
                    writer.write(frame)
                for _ in range(held):
                    writer.write(run.last)
    except BaseException:  # Ctrl-C too: no truncated video under ``path``
        writer.abort()
        raise
    else:
        writer.close()
    finally:
        for run in runs:
            run.close()
    return {"path": str(writer.path), "frames": writer.frames, "kept": writer.kept, "fps": fps,
            "returns": [run.total for run in runs], "size": writer.size}


def record_world(world, path: str | Path, seconds: float = 3.0, dt: float = 0.02,
                 element: int = 0, size: tuple[int, int] = (720, 480),
                 trail: float = 0.3) -> dict:
    """Film one element of a physics ``World`` (``physics.World``: any scene, any number of
    bodies) for ``seconds``, a frame after each step of ``dt`` seconds, played in real time
    (``1 / dt`` frames per second), to ``path`` (``.mp4`` or ``.gif``).

    A frame shows the table and cushions, every body with a spin arrow, the last ``trail``
    seconds of each body's path, an arrow at each contact of the step (scaled by its impulse,
    fading over the next frames) and a line with the time, the kinetic energy and the
    contacts so far. A body that would leave the view (a table without cushions) widens it
    for the rest of the film. The world is stepped in place (its state is the film's last
    frame); it films ``ceil(seconds / dt)`` steps.

    Returns:
        ``{"path", "frames", "fps", "size", "contacts"}``.
    """
    from spinstrike.envs.rendering import (
        Frame,
        Marker,
        Renderer,
        body_draws,
        body_points,
        view_need,
    )

    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds: must be a number > 0 (got {seconds!r})")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: must be a number > 0 s (got {dt!r})")
    if dt > seconds:  # (one step of dt was filmed, silently; the CLI refused it)
        raise ValueError(f"dt: a frame per step of {dt:g} s is longer than the {seconds:g} s "
                         f"to film; give a smaller dt")
    size = _check_size(size)
    b = element
    if isinstance(b, bool) or not isinstance(b, int | np.integer) or not 0 <= b < world.batch_size:
        raise ValueError(f"element: must be in [0, {world.batch_size}) (got {element!r})")
    half = world.table_half_size[b]
    walls = bool(world.walls)
    if np.isfinite(half).all():
        view = tuple(1.04 * half)
    else:  # an unbounded table: the bodies' extent now, with room to move
        reach = world.half_length[b] + world.radius[b]
        extent = np.abs(world.state.positions[b]).max(axis=0) + reach.max()
        view = (max(extent[0], 1.5 * extent[1]) * 1.5, max(extent[1], extent[0] / 1.5) * 1.5)
    renderer = Renderer(size, view)
    zoom = 1.0  # widened (never narrowed) where a body would leave the view: an unbounded
    #             table's bodies fly off the extent they started in
    reach = world.half_length[b] + world.radius[b]
    fps = 1.0 / dt
    keep = max(1, int(round(trail / dt)))
    paths: list[deque] = []
    markers: list[Marker] = []
    total = 0
    writer = VideoWriter(path, fps)

    def frame() -> np.ndarray:
        nonlocal zoom
        drawn = body_draws(world, b)  # bodies not named as the envs' are drawn grey
        out = view_need(world.state.positions[b], reach, view)  # > 1: a body leaves it
        if out > zoom:
            zoom = 1.25 * out  # with room to go on, not a view that creeps every frame
        points = [body_points(d) for d in drawn]
        while len(paths) < len(points):
            paths.append(deque(maxlen=keep))
        for path_, p in zip(paths, points, strict=True):
            path_.append(p)
        trails = [[step[k] for step in path_] for path_ in paths for k in range(len(path_[0]))]
        energy = float(world.kinetic_energy()[b])
        text = f"t = {float(world.time[b]):.2f} s   E = {energy:.3f} J   contacts {total}"
        return renderer.draw(Frame(drawn, tuple(half), walls, text=text, trails=trails,
                                   markers=list(markers), smooth=True, zoom=zoom))

    try:
        writer.write(frame())
        for _ in range(math.ceil(seconds / dt - 1e-9)):  # at least ``seconds``
            contacts = world.step(dt)
            mine = contacts.batch == b
            total += int(mine.sum())
            mine &= ~contacts.held  # impacts are marked; a disk held on a cushion is not
            markers = [Marker(m.x, m.y, m.nx, m.ny, m.j, m.fade * 0.6) for m in markers
                       if m.fade > 0.1]
            for a, c, point, normal, j in zip(contacts.body_a[mine], contacts.body_b[mine],
                                              contacts.point[mine], contacts.normal[mine],
                                              contacts.impulse[mine], strict=True):
                markers.append(Marker.on(int(c), int(a), int(c), point, normal, float(j)))
            writer.write(frame())
    except BaseException:
        writer.abort()
        raise
    writer.close()
    return {"path": str(writer.path), "frames": writer.frames, "kept": writer.kept, "fps": fps,
            "size": writer.size, "contacts": total}


def docs_media(folder: str | Path = "docs/images", seed: int = 2) -> list[str]:
    """Regenerate the README's media from this renderer: ``rodspin.gif`` (one oracle strike in
    slow motion, overlays and all), ``rodspincontrol.gif`` (two seconds of chase-and-hit),
    ``break.gif`` (docs/design.md: the packaged break scene, 1.8 s), and a still of each env
    (``<env>.png``: a strike's last frame, or a control step's, at half of 720 x 480)."""
    from PIL import Image

    from spinstrike.agents.oracle import oracle_for

    folder = Path(folder)
    size = (480, 320)
    written = []
    out = folder / "rodspin.gif"
    record(oracle_for("SpinStrike/RodSpin-v0"), "SpinStrike/RodSpin-v0", out, episodes=1,
           seed=seed, size=size, hold=1.0)
    written.append(str(out))
    out = folder / "rodspincontrol.gif"
    record(oracle_for("SpinStrike/RodSpinControl-v0"), "SpinStrike/RodSpinControl-v0", out,
           episodes=1, seed=seed, size=size, hold=0.0, env_kwargs={"max_episode_steps": 100})
    written.append(str(out))
    out = folder / "break.gif"  # docs/design.md: the many-body solver
    record_world(physics.World("break"), out, seconds=1.8, size=(640, 340), trail=0.2)
    written.append(str(out))
    for env_id in envs.ENV_IDS:
        if env_id == "SpinStrike/PuckSpeed-v0":  # deprecated; PuckSpeed-v1 draws the same table
            continue
        env = gym.make(env_id, render_mode="rgb_array")  # 720 x 480, shown at half size
        policy = oracle_for(env_id)
        obs, _ = env.reset(seed=seed)
        for _ in range(60 if "Control" in env_id else 1):  # a strike, or 60 control steps
            obs, *_ = env.step(policy(env, obs))
        out = folder / f"{env_id.split('/')[1].split('-v')[0].lower()}.png"
        image = Image.fromarray(env.render())
        image.resize((image.width // 2, image.height // 2), Image.LANCZOS).save(out,
                                                                               optimize=True)
        written.append(str(out))
        env.close()
    return written


def main(argv: list[str] | None = None) -> int:
    """``python -m spinstrike.agents.record [FOLDER]``: regenerate the README's media (a policy's
    video is ``spinstrike record``)."""
    import argparse
    import os

    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    p = argparse.ArgumentParser(
        prog="python -m spinstrike.agents.record",
        description="Regenerate the README's media (rodspin.gif, rodspincontrol.gif, "
                    "break.gif and a still of each env) from the renderer. To film a trained "
                    "policy, use `spinstrike record RUN_DIR`; a physics scene, `spinstrike "
                    "record --scene`.")
    p.add_argument("folder", nargs="?", default="docs/images",
                   help="where the images go (default: %(default)s)")
    p.add_argument("--seed", type=int, default=2, help="episode seed (default: %(default)s)")
    args = p.parse_args(argv)
    print("\n".join(docs_media(args.folder, args.seed)))
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main())
