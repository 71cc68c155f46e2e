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
from collections import deque
from pathlib import Path

import gymnasium as gym
import numpy as np

from spinstrike import envs  # noqa: F401
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
        kwargs["render_size"] = tuple(size)
    runs = [_Episode(policy, env_id, seed + k, kwargs) for k in range(episodes)]
    fps = runs[0].env.metadata["render_fps"]
    held = int(round(hold * fps))
    writer = VideoWriter(path, fps)
    try:
        if grid:
            columns = math.ceil(math.sqrt(episodes))
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
    finally:
        writer.close()
        for run in runs:
            run.close()
    return {"path": str(writer.path), "frames": writer.frames, "fps": fps,
            "returns": [run.total for run in runs], "size": writer.size}


def docs_media(folder: str | Path = "docs/images", seed: int = 2) -> list[str]:
    """Regenerate the README's media from this renderer: ``rodspin.gif`` (one oracle strike in
    slow motion, overlays and all), ``rodspincontrol.gif`` (two seconds of chase-and-hit), and a
    still of each env (``<env>.png``: a strike's last frame, or a control step's, at half of
    720 x 480)."""
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
        description="Regenerate the README's media (rodspin.gif, rodspincontrol.gif and a still "
                    "of each env) from the renderer. To film a trained policy, use "
                    "`spinstrike record RUN_DIR`.")
    p.add_argument("folder", nargs="?", default="docs/images",
                   help="where the images go (default: %(default)s)")
    p.add_argument("--seed", type=int, default=2, help="episode seed (default: %(default)s)")
    args = p.parse_args(argv)
    print("\n".join(docs_media(args.folder, args.seed)))
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main())
