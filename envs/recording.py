"""Video files of rollouts: every frame an env renders, written exactly once.

* :class:`RecordEveryFrame` is Gymnasium's ``RecordVideo`` (same arguments, same triggers) for
  envs whose ``render()`` returns *lists* of frames (``render_mode="rgb_array_list"``). Use it
  for the one-strike envs: a strike is one step, whose frames are the whole strike in slow
  motion, and ``RecordVideo`` keeps only the last frame of each list (its ``_capture_frame``),
  so it films one frame per strike. It streams the frames to the encoder as they come (nothing
  piles up in memory) and writes each one exactly once (moviepy, which ``RecordVideo`` uses,
  drops the last frame of some clips: 2.1 and 2.2 both). Its ``video_length`` is the frames a
  video holds; ``RecordVideo``'s films one frame more (it stops once it has more).
* :class:`VideoWriter` writes frames to an mp4 (H.264 through imageio-ffmpeg) or a GIF
  (Pillow), by the file's extension; :func:`tile` puts several frames side by side (what
  ``spinstrike record --grid`` shows).

Saving one step's frames with Gymnasium's own helper works too:
``gymnasium.utils.save_video.save_video(env.render(), "videos", fps=env.metadata["render_fps"])``.
"""

from __future__ import annotations

import contextlib
import errno
import gc
import glob
import math
import os
import re
import secrets
import socket
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

__all__ = ["RecordEveryFrame", "VideoWriter", "tile"]

#: file extensions :class:`VideoWriter` writes
FORMATS = (".mp4", ".gif")
#: the most frames per second a GIF keeps (viewers play a frame under 20 ms as 100 ms)
GIF_MAX_FPS = 50.0


#: this host's name, in a partial video's name (whose process is gone is known here only)
_HOST = re.sub(r"[^A-Za-z0-9_.]", "_", socket.gethostname()) or "host"


def _remove_stale_partials(path: Path) -> None:
    """Remove the partial files of ``path`` (``VideoWriter``'s) that a process of this host
    left when it was killed outright (SIGKILL): each one stayed, and every later kill added one
    (walk W20b). A live process's, another host's, or an unknown one's is left alone."""
    name = re.compile(rf"{re.escape(path.stem)}\.{re.escape(_HOST)}-(\d+)-[0-9a-f]{{8}}"
                      rf"\.partial{re.escape(path.suffix)}")
    for old in path.parent.glob(f"{glob.escape(path.stem)}.*.partial{glob.escape(path.suffix)}"):
        match = name.fullmatch(old.name)
        if match is None or int(match.group(1)) == os.getpid():
            continue
        try:
            os.kill(int(match.group(1)), 0)
        except ProcessLookupError:  # gone (PermissionError: alive, another user's)
            with contextlib.suppress(OSError):  # (a folder it may not write: left, as before)
                old.unlink(missing_ok=True)
        except (OverflowError, OSError):
            continue


class VideoWriter:
    """Write frames (``(H, W, 3)`` uint8, all of one size) to ``path``: ``.mp4`` (H.264, yuv420p,
    streamed to ffmpeg; an odd width or height is padded by one pixel, which yuv420p needs) or
    ``.gif`` (Pillow, looping, written on :meth:`close`; Pillow merges identical consecutive
    frames into one of their summed duration; above 50 fps only every k-th frame is kept, so
    that each lasts 20 ms or more and viewers play it in real time, and the last frame always:
    it shows the final state; :attr:`kept` counts the frames the file holds).

    The frames go to ``<stem>.<host>-<pid>-<random>.partial<suffix>`` beside ``path``, renamed
    to ``path`` by :meth:`close`: a recording stopped half way (Ctrl-C, an error) leaves no
    truncated video under ``path`` (nor replaces one that was there); :meth:`abort` removes the
    partial file. A process killed outright (SIGKILL, a crash) cannot: the next writer of
    ``path`` removes the partial files of processes of this host that are gone.

    Args:
        path: the file (its folder is created).
        fps: frames per second of the video.
    """

    def __init__(self, path: str | Path, fps: float) -> None:
        self.path = Path(path)
        if self.path.suffix.lower() not in FORMATS:
            raise ValueError(f"video path: must end in one of {list(FORMATS)} (got "
                             f"{str(path)!r})")
        if not (math.isfinite(fps) and fps > 0):
            raise ValueError(f"fps: must be a number > 0 (got {fps!r})")
        if self.path.is_dir():  # (it failed at the end, the whole video filmed in vain)
            raise IsADirectoryError(errno.EISDIR, "is a folder; the video needs a file name "
                                    f"ending in {' or '.join(FORMATS)}", str(path))
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # a name of its own beside path (a fixed NAME.partial.mp4 replaced a file of the user's
        # of that name); a place that cannot be written fails here, an OSError naming path
        # (ffmpeg failed at the first frame with a broken pipe; a GIF only at the end)
        # (os.open with 0o666 as open() does: the umask gives the video the user's usual
        # permissions, where mkstemp's 0600 kept it from everyone else)
        _remove_stale_partials(self.path)
        while True:
            partial = self.path.with_name(f"{self.path.stem}.{_HOST}-{os.getpid()}-"
                                          f"{secrets.token_hex(4)}.partial{self.path.suffix}")
            try:
                os.close(os.open(partial, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
                break
            except FileExistsError:
                continue
            except OSError as exc:
                raise OSError(exc.errno, exc.strerror, str(path)) from None
        self._partial = partial
        self.fps = fps
        #: frames written so far
        self.frames = 0
        #: frames the file holds, once closed: ``frames``, or for a GIF above 50 fps fewer
        self.kept = 0
        self._size: tuple[int, int] | None = None
        self._encoder = None
        self._gif: list = []  # a GIF's frames, as PIL images in palette mode
        self._gif_index: list[int] = []  # which frame each of them is
        self._gif_tail: np.ndarray | None = None  # the latest frame, where it was not kept
        # viewers show a GIF frame shorter than 20 ms for 100 ms (a 500 fps recording, a --dt
        # of 0.002 s, played 10x slow): above 50 fps a GIF keeps every k-th frame only
        self._gif_every = max(1, math.ceil(fps / GIF_MAX_FPS - 1e-9))

    @property
    def size(self) -> tuple[int, int] | None:
        """(width, height) of the video as written (None before the first frame): the frames',
        an ``.mp4``'s rounded up to even sizes (H.264's yuv420p needs them; the last row or
        column is repeated)."""
        if self._size is None:
            return None
        h, w = self._size
        if self.path.suffix.lower() != ".gif":
            h, w = h + h % 2, w + w % 2
        return w, h

    def write(self, frame: np.ndarray) -> None:
        """Append one frame."""
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ValueError(f"frame: must be (height, width, 3) uint8 (got {frame.shape} "
                             f"{frame.dtype})")
        if self._size is None:
            self._size = frame.shape[:2]
        elif frame.shape[:2] != self._size:
            raise ValueError(f"frame: size {frame.shape[:2]} differs from the video's "
                             f"{self._size}")
        if self.path.suffix.lower() == ".gif":
            # kept as Pillow's GIF writer would convert it, and only the frames the GIF keeps
            # (all of them, in RGB, took 3.1 GB for a 4-episode control grid; its mp4: 0.4 GB)
            if self.frames % self._gif_every == 0:
                self._gif.append(_palette(frame))
                self._gif_index.append(self.frames)
                self._gif_tail = None
            else:  # kept at close if it is the last (W17: the final state was never filmed)
                self._gif_tail = frame.copy()
        else:
            h, w = self._size
            if h % 2 or w % 2:
                frame = np.pad(frame, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
            if self._encoder is None:
                self._encoder = self._open(frame.shape[1], frame.shape[0])
            self._encoder.send(np.ascontiguousarray(frame))
        self.frames += 1

    def _open(self, width: int, height: int):
        import imageio_ffmpeg

        encoder = imageio_ffmpeg.write_frames(
            str(self._partial), (width, height), fps=self.fps, codec="libx264",
            pix_fmt_out="yuv420p", macro_block_size=1, output_params=["-loglevel", "error"])
        encoder.send(None)
        return encoder

    def close(self) -> None:
        """Finish the file (nothing is written for a video without frames)."""
        self.kept = self.frames
        if self._encoder is not None:
            self._encoder.close()
            self._encoder = None
        if self._gif:
            self._keep_last_gif_frame()
            images = self._gif
            # a GIF counts time in hundredths of a second: round the frames' cumulative times
            # to those, so that the whole lasts what it should (30 fps: 30, 30, 40, 30...);
            # each frame lasts until the next one's time, the last until the video's end
            # (each at least 20 ms)
            ends = np.round(np.append(self._gif_index, self.frames) * 100 / self.fps) * 10
            images[0].save(self._partial, save_all=True, append_images=images[1:], loop=0,
                           duration=np.maximum(np.diff(ends), 20).astype(int).tolist(),
                           optimize=True)
            self.kept = len(images)
            self._gif = []
            self._gif_index = []
        if self.frames == 0:  # (the file the constructor opened to see it can write there)
            self._partial.unlink(missing_ok=True)
        elif self._partial.exists():
            os.replace(self._partial, self.path)

    def _keep_last_gif_frame(self) -> None:
        """Put the last frame in a GIF that kept every k-th one: after the last kept frame when
        it would last the 20 ms viewers play (``GIF_MAX_FPS``), else in that frame's place."""
        if self._gif_tail is None:
            return
        last = self.frames - 1
        if len(self._gif) > 1 and (last - self._gif_index[-1]) * GIF_MAX_FPS < self.fps:
            self._gif.pop()
            self._gif_index.pop()
        self._gif.append(_palette(self._gif_tail))
        self._gif_index.append(last)
        self._gif_tail = None

    def abort(self) -> None:
        """Stop without a video: the partial file is removed, ``path`` left as it was."""
        if self._encoder is not None:
            with contextlib.suppress(Exception):  # ffmpeg may have died with the signal too
                self._encoder.close()
            self._encoder = None
        self._gif, self._gif_index, self._gif_tail = [], [], None
        self._partial.unlink(missing_ok=True)

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, kind, *exc: Any) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()


def _palette(frame: np.ndarray):
    """A frame as Pillow's GIF writer converts it: a palette of its own colours, one byte a
    pixel."""
    from PIL import Image

    return Image.fromarray(frame).convert("P", palette=Image.Palette.ADAPTIVE)


def tile(frames: Sequence[np.ndarray | None], columns: int) -> np.ndarray:
    """Frames of one size in a grid of ``columns`` columns, row by row; ``None`` (or a missing
    frame at the end of the last row) is a black tile."""
    shape = next(f.shape for f in frames if f is not None)
    rows = math.ceil(len(frames) / columns)
    out = np.zeros((rows * shape[0], columns * shape[1], 3), dtype=np.uint8)
    for k, f in enumerate(frames):
        if f is not None:
            r, c = divmod(k, columns)
            out[r * shape[0]:(r + 1) * shape[0], c * shape[1]:(c + 1) * shape[1]] = f
    return out


class RecordEveryFrame(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Records videos of episodes, every frame the env renders: Gymnasium's ``RecordVideo``
    for list-rendering envs, and the recorder to use for the one-strike envs.

    With ``render_mode="rgb_array_list"`` each step renders a list of frames (a strike: its
    whole slow-motion video) and every one of them goes into the video; with ``"rgb_array"`` it
    records one frame per step, as ``RecordVideo`` does. The arguments and triggers are
    ``RecordVideo``'s::

        env = gym.make("SpinStrike/RodSpin-v0", render_mode="rgb_array_list")
        env = RecordEveryFrame(env, "videos", episode_trigger=lambda e: e % 100 == 0)

    Args:
        env: the env (``render_mode`` ``rgb_array_list`` or ``rgb_array``).
        video_folder: where the mp4 files go.
        episode_trigger: ``episode_id -> bool``: start a recording at this episode.
        step_trigger: ``step_id -> bool``: start a recording at this step. Neither:
            ``gymnasium.utils.save_video.capped_cubic_video_schedule`` (episodes 0, 1, 8, 27...).
        video_length: frames per video (0: whole episodes, a recording stops at the next reset).
        name_prefix: file names are ``{name_prefix}-episode-{id}.mp4`` / ``-step-{id}.mp4``.
        fps: frames per second (default: the env's ``render_fps``, else 30).
        disable_logger: accepted for ``RecordVideo`` compatibility (this writer logs nothing).
        gc_trigger: ``episode_id -> bool``: collect garbage after a recording of this episode.

    While a recording runs the wrapper takes the env's frames after every reset and step, so
    ``render()`` returns only frames rendered since then (``RecordVideo`` instead keeps every
    frame it took for a later ``render()``, which piles up for as long as nobody calls it).
    """

    def __init__(self, env: gym.Env, video_folder: str,
                 episode_trigger: Callable[[int], bool] | None = None,
                 step_trigger: Callable[[int], bool] | None = None, video_length: int = 0,
                 name_prefix: str = "rl-video", fps: float | None = None,
                 disable_logger: bool = True,
                 gc_trigger: Callable[[int], bool] | None = lambda episode: True) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self, video_folder=video_folder, episode_trigger=episode_trigger,
            step_trigger=step_trigger, video_length=video_length, name_prefix=name_prefix,
            fps=fps, disable_logger=disable_logger, gc_trigger=gc_trigger)
        gym.Wrapper.__init__(self, env)
        if env.render_mode not in ("rgb_array_list", "rgb_array"):
            raise ValueError(f"render_mode: RecordEveryFrame needs 'rgb_array_list' (or "
                             f"'rgb_array'), got {env.render_mode!r}")
        if video_length < 0:
            raise ValueError(f"video_length: must be >= 0 frames (got {video_length})")
        if episode_trigger is None and step_trigger is None:
            try:  # gymnasium's module refuses to import without moviepy
                from gymnasium.utils.save_video import capped_cubic_video_schedule
            except gym.error.DependencyNotInstalled as exc:
                raise gym.error.DependencyNotInstalled(
                    "RecordEveryFrame's default episode_trigger is Gymnasium's "
                    "capped_cubic_video_schedule, whose module needs moviepy: pip install "
                    '"spinstrike[render]" (or pass episode_trigger or step_trigger)') from exc

            episode_trigger = capped_cubic_video_schedule
        self.episode_trigger = episode_trigger
        self.step_trigger = step_trigger
        self.gc_trigger = gc_trigger
        self.video_folder = os.path.abspath(video_folder)
        if os.path.isdir(self.video_folder):
            gym.logger.warn(f"Overwriting existing videos at {self.video_folder} folder (try "
                            "specifying a different `video_folder` if this is not desired)")
        os.makedirs(self.video_folder, exist_ok=True)
        self.frames_per_sec = fps if fps is not None else self.metadata.get("render_fps", 30)
        self.name_prefix = name_prefix
        self.video_length = video_length if video_length > 0 else math.inf
        self.recording = False
        self.step_id = -1
        self.episode_id = -1
        #: videos written so far (paths)
        self.videos: list[str] = []
        self._writer: VideoWriter | None = None

    def _capture(self) -> None:
        self._write(self.env.render())

    def _write(self, out: Any) -> None:
        """Write rendered frames (a list, or one frame) up to ``video_length``; stop there."""
        for frame in out if isinstance(out, list) else [out]:
            if not isinstance(frame, np.ndarray):
                self.stop_recording()
                gym.logger.warn(f"Recording stopped: render() returned {type(frame)}, not "
                                "numpy arrays")
                return
            self._writer.write(frame)
            if self._writer.frames >= self.video_length:
                self.stop_recording()
                return

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = super().reset(seed=seed, options=options)
        self.episode_id += 1
        if self.recording and self.video_length == math.inf:
            self.stop_recording()
        if self.episode_trigger and self.episode_trigger(self.episode_id):
            self.start_recording(f"{self.name_prefix}-episode-{self.episode_id}")
        if self.recording:
            self._capture()
        return obs, info

    def step(self, action):
        trigger = bool(self.step_trigger and self.step_trigger(self.step_id + 1))
        if trigger and self.env.render_mode == "rgb_array_list":
            self.env.render()  # frames of earlier steps, not part of the video about to start
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.step_id += 1
        if trigger:
            self.start_recording(f"{self.name_prefix}-step-{self.step_id}")
        if self.recording:
            self._capture()
        return obs, reward, terminated, truncated, info

    def render(self):
        """The env's frames since the last capture (recorded too, if a recording runs)."""
        out = super().render()
        if self.recording and self.env.render_mode == "rgb_array_list":
            self._write(out)
        return out

    def start_recording(self, video_name: str) -> None:
        """Start a video (stopping the one in progress)."""
        if self.recording:
            self.stop_recording()
        self.recording = True
        self._writer = VideoWriter(os.path.join(self.video_folder, f"{video_name}.mp4"),
                                   self.frames_per_sec)

    def stop_recording(self) -> None:
        """Finish the video in progress."""
        if self._writer is not None:
            self._writer.close()
            if self._writer.frames:
                self.videos.append(str(self._writer.path))
            else:
                gym.logger.warn("Ignored saving a video as there were zero frames to save.")
            self._writer = None
        self.recording = False
        if self.gc_trigger and self.gc_trigger(self.episode_id):
            gc.collect()

    def close(self) -> None:
        super().close()
        if self.recording:
            self.stop_recording()

    def __del__(self) -> None:
        """Dropped without :meth:`close` while recording: warn as Gymnasium's ``RecordVideo``
        does, and remove the unfinished video (it was left as ``*.partial.mp4``, silently)."""
        if getattr(self, "recording", False) and getattr(self, "_writer", None) is not None:
            gym.logger.warn("Unable to save last video! Did you call close()? (the unfinished "
                            f"video {self._writer.path} is not kept)")
            with contextlib.suppress(Exception):  # at interpreter shutdown: nothing left to do
                self._writer.abort()
