"""Stable-Baselines3 ``VecEnv`` adapter over a native SpinStrike vector env.

SB3 does not accept Gymnasium vector envs. :class:`SB3VecEnv` wraps one, so SB3 trains on the
batched world, and fills in per environment what SB3's ``Monitor`` and ``TimeLimit`` handling
would: ``terminal_observation``, ``TimeLimit.truncated`` and ``episode`` = ``{"r", "l", "t"}``
(``r`` and ``t`` rounded to 6 digits, as Monitor does) on the step an episode ends, and
``reset_infos`` (each element's reset info, at ``reset()`` and at each autoreset) as
DummyVecEnv does. The env's own step info (RodSpin's ``spin``, ``best_reward``, ...; the
control envs' ``hits``, ``reward_hit``, ...) is in the info of each element whose episode
ended, as a single env returns it; every element's, every step, exactly as a DummyVecEnv of
``gym.make`` envs gives it, with ``step_infos=True``. That is opt-in as it costs: building N
dicts a step made the adapter's step ~40 % slower on RodSpinControl-v0 with 16 envs (~90 us a
step; ~3 % of PPO's wall time at the README's 8.4 % env share). Without it the other
elements' infos hold only ``TimeLimit.truncated`` (False), and the step's info arrays stay in
:attr:`SB3VecEnv.last_info`. Importing this module needs ``stable-baselines3``.
"""

from __future__ import annotations

import time
from typing import Any

import gymnasium as gym
import numpy as np

try:
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv
except ModuleNotFoundError as exc:  # name the extra; exc.name stays for the CLI's message
    raise ModuleNotFoundError(
        f"spinstrike.envs.sb3 needs stable-baselines3 ({exc.name} is missing), which comes with "
        "the 'train' extra: pip install \"spinstrike[train]\"", name=exc.name) from exc

__all__ = ["SB3VecEnv", "element_infos", "make_sb3_vec_env"]


class SB3VecEnv(VecEnv):
    """An SB3 ``VecEnv`` backed by a :class:`envs.core.SpinStrikeVectorEnv` in ``SAME_STEP``
    autoreset mode (SB3's own convention: the step that ends an episode returns the next
    episode's first observation).

    The envs are one batched world, not separate env objects: ``get_attr`` and ``env_method``
    act on the vector env (a method is called once, for all envs) and return its answer once
    per index (a single env's methods, such
    as ``get_physics_state``, are not there: use ``make_vec_env`` with ``DummyVecEnv`` for
    them), and ``set_attr`` sets the vector env's attribute, so it refuses ``indices`` that
    select only some envs. ``env_method("reset", seed=..., options=..., indices=...)`` is as
    DummyVecEnv's: only the elements of ``indices`` restart (the vector env's ``reset_mask``),
    each seeded ``seed`` as a single env would be, with their episode return and length, and
    each one's ``(obs, info)`` is returned. ``metadata`` is the vector env's (its
    ``render_fps``, which SB3's ``VecVideoRecorder`` films at) with SB3's render modes.

    ``step_infos``: every element's step info each step, as DummyVecEnv (else only the ended
    elements'; see the module's docstring for the cost). ``last_info``: the vector env's
    last info (arrays with ``_key`` masks)."""

    def __init__(self, venv: gym.vector.VectorEnv, step_infos: bool = False) -> None:
        mode = venv.metadata.get("autoreset_mode")
        if mode is not gym.vector.AutoresetMode.SAME_STEP:
            raise ValueError(f"SB3VecEnv: the vector env must autoreset in SAME_STEP mode "
                             f"(gym.make_vec(..., autoreset_mode='same_step')), got {mode}")
        self.venv = venv
        self.step_infos = step_infos
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self.render_mode = venv.render_mode
        # the vector env's metadata (render_fps, which SB3's VecVideoRecorder films at: a
        # control dt's, e.g. 20 at dt=0.05), as DummyVecEnv forwards its envs'; the render
        # modes stay SB3's (its render() tiles rgb_array frames, also for "human")
        self.metadata = {**venv.metadata, "render_modes": self.metadata["render_modes"]}
        self._actions: np.ndarray | None = None
        self._returns = np.zeros(self.num_envs)
        self._lengths = np.zeros(self.num_envs, dtype=np.int64)
        self._t0 = time.time()
        self.last_info: dict[str, Any] = {}

    def reset(self):
        seeds = None
        if any(s is not None for s in self._seeds):
            seeds = [s if s is not None else int(np.random.SeedSequence().entropy % 2**31)
                     for s in self._seeds]
        obs, info = self.venv.reset(seed=seeds)
        self._reset_seeds()
        self._reset_options()
        self._returns[:] = 0.0
        self._lengths[:] = 0
        self.last_info = info
        self.reset_infos = element_infos(info, self.num_envs)
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        obs, reward, terminated, truncated, info = self.venv.step(self._actions)
        self.last_info = info
        done = terminated | truncated
        self._returns += reward
        self._lengths += 1
        n = self.num_envs
        ended = done.any()
        # an ended element's top-level info is its new episode's reset info: its step's info
        # is in final_info
        if self.step_infos:
            infos = element_infos(info, n, ~done if ended else None)
        else:
            infos = [{} for _ in range(n)]
        for row in infos:  # as DummyVecEnv: every info has it (ended ones: set below)
            row["TimeLimit.truncated"] = False
        if ended:
            final = info["final_obs"]
            elapsed = round(time.time() - self._t0, 6)
            last = element_infos(info["final_info"], n, done)
            resets = element_infos(info, n, done)  # the new episodes' reset infos
            for i in np.flatnonzero(done):
                row = infos[i] = last[i]  # keys in DummyVecEnv's order (Monitor's episode first)
                row["episode"] = {"r": round(float(self._returns[i]), 6),
                                  "l": int(self._lengths[i]), "t": elapsed}
                row["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                row["terminal_observation"] = final[i]
                self.reset_infos[i] = resets[i]
            self._returns[done] = 0.0
            self._lengths[done] = 0
        return obs, reward.astype(np.float32), done, infos

    def close(self) -> None:
        self.venv.close()

    def get_images(self):
        frames = self.venv.render()
        return list(frames) if frames is not None else [None] * self.num_envs

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        if sorted(set(self._get_indices(indices))) != list(range(self.num_envs)):
            raise ValueError(f"set_attr: the {self.num_envs} envs are one batched world, so "
                             f"{attr_name!r} is set for all of them; indices={indices!r} "
                             f"selects only some (a DummyVecEnv of single envs can)")
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list[Any]:
        if method_name == "compute_reward":  # HER, on a goal-conditioned env
            achieved, desired = args[0], args[1]
            result = self.venv.task.goal_reward(np.asarray(achieved, dtype=np.float64),
                                                np.asarray(desired, dtype=np.float64),
                                                self.venv.cfg)
            return [result for _ in self._get_indices(indices)]
        if method_name == "reset":  # as DummyVecEnv: only the elements asked
            return self._reset_some(self._get_indices(indices), *args, **kwargs)
        # once: the envs are one world, and a method called once per index would act N
        # times on all of them (env_method("step", a) stepped every env N times)
        result = getattr(self.venv, method_name)(*args, **kwargs)
        return [result for _ in self._get_indices(indices)]

    def _reset_some(self, indices, *args, seed: int | None = None,
                    options: dict | None = None) -> list[tuple[Any, dict[str, Any]]]:
        """``env_method("reset", ...)``: each element of ``indices`` reset as its single env's
        ``reset(seed=seed, options=options)`` would be (the vector env's ``reset_mask``), its
        episode return and length restarted, the others left as they are; returns each one's
        ``(obs, info)``."""
        if args:
            raise TypeError("env_method('reset'): reset takes keyword arguments only "
                            "(seed=..., options=...)")
        idx = list(indices)
        mask = np.zeros(self.num_envs, dtype=bool)
        mask[idx] = True
        opts = dict(options or {})
        if not mask.all():
            opts["reset_mask"] = mask
        seeds = None if seed is None else [seed if m else None for m in mask.tolist()]
        obs, info = self.venv.reset(seed=seeds, options=opts or None)
        self._returns[mask] = 0.0
        self._lengths[mask] = 0
        rows = element_infos(info, self.num_envs, mask)
        return [(_row(obs, i), rows[i]) for i in idx]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        # the adapter reports episodes as SB3's Monitor does, and nothing else wraps the envs
        from stable_baselines3.common.monitor import Monitor

        wrapped = wrapper_class is Monitor
        return [wrapped for _ in self._get_indices(indices)]


#: keys of a SAME_STEP vector info that are not an element's own info
_VECTOR_KEYS = frozenset({"final_obs", "final_info"})


def element_infos(info: dict[str, Any], n: int, which: np.ndarray | None = None
                  ) -> list[dict[str, Any]]:
    """Each element's info dict from a vector info (``key`` arrays with ``_key`` masks), as a
    single env returns it: a key only where its mask is set, numbers as Python scalars, array
    values as arrays of their own; ``which`` (a bool mask): only those elements, ``{}`` for the
    others. ``final_obs`` / ``final_info`` are left out."""
    idx = None if which is None or which.all() else np.flatnonzero(which)
    keys, columns, holes = [], [], []
    for k, v in info.items():
        if k[0] == "_" or k in _VECTOR_KEYS:
            continue
        mask = info.get(f"_{k}")
        if idx is not None:
            v = v[idx]
            mask = None if mask is None else mask[idx]
        keys.append(k)
        if v.dtype == object:
            columns.append([_plain(x) for x in v])
        else:  # one conversion per key (a copy: rows of a 2-D value are the copy's)
            columns.append(v.tolist() if v.ndim == 1 else list(v.copy()))
        if mask is not None:
            kept = mask.tolist()
            if not all(kept):
                holes.append((k, kept))
    count = n if idx is None else len(idx)
    picked = ([dict(zip(keys, values, strict=True)) for values in zip(*columns, strict=True)]
              if keys else [{} for _ in range(count)])
    for k, kept in holes:
        for row, keep in zip(picked, kept, strict=True):
            if not keep:
                del row[k]
    if idx is None:
        return picked
    rows: list[dict[str, Any]] = [{} for _ in range(n)]
    for i, row in zip(idx.tolist(), picked, strict=True):
        rows[i] = row
    return rows


def _row(obs: Any, i: int) -> Any:
    """Element ``i``'s observation (a dict observation: each key's)."""
    if isinstance(obs, dict):
        return {k: v[i] for k, v in obs.items()}
    return obs[i]


def _plain(x: Any) -> Any:
    """A numpy scalar as a Python one, an array as an array of its own."""
    if isinstance(x, np.generic):
        return x.item()
    return x.copy() if isinstance(x, np.ndarray) else x


def make_sb3_vec_env(env_id: str, n_envs: int, seed: int | None = None,
                     env_kwargs: dict | None = None, step_infos: bool = False) -> SB3VecEnv:
    """Native batched vector env of ``env_id`` (``gym.make_vec``; a registered variant's as
    ``envs.native_vector`` builds it) wrapped for SB3 (``step_infos``: :class:`SB3VecEnv`'s)."""
    from spinstrike import envs  # registers the ids

    make_id, kwargs = envs.native_vector(env_id)  # a variant without a vector entry point too
    kwargs.update(env_kwargs or {})
    kwargs["autoreset_mode"] = gym.vector.AutoresetMode.SAME_STEP  # SB3's convention
    venv = gym.make_vec(make_id, num_envs=n_envs, vectorization_mode="vector_entry_point",
                        **kwargs)
    vec = SB3VecEnv(venv, step_infos=step_infos)
    if seed is not None:
        vec.seed(seed)
    return vec
