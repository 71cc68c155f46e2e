"""Model-predictive control for the control envs (``RodSpinControl-v0``,
``PuckSpeedControl-v0``): the cross-entropy method (CEM) over a what-if copy of the env's own
world.

At each decision the planner copies the env's element (parameters, materials, table, state,
forces, clock: ``World.load_element``) into every element of a scratch batch of ``samples``
worlds of the same task, draws ``samples`` action sequences of ``horizon`` steps from a Gaussian,
and steps all of them at once through the native batch (``Task.step``: the compiled control step
the env itself runs), summing the env's own reward. The best ``elites`` sequences refit the
Gaussian; after ``iterations`` rounds the first action of the best sequence seen is applied, and
the plan, shifted by one step, seeds the next decision. The model is the env itself (same kernel,
same parameters), so the planner's only approximations are its horizon and its sampling. With
``solver: pymunk`` the copy is close, not exact: pymunk keeps contact state of its own between steps
(its cached impulses warm-start the next step) that a copy starts without, so a step with a
contact ends ~1e-5 m apart (1 step in 120 on each control env, measured).

    from spinstrike.agents.planner import CEMPlanner
    planner = CEMPlanner(horizon=10, samples=64)   # the defaults (docs/planner.md)
    action = planner(env, obs)          # the common policy(env, obs) signature

    spinstrike evaluate --planner --env SpinStrike/PuckSpeedControl-v0 --episodes 10
    spinstrike record   --planner --env SpinStrike/RodSpinControl-v0 --out planner.mp4

Rewards in these envs are sparse (only steps with a hit earn), so a sequence that hits nothing
scores 0; ``approach`` (0.3 by default) subtracts ``approach x distance(mallet, target)`` (m) at
the horizon's end, which ranks the sequences that hit nothing (a hit is worth more than the
whole table's width of it). On short horizons it matters: 15 steps, 32 samples, 10
episodes of 60 steps (``run_episodes`` seeds 1000...): PuckSpeedControl 1.73 without it, 6.25
with it (RodSpinControl 5.66, 11.20).
"""

from __future__ import annotations

import copy
import math

import gymnasium as gym
import numpy as np

from spinstrike.envs.control import _ControlTask

__all__ = ["CEMPlanner"]


class CEMPlanner:
    """CEM model-predictive control on a batched what-if copy of the env's world.

    The defaults (10 steps = 0.2 s ahead, 64 samples, 3 iterations) are where the sweep in
    ``docs/planner.md`` plateaus: more samples do not raise the return, longer horizons lower it
    (with 3 CEM iterations a 40-step plan is a 80-dimensional search), at 7-11 ms of CPU per
    decision. From 256 samples the scratch world runs its parallel kernel: on busy cores a
    decision can take 25x the wall time of 255 samples (``NUMBA_NUM_THREADS=1`` avoids it).
    Asked twice at one state with no step between, it decides once (the same action).

    Args:
        horizon: steps planned ahead (``dt`` each: 0.02 s by default).
        samples: action sequences evaluated per CEM iteration (the scratch batch size).
        iterations: CEM refits per decision.
        elites: sequences that refit the Gaussian (default 6; below 6 samples, half of them).
        init_std: the Gaussian's initial standard deviation (actions live in [-1, 1]).
        gamma: discount of the planned rewards.
        approach: weight of the terminal term ``-distance(mallet, target)`` (m); 0 disables it.
        seed: the sampling generator's seed; it is reseeded at every episode start (the env's
            clock at 0, or behind the last decision's: an episode whose first steps another
            policy took), so an episode's actions depend only on the episode and this seed.
            Call :meth:`reset` where an episode starts that the clock cannot tell.
        warm_start: seed each decision's Gaussian with the last decision's best plan shifted by
            one step (the default). With ``False`` every decision starts from a zero mean, so
            the action depends on the current state (and the sampling) only, as a reactive
            policy's does: the reference a learned state-feedback policy can aim at (see
            ``docs/planner.md``, "Warm start"; ``warm_start_table`` measures it).
        common_noise: reseed the generator with ``seed`` before every decision, so that every
            decision draws the same standard-normal samples (common random numbers). With
            ``warm_start=False`` the action is then a deterministic function of the state: a
            state visited twice gets one action, and nearby states rank the same candidate
            sequences, so the mallet does not waver between approaches from step to step.
    """

    def __init__(self, horizon: int = 10, samples: int = 64, iterations: int = 3,
                 elites: int | None = None, init_std: float = 0.7, gamma: float = 1.0,
                 approach: float = 0.3, seed: int = 0, warm_start: bool = True,
                 common_noise: bool = False) -> None:
        if elites is None:  # 6; fewer samples than that: half of them (6 was refused)
            elites = 6 if not isinstance(samples, (int, np.integer)) or samples >= 6 else \
                max(1, int(samples) // 2)
        for name, value, low in (("horizon", horizon, 1), ("samples", samples, 2),
                                 ("iterations", iterations, 1), ("elites", elites, 1)):
            if not isinstance(value, (int, np.integer)) or value < low:
                raise ValueError(f"{name}: must be an integer >= {low} (got {value!r})")
        if elites > samples:
            raise ValueError(f"elites: must be <= samples ({samples}) (got {elites})")
        if not init_std > 0:
            raise ValueError(f"init_std: must be > 0 (got {init_std!r})")
        if not 0 < gamma <= 1:
            raise ValueError(f"gamma: must be in (0, 1] (got {gamma!r})")
        if not (isinstance(approach, (int, float, np.integer, np.floating))
                and math.isfinite(approach) and approach >= 0):
            # (NaN made every plan's value NaN: the planner stood still, silently)
            raise ValueError(f"approach: must be a finite number >= 0 (got {approach!r})")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"seed: must be an integer >= 0 (got {seed!r})")
        if not math.isfinite(init_std):
            raise ValueError(f"init_std: must be finite (got {init_std!r})")
        self.horizon, self.samples, self.iterations = int(horizon), int(samples), int(iterations)
        self.elites, self.init_std, self.gamma = int(elites), float(init_std), float(gamma)
        self.approach = float(approach)
        self.warm_start = bool(warm_start)
        self.common_noise = bool(common_noise)
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        self._scratch: _ControlTask | None = None
        self._source: _ControlTask | None = None
        self._mean: np.ndarray | None = None
        self._last_time = math.inf
        self._last: tuple[np.ndarray, np.ndarray] | None = None  # (state, action) decided
        #: batched steps taken by the last decision (iterations x horizon)
        self.last_steps = 0

    def _scratch_for(self, task: _ControlTask) -> _ControlTask:
        s = self._scratch
        if s is None or type(s) is not type(task) or s.cfg is not task.cfg:
            s = type(task)(task.cfg, self.samples)
            self._scratch = s
        return s

    def reset(self) -> None:
        """Forget the warm start and reseed (called by itself at an episode's start)."""
        self.rng = np.random.default_rng(self.seed)
        self._mean = None
        self._last = None

    def for_episode(self, k: int) -> CEMPlanner:
        """A planner of its own for the k-th of several episodes run at once (``record
        --grid``): it keeps memory of the one env it drives (its warm start, its generator),
        and one planner handed another env each step started every decision afresh."""
        return copy.deepcopy(self)

    def plan(self, task: _ControlTask) -> np.ndarray:
        """The first action of the best plan from element 0 of ``task``'s world, ``[2]``."""
        if not isinstance(task, _ControlTask):
            raise TypeError(f"the planner drives the control envs (RodSpinControl, "
                            f"PuckSpeedControl), not {type(task).__name__}")
        now = float(task.world.time[0])
        st = task.world.state
        state = np.concatenate([st.positions[0].ravel(), st.angles[0], st.velocities[0].ravel(),
                                st.omegas[0]])
        if (task is self._source and now == self._last_time and self._last is not None
                and np.array_equal(self._last[0], state)):
            return self._last[1].copy()  # asked again, nothing stepped: the same decision
        if task is not self._source or now == 0.0 or now <= self._last_time:
            self._source = task  # another env, or a new episode (its clock restarted)
            self.reset()
        elif self.common_noise:
            self.rng = np.random.default_rng(self.seed)
        scratch = self._scratch_for(task)
        w = scratch.world
        w.load_element(task.world, 0)
        start = w.get_state()
        H, N, A = self.horizon, self.samples, len(task.ACTIONS)
        mean = np.zeros((H, A)) if self._mean is None else self._mean
        std = np.full((H, A), self.init_std)
        discount = self.gamma ** np.arange(H)
        best_value, best_seq = -np.inf, mean
        for it in range(self.iterations):
            seqs = np.clip(mean + std * self.rng.standard_normal((N, H, A)), -1.0, 1.0)
            seqs[0] = np.clip(mean, -1.0, 1.0)  # the current plan is always among them
            if it > 0:
                w.restore(start)
            value = np.zeros(N)
            for h in range(H):
                reward, _, _ = scratch.step(seqs[:, h], batch_info=False)
                value += discount[h] * reward
            if self.approach:
                d = w.state.positions[:, task.im] - w.state.positions[:, task.it]
                value -= self.approach * np.sqrt((d**2).sum(1))
            order = np.argsort(-value, kind="stable")
            elite = seqs[order[:self.elites]]
            if value[order[0]] > best_value:
                best_value, best_seq = value[order[0]], seqs[order[0]]
            mean = elite.mean(0)
            std = np.maximum(elite.std(0), 0.05)
        self.last_steps = self.iterations * H
        self._last_time = now
        self._last = (state.copy(), best_seq[0].copy())
        # warm start: the best plan shifted by one step, the last action repeated
        if self.warm_start:
            self._mean = np.concatenate([best_seq[1:], best_seq[-1:]])
        return best_seq[0].copy()

    def __call__(self, env, obs) -> np.ndarray:
        """The action for ``env`` (a single env, ``gym.make``: one planner per env, since its
        warm start is the plan carried over from that env's last step)."""
        if not isinstance(getattr(env, "unwrapped", None), gym.Env):
            # a Gymnasium vector env: it planned element 0 alone; an SB3 VecEnv: an
            # AttributeError (no task)
            raise TypeError("the planner drives one env (gym.make), not a vector env: plan "
                            "each element with its own planner on a single env")
        return self.plan(env.unwrapped.task).astype(np.float32)


def timed_episodes(planner: CEMPlanner, env_id: str, episodes: int, seed: int = 1000,
                   env_kwargs: dict | None = None):
    """``planner`` on episodes ``seed...`` of ``env_id`` (``evaluate.run_episodes``) and its
    CPU time (``time.process_time``) per decision, in ms: ``(Evaluation, cost)``."""
    import time

    from spinstrike.agents.evaluate import run_episodes

    t = time.process_time()
    ev = run_episodes(planner, env_id, episodes, seed, env_kwargs, "planner")
    return ev, 1000 * (time.process_time() - t) / (episodes * ev.mean_length)


#: the envs the planner drives
CONTROL_IDS = ("SpinStrike/RodSpinControl-v0", "SpinStrike/PuckSpeedControl-v0")


def sweep(env_ids=CONTROL_IDS,
          horizons=(5, 10, 20, 40), samples=(16, 64, 256), episodes: int = 3,
          steps: int = 100, seed: int = 1000, out: str | None = None,
          command: str = "python -m spinstrike.agents.planner --out docs/planner.md") -> str:
    """Return against horizon x samples, with the CPU time per decision, on the same short
    episodes (``steps`` steps, seeds ``seed``...) beside chase-and-hit; a markdown report,
    also written into ``out`` between the markers :data:`BEGIN` and :data:`END` (what the
    file has around them, the notes written by hand, is kept)."""
    import os

    from spinstrike.agents.evaluate import run_episodes
    from spinstrike.agents.oracle import ChaseAndHit

    kwargs = {"max_episode_steps": steps}
    lines = ["# The CEM planner", "",
             f"Produced by `{command}` (`agents/planner.py`): "
             f"{episodes} episodes of {steps} steps ({steps * 0.02:g} s) per cell, seeds "
             f"{seed}..{seed + episodes - 1}, the same for every cell; {os.cpu_count()} shared "
             f"cores (load average at start {os.getloadavg()[0]:.2f}). Return: mean over the "
             "episodes. Cost: CPU time (`time.process_time`) per decision, in ms; every "
             "decision steps `samples` what-if copies `iterations (3) x horizon` times.", ""]
    for env_id in env_ids:
        ref = run_episodes(ChaseAndHit(), env_id, episodes, seed, kwargs, "chase-and-hit")
        lines += [f"## {env_id}", "",
                  f"Scripted chase-and-hit on the same episodes: {ref.mean:.2f}.", "",
                  "| horizon \\ samples | " + " | ".join(str(n) for n in samples) + " |",
                  "|---|" + "---|" * len(samples)]
        for h in horizons:
            cells = []
            for n in samples:
                planner = CEMPlanner(horizon=h, samples=n, elites=max(2, n // 10))
                ev, cost = timed_episodes(planner, env_id, episodes, seed, kwargs)
                cells.append(f"{ev.mean:.2f} ({cost:.0f} ms)")
                print(f"{env_id} H={h} N={n}: {ev.mean:.3f} {cost:.1f} ms", flush=True)
            lines.append(f"| {h} | " + " | ".join(cells) + " |")
        lines.append("")
    text = "\n".join(lines) + "\n"
    if out:
        from pathlib import Path

        from spinstrike.agents.baselines import END, write_doc

        write_doc(Path(out), text, BEGIN, END, "--out")
    return text


#: the sweep's part of its document starts at this line and ends at ``baselines.END``, as the
#: baselines document's does; a rerun keeps the rest
BEGIN = "<!-- generated by `python -m spinstrike.agents.planner`: a rerun replaces this part -->"


#: the settings ``warm_start_table`` compares: (warm start, samples, iterations, elites,
#: common noise)
WARM_START_SETTINGS = ((True, 64, 3, 6, False), (False, 64, 3, 6, False),
                       (False, 64, 3, 6, True), (False, 128, 4, 12, False),
                       (False, 128, 4, 12, True), (False, 256, 5, 16, False))


def warm_start_table(env_id: str, episodes: int = 20, seed: int = 1000,
                     settings=WARM_START_SETTINGS) -> str:
    """Markdown rows: the planner with and without its warm start (and, without, at more
    samples and iterations, with fresh or common noise) on the evaluation episodes
    ``seed...``, with the CPU time per decision. Without the warm start the planner is a
    reactive (state-feedback) policy; with common noise as well, a deterministic one."""
    rows = [f"| {env_id} | warm start | noise | samples x iterations | return (mean +/- std) | "
            "ms CPU per decision |", "|---|---|---|---|---|---|"]
    for warm, n, iters, elites, common in settings:
        planner = CEMPlanner(samples=n, iterations=iters, elites=elites, warm_start=warm,
                             common_noise=common)
        ev, cost = timed_episodes(planner, env_id, episodes, seed)
        noise = "common" if common else "fresh"
        print(f"{env_id} warm={warm} {noise} {n}x{iters}: {ev.mean:.3f} +/- {ev.std:.3f} "
              f"{cost:.1f} ms", flush=True)
        rows.append(f"| | {'yes' if warm else 'no'} | {noise} | {n} x {iters} | {ev.mean:.2f} "
                    f"+/- {ev.std:.2f} | {cost:.0f} |")
    return "\n".join(rows) + "\n"


def main(argv: list[str] | None = None) -> int:
    """``python -m spinstrike.agents.planner``: the sweep (printed; ``--out`` writes it into a
    document, keeping its notes written by hand), or ``--warm-start-table ENV_ID``."""
    import argparse
    import shlex
    import sys

    p = argparse.ArgumentParser(prog="python -m spinstrike.agents.planner",
                                description="return of the CEM planner against horizon x "
                                "samples, with the cost per decision")
    p.add_argument("--episodes", type=int, default=3)
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--horizons", type=int, nargs="+", default=[5, 10, 20, 40])
    p.add_argument("--samples", type=int, nargs="+", default=[16, 64, 256])
    p.add_argument("--envs", nargs="+", default=list(CONTROL_IDS),
                   help=f"control env ids (default: {' '.join(CONTROL_IDS)})")
    p.add_argument("--out", help="write the report into this markdown file between its "
                   "generated-part markers, e.g. docs/planner.md (default: print only)")
    p.add_argument("--warm-start-table", metavar="ENV_ID",
                   help="instead of the sweep: the planner with and without its warm start on "
                        "ENV_ID's first --episodes evaluation episodes (seeds 1000...)")
    a = p.parse_args(argv)
    table = a.warm_start_table and a.warm_start_table.removeprefix("spinstrike:")
    env_ids = [e.removeprefix("spinstrike:") for e in a.envs]
    for name, values, low in (("--episodes", [a.episodes], 1), ("--steps", [a.steps], 1),
                              ("--horizons", a.horizons, 1), ("--samples", a.samples, 2)):
        if min(values) < low:  # one line, not the planner's traceback
            p.error(f"{name}: must be >= {low} (got {min(values)})")
    from spinstrike.envs import ConfigError, base_id

    for env_id in [table] if table else env_ids:
        # a variant registered with gym.register ('module:Namespace/Name-vN') of a control env
        # is one too (`spinstrike evaluate --planner` took it; this refused it, W14)
        try:
            base = base_id(env_id)
        except ConfigError as exc:
            p.error(str(exc))
        if base not in CONTROL_IDS:
            p.error(f"the planner drives the control envs only, {list(CONTROL_IDS)} or a "
                    f"variant of one (got {env_id!r})")
    if table:
        print(warm_start_table(table, a.episodes))
        return 0
    # the command that ran, as the report's first line says (it named the defaults' always)
    command = shlex.join(["python", "-m", "spinstrike.agents.planner",
                          *(sys.argv[1:] if argv is None else argv)])
    print(sweep(env_ids=env_ids, horizons=a.horizons, samples=a.samples, episodes=a.episodes,
                steps=a.steps, out=a.out, command=command))
    if a.out:
        print(f"wrote {a.out} (the part between its generated-part markers)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
