"""Record mp4 rollouts of a policy.

Control envs: one frame per step. One-strike envs: the strike itself is animated (one frame per
``envs.strike.CHUNK`` of simulated time), then the final frame with the strike's ghost poses and
impulses is held for half a second.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

from spinstrike import envs  # noqa: F401
from spinstrike.envs.strike import CHUNK

__all__ = ["record"]


def _writer(path: Path, size: tuple[int, int], fps: int):
    import imageio_ffmpeg

    gen = imageio_ffmpeg.write_frames(str(path), size, fps=fps, codec="libx264",
                                      pix_fmt_out="yuv420p", macro_block_size=2,
                                      output_params=["-loglevel", "error"])
    gen.send(None)
    return gen


def record(policy, env_id: str, path: str | Path, episodes: int = 3, seed: int = 2000,
           env_kwargs: dict | None = None, size: tuple[int, int] = (480, 320)) -> dict:
    """Write ``episodes`` rollouts of ``policy(env, obs)`` to one mp4 at ``path``.

    Returns:
        ``{"path", "frames", "fps", "returns"}``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    env = gym.make(env_id, render_mode="rgb_array", render_size=size, **(env_kwargs or {}))
    task = env.unwrapped.task
    one_strike = hasattr(task, "strike_frames")
    fps = int(round(1 / CHUNK)) if one_strike else env.metadata["render_fps"]
    writer = _writer(path, size, fps)
    frames = 0
    returns = []
    try:
        for k in range(episodes):
            obs, _ = env.reset(seed=seed + k)
            total, done = 0.0, False
            if not one_strike:
                writer.send(np.ascontiguousarray(env.render()))
                frames += 1
            while not done:
                obs, r, term, trunc, _ = env.step(policy(env, obs))
                total += float(r)
                done = term or trunc
                if one_strike:
                    for frame in task.strike_frames():
                        writer.send(np.ascontiguousarray(task.draw(frame)))
                        frames += 1
                    final = np.ascontiguousarray(env.render())
                    for _ in range(fps // 2):
                        writer.send(final)
                        frames += 1
                else:
                    writer.send(np.ascontiguousarray(env.render()))
                    frames += 1
            returns.append(total)
    finally:
        writer.close()
        env.close()
    return {"path": str(path), "frames": frames, "fps": fps, "returns": returns}
