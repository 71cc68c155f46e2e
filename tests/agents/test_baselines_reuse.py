"""``spinstrike baselines`` reuses a finished run under ``--root`` only if it was trained on what
the report would train now (W18a F2): the run's recorded env arguments (a variant's registered
ones among them) and hyperparameters against the current registration and hyperparameter
file. A variant whose registration was edited between two reports (restitution 0.95 -> 0.2) was
reported with the old run's score beside random and the oracle of the new registration, and
``--re-evaluate`` scored the old model on the new registration; an edited hyperparameter file
went unnoticed too. Now such a run is trained again, saying which and what changed, and
``--reuse-only`` (which trains nothing) refuses naming it. An unchanged one is still reused.

The hyperparameter file is the packaged one (``configs/agents/ppo.yml``), looked up in a copy
with a tiny budget here: editing the shipped file would change the runs of the other tests.
"""

import json

import pytest
import yaml

from spinstrike.agents import config as agent_config
from spinstrike.agents.cli import main

pytest.importorskip("rliable")

MODULE = "spinstrike_reuse_lab"
VARIANT = f"{MODULE}:ReuseLab/EditRod-v0"
RUN = "ppo-ReuseLab-EditRod-v0-s0"
# 2,560 steps scaled by --quick's 0.1: one rollout of 4 x 64 steps
TINY = {"n_timesteps": 2560, "policy": "MlpPolicy", "n_envs": 4, "n_steps": 64,
        "batch_size": 128, "n_epochs": 1, "gamma": 0.0, "learning_rate": 3.0e-4,
        "policy_kwargs": {"net_arch": [16]}}


@pytest.fixture
def ppo_yml(tmp_path, monkeypatch):
    """The packaged ``ppo.yml``, as a tiny copy the test edits: ``write(**changes)``."""
    path = tmp_path / "ppo.yml"

    def write(**changes):
        path.write_text(yaml.safe_dump({"SpinStrike/RodSpin-v0": {**TINY, **changes}}))

    write()
    monkeypatch.setattr(agent_config, "packaged_config_path", lambda algo: path)
    return write


def _register(user_module, restitution):
    """The user's module, registering the variant with ``restitution`` (edited between the
    reports as a user edits it, then imported again by the next ``spinstrike baselines``)."""
    return _write_module(user_module, "ReuseLab/EditRod-v0", (
        "import gymnasium as gym\n"
        "gym.register('ReuseLab/EditRod-v0', entry_point='spinstrike.envs.strike:RodSpinEnv',"
        " vector_entry_point='spinstrike.envs.strike:RodSpinVectorEnv',"
        f" kwargs={{'restitution': {restitution}}})\n"))


def _write_module(user_module, env_id: str, source: str):
    """The user's module as ``source`` (registering ``env_id``), as the next ``spinstrike
    baselines`` imports it again after the user edited it."""
    import importlib
    import sys

    import gymnasium as gym

    sys.modules.pop(MODULE, None)
    gym.registry.pop(env_id, None)
    here = user_module(MODULE, source)
    importlib.invalidate_caches()
    return here


def _baselines(env_id, root, doc, *more):
    return main(["baselines", "--quick", "--envs", env_id, "--algos", "ppo", "--no-transfer",
                 "--root", str(root), "--doc", str(doc), *more])


def _recorded(run):
    record = yaml.safe_load((run / "config.yml").read_text())
    return record["hyperparameters"][record["env"]]


def test_an_edited_registration_trains_the_run_again(user_module, ppo_yml, capsys):
    here = _register(user_module, 0.95)
    root, doc = here / "runs", here / "baselines.md"
    run = root / RUN
    assert _baselines(VARIANT, root, doc) == 0
    assert _recorded(run)["env_kwargs"] == {"restitution": 0.95}
    result = run / "baseline.json"
    first, stamp = result.read_text(), result.stat().st_mtime_ns

    # unchanged: reused, not trained again
    capsys.readouterr()
    assert _baselines(VARIANT, root, doc) == 0
    assert "training it again" not in capsys.readouterr().out
    assert result.stat().st_mtime_ns == stamp and result.read_text() == first

    _register(user_module, 0.8)  # the user edits the module (at 0.2 its oracle takes 30 s)
    # --reuse-only trains nothing: refused, naming the run and what changed
    with pytest.raises(SystemExit) as refused:
        _baselines(VARIANT, root, doc, "--reuse-only")
    message = str(refused.value.code)
    assert message.startswith(f"{run}: trained with restitution 0.95, the registration now "
                              f"gives 0.8"), message
    assert "--reuse-only" in message
    assert result.read_text() == first

    # without it: trained again on the registration as it is now, and said so
    capsys.readouterr()
    assert _baselines(VARIANT, root, doc) == 0
    out = capsys.readouterr().out
    assert f"{run}: trained with restitution 0.95, the registration now gives 0.8: training it " \
           f"again" in out, out
    assert _recorded(run)["env_kwargs"] == {"restitution": 0.8}
    assert result.read_text() != first
    # the report's section says which registration it reports (F4)
    text = doc.read_text()
    assert "Registered arguments: restitution 0.8 " in text and "restitution 0.95" not in text

    # --re-evaluate scores a model only on the env it trained on: trained again here too
    _register(user_module, 0.95)
    second = result.read_text()
    capsys.readouterr()
    assert _baselines(VARIANT, root, doc, "--re-evaluate") == 0
    assert "the registration now gives 0.95: training it again" in capsys.readouterr().out
    assert _recorded(run)["env_kwargs"] == {"restitution": 0.95}
    assert json.loads(result.read_text())["mean"] == json.loads(first)["mean"]  # as trained first
    assert result.read_text() != second


def test_an_edited_hyperparameter_file_trains_the_run_again(tmp_path, ppo_yml, monkeypatch,
                                                            capsys):
    monkeypatch.chdir(tmp_path)
    root, doc = tmp_path / "runs", tmp_path / "baselines.md"
    run = root / "ppo-RodSpin-v0-s0"
    assert _baselines("SpinStrike/RodSpin-v0", root, doc) == 0
    assert _recorded(run)["learning_rate"] == 3.0e-4
    stamp = (run / "baseline.json").stat().st_mtime_ns

    ppo_yml(learning_rate=1.0e-3)  # the user edits configs/agents/ppo.yml
    with pytest.raises(SystemExit) as refused:
        _baselines("SpinStrike/RodSpin-v0", root, doc, "--reuse-only")
    message = str(refused.value.code)
    assert message.startswith(f"{run}: trained with learning_rate 0.0003, "
                              f"ppo.yml[SpinStrike/RodSpin-v0] now gives 0.001"), message
    assert (run / "baseline.json").stat().st_mtime_ns == stamp

    capsys.readouterr()
    assert _baselines("SpinStrike/RodSpin-v0", root, doc) == 0
    assert "learning_rate 0.0003, ppo.yml[SpinStrike/RodSpin-v0] now gives 0.001: training it " \
           "again" in capsys.readouterr().out
    assert _recorded(run)["learning_rate"] == 1.0e-3


def test_a_runs_summary_names_the_env_arguments_it_was_given(tmp_path, ppo_yml, monkeypatch):
    """Runs of a grid over an env argument had one summary title: "PPO on
    SpinStrike/RodSpin-v0 (seed 0, ...)"; the arguments given are in it now."""
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--env", "SpinStrike/RodSpin-v0", "--timesteps", "256",
                 "--eval-episodes", "2", "--no-video", "--no-progress", "--out", "run",
                 "--env-kwargs", "{restitution: 0.3}"]) == 0
    title = (tmp_path / "run" / "summary.md").read_text().splitlines()[0]
    assert title.startswith("## PPO on SpinStrike/RodSpin-v0 with restitution 0.3 (seed 0, "), \
        title


def test_an_edited_subclass_trains_the_run_again(user_module, ppo_yml, capsys):
    """A variant that is a subclass of the user's: an edit of its code (its reward) since the
    run trained is a change too (the run records a digest of the module's source), where only
    its registered arguments were compared: the old run's score was reported beside the new
    reward's random policy and oracle."""
    def register(bonus):
        return _write_module(user_module, "ReuseLab/BonusRod-v0", (
            "import gymnasium as gym\n"
            "import numpy as np\n"
            "from spinstrike.envs.strike import RodSpinEnv, RodSpinTask, RodSpinVectorEnv\n"
            "class BonusTask(RodSpinTask):\n"
            "    def step(self, actions, batch_info=True):\n"
            "        reward, terminated, info = super().step(actions, batch_info)\n"
            f"        return reward + {bonus} * np.asarray(info['speed']), terminated, info\n"
            "class BonusRod(RodSpinEnv):\n"
            "    TASK = BonusTask\n"
            "class BonusRodVec(RodSpinVectorEnv):\n"
            "    TASK = BonusTask\n"
            "gym.register('ReuseLab/BonusRod-v0', entry_point=BonusRod,"
            " vector_entry_point=BonusRodVec)\n"))

    here = register(0.5)
    variant, run = f"{MODULE}:ReuseLab/BonusRod-v0", "ppo-ReuseLab-BonusRod-v0-s0"
    root, doc = here / "runs", here / "baselines.md"
    assert _baselines(variant, root, doc) == 0
    capsys.readouterr()
    assert _baselines(variant, root, doc, "--reuse-only") == 0  # unchanged: reused
    register(5.0)
    with pytest.raises(SystemExit) as refused:
        _baselines(variant, root, doc, "--reuse-only")
    assert str(refused.value.code).startswith(
        f"{root / run}: trained with the code of {MODULE} as it was then (it changed "
        f"since)"), refused.value.code


def test_a_report_names_the_commits_its_reused_runs_were_scored_at(tmp_path, ppo_yml,
                                                                    monkeypatch):
    """Walk W24b F5: a report over a teammate's runs said "Code at commit f9f22c9" while those
    runs were scored at f9f22c9+dirty; the runs scored elsewhere are named (``baseline.json``'s
    ``evaluated_at``, edited here as another commit's run reads), and ``--re-evaluate`` scores
    them with this code."""
    monkeypatch.chdir(tmp_path)
    root, doc = tmp_path / "runs", tmp_path / "baselines.md"
    assert _baselines("SpinStrike/RodSpin-v0", root, doc) == 0
    assert "Runs scored at other commits" not in doc.read_text()
    result = root / "ppo-RodSpin-v0-s0" / "baseline.json"
    out = json.loads(result.read_text())
    result.write_text(json.dumps({**out, "evaluated_at": "0123abc"}))
    assert _baselines("SpinStrike/RodSpin-v0", root, doc, "--reuse-only") == 0
    assert "Runs scored at other commits (reused; `--re-evaluate` scores them with this code): " \
           "1 at 0123abc." in doc.read_text()
    assert _baselines("SpinStrike/RodSpin-v0", root, doc, "--reuse-only", "--re-evaluate") == 0
    assert "Runs scored at other commits" not in doc.read_text()
