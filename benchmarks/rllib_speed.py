"""RLlib sampling speed: PPO's env runners on CartPole-v1 beside SpinStrike envs, same config.

    python -m spinstrike.benchmarks.rllib_speed [--runners 2] [--envs 64] [--steps 8192]
                                                [--repeats 3] [--profile]

For each env (``CartPole-v1`` as RLlib runs it by default, a ``SyncVectorEnv``; the SpinStrike
envs as :mod:`spinstrike.envs.rllib` runs them, one native vector env per runner in NEXT_STEP
mode) one PPO algorithm with ``--runners`` env runners of ``--envs`` envs each is built, and
every runner samples ``--steps`` env steps with the module's actions (``EnvRunner.sample``, what
``Algorithm.train`` calls), after one warm-up sample. Per runner: env steps per second of wall
time and of the runner's CPU time, the share of the time spent inside the vector env's ``step``
(the rest is RLlib: the module's forward pass, connectors, episode bookkeeping), and episodes
per second. The ratios are against CartPole-v1 in the same run. ``--profile`` adds, for the
one-strike env, the top functions of a ``cProfile`` of one runner's sample (where its time
goes). Needs the ``rllib`` extra; the numbers depend on the machine and its load (the runners
share the cores with the learner's process only while sampling here).
"""

from __future__ import annotations

import argparse
import time

__all__ = ["main", "measure"]

ENVS = ["CartPole-v1", "SpinStrike/RodSpinControl-v0", "SpinStrike/RodSpin-v0"]


def _sample_timed(runner, steps: int, repeats: int, profile: bool) -> dict:
    """Runs in an env runner: time ``sample`` and the vector env's ``step`` inside it."""
    import cProfile
    import io
    import pstats

    env = runner.env
    inner = env.env  # DictInfoToList's vector env (SpinStrike's, or a SyncVectorEnv)
    spent = [0.0, 0]
    original = inner.step

    def timed_step(actions):
        t = time.perf_counter()
        out = original(actions)
        spent[0] += time.perf_counter() - t
        spent[1] += 1
        return out

    inner.step = timed_step
    try:
        runner.sample(num_timesteps=steps, random_actions=False)  # warm-up
        best = None
        for _ in range(repeats):
            spent[:] = [0.0, 0]
            w0, c0 = time.perf_counter(), time.process_time()
            episodes = runner.sample(num_timesteps=steps, random_actions=False)
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            n = sum(len(e) for e in episodes)
            done = sum(1 for e in episodes if e.is_done)
            row = {"steps": n, "wall": wall, "cpu": cpu, "env": spent[0], "env_calls": spent[1],
                   "episodes": done}
            if best is None or n / wall > best["steps"] / best["wall"]:
                best = row
        if profile:
            prof = cProfile.Profile()
            prof.enable()
            runner.sample(num_timesteps=steps, random_actions=False)
            prof.disable()
            out = io.StringIO()
            stats = pstats.Stats(prof, stream=out)
            best["breakdown"] = _breakdown(stats)
            stats.sort_stats("tottime").print_stats(14)
            best["profile"] = out.getvalue()
        return best
    finally:
        inner.step = original


def _breakdown(stats) -> list[tuple[str, float]]:
    """Where ``SingleAgentEnvRunner._sample`` spends its time: the cumulative time of each
    function it calls directly (its own lines as ``_sample itself``), largest first, as shares
    of its total."""
    total, rows = 0.0, {}
    for (file, _, name), (_, _, tt, ct, callers) in stats.stats.items():
        if name == "_sample" and file.endswith("single_agent_env_runner.py"):
            total = ct
            rows["_sample itself"] = rows.get("_sample itself", 0.0) + tt
        for (cfile, _, cname), caller in callers.items():
            # the runner's own methods are reached through Ray's tracing wrapper: list them
            direct = cname == "_sample" and cfile.endswith("single_agent_env_runner.py")
            wrapped = (cname == "_resume_span" and "/rllib/env/" in file
                       and name not in ("sample", "_sample"))
            if (direct and name != "_resume_span") or wrapped:
                short = "/".join(file.split("/")[-2:])
                label = f"{short}:{name}"
                rows[label] = rows.get(label, 0.0) + caller[3]
    return sorted(((k, v / total) for k, v in rows.items()), key=lambda kv: -kv[1])


def measure(env_id: str, runners: int, envs: int, steps: int, repeats: int,
            profile: bool = False) -> list[dict]:
    """Per-runner sampling figures for ``env_id`` (see the module's docstring)."""
    from ray.rllib.algorithms.ppo import PPOConfig

    from spinstrike.envs.rllib import configure

    config = PPOConfig().env_runners(num_env_runners=runners, num_envs_per_env_runner=envs)
    if env_id.startswith("SpinStrike/"):
        config = configure(config, env_id)
    else:
        config = config.environment(env_id)
    batch = runners * envs * 4
    # (a fixed minibatch of 128 was refused by RLlib below 32 runners x envs)
    config = config.training(train_batch_size_per_learner=batch, minibatch_size=min(128, batch),
                             num_epochs=1)
    algo = config.build_algo()
    try:
        return algo.env_runner_group.foreach_env_runner(
            lambda r: _sample_timed(r, steps, repeats, profile), local_env_runner=False)
    finally:
        algo.stop()


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    p.add_argument("--runners", type=int, default=2)
    p.add_argument("--envs", type=int, default=64)
    p.add_argument("--steps", type=int, default=8192, help="env steps per runner per sample")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--profile", action="store_true")
    p.add_argument("--address", help="a running Ray cluster (default: a local Ray)")
    args = p.parse_args(argv)
    import ray

    import spinstrike  # noqa: F401  (registers the ids)

    ray.init(address=args.address, include_dashboard=False, log_to_driver=False)
    rows = {}
    try:
        for env_id in ENVS:
            rows[env_id] = measure(env_id, args.runners, args.envs, args.steps, args.repeats,
                                   profile=args.profile and env_id == "SpinStrike/RodSpin-v0")
    finally:
        ray.shutdown()
    print(f"RLlib PPO sampling, {args.runners} runners x {args.envs} envs, {args.steps} env "
          f"steps per runner per sample, best of {args.repeats} (per runner, mean over runners)")
    print(f"{'env':32s} {'steps/s wall':>12s} {'steps/s CPU':>12s} {'x CartPole':>10s} "
          f"{'in env.step':>11s} {'episodes/s':>10s}")
    base = None
    for env_id, per_runner in rows.items():
        wall = sum(r["steps"] / r["wall"] for r in per_runner) / len(per_runner)
        cpu = sum(r["steps"] / r["cpu"] for r in per_runner) / len(per_runner)
        share = sum(r["env"] / r["wall"] for r in per_runner) / len(per_runner)
        eps = sum(r["episodes"] / r["wall"] for r in per_runner) / len(per_runner)
        base = base or wall
        print(f"{env_id:32s} {wall:12,.0f} {cpu:12,.0f} {wall / base:10.2f} {share:11.0%} "
              f"{eps:10,.0f}")
    for env_id, per_runner in rows.items():
        if "profile" in per_runner[0]:
            print(f"\nWhere one runner's sample on {env_id} goes (cProfile; the direct "
                  "callees of SingleAgentEnvRunner._sample, share of its time):")
            for label, share in per_runner[0]["breakdown"][:12]:
                print(f"  {share:6.1%}  {label}")
            print("\nTop functions by own time:")
            print(per_runner[0]["profile"])


if __name__ == "__main__":
    main()
