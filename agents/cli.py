"""The ``spinstrike`` command line.

    spinstrike train    --algo ppo --env SpinStrike/RodSpin-v0 [--seed 0] [--timesteps N]
    spinstrike train    --algo ppo --env ID --imitate planner   (DAgger first, then PPO)
    spinstrike train    --backend rllib --env ID [--num-env-runners N] [--address ADDR]
    spinstrike evaluate RUN_DIR | --oracle/--random/--planner --env ID [--env-kwargs YAML]
                        [--episodes 50] [--json]
    spinstrike record   RUN_DIR | --oracle/--random/--planner --env ID [--env-kwargs YAML]
                        [--out rollout.mp4|.gif] [--grid]
    spinstrike record   --scene break [--seconds 3] [--dt 0.02]   (a physics scene, no policy)
    spinstrike envs
    spinstrike cache    [--clear | --prune]
    spinstrike bench    accuracy|speed [--quick]
    spinstrike baselines [--quick]

Invalid arguments, configs or env kwargs print one ``error:`` line naming what is wrong and exit
with status 2, before anything is written.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import math
import os
import re
import shlex
import signal
import sys
from pathlib import Path

__all__ = ["main"]

DEFAULT_ENV = "SpinStrike/RodSpin-v0"


def _kwargs(text: str | None) -> dict:
    if not text:
        return {}
    import yaml

    from spinstrike.agents.config import AgentConfigError, yaml_problem
    from spinstrike.physics.scene import load_yaml

    try:
        value = load_yaml(text)
    except yaml.YAMLError as exc:
        raise AgentConfigError(f"--env-kwargs: not valid YAML/JSON ({yaml_problem(exc)})") \
            from None
    if not isinstance(value, dict):
        raise AgentConfigError(f"--env-kwargs: must be a mapping such as "
                               f"'{{restitution: 0.8}}' (got {text!r})")
    glued = [key for key, v in value.items() if v is None and isinstance(key, str) and ":" in key]
    if glued:  # YAML reads {max_force:1} as the key 'max_force:1' with no value
        key, _, rest = glued[0].partition(":")
        raise AgentConfigError(f"--env-kwargs: {glued[0]!r} reads as one key with no value: "
                               f"YAML needs a space after the colon ('{{{key}: {rest}}}')")
    return value


def _check_env_id(env_id: str) -> str:
    """Refuse an id that is not a SpinStrike env (or a variant of one); return its shipped id."""
    from spinstrike.agents.config import check_env_id

    return check_env_id(env_id, "--env")


def _check_episodes(option: str, value: int) -> None:
    from spinstrike.agents.config import AgentConfigError

    if value < 1:
        raise AgentConfigError(f"{option}: must be >= 1 (got {value})")


def _run_policy(run: Path):
    """A run folder's agent: (policy, env id, env arguments, "agent"), from ``spinstrike
    train``'s run (SB3's or RLlib's) or rl-zoo3's."""
    from spinstrike.agents.config import AgentConfigError, check_env_id
    from spinstrike.agents.evaluate import load_model_policy, load_zoo_policy, zoo_run_files

    if (run / "checkpoint").is_dir() and (run / "config.yml").is_file() and \
            not (run / "model.zip").exists():  # spinstrike train --backend rllib
        from spinstrike.agents.rllib_train import load_rllib_policy

        policy, meta = load_rllib_policy(run)
        env_kwargs = meta["hyperparameters"][meta["env"]].get("env_kwargs", {})
        _note_registration_changes(run, meta, env_kwargs)
        return policy, meta["env"], env_kwargs, "agent"
    if not (run / "config.yml").is_file():  # a Tune trial (or its checkpoint), rl-zoo3's run
        from spinstrike.agents.rllib_train import (
            algorithm_checkpoint,
            load_algorithm_policy,
            load_tune_policy,
            tune_checkpoint,
        )

        for found, load, what in ((tune_checkpoint, load_tune_policy, "Tune trial"),
                                  (algorithm_checkpoint, load_algorithm_policy,
                                   "RLlib checkpoint"),
                                  (zoo_run_files, load_zoo_policy, "rl-zoo3 run")):
            if found(run) is not None:
                policy, env_id, env_kwargs = load(run)
                check_env_id(env_id, f"run_dir: the {what}'s env")
                return policy, env_id, env_kwargs, "agent"
    missing = [f for f in ("model.zip", "config.yml") if not (run / f).is_file()]
    if missing == ["model.zip"] and list((run / "checkpoints").glob("model_*_steps.zip")):
        out = run.with_name(run.name.removesuffix(".partial"))
        raise AgentConfigError(f"run_dir: {run} is an interrupted run (checkpoints, no "
                               f"model.zip yet): `spinstrike train --resume --out {out}` "
                               f"finishes it")
    partial = run.with_name(run.name + ".partial")
    if missing and not run.exists() and partial.is_dir():
        raise AgentConfigError(f"run_dir: {run} does not exist, but {partial} does: an "
                               f"interrupted run; `spinstrike train --resume --out {run}` "
                               f"finishes it")
    if missing:
        raise AgentConfigError(f"run_dir: {run} has no {' or '.join(missing)} (not a run: "
                               f"takes a `spinstrike train` run, an rl-zoo3 run, a Tune "
                               f"trial of RLlib or one of its checkpoint_* folders, or an "
                               f"RLlib algo.save() folder)")
    policy, meta = load_model_policy(run)
    env_kwargs = meta["hyperparameters"][meta["env"]].get("env_kwargs", {})
    _note_registration_changes(run, meta, env_kwargs)
    return policy, meta["env"], env_kwargs, "agent"


def _run_of_checkpoint(path: Path) -> Path:
    """The run ``path`` is the RLlib checkpoint of (``RUN/checkpoint``, which loads as an
    ``algo.save()`` folder too), else ``path``: evaluated or filmed as the run, its summary and
    video in the run's folder under the run's title (walk W26a: they were written inside
    ``checkpoint/``, titled by the env id alone)."""
    from spinstrike.agents.rllib_train import CHECKPOINT

    run = path.parent
    if path.name != CHECKPOINT or \
            _run_record(str(run / "config.yml"), full=True).get("backend") != "rllib":
        return path
    print(f"note: {path} is the RLlib checkpoint of the run {run}: the run is evaluated or "
          f"filmed (what is written goes there)", file=sys.stderr)
    return run


def _policy(args):
    from spinstrike import envs
    from spinstrike.agents.config import AgentConfigError
    from spinstrike.agents.oracle import RandomPolicy, oracle_for

    if args.run_dir and args.env_kwargs:
        raise AgentConfigError("--env-kwargs: a run is evaluated and filmed on the env it was "
                               "trained on (its config.yml's env_kwargs); the option goes with "
                               "--oracle, --random or --planner")
    # a run's agent on the run's env: these options chose another policy or env, and were
    # dropped without a word (another env's numbers were the training env's)
    given = [f"--{flag}" for flag in ("env", "oracle", "random", "planner")
             if getattr(args, flag, None)]
    if args.run_dir and given:
        raise AgentConfigError(f"{', '.join(given)}: a run is evaluated and filmed with its own "
                               f"agent on the env it was trained on (its config.yml); "
                               f"{' and '.join(given)} {'go' if len(given) > 1 else 'goes'} "
                               f"without a run directory")
    if args.run_dir:
        args.run_dir = str(_run_of_checkpoint(Path(args.run_dir)))
        return _run_policy(Path(args.run_dir))
    if not args.env:
        for flag in ("oracle", "random", "planner"):
            if getattr(args, flag):
                raise AgentConfigError(f"--{flag}: needs --env ID; ids: {list(envs.ENV_IDS)}")
        raise AgentConfigError("give a run directory, or --oracle, --random or --planner "
                               "with --env ID")
    base = _check_env_id(args.env)
    env_kwargs = _kwargs(args.env_kwargs)
    from spinstrike.agents.train import check_env_kwargs

    # a bad one: a ConfigError naming it; a variant whose episodes would never end, refused
    check_env_kwargs(args.env, env_kwargs, "--env-kwargs", args.command)
    if args.random:
        return RandomPolicy(args.seed), args.env, env_kwargs, "random"
    if args.oracle:
        return oracle_for(args.env), args.env, env_kwargs, "oracle"
    if args.planner:
        from spinstrike.agents.planner import CEMPlanner

        if "Control" not in base:
            raise AgentConfigError(f"--planner: drives the control envs only "
                                   f"(SpinStrike/RodSpinControl-v0, SpinStrike/PuckSpeedControl-v0)"
                                   f"; got {args.env!r}")
        return CEMPlanner(), args.env, env_kwargs, "planner"
    raise AgentConfigError("give a run directory, or --oracle, --random or --planner with "
                           "--env ID")


def _train_defaults(args) -> None:
    """Fill in ``--algo``, ``--env`` and ``--seed`` left out. Resuming, those left out are the
    run's (its config.yml); only the default ``--out`` is named from the defaults."""
    if args.resume:
        if args.out is None:
            from spinstrike.agents.train import default_run_dir

            algo = "ppo-rllib" if args.backend == "rllib" else args.algo or "ppo"
            args.out = str(default_run_dir(algo, args.env or DEFAULT_ENV, args.seed or 0))
        return
    record = _run_record(args.config)  # `--config RUN/config.yml`: the run's algo and env
    args.algo = args.algo or record.get("algo") or "ppo"
    args.env = args.env or record.get("env") or DEFAULT_ENV
    args.seed = 0 if args.seed is None else args.seed


def _run_record(path: str | None, full: bool = False) -> dict:
    """The algo and env of a run's ``config.yml`` given as ``--config`` (empty for a
    hyperparameter file, or anything unreadable: the loader says what is wrong with it). Left
    out on the command line, they were the defaults' (ppo, RodSpin-v0), and a run of another env
    was refused for having no entry for RodSpin-v0. ``full``: the whole record."""
    if path is None:
        return {}
    from spinstrike.agents.config import run_record

    data = run_record(path)
    if full or not data:
        return data
    return {k: data[k] for k in ("algo", "env") if isinstance(data.get(k), str)}


def _train_backend(args) -> None:
    """``--backend`` left out: ``sb3``, or the backend the run's config.yml records, resuming
    (``--resume --out RUN``: an RLlib run's resume looked for SB3's checkpoints and said the run
    had none, walk W26a F2) or training a record again (``--config RUN/config.yml``)."""
    if args.backend is not None:
        return
    args.backend = "sb3"
    if not args.resume and _run_record(args.config, full=True).get("backend") == "rllib":
        # `train --config RLLIB_RUN/config.yml` trains the record again: with RLlib, not
        # silently with SB3's PPO (walk W26a F4)
        args.backend = "rllib"
    if args.resume and args.out is not None:
        from spinstrike.agents.config import run_record
        from spinstrike.agents.train import resume_folder

        if run_record(resume_folder(Path(args.out)) / "config.yml").get("backend") == "rllib":
            args.backend = "rllib"


def cmd_train(args) -> int:
    from spinstrike.agents.train import train

    _train_backend(args)
    _train_defaults(args)
    if args.env is not None:
        _check_env_id(args.env)
    if not args.no_eval and args.eval_episodes is not None:
        _check_episodes("--eval-episodes", args.eval_episodes)
    _refuse_unused(args)
    if args.backend == "rllib" and args.imitate:
        from spinstrike.agents.config import AgentConfigError

        raise AgentConfigError("--imitate: starts SB3's PPO only (not --backend rllib)")
    _require_extra("train", {**TRAIN_MODULES, **({"ray": "rllib"} if args.backend == "rllib"
                                                  else {})})
    if args.backend == "rllib":
        from spinstrike.agents.rllib_train import RunnersLost

        try:
            result = _train_rllib(args)
        except KeyboardInterrupt:  # Ctrl-C: train_rllib said how to go on; no traceback
            return 128 + 2  # SIGINT
        except RunnersLost as exc:  # stopped short of the budget, the run kept: not an exit 0
            print("error: " + " ".join(str(exc).split()), file=sys.stderr)
            return 1
    else:
        try:
            result = train(args.algo, args.env, config=args.config, seed=args.seed,
                           timesteps=args.timesteps, out=args.out, n_envs=args.n_envs,
                           device=args.device, resume=args.resume, force=args.force,
                           progress=not args.no_progress,
                           # a flag left out: a resumed run finishes as its record says
                           evaluate=False if args.no_eval else None,
                           eval_episodes=args.eval_episodes,
                           video=False if args.no_video else None,
                           env_kwargs=_kwargs(args.env_kwargs),
                           torch_threads=args.torch_threads or None,
                           command="spinstrike " + shlex.join(args.argv),
                           imitate=args.imitate,
                           # given only: train()'s own defaults otherwise
                           **{k: v for k, v in (("imitate_rounds", args.imitate_rounds),
                                                ("imitate_episodes", args.imitate_episodes))
                              if v is not None})
        except KeyboardInterrupt:  # Ctrl-C: train() said how to go on; no traceback (as SIGTERM)
            return 128 + 2  # SIGINT
    sessions = result.get("sessions", 1)
    if "complete" in result:  # --resume of a run that has trained its budget
        print(f"run: {result['run_dir']} has trained its budget ({result['timesteps']} steps): "
              + ("nothing to do" if not result["complete"] else
                 f"wrote its missing {' and '.join(NAMES[k] for k in result['complete'])}")
              + "; --timesteps N above it trains further")
    else:
        print(f"run: {result['run_dir']}  ({result['timesteps']} steps, "
              f"{result['wall_time']:.1f} s" + (f"; {result['total_wall_time']:.0f} s in "
                                                 f"{sessions} sessions" if sessions > 1 else "")
              + ")" + _rounded_up(result))
    from spinstrike.agents.evaluate import policy_label

    control = "Control" in _check_env_id(result.get("env") or args.env)
    for name, (mean, std) in result.get("evaluations", {}).items():
        print(f"  {policy_label(name, control):>7s}: {mean:.4f} +/- {std:.4f}")
    if "video" in result:
        print(f"video: {result['video']}")
    return 0


#: what ``train``'s finish writes
NAMES = {"evaluate": "summary", "video": "video"}


def _refuse_unused(args) -> None:
    """A flag that the rest of the command line turns off is refused (it was accepted and
    ignored: ``--imitate-rounds 3`` without ``--imitate``, ``--num-env-runners`` on SB3)."""
    from spinstrike.agents.config import AgentConfigError

    unused = []
    if args.backend != "rllib":
        unused += [(flag, value, "--backend rllib's") for flag, value in (
            ("--num-env-runners", args.num_env_runners), ("--address", args.address))]
    if not args.imitate:
        unused += [(flag, value, "--imitate's") for flag, value in (
            ("--imitate-rounds", args.imitate_rounds),
            ("--imitate-episodes", args.imitate_episodes))]
    if args.no_eval and not args.resume:  # (resuming, the record's contradictions are said)
        unused.append(("--eval-episodes", args.eval_episodes,
                       "the final evaluation's, which --no-eval leaves out"))
    for flag, value, whose in unused:
        if value is not None:
            raise AgentConfigError(f"{flag}: {whose}, not given (got {value!r})")


def _rounded_up(result: dict) -> str:
    """What the run line adds where the run trained more steps than its budget: SB3 trains
    whole rollouts (``n_envs x n_steps`` for PPO, ``n_envs`` steps a call for SAC and TD3; so
    ``--timesteps 100`` trains 1024 steps at the shipped PPO entries), RLlib whole iterations."""
    from spinstrike.agents.config import run_record
    from spinstrike.agents.train import recorded_budget

    work = Path(result["run_dir"])
    meta = run_record(work / "config.yml")
    if not meta:
        return ""
    budget = recorded_budget(work, meta)
    if budget is None or result["timesteps"] <= budget:
        return ""
    rllib = meta.get("backend") == "rllib"
    return (f"; the budget of {budget} rounded up to whole "
            + ("training iterations, as RLlib trains them" if rllib
               else "rollouts, as SB3 trains them"))


def _train_rllib(args) -> dict:
    """``spinstrike train --backend rllib``: PPO with Ray RLlib (``agents.rllib_train``)."""
    from spinstrike.agents.config import AgentConfigError

    if args.algo not in (None, "ppo"):
        raise AgentConfigError(f"--algo: --backend rllib trains ppo only (got {args.algo!r})")
    runners = args.num_env_runners  # (None: 2, or resuming, the run's)
    if runners is not None and runners < 0:
        raise AgentConfigError(f"--num-env-runners: must be >= 0 (got {runners})")
    for flag, value, default in (("--device", args.device, "cpu"),
                                 ("--torch-threads", args.torch_threads, 1)):
        if value != default:  # was accepted and ignored
            raise AgentConfigError(f"{flag}: the SB3 backend's; --backend rllib trains on the "
                                   f"CPU with RLlib's own settings (got {value!r})")
    from spinstrike.agents.rllib_train import train_rllib

    return train_rllib(args.env, config=args.config, seed=args.seed, timesteps=args.timesteps,
                       out=args.out, n_envs=args.n_envs, num_env_runners=runners,
                       address=args.address, force=args.force, resume=args.resume,
                       # a flag left out: the default, or a resumed run's record
                       evaluate=False if args.no_eval else None,
                       eval_episodes=args.eval_episodes,
                       video=False if args.no_video else None,
                       env_kwargs=_kwargs(args.env_kwargs),
                       command="spinstrike " + shlex.join(args.argv))


def cmd_evaluate(args) -> int:
    from spinstrike.agents.evaluate import evaluate, summarise

    _check_episodes("--episodes", args.episodes)
    policy, env_id, env_kwargs, name = _policy(args)
    # random and the oracle are always among the baselines; a run's agent or the planner joins
    named = name not in ("random", "oracle")
    results = evaluate(env_id, policy if named else None, args.episodes, args.seed,
                       env_kwargs, baselines=True, name=name)
    out = Path(args.run_dir) if args.run_dir and not args.no_save else None
    header, fields = f"## {env_id}", {}
    if out is not None:  # the run's own title (algorithm, seed, steps, time) stays on top
        old = out / "summary.md"
        title = old.read_text().splitlines()[0] if old.is_file() else ""
        again = title.startswith("#")
        record = _run_record(str(out / "config.yml"), full=True)
        if not again:  # a --no-eval run has no summary: its record has the title
            from spinstrike.agents.train import run_title

            title = run_title(record) if record else header
        header = (f"{title}\n\n{'Re-evaluated' if again else 'Evaluated'} by `spinstrike "
                  f"evaluate`: {args.episodes} episodes from seed {args.seed}"
                  f"{_versions_note(record)}." + _code_notes(env_id, record, fields))
    text = summarise(results, out, header, fields)
    if args.json:  # stdout is the JSON alone, for a pipe
        print(json.dumps({r.policy: {"mean": r.mean, "std": r.std, "episodes": r.episodes,
                                     **({"hits": r.hits} if r.hits else {})}
                          for r in results}))
    else:
        print(text)
    if out is not None:
        print(f"wrote {out / 'summary.md'} and summary.json (--no-save leaves them)",
              file=sys.stderr)
    return 0


def _versions_note(record: dict | None) -> str:
    """What a re-written ``summary.md`` says of the code that scored it: the commit, and the
    versions that differ from the run's record (walk W24b F5: a summary re-written at another
    commit did not say so)."""
    from spinstrike.agents.config import code_version, version_changes

    now = code_version()
    changed = version_changes((record or {}).get("versions"), now)
    return (f", at commit {now['spinstrike_commit']}"
            + (f" (the run trained with {'; '.join(changed)})" if changed else ""))


def _code_notes(env_id: str, record: dict, fields: dict) -> str:
    """What a run's re-written ``summary.md`` says under its title where the code of the
    user's its variant runs is not the code the run trained with (``envs.code_check``), and
    ``fields`` gets for each entry of ``summary.json``: ``code_changed`` (the modules) and
    ``code_unchecked`` (each with why it is not compared). The note went to stderr only, and a
    shared run's summary held another code's scores with no word of it (walk W24b F6)."""
    from spinstrike.envs import code_check

    changed, unchecked = code_check(env_id, record.get("code")) if record else ([], {})
    text = ""
    if changed:
        fields["code_changed"] = changed
        text += (f" The code of {', '.join(f'`{m}`' for m in changed)} changed since the run "
                 f"trained: these scores are of the code as it is now.")
    if unchecked:
        fields["code_unchecked"] = unchecked
        text += (f" The code of {', '.join(f'`{m}`' for m in unchecked)} was not checked "
                 f"against the run's ({'; '.join(unchecked.values())}).")
    return text


def _size(text: str) -> tuple[int, int]:
    from spinstrike.agents.config import AgentConfigError
    from spinstrike.envs.config import size_problem

    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise AgentConfigError(f"--size: must be WIDTHxHEIGHT in pixels, e.g. 720x480 "
                               f"(got {text!r})") from None
    problem = size_problem((w, h))
    if problem:
        raise AgentConfigError(f"--size: {problem}")
    return w, h


def _video_frames(result: dict) -> str:
    """The frames filmed and their rate, and those a GIF keeps where it keeps fewer (above
    50 fps it keeps every k-th frame and the last, each shown >= 20 ms)."""
    said = f"{result['frames']} frames at {result['fps']:g} fps"
    if result["kept"] != result["frames"]:
        said += f"; the GIF keeps {result['kept']} of them, the last included, >= 20 ms each"
    return said


def _video_size(result: dict, asked: tuple[int, int] | None) -> str:
    """The video's ``WxH`` as written, saying so where H.264 rounded the asked size up."""
    w, h = result["size"]
    if asked is not None and tuple(asked) != (w, h):
        return f"{w}x{h}: --size {asked[0]}x{asked[1]} rounded up to even sizes, as H.264 needs"
    return f"{w}x{h}"


def _check_video_out(out: str) -> None:
    from spinstrike.agents.config import AgentConfigError
    from spinstrike.envs.recording import FORMATS

    if Path(out).suffix.lower() not in FORMATS:
        raise AgentConfigError(f"--out: must end in .mp4 or .gif (got {out!r})")
    if Path(out).is_dir():  # (refused before the policy loads and the episodes are filmed)
        raise AgentConfigError(f"--out: {out} is a folder; the video needs a file name "
                               f"ending in .mp4 or .gif")


#: ``spinstrike record``'s options that only a policy's video uses, with their defaults, and
#: those that only ``--scene`` uses (None: left out; each is refused where it is not used)
RECORD_POLICY = {"--episodes": 3, "--seed": 2000}
RECORD_SCENE = {"--seconds": 3.0, "--dt": 0.02}


def _fill_defaults(args, defaults: dict) -> None:
    for flag, value in defaults.items():
        name = flag.removeprefix("--").replace("-", "_")
        if getattr(args, name) is None:
            setattr(args, name, value)


def cmd_record(args) -> int:
    from spinstrike.agents.config import AgentConfigError
    from spinstrike.agents.record import record

    _require_video(args.out or "rollout.mp4")  # before an env or a scene compiles its kernels
    if args.scene is not None:
        return _record_scene(args)
    given = [flag for flag in RECORD_SCENE if getattr(args, flag[2:]) is not None]
    if given:
        raise AgentConfigError(f"{', '.join(given)}: only with --scene (a physics scene's "
                               f"video); a policy's video lasts --episodes episodes")
    _fill_defaults(args, RECORD_POLICY)
    _check_episodes("--episodes", args.episodes)
    policy, env_id, env_kwargs, name = _policy(args)
    out = args.out if args.out is not None else (
        str(Path(args.run_dir) / "rollout.mp4") if args.run_dir
        else f"{name}-{env_id.split('/')[-1]}.mp4")
    _check_video_out(out)
    size = _size(args.size) if args.size else None
    replaced = _replaces(out)
    result = record(policy, env_id, out, episodes=args.episodes, seed=args.seed,
                    env_kwargs=env_kwargs, size=size, grid=args.grid)
    print(f"video: {result['path']} ({_video_frames(result)}, "
          f"{_video_size(result, None if args.grid else size)}){replaced}")
    return 0


def _replaces(out: str) -> str:
    """What ``record``'s line adds where the video replaces a file (a run's ``rollout.mp4``
    filmed again, or a name given twice): it is overwritten, as ffmpeg's ``-y`` does, but said."""
    return "; it replaces the file that was there" if Path(out).exists() else ""


def _record_scene(args) -> int:
    """``spinstrike record --scene S``: film a physics scene as it evolves (no policy)."""
    from spinstrike import physics
    from spinstrike.agents.config import AgentConfigError
    from spinstrike.agents.record import record_world

    # every option of a policy's video, given: each would be ignored
    others = [flag for flag, on in (("RUN_DIR", args.run_dir), ("--env", args.env),
                                    ("--oracle", args.oracle), ("--random", args.random),
                                    ("--planner", args.planner),
                                    ("--env-kwargs", args.env_kwargs is not None),
                                    ("--episodes", args.episodes is not None),
                                    ("--seed", args.seed is not None),
                                    ("--grid", args.grid)) if on]
    if others:
        raise AgentConfigError(f"--scene: films a physics scene with no policy; it does not "
                               f"take {', '.join(others)} (it takes --out, --seconds, --dt "
                               f"and --size)")
    _fill_defaults(args, RECORD_SCENE)
    for flag, value in (("--seconds", args.seconds), ("--dt", args.dt)):
        if not (math.isfinite(value) and value > 0):
            raise AgentConfigError(f"{flag}: must be a number > 0 (got {value})")
    if args.dt > args.seconds:  # one step of --dt was filmed: 5 s simulated for --seconds 3
        raise AgentConfigError(f"--dt: a frame per step of {args.dt:g} s is longer than the "
                               f"--seconds {args.seconds:g} to film; give a smaller --dt")
    out = args.out if args.out is not None else f"{Path(str(args.scene)).stem}.mp4"
    _check_video_out(out)
    world = physics.World(args.scene)
    size = _size(args.size) if args.size else (720, 480)
    replaced = _replaces(out)
    result = record_world(world, out, seconds=args.seconds, dt=args.dt, size=size)
    print(f"video: {result['path']} ({_video_frames(result)}, "
          f"{_video_size(result, size)}; {result['contacts']} contacts){replaced}")
    return 0


def cmd_envs(args) -> int:
    from spinstrike import envs

    print(envs.describe())
    return 0


def _kernel_counts(d: dict) -> str:
    return (f"{d['files']} files, {d['bytes'] / 1e6:.1f} MB in {d['folders']} "
            f"folder{'' if d['folders'] == 1 else 's'}")


def _not_removed(failed, what: str) -> int:
    """Say on stderr what ``spinstrike cache --clear``/``--prune`` could not remove, one line
    per directory; 1 if anything (the exit status), else 0 (walk W24b F8: a read-only cache
    kept its files while ``--clear`` said they were removed, exit 0)."""
    for where, count, why in failed:
        print(f"spinstrike cache: could not remove {count} {what} in {where} ({why})",
              file=sys.stderr)
    return 1 if failed else 0


def _by_directory(failed) -> list[tuple[Path, int, str]]:
    """``[(path, why)]`` of files or folders -> ``[(the folder they are in, how many, why)]``."""
    grouped: dict[Path, list] = {}
    for path, why in failed:
        grouped.setdefault(Path(path).parent, [0, why])[0] += 1
    return [(d, n, why) for d, (n, why) in grouped.items()]


def cmd_cache(args) -> int:
    """``spinstrike cache``: the cache directory and the fallback, each with its own counts (the
    fallback only where it is in use or holds kernels); ``--clear``/``--prune`` say what they
    could not remove and exit 1 then (walk W24b F8)."""
    from spinstrike.physics.cache import (
        ENV_VAR,
        cache_info,
        clear_cache,
        prune_cache,
        prune_outdated,
    )

    if args.clear:
        removed, failed = clear_cache()
        print(f"removed {removed} cached kernel files"
              + ("; the next run recompiles (about half a minute)" if removed and not failed
                 else ""))  # (a read-only folder's kernels still load, walk W25 F11)
        return _not_removed(failed, "kernel files")
    if args.prune:
        folders, failed_folders = prune_cache()
        print(f"removed {folders} cache folders of source directories that are gone")
        files, size, failed_files = prune_outdated()
        print(f"removed {files} files ({size / 1e6:.1f} MB) of this install's kernels that its "
              "edited sources have outdated")
        return max(_not_removed(_by_directory(failed_folders), "folders of sources that are gone"),
                   _not_removed(_by_directory(failed_files), "outdated kernel files"))
    info = cache_info()
    where = (f"from {ENV_VAR}" if os.environ.get(ENV_VAR)
             else f"set {ENV_VAR} to move it")
    read_only = ("" if info["writable"]
                 else "; not writable: its kernels load, new ones go to the fallback")
    print(f"compiled kernels: {info['path']} ({_kernel_counts(info)}, one per source "
          f"directory; {where}{read_only})")
    if info["stale"]:
        print(f"{info['stale']} of them ({info['stale_bytes'] / 1e6:.1f} MB) belong to source "
              f"directories that are gone: spinstrike cache --prune removes them")
    if info["outdated"]:
        print(f"{info['outdated']} files ({info['outdated_bytes'] / 1e6:.1f} MB) are this "
              "install's kernels that its edited sources have outdated (numba names them by "
              "line, so an edit leaves them behind): spinstrike cache --prune removes them")
    fallback = info["fallback"]
    if fallback and fallback["in_use"]:
        print(f"fallback: {fallback['path']} ({_kernel_counts(fallback)}): the directory above "
              "is not writable, so the kernels it lacks compile into the fallback")
    elif fallback:
        print(f"fallback: {fallback['path']} ({_kernel_counts(fallback)}), from when the "
              "directory above was not writable; not used while it is (spinstrike cache "
              "--clear removes them)")
    return 0


def cmd_bench(args) -> int:
    import importlib

    module = importlib.import_module(f"spinstrike.benchmarks.{args.which}")
    # its usage and errors name the command typed, not python -m ...
    return int(module.main(args.rest, prog=f"spinstrike bench {args.which}") or 0)


def cmd_baselines(args) -> int:
    from spinstrike.agents.baselines import main as baselines_main

    return int(baselines_main(args.rest) or 0)


def _note_registration_changes(run: Path, meta: dict, env_kwargs: dict) -> None:
    """Say where a variant's registration (the user's module, imported again) no longer
    matches what the run recorded (``registration_changes``): the run's arguments are used;
    one its record lacks (a run recorded before the record held them) comes from the
    registration now."""
    from spinstrike.agents.config import version_changes
    from spinstrike.envs import (
        code_check,
        registration_changes,
        unread_scene_file,
        variant_kwargs,
    )

    versions = version_changes(meta.get("versions"))
    if versions:  # (walk W24b F5: said nowhere)
        print(f"note: {run} was trained with other versions than these: {'; '.join(versions)}",
              file=sys.stderr)

    changes = registration_changes(meta["env"], env_kwargs, meta.get("registered"))
    if changes:
        print(f"note: {meta['env']} is registered with other arguments than when {run} "
              f"trained: {'; '.join(changes)}; the run's are used", file=sys.stderr)
    edited, unchecked = code_check(meta["env"], meta.get("code"))
    if edited:
        print(f"note: the code of {', '.join(edited)} ({meta['env']}'s classes and the "
              f"modules of yours they import) changed since {run} trained: a run records its "
              f"arguments, not its code, so the code as it is now runs (a changed reward or "
              f"observation changes what the run is scored on)", file=sys.stderr)
    if unchecked:  # (said, not silent: walk W24b F2, F4)
        print(f"note: cannot check the code of "
              f"{'; '.join(f'{m} ({why})' for m, why in unchecked.items())} against what {run} "
              f"trained with: the code as it is now runs", file=sys.stderr)
    # (the registration as given: registered_kwargs would read its scene file a second time)
    unread = unread_scene_file(variant_kwargs(meta["env"]).get("scene"))
    if unread and "scene" in env_kwargs:  # (the run recorded its scene as read)
        print(f"note: {meta['env']} registers its scene as the file {unread!r}, not found from "
              f"{str(Path.cwd())!r} (where relative paths start), so it is not compared with "
              f"the scene {run} trained on, which is used", file=sys.stderr)


def _at_least(low: int, note: str = "", high: int | None = None):
    """An argparse type: an integer >= ``low`` (and <= ``high``; ``note`` added to the
    message)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = low - 1
        if value < low or (high is not None and value > high):
            within = f">= {low}" if high is None else f"from {low} to {high}"
            raise argparse.ArgumentTypeError(f"must be an integer {within}{note} (got {text!r})")
        return value

    return parse


#: a seed (a negative one was numpy's or Gymnasium's traceback); PyTorch threads; a number of
#: envs (0 was refused naming the hyperparameter file's n_envs, not the flag)
_seed = _at_least(0)
#: a training run's seed: SB3 seeds numpy's legacy generator, which takes 32 bits (a larger one
#: was refused as if the hyperparameter file were wrong)
_train_seed = _at_least(0, " (SB3 seeds numpy's 32-bit generator)", high=2**32 - 1)
_threads = _at_least(0, ", 0 for torch's default")
_n_envs = _at_least(1)


def _device(text: str) -> str:
    """A PyTorch device string, checked as torch parses it (``gpu`` was torch's traceback
    after the run directory was made). Without torch it is left to the command, which names
    the extra to install (argparse checks the default too: ``train`` without the train extra
    was a traceback)."""
    try:
        import torch
    except ModuleNotFoundError:
        return text
    if text == "auto":  # SB3's: cuda where there is one, else the CPU
        return text
    try:
        device = torch.device(text)
    except (RuntimeError, ValueError):
        raise argparse.ArgumentTypeError(f"not a PyTorch device (got {text!r}); e.g. cpu, "
                                         "cuda, cuda:1, mps, auto") from None
    # SB3 trains on the CPU without a word when the device asked for is not there
    there = {"cuda": torch.cuda.is_available, "mps": torch.backends.mps.is_available}
    if device.type in there and not there[device.type]():
        raise argparse.ArgumentTypeError(
            f"PyTorch {torch.__version__} sees no {device.type} device here (got {text!r}); "
            f"use cpu, or auto for {device.type} where there is one")
    if device.type == "cuda" and device.index is not None \
            and device.index >= torch.cuda.device_count():
        raise argparse.ArgumentTypeError(f"no such CUDA device (got {text!r}; "
                                         f"{torch.cuda.device_count()} here)")
    return text


def _step_count(text: str) -> int:
    """A number of steps >= 1: an integer, or a whole number written as a float (``2e6``, as
    the hyperparameter files' ``n_timesteps`` may be)."""
    try:
        return _one_or_more(int(text), text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number of steps (got {text!r})") \
            from None
    if not value.is_integer():
        raise argparse.ArgumentTypeError(f"must be a whole number of steps (got {text!r})")
    return _one_or_more(int(value), text)


def _one_or_more(steps: int, text: str) -> int:
    if steps < 1:  # (was refused naming the file's n_timesteps, not the flag)
        raise argparse.ArgumentTypeError(f"must be >= 1 step (got {text!r})")
    return steps


class _Version(argparse.Action):
    """``spinstrike --version``: the version and the commit a run's ``config.yml`` records."""

    def __call__(self, parser, namespace, values, option_string=None):
        from spinstrike.agents.config import code_version

        v = code_version()
        print(f"spinstrike {v['spinstrike']} (commit {v['spinstrike_commit']})")
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    from spinstrike.agents.config import ALGOS

    p = argparse.ArgumentParser(prog="spinstrike", description=__doc__.replace("``", "`"),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action=_Version, nargs=0,
                   help="SpinStrike's version and commit (a run's config.yml records the same: "
                   "from git; read from .git where git refuses the checkout; stamped into a "
                   "wheel at build; else 'unknown: <why>'), and exit")
    sub = p.add_subparsers(dest="command", required=True)

    t = sub.add_parser("train", help="train an SB3 agent from an rl-zoo3 hyperparameter file")
    t.add_argument("--algo", choices=ALGOS, help="default ppo (resuming: the run's)")
    t.add_argument("--env", help=f"default {DEFAULT_ENV} (resuming: the run's)")
    t.add_argument("--config", help="hyperparameter YAML (default: configs/agents/<algo>.yml)")
    t.add_argument("--seed", type=_train_seed, help="default 0 (resuming: the run's)")
    t.add_argument("--timesteps", type=_step_count, help="override n_timesteps, e.g. 2e6 as "
                   "in an rl-zoo3 file (resuming: a new budget for the run, recorded in its "
                   "config.yml)")
    t.add_argument("--n-envs", type=_n_envs, help="override n_envs")
    t.add_argument("--env-kwargs",
                   help="env constructor arguments as YAML, e.g. '{restitution: 0.8}'")
    t.add_argument("--out", help="run directory (default runs/<algo>-<env>-s<seed>)")
    t.add_argument("--resume", action="store_true",
                   help="continue --out from its last checkpoint, as its config.yml records it "
                        "(algo, env, env kwargs, hyperparameters, seed, budget); options that "
                        "contradict the record are refused")
    t.add_argument("--force", action="store_true",
                   help="replace an existing run directory, or an interrupted one "
                        "(<out>.partial)")
    t.add_argument("--device", type=_device, default="cpu",
                   help="PyTorch device: cpu (default), cuda, cuda:N, mps, or auto (SB3's: cuda "
                        "where there is one)")
    t.add_argument("--torch-threads", type=_threads, default=1,
                   help="PyTorch CPU threads (default 1: fastest for small networks; 0 = torch's "
                        "default)")
    t.add_argument("--eval-episodes", type=int, default=None,
                   help="episodes of the final evaluation (default 50; a resumed run: its "
                        "first command's)")
    t.add_argument("--no-eval", action="store_true")
    t.add_argument("--no-video", action="store_true")
    t.add_argument("--no-progress", action="store_true")
    t.add_argument("--imitate", metavar="TEACHER",
                   help="PPO: start the policy from a teacher's behaviour by DAgger before "
                        "training (planner | reactive-planner | chase-and-hit; "
                        "agents/imitate.py)")
    t.add_argument("--imitate-rounds", type=int, default=None,
                   help="DAgger rounds (default 20; round 0 is the teacher's)")
    t.add_argument("--imitate-episodes", type=int, default=None,
                   help="episodes per DAgger round (default 16)")
    t.add_argument("--backend", choices=("sb3", "rllib"), default=None,
                   help="sb3 (default; resuming: the run's) or rllib: PPO with Ray RLlib (the "
                        "rllib extra; docs/rllib.md)")
    t.add_argument("--num-env-runners", type=int, default=None,
                   help="rllib: env runner processes (default 2; resuming: the run's)")
    t.add_argument("--address", help="rllib: a running Ray cluster's address (default: a "
                                     "local Ray)")
    t.set_defaults(func=cmd_train)

    for name, func, helptext in (
            ("evaluate", cmd_evaluate, "mean +/- std return vs random and the oracle (control "
             "envs: and what their hits gained and lost)"),
            ("record", cmd_record, "film a run's policy, the oracle or the planner: an mp4 "
             "(or a GIF) of every rendered frame")):
        e = sub.add_parser(name, help=helptext)
        e.add_argument("run_dir", nargs="?")
        e.add_argument("--env")
        who = e.add_mutually_exclusive_group()  # (--oracle --random filmed random silently)
        who.add_argument("--oracle", action="store_true")
        who.add_argument("--planner", action="store_true",
                         help="the CEM planner (control envs; agents/planner.py)")
        who.add_argument("--random", action="store_true", help="uniformly random actions")
        e.add_argument("--env-kwargs", help="with --oracle, --random or --planner: env "
                       "arguments as YAML, e.g. '{restitution: 0.8}' (a run uses its own)")
        if name == "evaluate":
            e.add_argument("--episodes", type=int, default=50)
            e.add_argument("--seed", type=_seed, default=1000,
                           help="episode k is reset with seed SEED + k, for every policy "
                                "(default 1000; the learning curve's evaluations use one env "
                                "seeded 10000 instead)")
            e.add_argument("--json", action="store_true",
                           help="print the scores as one JSON object")
            e.add_argument("--no-save", action="store_true",
                           help="leave a run's summary.md and summary.json as they are")
        else:
            e.add_argument("--out", help="video file, .mp4 or .gif, replaced if there, its "
                           "folders made if missing "
                           "(default: rollout.mp4 in the run directory; else, in the working "
                           "folder, oracle-ENV.mp4, random-, planner- or the --scene's name)")
            e.add_argument("--episodes", type=int,
                           help=f"default {RECORD_POLICY['--episodes']} (not with --scene)")
            e.add_argument("--seed", type=_seed,
                           help=f"default {RECORD_POLICY['--seed']} (not with --scene)")
            e.add_argument("--grid", action="store_true",
                           help="tile the episodes in one video, played side by side")
            e.add_argument("--size", help="WIDTHxHEIGHT of an episode's frames (default: the "
                           "env's render_size, 720x480)")
            e.add_argument("--scene", help="film a physics scene instead (a packaged scene's "
                           "name, e.g. break, or a YAML path): a frame per --dt step for "
                           "--seconds, no policy")
            e.add_argument("--seconds", type=float,
                           help=f"--scene: simulated seconds (default: "
                           f"{RECORD_SCENE['--seconds']})")
            e.add_argument("--dt", type=float,
                           help=f"--scene: step, s; the video plays in real time "
                           f"(default: {RECORD_SCENE['--dt']})")
        e.set_defaults(func=func)

    s = sub.add_parser("envs", help="list the environments")
    s.set_defaults(func=cmd_envs)

    c = sub.add_parser("cache", help="where the compiled physics kernels are cached; --clear "
                       "empties the cache")
    # one or the other: --clear --prune cleared and ignored --prune
    what = c.add_mutually_exclusive_group()
    what.add_argument("--clear", action="store_true", help="remove every cached kernel")
    what.add_argument("--prune", action="store_true",
                   help="remove the kernels no run will load again: those of source "
                        "directories that are gone (deleted clones, virtual environments) and "
                        "this install's that its edited sources have outdated")
    c.set_defaults(func=cmd_cache)

    b = sub.add_parser("bench", help="benchmarks: accuracy vs time, speed")
    b.add_argument("which", choices=("accuracy", "speed"),
                   help="accuracy: error against time per collision beside pymunk; speed: "
                        "throughput beside pymunk and CartPole")
    b.add_argument("rest", nargs=argparse.REMAINDER, metavar="...",
                   help="the benchmark's own options (spinstrike bench accuracy --help)")
    b.set_defaults(func=cmd_bench)

    r = sub.add_parser("baselines", help="train the baseline matrix and write docs/baselines.md")
    r.add_argument("rest", nargs=argparse.REMAINDER)
    r.set_defaults(func=cmd_baselines)
    return p


def _dispatch(args) -> int:
    if args.command in ("evaluate", "record"):
        from spinstrike.agents.imitate import _sigterm_exits

        # SIGTERM as Ctrl-C: the unfinished video is removed (a *.partial.mp4 was left)
        with _sigterm_exits():
            return args.func(args)
    return args.func(args)


@contextlib.contextmanager
def _deprecations_once():
    """Gymnasium's deprecation of an env id (``PuckSpeed-v0``), once and as plain text. Its
    "once" filter forgets what it showed whenever a library changes the warning filters (SB3
    and the recorder do), so a run printed it four times, in terminal colour codes."""
    import warnings

    shown = set()
    show = warnings.showwarning

    def showwarning(message, category, filename, lineno, file=None, line=None):
        text = re.sub(r"\x1b\[[0-9;]*m", "", str(message))
        if not issubclass(category, DeprecationWarning) or "gymnasium" not in filename:
            return show(message, category, filename, lineno, file, line)
        if text not in shown:
            shown.add(text)
            print(f"warning: {text.removeprefix('WARN: ')}", file=sys.stderr)
        return None

    warnings.showwarning = showwarning
    try:
        yield
    finally:
        warnings.showwarning = show


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["baselines"]:  # argparse's REMAINDER would refuse a leading --option
        args = parser.parse_args(["baselines"])
        args.rest = argv[1:]
    else:
        args = parser.parse_args(argv)
    from spinstrike.agents.config import AgentConfigError
    from spinstrike.envs.config import ConfigError
    from spinstrike.physics import SceneError

    args.argv = argv  # what command.txt records (main's own argv, not the interpreter's)
    if getattr(args, "env", None):  # gym.make's module-qualified id, as the README shows it
        args.env = args.env.removeprefix("spinstrike:")
    # a variant's registering module ("mylab:MyLab/Heavy-v0") may sit in the working directory,
    # which a console script does not put on sys.path (python -m does, first); last, so that it
    # shadows nothing installed
    if os.getcwd() not in sys.path and "" not in sys.path:
        sys.path.append(os.getcwd())
    try:
        with _deprecations_once():
            return _dispatch(args)
    except KeyboardInterrupt:  # evaluate, record: no traceback (train returns 130 itself)
        print(f"spinstrike {args.command}: interrupted", file=sys.stderr)
        return 128 + 2
    except SystemExit as exc:  # evaluate, record: SIGTERM (_dispatch) ended them in silence
        if args.command not in ("evaluate", "record") or exc.code != 128 + signal.SIGTERM:
            raise
        print(f"spinstrike {args.command}: interrupted (SIGTERM)", file=sys.stderr)
        return exc.code
    except (AgentConfigError, ConfigError, SceneError) as exc:
        print("error: " + " ".join(str(exc).split()), file=sys.stderr)  # on one line
        return 2
    except OSError as exc:  # a path that cannot be written (a file where a folder goes, ...)
        if exc.filename is None:
            raise
        where = (" (a file, where the path needs a folder)"
                 if isinstance(exc, (FileExistsError, NotADirectoryError)) else "")
        print(f"error: {exc.filename}: {exc.strerror}{where}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:  # an optional dependency: name the extra, not a traceback
        top = (exc.name or "").split(".")[0]
        if top not in EXTRA_OF:
            raise
        extra = "bench" if args.command == "bench" and top == "matplotlib" else EXTRA_OF[top]
        print("error: " + _needs_extras(args.command, [top], [extra],
                                        cpu_torch=extra in ("train", "rllib")), file=sys.stderr)
        return 2


#: what ``spinstrike train`` uses, each brought by the train extra (SB3's TensorBoard logger and
#: progress bar, the learning-curve plot, the video): checked before anything trains. The zoo
#: extra brings SB3 alone: train died in SB3's "tensorboard is not installed" assertion, and
#: with tensorboard added it trained the whole budget and lost the run to the missing plot
TRAIN_MODULES = dict.fromkeys(("stable_baselines3", "torch", "tensorboard", "tqdm", "rich",
                               "matplotlib", "pygame", "moviepy", "imageio_ffmpeg", "PIL"),
                              "train")


def _require_extra(command: str, modules: dict[str, str]) -> None:
    """Refuse ``spinstrike COMMAND`` where a module it uses (``modules``: each with the extra
    that brings it) is not installed, naming every missing module and the extras."""
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        from spinstrike.agents.config import AgentConfigError

        raise AgentConfigError(_needs_extras(command, missing,
                                             sorted({modules[m] for m in missing}),
                                             cpu_torch="torch" in missing))


def _require_video(out: str) -> None:
    """Refuse ``spinstrike record`` without what draws and writes its video (pygame, and
    imageio-ffmpeg for an mp4 or Pillow for a GIF), before the film's kernels compile (it
    compiled for up to a minute, then named the render extra)."""
    _require_extra("record", {"pygame": "render",
                              ("PIL" if out.lower().endswith(".gif") else "imageio_ffmpeg"):
                              "render"})


def _needs_extras(command: str, missing: list[str], extras: list[str], cpu_torch: bool) -> str:
    """``spinstrike COMMAND needs ...``: the missing modules, the extras that bring them and
    the ``pip install`` (with CPU-only PyTorch first where ``cpu_torch``)."""
    from spinstrike.agents.config import CPU_TORCH_FIRST

    return (f"spinstrike {command} needs {', '.join(missing)}, which "
            f"{'comes' if len(missing) == 1 else 'come'} with the "
            f"{' and '.join(repr(e) for e in extras)} extra{'s' if len(extras) > 1 else ''}: "
            f"pip install \"spinstrike[{','.join(extras)}]\""
            + (f" {CPU_TORCH_FIRST}" if cpu_torch else ""))


#: the extra that brings each optional module the commands import
EXTRA_OF = {"stable_baselines3": "train", "torch": "train", "tensorboard": "train",
            "tqdm": "train", "rich": "train", "matplotlib": "train", "pygame": "render",
            "moviepy": "render", "imageio_ffmpeg": "render", "PIL": "render", "mpmath": "bench",
            "rliable": "stats", "pandas": "stats", "rl_zoo3": "zoo", "ray": "rllib"}


if __name__ == "__main__":
    sys.exit(main())
