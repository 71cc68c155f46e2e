"""Start a PPO policy from a teacher's behaviour: DAgger (dataset aggregation).

The control envs pay only for hits, and PPO, SAC and TD3 from scratch stop at chasing the
target and bumping it (``docs/baselines.md``, control envs); the CEM planner juggles. DAgger
(Ross, Gordon and Bagnell, 2011) hands the planner's skill to the policy network:

1. round 0: the teacher acts; every state it visits is stored with its action;
2. round r >= 1: the student (the policy as fitted so far, deterministic) acts, and the teacher
   labels every state the *student* visits with the action it would have taken there;
3. after every round the student's mean action is refitted (least squares, which for SB3's
   Gaussian policy is maximum likelihood of the mean) on all the states gathered so far.

Labelling the student's own states is what plain behaviour cloning lacks: the student learns what
to do where its own mistakes take it. At the end the policy's ``log_std`` is set to the log of
the per-dimension RMS residual (the maximum-likelihood width of a Gaussian around the fitted mean)
and the value head is fitted to the discounted returns of the rounds the student acted, so that PPO
continues from a policy whose exploration is as wide as its uncertainty and whose critic starts
at the scale of its returns rather than at zero. (How much more it knows is modest: in the
test, chase-and-hit as the teacher, 24 student episodes, it explains half the variance of the
returns it was fitted on, and on new episodes it is only a little better than an untrained
critic; a return depends on the episode's layout more than a few dozen episodes teach. The
returns are not bootstrapped at the 250-step truncation.)

Measured (``docs/baselines.md``, control envs): PuckSpeedControl, the shipped PPO entry, 20
rounds of 16 episodes (80,000 labelled states, 587 s on 2 cores): the student's return rose from
2.1 to 13.3 over the rounds; PPO's 500k steps after it reached 14.5 (50 evaluation episodes;
over seeds 0-4 an IQM of 14.40), against 8.90 for PPO alone after 2M steps and 28.4 for the
planner. On RodSpinControl the student stays at 2-4, PPO alone's level.
"""

from __future__ import annotations

import csv
import time
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["TEACHERS", "ImitationResult", "check_teacher", "dagger", "make_teacher",
           "settings"]

#: teachers by name: what ``--imitate`` accepts
TEACHERS = ("planner", "reactive-planner", "chase-and-hit")
#: the fewest gradient steps of the critic's fit
CRITIC_STEPS = 500


def check_teacher(name: str) -> None:
    """Raise :class:`AgentConfigError` unless ``name`` is one of :data:`TEACHERS`."""
    if name not in TEACHERS:
        from spinstrike.agents.config import AgentConfigError

        raise AgentConfigError(f"--imitate: unknown teacher {name!r}; allowed: "
                               f"{list(TEACHERS)}")


def make_teacher(name: str, seed: int = 0):
    """The policy ``name`` (one of :data:`TEACHERS`) with the ``policy(env, obs)`` signature."""
    check_teacher(name)
    if name == "chase-and-hit":
        from spinstrike.agents.oracle import ChaseAndHit

        return ChaseAndHit()
    from spinstrike.agents.planner import CEMPlanner

    if name == "planner":
        return CEMPlanner(seed=seed)
    # reactive-planner: a deterministic function of the state (no warm start, common noise),
    # more search instead: 0.95 (RodSpinControl) and 0.89 (PuckSpeedControl) of the planner
    # (docs/planner.md, warm-start table: 128 x 4, common noise)
    return CEMPlanner(samples=128, iterations=4, elites=12, warm_start=False, common_noise=True,
                      seed=seed)


def settings(teacher: str, algo: str, env_id: str, normalize: bool, rounds: int,
             episodes: int) -> dict:
    """``spinstrike train --imitate``'s settings, checked before anything is built: the
    keyword arguments of :func:`dagger`.

    Raises:
        AgentConfigError: naming the option and what is allowed.
    """
    from spinstrike.agents.config import AgentConfigError

    if algo != "ppo":
        raise AgentConfigError(f"--imitate: starts PPO only (got --algo {algo})")
    check_teacher(teacher)
    from spinstrike.envs import base_id

    if teacher.endswith("planner") and "Control" not in base_id(env_id):
        raise AgentConfigError(f"--imitate {teacher}: the planner drives the control envs only "
                               f"(got {env_id})")
    if normalize:
        raise AgentConfigError("--imitate: not with 'normalize: true' in the hyperparameters "
                               "(the teacher's states would have to pass through the running "
                               "normalisation)")
    for option, value in (("--imitate-rounds", rounds), ("--imitate-episodes", episodes)):
        if not isinstance(value, int) or value < 1:
            raise AgentConfigError(f"{option}: must be an integer >= 1 (got {value!r})")
    return {"teacher": teacher, "rounds": rounds, "episodes": episodes}


@dataclass
class ImitationResult:
    """What the rounds did: per round, who acted, the mean return of its episodes, the states
    labelled so far, the fit's mean squared error and the round's wall time."""

    rounds: list[dict] = field(default_factory=list)
    log_std: list[float] = field(default_factory=list)
    critic_mse: float = 0.0
    critic_var: float = 0.0
    wall_time: float = 0.0

    def write_csv(self, path: str | Path) -> None:
        with open(path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(self.rounds[0]))
            w.writeheader()
            w.writerows(self.rounds)

    def plot(self, path: str | Path, title: str) -> Path:
        """The student's return per round (mean +/- std over the round's episodes) against the
        teacher's (round 0): ``imitation.png``."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        rounds = np.array([r["round"] for r in self.rounds[1:]])
        mean = np.array([r["return_mean"] for r in self.rounds[1:]])
        std = np.array([r["return_std"] for r in self.rounds[1:]])
        fig, ax = plt.subplots(figsize=(6, 3.5))
        if len(rounds):
            ax.plot(rounds, mean, marker="o", ms=3, label="student (acts in round r)")
            ax.fill_between(rounds, mean - std, mean + std, alpha=0.25)
        ax.axhline(self.rounds[0]["return_mean"], color="k", ls="--",
                   label=f"{self.rounds[0]['acted']} (round 0)")
        ax.set_xlabel("DAgger round")
        ax.xaxis.set_major_locator(plt.MaxNLocator(integer=True))
        ax.set_ylabel("episode return")
        ax.set_title(title)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=8)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return Path(path)


@contextmanager
def _sigterm_exits():
    """Within: SIGTERM raises ``SystemExit(143)`` in the main thread, as Ctrl-C raises
    ``KeyboardInterrupt``, so that the worker pool's ``with`` block terminates its workers on
    the way out (by default SIGTERM ends the process at once and leaves the spawned workers to
    finish the round they are running). Yields the list of the signals received (an RLlib run
    exits with the signal's code: Ray's ``wait`` turns a ``SystemExit`` raised while it waits
    into its own ``SystemExit(1)``)."""
    import signal

    received: list[int] = []

    def _exit(signum, frame):
        received.append(signum)
        raise SystemExit(128 + signum)

    with handling((signal.SIGTERM,), _exit):
        yield received


@contextmanager
def handling(signums, handler):
    """Within: ``handler`` for each of ``signums`` that the process does not ignore, the
    previous handlers back after. A signal ignored stays ignored (SIGINT in a job started in
    the background, ``nohup ... &`` or by a scheduler: a handler installed over ``SIG_IGN``
    stopped such a run on a signal it was not meant to see, ci38). Nothing outside the main
    thread, where Python runs signal handlers and lets them be set."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, handler) for sig in signums
                if signal.getsignal(sig) is not signal.SIG_IGN}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _worker_init() -> None:
    import torch

    import spinstrike  # noqa: F401  (registers the ids in a spawned worker)

    torch.set_num_threads(1)


def _rollouts(job: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[float]]:
    """Episodes ``seeds`` of ``env_id``, acted by ``student`` (an SB3 policy; None: the
    teacher), every visited state labelled by the teacher (seeded with the episode's seed, so
    that the labels do not depend on how the episodes are shared among workers)."""
    env_id, env_kwargs, seeds, teacher_name, student = job
    import gymnasium as gym

    env = gym.make(env_id, **env_kwargs)
    obs_out, act_out, rew_out, returns = [], [], [], []
    for s in seeds:
        teacher = make_teacher(teacher_name, int(s))
        obs, _ = env.reset(seed=int(s))
        done, total = False, 0.0
        while not done:
            label = np.asarray(teacher(env, obs), dtype=np.float32)
            act = label if student is None else student.predict(obs, deterministic=True)[0]
            obs_out.append(obs)
            act_out.append(label)
            obs, reward, term, trunc, _ = env.step(act)
            rew_out.append((float(reward), bool(term), bool(term or trunc)))
            total += float(reward)
            done = term or trunc
        returns.append(total)
    env.close()
    return (np.asarray(obs_out, np.float32), np.asarray(act_out, np.float32),
            np.asarray(rew_out, np.float64), returns)


def _discounted(rewards: np.ndarray, gamma: float) -> np.ndarray:
    """Returns-to-go of consecutive episodes: rows (reward, terminated, episode ended)."""
    out = np.zeros(len(rewards))
    g = 0.0
    for i in range(len(rewards) - 1, -1, -1):
        r, _, ended = rewards[i]
        if ended:
            g = 0.0  # a truncated episode's tail is not bootstrapped: a small, known bias
        g = r + gamma * g
        out[i] = g
    return out


def _fit(policy, obs: np.ndarray, target: np.ndarray, *, head: str, epochs: int,
         batch_size: int, lr: float, rng: np.random.Generator) -> float:
    """Least-squares fit of the policy's mean action (``head="actor"``) or value
    (``"critic"``) to ``target``; returns the final mean squared error over all the data."""
    import torch

    th_obs = torch.as_tensor(obs)
    th_target = torch.as_tensor(target, dtype=torch.float32)
    if head == "actor":
        params = [p for n, p in policy.named_parameters()
                  if not n.startswith(("value_net", "log_std", "mlp_extractor.value_net"))]

        def predict(x):
            return policy.get_distribution(x).distribution.mean
    else:
        params = [p for n, p in policy.named_parameters()
                  if n.startswith(("value_net", "mlp_extractor.value_net"))]

        def predict(x):
            return policy.predict_values(x).squeeze(-1)
    opt = torch.optim.Adam(params, lr=lr)
    n = len(th_obs)
    policy.set_training_mode(True)
    for _ in range(epochs):
        order = torch.as_tensor(rng.permutation(n))
        for i in range(0, n, batch_size):
            idx = order[i:i + batch_size]
            loss = ((predict(th_obs[idx]) - th_target[idx]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    policy.set_training_mode(False)
    with torch.no_grad():
        return float(((predict(th_obs) - th_target) ** 2).mean())


def dagger(model, env_id: str, teacher: str = "planner", *, rounds: int = 20,
           episodes: int = 16, seed: int = 0, workers: int = 2, epochs: int = 30,
           batch_size: int = 256, lr: float = 1e-3, env_kwargs: dict | None = None,
           log: Path | None = None, progress: bool = True) -> ImitationResult:
    """Fit ``model``'s policy (SB3 PPO, Box actions) to ``teacher`` by DAgger, in place.

    Args:
        model: the PPO model whose policy is fitted (its actor and critic; ``log_std`` set).
        teacher: one of :data:`TEACHERS`.
        rounds: rounds in all (round 0 is the teacher's, the others the student's).
        episodes: episodes per round (seeds ``10**6 * (seed + 1) + round * episodes + k``:
            never the evaluation's 1000...).
        workers: processes that run a round's episodes (0: in this process, one after the
            other; the same results as any other count).
        epochs, batch_size, lr: the fit after each round (Adam; it continues from the last
            round's weights over all the states gathered so far).
        log: where to write the rounds as CSV (``imitation.csv``), after every round; their
            plot goes beside it at the end (``imitation.png``).

    Raises:
        AgentConfigError: bad settings or a model this does not apply to.
    """
    import torch

    from spinstrike.agents.config import AgentConfigError

    for name, value, low in (("rounds", rounds, 1), ("episodes", episodes, 1),
                             ("workers", workers, 0), ("epochs", epochs, 1),
                             ("batch_size", batch_size, 1)):
        if not isinstance(value, (int, np.integer)) or value < low:
            raise AgentConfigError(f"imitation {name}: must be an integer >= {low} "
                                   f"(got {value!r})")
    check_teacher(teacher)
    policy = model.policy
    if not hasattr(policy, "log_std") or not hasattr(policy, "predict_values"):
        raise AgentConfigError("--imitate: starts PPO's Gaussian policy only (--algo ppo)")
    if model.get_vec_normalize_env() is not None:
        raise AgentConfigError("--imitate: not with 'normalize: true' (the teacher's states "
                               "would have to pass through the running normalisation)")
    env_kwargs = dict(env_kwargs or {})
    rng = np.random.default_rng(seed)
    torch.manual_seed(seed)
    gamma = float(getattr(model, "gamma", 0.99))
    result = ImitationResult()
    obs_all = np.zeros((0, *policy.observation_space.shape), np.float32)
    act_all = np.zeros((0, *policy.action_space.shape), np.float32)
    critic_obs: list[np.ndarray] = []
    critic_returns: list[np.ndarray] = []
    start = time.time()
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=rounds, desc=f"DAgger from the {teacher}", unit="round")
    from multiprocessing import get_context

    parallel = max(workers, 1)
    # the handler first, then the pool (a with statement enters them in order)
    with _sigterm_exits(), (get_context("spawn").Pool(workers, _worker_init) if workers
                            else nullcontext()) as pool:
        run = pool.map if pool is not None else lambda f, jobs: list(map(f, jobs))
        for r in range(rounds):
            t0 = time.time()
            seeds = 10**6 * (seed + 1) + r * episodes + np.arange(episodes)
            student = None
            if r > 0:
                student = policy
                student.set_training_mode(False)
            # contiguous shares: the data come back in seed order whatever the split
            jobs = [(env_id, env_kwargs, share, teacher, student)
                    for share in np.array_split(seeds, parallel) if len(share)]
            parts = run(_rollouts, jobs)
            obs = np.concatenate([p[0] for p in parts])
            obs_all = np.concatenate([obs_all, obs])
            act_all = np.concatenate([act_all, *(p[1] for p in parts)])
            if r > 0 or rounds == 1:  # the critic's data: the rounds the student acted
                critic_obs.append(obs)
                critic_returns.append(_discounted(np.concatenate([p[2] for p in parts]), gamma))
            returns = [x for p in parts for x in p[3]]
            mse = _fit(policy, obs_all, act_all, head="actor", epochs=epochs,
                       batch_size=batch_size, lr=lr, rng=rng)
            result.rounds.append({"round": r, "acted": "student" if r else teacher,
                                  "return_mean": round(float(np.mean(returns)), 4),
                                  "return_std": round(float(np.std(returns)), 4),
                                  "states": len(obs_all), "mse": round(mse, 5),
                                  "wall_time_s": round(time.time() - t0, 1)})
            if log is not None:  # written as the rounds go: a long run shows where it is
                result.write_csv(log)
            if bar is not None:
                bar.set_postfix(ret=f"{np.mean(returns):.2f}", mse=f"{mse:.3f}")
                bar.update()
    if bar is not None:
        bar.close()
    # the Gaussian's width: the RMS residual of the fitted mean, per action dimension
    with torch.no_grad():
        mean = policy.get_distribution(torch.as_tensor(obs_all)).distribution.mean.numpy()
        resid = np.sqrt(((mean - act_all) ** 2).mean(0))
        policy.log_std.copy_(torch.as_tensor(np.log(np.maximum(resid, 1e-3)),
                                             dtype=policy.log_std.dtype))
    result.log_std = [float(x) for x in policy.log_std.detach().numpy()]
    # the critic: discounted returns of the rounds the student acted (the teacher's round if
    # there is no other), at least CRITIC_STEPS gradient steps: it starts from zero
    c_obs, c_ret = np.concatenate(critic_obs), np.concatenate(critic_returns)
    critic_epochs = max(epochs, -(-CRITIC_STEPS * batch_size // len(c_obs)))
    result.critic_var = float(c_ret.var())
    result.critic_mse = _fit(policy, c_obs, c_ret, head="critic", epochs=critic_epochs,
                             batch_size=batch_size, lr=lr, rng=rng)
    result.wall_time = time.time() - start
    if log is not None:
        result.plot(Path(log).with_suffix(".png"), f"DAgger from the {teacher} on {env_id}")
    return result
