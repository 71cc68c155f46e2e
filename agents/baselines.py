"""The baseline matrix: every env x PPO, SAC, TD3 x seeds, beside random and the oracle, and the
accuracy-transfer study; writes ``docs/baselines.md`` and learning-curve plots.

    spinstrike baselines            # the full matrix, 5 seeds (about 3 hours on 2 cores)
    spinstrike baselines --quick    # one seed, a tenth of the budgets (a smoke test, in
                                    # runs/baselines-quick: docs/ is left alone)
    spinstrike baselines --envs SpinStrike/RodSpin-v0 --algos ppo --seeds 0 1 2 3 4

Runs live in ``runs/baselines/<algo>-<env>-s<seed>`` and finished ones are reused, so an
interrupted matrix picks up where it stopped; only if trained on what the report would train
now, though: a run whose ``config.yml`` records other env arguments (a variant's registration
edited since) or other hyperparameters (``configs/agents/*.yml`` edited) is trained again, and
``--reuse-only`` refuses it. Every agent is evaluated on the same 50 episodes
(seeds 1000..1049) as the random policy and the oracle, and its learning curve on the same 10
episodes at every point. Results are reported as the field does (``agents.stats``, needs
``spinstrike[stats]``): the interquartile mean over seeds with a 95% stratified-bootstrap
confidence interval, beside mean +/- std; curves as IQM with its bootstrap band.

The document's generated part sits between two marker comments (:data:`BEGIN`, :data:`END`); a
rerun replaces only that part, so notes written above or below it by hand (budgets, analyses)
are kept.

*Does accuracy matter for learning?* PPO is trained on ``RodSpin-v0`` with the ``fixed`` solver
(1 substep per chunk) and with pymunk, and every agent is then evaluated on the ``exact`` solver,
beside agents trained on ``exact``, with the wall time each training took.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from spinstrike import envs
from spinstrike.agents.config import (
    ALGOS,
    env_file_name,
    load_agent_config,
    run_record,
    short_value,
)
from spinstrike.agents.config import commit as _commit
from spinstrike.benchmarks import cpu_model

__all__ = ["main"]

EVAL_EPISODES = 50
TRANSFER_SOLVERS = {"exact": None, "fixed (1 substep)": {"mode": "fixed", "substeps": 1},
                    "pymunk (10 steps, 10 iterations)": {"mode": "pymunk", "substeps": 10,
                                                        "iterations": 10}}


def _machine() -> str:
    model = cpu_model() or "unknown CPU"
    import stable_baselines3
    import torch

    return (f"{os.cpu_count()} cores ({model}), Python {platform.python_version()}, "
            f"torch {torch.__version__}, stable-baselines3 {stable_baselines3.__version__}")


def _name(algo: str, env_id: str, tag: str, seed: int) -> str:
    return f"{algo}-{env_file_name(env_id)}{tag}-s{seed}"


def _scores(run: Path, env_id: str) -> dict:
    """The finished run's policy on the :data:`EVAL_EPISODES` evaluation episodes, always on
    the exact solver (the transfer study trains on others)."""
    from spinstrike.agents.evaluate import load_model_policy, run_episodes

    policy, _ = load_model_policy(run)
    ev = run_episodes(policy, env_id, EVAL_EPISODES, name="agent")
    return {"mean": ev.mean, "std": ev.std, "returns": ev.returns}


def _trained_otherwise(run: Path, env_id: str, planned: dict, where: str,
                       scale: float) -> list[str]:
    """How the finished ``run`` was trained otherwise than this report would train it now:
    its ``config.yml``'s env arguments (a variant's registered ones among them) and
    hyperparameters against ``planned`` (``train.new_run_record``: the current registration
    and hyperparameter file, with this report's budget scaling and warm-up). A run without
    the record (before config.yml, or one that cannot be read) has nothing to compare, and a
    variant's argument its record lacks (recorded before its registration was, 2026-11-28) is
    not known: both are kept as they were; so is the code of a module whose digest cannot be
    compared (``envs.compare_code``: recorded with an older digest scheme, a source not
    readable), said in a note (an identical ``mylab.py`` read as changed, and ``--reuse-only``
    refused the run, walk W24b F4)."""
    from spinstrike.envs import compare_code, flat_kwargs

    meta = run_record(run / "config.yml")
    recorded = meta.get("hyperparameters", {}).get(env_id)
    if not isinstance(recorded, dict):
        return []
    recorded = dict(recorded)
    now = dict(planned["hyperparameters"][env_id])
    then_kwargs = flat_kwargs(recorded.pop("env_kwargs", None) or {})
    now_kwargs = now.pop("env_kwargs", None) or {}
    registered_now = planned.get("registered") or {}
    registered_then = meta.get("registered")
    changes = []
    for key in dict.fromkeys([*then_kwargs, *now_kwargs]):
        if key not in then_kwargs and registered_then is None and key in registered_now:
            continue
        if then_kwargs.get(key, _NONE) == now_kwargs.get(key, _NONE):
            continue
        by = ("the registration now gives" if key in registered_now
              or key in (registered_then or {}) else "this report now gives")
        changes.append(_change(key, then_kwargs, now_kwargs, by))
    # (a run recorded before 2026-11-29 has none to compare)
    changed, unchecked = compare_code(meta.get("code"), planned.get("code") or {})
    changes += [f"trained with the code of {module} as it was then (it changed since)"
                for module in changed]
    if unchecked:  # reused, as a run with no digest is: not known to differ (walk W24b F4)
        print(f"note: {run}: cannot check the code of "
              f"{'; '.join(f'{m} ({why})' for m, why in unchecked.items())}; reused if nothing "
              f"else changed (delete the run to train it again)", flush=True)
    for key in dict.fromkeys([*recorded, *now]):
        if recorded.get(key, _NONE) != now.get(key, _NONE):
            scaled = f" scaled by {scale:g}" if scale != 1 and key in (
                "n_timesteps", "learning_starts") else ""
            changes.append(_change(key, recorded, now, f"{where}{scaled} now gives"))
    return changes


_NONE = object()


def _change(key: str, then: dict, now: dict, by: str) -> str:
    was = f"with {key} {short_value(then[key])}" if key in then else f"without {key}"
    return f"trained {was}, {by} {short_value(now[key]) if key in now else 'none'}"


#: the commit each result of this report was scored at (``baseline.json``'s ``evaluated_at``):
#: a reused run scored at another commit is named under the report (walk W24b F5: "Code at
#: commit f9f22c9" stood over runs trained and scored at f9f22c9+dirty)
_SCORED_AT: dict[str, int] = {}


def _run(*args, **kwargs) -> dict:
    """:func:`_run_once`, its result's commit counted in ``_SCORED_AT``."""
    out = _run_once(*args, **kwargs)
    at = str(out.get("evaluated_at", "unknown (before 2026-11)"))
    _SCORED_AT[at] = _SCORED_AT.get(at, 0) + 1
    return out


def _scored_elsewhere(commit: str) -> str:
    """The report's last words on the runs scored at another commit than ``commit``."""
    other = {at: n for at, n in _SCORED_AT.items() if at != commit}
    if not other:
        return ""
    return (" Runs scored at other commits (reused; `--re-evaluate` scores them with this "
            "code): " + ", ".join(f"{n} at {at}" for at, n in sorted(other.items())) + ".")


def _run_once(algo, env_id, seed, root: Path, scale: float, env_kwargs=None, tag="",
              imitate: str | None = None, re_evaluate: bool = False,
              reuse_only: bool = False) -> dict:
    """One run of the matrix: the finished one under ``root`` if it was trained as this
    report would train it now (else trained again, or with ``reuse_only`` refused), else
    trained; scored on the evaluation episodes (again with ``re_evaluate``)."""
    from spinstrike.agents.train import new_run_record, train

    name = _name(algo, env_id, tag, seed)
    run = root / name
    result_file = run / "baseline.json"
    cfg = load_agent_config(algo, env_id)
    steps = max(int(cfg.n_timesteps * scale), 256)
    rounds = {} if imitate is None or scale >= 1 else {"imitate_rounds": 2,
                                                       "imitate_episodes": 2}
    # a scaled budget scales the off-policy warm-up too: --quick's SAC and TD3 (6,000 and 8,000
    # steps on the control envs) never reached learning_starts (10,000) and never trained
    warm_up = ({"learning_starts": int(cfg.raw["learning_starts"] * scale)}
               if scale < 1 and "learning_starts" in cfg.raw else None)
    if result_file.exists():
        out = json.loads(result_file.read_text())
        if out.get("scale", 1.0) != scale:  # runs before the key were full runs
            raise SystemExit(f"{run}: trained with budgets scaled by {out.get('scale', 1.0)}, "
                             f"this report asks for {scale}; pass another --root (a --quick "
                             "run's default is runs/baselines-quick)")
        if out.get("env", env_id) != env_id:
            raise SystemExit(f"{run}: holds a run of {out['env']}, not of {env_id}; pass "
                             "another --root")
        # reused only if trained on what this report would train now: an edit of the
        # variant's registration or of the hyperparameter file reported the old run's score
        # beside random and the oracle on the new env (and --re-evaluate scored its model there)
        planned = new_run_record(algo, env_id, timesteps=steps, env_kwargs=env_kwargs,
                                 hyperparameters=warm_up)
        changes = _trained_otherwise(run, env_id, planned, cfg.where or cfg.source, scale)
        if not changes:
            if re_evaluate:  # the same model, scored by the current code (e.g. a physics fix)
                out.update(_scores(run, env_id), evaluated_at=_commit())
                result_file.write_text(json.dumps(out))
            return out
        if reuse_only:
            raise SystemExit(f"{run}: {'; '.join(changes)}, so this report would train it "
                             f"again, and --reuse-only trains nothing: run without "
                             f"--reuse-only to train it again, put the registration or the "
                             f"hyperparameters back, or pass another --root")
        print(f"{run}: {'; '.join(changes)}: training it again", flush=True)
    res = train(algo, env_id, seed=seed, timesteps=steps, out=run, force=True, progress=False,
                evaluate=False, video=False, env_kwargs=env_kwargs, imitate=imitate,
                hyperparameters=warm_up, **rounds)
    dagger = 0.0
    if imitate is not None:  # DAgger's wall time, before PPO's (``res["wall_time"]``)
        import csv

        with open(run / "imitation.csv") as f:
            dagger = sum(float(r["wall_time_s"]) for r in csv.DictReader(f))
    out = {"algo": algo, "env": env_id, "seed": seed, "scale": scale,
           "timesteps": res["timesteps"],
           "wall_time": res["wall_time"], "tag": tag, "imitate": imitate,
           "dagger_wall_time": dagger, **_scores(run, env_id), "evaluated_at": _commit()}
    result_file.write_text(json.dumps(out))
    return out


def _curves(env_id: str, root: Path, algos, seeds, out: Path, imitate: str | None = None) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from spinstrike.agents.stats import curve_bands

    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    series = [(algo, "", algo.upper()) for algo in algos]
    if imitate is not None:
        series.append(("ppo", f"-imitate-{imitate}", f"PPO after DAgger from the {imitate}"))
    for algo, tag, label in series:
        curves = []
        for seed in seeds:
            f = root / _name(algo, env_id, tag, seed) / "evaluations.npz"
            if f.exists():
                d = np.load(f)
                curves.append((d["timesteps"], d["results"].mean(1)))
        if not curves:
            continue
        n = min(len(c[0]) for c in curves)
        steps = curves[0][0][:n]
        values = np.array([c[1][:n] for c in curves])
        mid, low, high = curve_bands(values)
        ax.plot(steps, mid, label=f"{label} (IQM, {len(curves)} seeds)")
        ax.fill_between(steps, low, high, alpha=0.2)
    ax.set_title(f"{env_id}: evaluation during training\n(IQM over seeds, 95% bootstrap band)",
                 fontsize=10)
    ax.set_xlabel("timesteps")
    ax.set_ylabel("mean episode return")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:  # nothing drawn when no seed has run yet
        ax.legend()
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _row(label: str, means: np.ndarray, reference: float, extra: str) -> str:
    """A table row: IQM [95% CI], mean +/- std, IQM as a fraction of the reference."""
    from spinstrike.agents.stats import summary

    st = summary(means)
    frac = f"{st['iqm'] / reference:.3f}" if reference > 0 else "-"
    return (f"| {label} | {st['iqm']:.3f} [{st['iqm_low']:.3f}, {st['iqm_high']:.3f}] | "
            f"{st['mean']:.3f} +/- {st['std']:.3f} | {frac} | {st['runs']} | {extra}")


def _seeds_row(label: str, algo: str, env_id: str, args, root: Path, scale: float, seeds,
               reference: float, imitate: str | None = None) -> str:
    """One agent's table row over ``seeds`` (training the seeds not run yet; ``--reuse-only``
    reports the finished ones only). With ``imitate``: PPO started from that teacher by DAgger
    (``spinstrike train --imitate``), its runs tagged apart, DAgger's wall time beside PPO's."""
    tag = "" if imitate is None else f"-imitate-{imitate}"
    todo = seeds
    if args.reuse_only:  # report the finished runs only (a budget-limited document)
        todo = [s for s in seeds if (root / _name(algo, env_id, tag, s) / "baseline.json")
                .exists()]
        if not todo:
            return f"| {label} | not run in this budget | - | - | 0 | - | - |"
    results = [_run(algo, env_id, s, root, scale, tag=tag, imitate=imitate,
                    re_evaluate=args.re_evaluate, reuse_only=args.reuse_only) for s in todo]
    means = np.array([r["mean"] for r in results])
    wall = f"{np.mean([r['wall_time'] for r in results]):.0f} s"
    if imitate is not None:
        wall = f"{np.mean([r['dagger_wall_time'] for r in results]):.0f} s DAgger + {wall} PPO"
    row = _row(label, means, reference, f"{results[0]['timesteps']} | {wall} |")
    print(f"{env_id} {algo}{tag}: {row}", flush=True)
    return row


def _planner_row(env_id: str, episodes: int, reference: float) -> str:
    """The CEM planner (defaults of ``agents.planner.CEMPlanner``) on the first ``episodes``
    of the evaluation episodes, with its CPU time per decision."""
    from spinstrike.agents.planner import CEMPlanner, timed_episodes

    ev, cost = timed_episodes(CEMPlanner(), env_id, episodes, 1000)
    print(f"{env_id} planner: {ev.mean:.3f} ({cost:.0f} ms CPU per decision)", flush=True)
    return (f"| CEM planner (first {episodes} episodes) | - | {ev.mean:.3f} +/- {ev.std:.3f} | "
            f"{ev.mean / reference:.3f} | - | - | {cost:.0f} ms CPU per decision |")


def _registration(env_id: str) -> list[str]:
    """A variant's section says the arguments it is registered with (two registrations of
    one name, before and after an edit, read alike); nothing for a shipped id."""
    if env_id.rpartition(":")[2] in envs.ENV_IDS:
        return []
    given = envs.variant_kwargs(env_id)
    what = (", ".join(f"{key} {short_value(value)}" for key, value in given.items())
            if given else "none")
    return [f"Registered arguments: {what} (over {envs.base_id(env_id)}'s defaults).", ""]


#: the generated part of the document lies between these lines; the rest is kept on a rerun
BEGIN = "<!-- generated by `spinstrike baselines`: a rerun replaces this part -->"
END = "<!-- end of the generated part: what follows is written by hand and kept -->"


def write_doc(doc: Path, generated: str, begin: str = BEGIN, end: str = END,
              option: str = "--doc") -> None:
    """Write ``generated`` into ``doc`` between the markers ``begin`` and ``end`` (default
    :data:`BEGIN`, :data:`END`), keeping what an existing ``doc`` has around them. A file
    with text but without the markers is refused (it was replaced: a user's own notes given
    as ``--doc`` were lost), as is one with only one of them, or either twice, rather than
    guessed at (``option`` names the command's option for another file)."""
    before, after = "", "\n"
    if doc.exists():
        old = doc.read_text()
        counts = old.count(begin), old.count(end)
        if counts == (0, 0) and old.strip():
            raise SystemExit(f"{doc}: has text but no markers of a generated part, so it is not "
                             f"replaced; pass another {option}, or put the lines {begin!r} and "
                             f"{end!r} where the generated part goes")
        if counts != (0, 0):
            if counts != (1, 1) or old.index(begin) > old.index(end):
                raise SystemExit(f"{doc}: expected the markers {begin!r} and {end!r} once each, "
                                 f"in that order; fix the file or pass another {option}")
            before = old[:old.index(begin)]
            after = old[old.index(end) + len(end):]
    doc.parent.mkdir(parents=True, exist_ok=True)
    doc.write_text(f"{before}{begin}\n{generated.rstrip()}\n{end}{after}")


#: ids the matrix runs by default (PuckSpeed-v0 is kept for old runs only)
DEFAULT_ENVS = [e for e in envs.ENV_IDS if e != "SpinStrike/PuckSpeed-v0"]


def main(argv: list[str] | None = None) -> int:
    from spinstrike.agents.cli import _at_least, _train_seed

    p = argparse.ArgumentParser(prog="spinstrike baselines",
                                description=" ".join(__doc__.split("\n\n")[0].split()))
    p.add_argument("--envs", nargs="+", default=DEFAULT_ENVS, metavar="ID",
                   help=f"shipped ids ({', '.join(envs.ENV_IDS)}) or variants registered with "
                        "gym.register in a module of your own, as 'module:Namespace/Name-vN' "
                        "(default: the shipped ids but PuckSpeed-v0)")
    p.add_argument("--algos", nargs="+", default=list(ALGOS), choices=ALGOS)
    p.add_argument("--seeds", nargs="+", type=_train_seed, default=[0, 1, 2, 3, 4])
    p.add_argument("--quick", action="store_true",
                   help="one seed, a tenth of each budget and of SAC's and TD3's "
                        "learning_starts (a smoke test: its runs and report go to "
                        "runs/baselines-quick unless --root/--doc say otherwise)")
    p.add_argument("--root", default=None,
                   help="where the runs are trained and reused (default: runs/baselines, or "
                        "runs/baselines-quick with --quick)")
    p.add_argument("--doc", default=None,
                   help="the report to write (default: docs/baselines.md, or ROOT/baselines.md "
                        "with --quick); only its generated part is replaced")
    p.add_argument("--no-transfer", action="store_true")
    p.add_argument("--reuse-only", action="store_true",
                   help="train nothing: report the finished runs under --root (and say which "
                        "were not run); one trained on other env arguments or hyperparameters "
                        "than this report's is refused")
    p.add_argument("--re-evaluate", action="store_true",
                   help="score the finished runs again with the current code (their models "
                        "as they are), e.g. after a change to the physics")
    p.add_argument("--imitate", metavar="TEACHER", default=None,
                   help="also train PPO started from TEACHER by DAgger on each control env "
                        "(spinstrike train --imitate; a row of its own)")
    p.add_argument("--planner-episodes", type=_at_least(0), default=20,
                   help="episodes of the CEM planner on each control env (0: none)")
    args = p.parse_args(argv)
    from spinstrike.agents.config import CPU_TORCH_FIRST, AgentConfigError, check_env_id
    from spinstrike.agents.evaluate import evaluate
    from spinstrike.agents.stats import _rliable

    # training needs SB3 (the train extra), the report's intervals rliable (stats): both said
    # at once, before anything trains (one extra named, then the next after its install)
    missing = [extra for module, extra in (("stable_baselines3", "train"), ("rliable", "stats"))
               if importlib.util.find_spec(module) is None]
    if missing:
        raise AgentConfigError(
            f"spinstrike baselines trains with stable-baselines3 ('train' extra) and reports "
            f"confidence intervals with rliable ('stats' extra); missing: {missing}: pip install "
            f"\"spinstrike[{','.join(missing)}]\""
            + (f" {CPU_TORCH_FIRST}" if "train" in missing else ""))
    try:
        _rliable()
    except ImportError as exc:
        raise AgentConfigError(str(exc)) from None

    # each id checked before anything trains; a variant is a control env if its class is one
    control = {e: "Control" in check_env_id(e, "--envs") for e in args.envs}
    if args.imitate is not None:
        from spinstrike.agents.imitate import check_teacher

        check_teacher(args.imitate)
        if not any(control.values()):
            raise AgentConfigError(f"--imitate: adds a row on the control envs only, and none "
                                   f"is among --envs {' '.join(args.envs)}")

    scale = 0.1 if args.quick else 1.0
    seeds = args.seeds[:1] if args.quick else args.seeds
    root = Path(args.root or ("runs/baselines-quick" if args.quick else "runs/baselines"))
    doc = Path(args.doc) if args.doc else (root / "baselines.md" if args.quick
                                           else Path("docs/baselines.md"))
    started = time.time()
    _SCORED_AT.clear()
    load0 = os.getloadavg()[0]
    # this process adds ~1 once it trains: a load already near 1 means another job is running
    shared = ": other jobs shared the cores, so wall times are upper bounds" if load0 >= 0.5 else ""
    lines = ["# Baselines", "",
             f"Produced by `{shlex.join(['spinstrike', 'baselines', *(argv or sys.argv[1:])])}` "
             f"on {_machine()} (load average at start {load0:.2f}{shared}); "
             f"{len(seeds)} seed(s) per algorithm, budgets from "
             f"`configs/agents/*.yml`{' scaled by 0.1 (--quick)' if args.quick else ''}. Every "
             f"policy is evaluated on the same {EVAL_EPISODES} episodes (seeds 1000..1049, "
             "deterministic actions, exact solver). Each seed's score is its mean return over "
             "them; the table gives the interquartile mean (IQM) of the seeds' scores with its "
             "95% stratified-bootstrap confidence interval (rliable, 2000 replications), their "
             "mean +/- std, and the IQM as a fraction of the reference (the oracle; for the "
             "control envs the scripted chase-and-hit). Random and reference: over episodes. "
             "Learning curves: IQM over seeds of the mean return on the same 10 episodes at "
             "every point, with its 95% bootstrap band.", ""]
    table: dict[str, list[str]] = {}
    for env_id in args.envs:
        rows = []
        base = {r.policy: r for r in evaluate(env_id, None, EVAL_EPISODES, 1000)}
        reference = base["oracle"].mean
        for algo in args.algos:
            rows.append(_seeds_row(algo.upper(), algo, env_id, args, root, scale, seeds,
                                   reference))
        if args.imitate is not None and control[env_id]:
            rows.append(_seeds_row(f"PPO from the {args.imitate} (DAgger)", "ppo", env_id, args,
                                   root, scale, seeds, reference, imitate=args.imitate))
        oracle = "scripted chase-and-hit" if control[env_id] else "oracle (closed form)"
        for label, key in (("random", "random"), (oracle, "oracle")):
            r = base[key]
            frac = f"{r.mean / reference:.3f}" if reference > 0 else "-"
            rows.append(f"| {label} | - | {r.mean:.3f} +/- {r.std:.3f} | {frac} | - | - | - |")
        if control[env_id] and args.planner_episodes > 0:
            rows.append(_planner_row(env_id, args.planner_episodes, reference))
        plot = _curves(env_id, root, args.algos, seeds,
                       doc.parent / "baselines" / f"{env_file_name(env_id)}.png",
                       args.imitate if control[env_id] else None)
        table[env_id] = rows
        lines += [f"## {env_id}", "", *_registration(env_id),
                  "| policy | IQM [95% CI] | mean +/- std | IQM / reference | seeds | "
                  "timesteps | train wall time |", "|---|---|---|---|---|---|---|", *rows, "",
                  f"![learning curves]({plot.relative_to(doc.parent).as_posix()})", ""]
    if not args.no_transfer and "SpinStrike/RodSpin-v0" in args.envs:
        lines += ["## Does accuracy matter for learning?", "",
                  "PPO on `SpinStrike/RodSpin-v0`, trained with each solver, all evaluated on the "
                  "exact solver:", "",
                  "| trained on | IQM [95% CI] | mean +/- std | IQM / oracle | seeds | "
                  "train wall time |", "|---|---|---|---|---|---|"]
        for label, solver in TRANSFER_SOLVERS.items():
            tag = "" if solver is None else "-" + solver["mode"]
            kwargs = None if solver is None else {"solver": solver}
            results = [_run("ppo", "SpinStrike/RodSpin-v0", s, root, scale, kwargs, tag,
                            re_evaluate=args.re_evaluate, reuse_only=args.reuse_only)
                       for s in seeds]
            means = np.array([r["mean"] for r in results])
            lines.append(_row(label, means, 1.0,
                              f"{np.mean([r['wall_time'] for r in results]):.0f} s |"))
            print(f"transfer {label}: {means.mean():.3f}", flush=True)
        lines.append("")
    commit = _commit()
    lines.append(f"Total wall time of this run: {time.time() - started:.0f} s (reused runs "
                 f"count as 0); load average at the end {os.getloadavg()[0]:.2f}. Code at commit "
                 f"{commit}.{_scored_elsewhere(commit)}")
    write_doc(doc, "\n".join(lines))
    print(f"wrote {doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
