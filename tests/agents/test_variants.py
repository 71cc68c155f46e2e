"""A variant a user registers (``gym.register`` with a SpinStrike env class as its entry point, in
a module of their own) trains, evaluates and films through the CLI as a shipped id does, given
in ``gym.make``'s form ``"module:Namespace/Name-vN"``; ``spinstrike train`` refused any id but the
shipped ones. The variant's registered arguments reach the batched env training steps (the
native vector env), its run's record names it, and a later process finds it again through the
module; ids that are not SpinStrike envs are refused naming what is allowed."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

from spinstrike import envs
from spinstrike.agents.cli import main
from spinstrike.agents.config import AgentConfigError, load_agent_config
from spinstrike.envs.sb3 import make_sb3_vec_env

MODULE = "spinstrike_test_lab"
VARIANT = "TestLab/BouncyRod-v0"
LAB = textwrap.dedent(f"""
    import gymnasium as gym
    from spinstrike.envs.strike import RodSpinEnv

    class LoudRod(RodSpinEnv):  # a subclass, registered once without a vector env
        pass

    gym.register("{VARIANT}", entry_point="spinstrike.envs.strike:RodSpinEnv",
                 kwargs={{"restitution": 0.95}})
    gym.register("TestLab/LoudRod-v0", entry_point=LoudRod)
    gym.register("TestLab/LoudRodVec-v0", entry_point=LoudRod,
                 vector_entry_point="spinstrike.envs.strike:RodSpinVectorEnv")
    gym.register("TestLab/Cart-v0", entry_point="gymnasium.envs.classic_control:CartPoleEnv")
""")
@pytest.fixture
def lab(user_module):
    """The user's registering module in the working directory (``user_module``)."""
    return user_module(MODULE, LAB)


def test_a_variant_trains_evaluates_and_films_through_the_cli(lab, capsys):
    run = lab / "run"
    assert main(["train", "--env", f"{MODULE}:{VARIANT}", "--timesteps", "256", "--n-envs",
                 "2", "--eval-episodes", "2", "--no-video", "--out", str(run),
                 "--no-progress"]) == 0
    record = yaml.safe_load((run / "config.yml").read_text())
    assert record["env"] == f"{MODULE}:{VARIANT}"
    assert record["source"].endswith("ppo.yml")  # the shipped RodSpin-v0 entry, no entry of its own
    assert "oracle: 1.0000" in capsys.readouterr().out  # the closed-form oracle of its env class
    # a new process (the console script, which puts no working directory on sys.path) finds
    # the variant through its module: evaluate and record the run
    script = Path(sys.executable).with_name("spinstrike")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = os.environ.get("PYTHONPATH", "")  # (the checkout, if the suite uses it)
    for args in (["evaluate", str(run), "--episodes", "2", "--no-save"],
                 ["record", str(run), "--out", str(lab / "v.mp4"), "--episodes", "1"]):
        out = subprocess.run([str(script), *args], cwd=lab, env=env, capture_output=True,
                             text=True, timeout=600)
        assert out.returncode == 0, out.stderr[-2000:]
    assert (lab / "v.mp4").stat().st_size > 0


def test_the_variants_arguments_reach_the_batched_env(lab):
    """Training steps the native vector env; a variant registered without a vector entry point
    gets its env class's, with the variant's registered arguments: element i of it is the
    single env ``gym.make`` makes, seeded seed + i, bit for bit."""
    __import__(MODULE)
    vec = make_sb3_vec_env(VARIANT, n_envs=3, seed=7)
    assert np.all(vec.venv.unwrapped.world.restitution("rod", "striker") == 0.95)
    actions = np.array([[0.3, -0.2, 0.9], [-0.7, 0.4, 0.1], [0.0, 0.0, -1.0]], np.float32)
    vec.reset()
    vec.step_async(actions)
    obs, rewards, _, infos = vec.step_wait()
    for i in range(3):
        single = gym.make(VARIANT)
        assert single.unwrapped.world.restitution("rod", "striker")[0] == 0.95
        single.reset(seed=7 + i)
        *_, reward, term, trunc, info = single.step(actions[i])
        assert reward == rewards[i] and info["spin"] == infos[i]["spin"]
    # the shipped env itself is elastic: the variant's argument made the difference
    assert envs.native_vector("SpinStrike/RodSpin-v0") == ("SpinStrike/RodSpin-v0", {})
    assert envs.native_vector(VARIANT) == ("SpinStrike/RodSpin-v0", {"restitution": 0.95})


def test_subclasses_and_hyperparameter_entries(lab, tmp_path):
    __import__(MODULE)
    assert envs.base_id(f"{MODULE}:TestLab/LoudRodVec-v0") == "SpinStrike/RodSpin-v0"
    # a subclass without a vector env: the shipped vector env would drop what it changes
    with pytest.raises(envs.ConfigError, match="vector_entry_point"):
        make_sb3_vec_env("TestLab/LoudRod-v0", n_envs=2)
    # an entry of the variant's own is used; without one, its env class's
    path = tmp_path / "ppo.yml"
    shipped = load_agent_config("ppo", "SpinStrike/RodSpin-v0").raw
    path.write_text(yaml.safe_dump({VARIANT: dict(shipped, n_steps=32),
                                    "SpinStrike/RodSpin-v0": shipped}))
    assert load_agent_config("ppo", f"{MODULE}:{VARIANT}", path).raw["n_steps"] == 32
    assert load_agent_config("ppo", "TestLab/LoudRodVec-v0", path).raw["n_steps"] == \
        shipped["n_steps"] != 32


@pytest.mark.parametrize("env_id, message", [
    (f"{MODULE}:TestLab/Cart-v0", "not a SpinStrike env class"),
    (f"{MODULE}:TestLab/Nope-v0", "unknown id"),
    ("no_such_lab_module:TestLab/X-v0", "cannot import 'no_such_lab_module'"),
    # a user's sched.py: `import sched` finds the standard library's (walk W25 F12)
    ("sched:TestLab/X-v0", "'sched' is also a module of Python's standard library"),
])
def test_ids_that_are_not_spinstrike_envs_are_refused(lab, env_id, message, capsys):
    assert main(["train", "--env", env_id, "--out", str(lab / "run")]) == 2
    err = capsys.readouterr().err
    assert message in err and "--env" in err
    if "cannot import" in message:  # what is missing, not the shipped ids (walk W24b F12)
        assert "put that folder on PYTHONPATH, or install the module" in err
        assert "SpinStrike/RodSpin-v0" not in err
    elif "standard library" in message:
        assert "rename your module" in err
    else:
        assert "module:Namespace/Name-vN" in err
    assert not (lab / "run").exists()
    with pytest.raises(AgentConfigError, match=message):
        load_agent_config("ppo", env_id)


def test_baselines_train_and_report_a_variant(user_module, capsys):
    """``spinstrike baselines --envs`` took the shipped ids only (argparse's choices): a variant
    given as ``module:Namespace/Name-vN`` is trained, scored against its own random policy and
    oracle, and reported under its id; an id that is no SpinStrike env is refused naming
    ``--envs`` before anything trains."""
    pytest.importorskip("rliable")
    # named as a shipped env is: its run and plot were the shipped env's file names, so a
    # report of both scored the variant with the shipped env's run
    here = user_module("spinstrike_baselines_lab", (
        "import gymnasium as gym\n"
        "gym.register('BaseLab/PuckSpeed-v1', entry_point='spinstrike.envs.strike:PuckSpeedV1Env',"
        " kwargs={'restitution': 0.6})\n"))
    variant = "spinstrike_baselines_lab:BaseLab/PuckSpeed-v1"
    root, doc = here / "runs", here / "report" / "baselines.md"
    assert main(["baselines", "--quick", "--envs", variant, "--algos", "ppo", "--seeds", "0",
                 "--no-transfer", "--root", str(root), "--doc", str(doc)]) == 0
    text = doc.read_text()
    assert f"## {variant}" in text and "| oracle (closed form) | - | 1.000 +/- 0.000 |" in text
    run = root / "ppo-BaseLab-PuckSpeed-v1-s0"
    assert yaml.safe_load((run / "config.yml").read_text())["env"] == variant
    assert (doc.parent / "baselines" / "BaseLab-PuckSpeed-v1.png").is_file()
    # a run folder holding another env's run is not reused for this one
    from spinstrike.agents.baselines import _run

    with pytest.raises(SystemExit, match=r"holds a run of spinstrike_baselines_lab:BaseLab/"
                                         r"PuckSpeed-v1, not of SpinStrike/PuckSpeed-v1"):
        run.rename(root / "ppo-PuckSpeed-v1-s0")
        _run("ppo", "SpinStrike/PuckSpeed-v1", 0, root, 0.1)
    (root / "ppo-PuckSpeed-v1-s0").rename(run)
    capsys.readouterr()
    assert main(["baselines", "--quick", "--envs", "CartPole-v1", "--root", str(root),
                 "--doc", str(doc)]) == 2
    assert "--envs: 'CartPole-v1'" in capsys.readouterr().err
    assert sorted(p.name for p in root.iterdir()) == [run.name]


def test_a_control_variant_without_a_step_limit_is_refused_not_run_for_ever(user_module, capsys):
    """A control env registered without ``max_episode_steps``: ``gym.make`` adds no limit and
    its episodes never end, so ``evaluate`` and ``record`` ran until killed and ``train`` hung
    in its final evaluation (its batched env stopped at 250 steps). Refused, saying what to
    register; ``--env-kwargs '{max_episode_steps: N}'`` makes it finite."""
    user_module("spinstrike_ctl_lab", (
        "import gymnasium as gym\n"
        "gym.register('CtlLab/Push-v0', entry_point='spinstrike.envs.control:RodSpinControlEnv',"
        " kwargs={'max_force': 8.0})\n"))
    variant = "spinstrike_ctl_lab:CtlLab/Push-v0"
    for argv in (["evaluate", "--random", "--env", variant, "--episodes", "1", "--no-save"],
                 ["record", "--random", "--env", variant, "--episodes", "1", "--out", "v.mp4"],
                 ["train", "--env", variant, "--timesteps", "64", "--out", "run"]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "a control env's episodes never end and it registers no max_episode_steps" in err
        assert "register it with max_episode_steps" in err
    assert not Path("run").exists() and not Path("v.mp4").exists()
    assert main(["evaluate", "--random", "--env", variant, "--episodes", "1", "--no-save",
                 "--env-kwargs", "{max_episode_steps: 5}", "--json"]) == 0


def test_one_hyperparameter_file_for_the_lab_and_the_shipped_envs(lab, capsys):
    """A file holding an entry for a variant in a namespace of the user's own, keyed by its plain
    id: training any other env (whose run does not import the variant's module) refused the
    whole file as naming an "unknown env id". Such a key is skipped, as rl-zoo3 skips every other
    entry; a key in SpinStrike's namespace, or in the namespace of the env being trained (its
    module imported), is still checked, so a typo there is refused."""
    shipped = load_agent_config("ppo", "SpinStrike/RodSpin-v0").raw
    path = lab / "lab.yml"
    path.write_text(yaml.safe_dump({"OtherLab/Far-v0": dict(shipped, n_steps=16),
                                    VARIANT: dict(shipped, n_steps=32),
                                    "SpinStrike/RodSpin-v0": dict(shipped, n_steps=64)}))
    common = ["--timesteps", "128", "--n-envs", "2", "--eval-episodes", "1", "--no-video",
              "--no-progress", "--config", str(path)]
    assert main(["train", "--env", "SpinStrike/RodSpin-v0", "--out", "shipped", *common]) == 0
    assert main(["train", "--env", f"{MODULE}:{VARIANT}", "--out", "variant", *common]) == 0
    for run, n_steps in (("shipped", 64), ("variant", 32)):
        record = yaml.safe_load((lab / run / "config.yml").read_text())
        assert record["hyperparameters"][record["env"]]["n_steps"] == n_steps
    capsys.readouterr()
    for typo in ("SpinStrike/RodSpn-v0", "TestLab/BouncyRd-v0", "spinstrike_no_lab:X/Y-v0"):
        path.write_text(yaml.safe_dump({typo: shipped, VARIANT: shipped}))
        assert main(["train", "--env", f"{MODULE}:{VARIANT}", "--out", "typo", *common]) == 2
        assert f"unknown env id {typo!r}" in capsys.readouterr().err
    assert not (lab / "typo").exists()


def test_the_readmes_variant_is_the_batched_env_under_make_vec(user_module):
    """The README's ``mylab.py``, as written there: ``gym.make_vec`` of it is the native vector
    env with the variant's arguments and takes ``autoreset_mode=`` (registered without a
    ``vector_entry_point`` it was a SyncVectorEnv, which passed ``autoreset_mode`` to the env and
    the env refused it); its elements are the single envs ``gym.make`` makes, bit for bit."""
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    block = readme.split("```python\n# mylab.py", 1)[1].split("```", 1)[0]
    user_module("spinstrike_readme_lab", "# mylab.py" + block)
    variant = "spinstrike_readme_lab:MyLab/BouncyRod-v0"
    vec = gym.make_vec(variant, 3, autoreset_mode="same_step")
    assert type(vec).__name__ == "RodSpinVectorEnv"
    assert vec.metadata["autoreset_mode"] == gym.vector.AutoresetMode.SAME_STEP
    assert np.all(vec.unwrapped.world.restitution("rod", "striker") == 0.95)
    sync = gym.make_vec(variant, 3, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP})
    actions = np.array([[0.3, -0.2, 0.9], [-0.7, 0.4, 0.1], [0.0, 0.0, -1.0]], np.float32)
    for v in (vec, sync):
        v.reset(seed=11)
    for a, b in zip(vec.step(actions), sync.step(actions), strict=True):
        if isinstance(a, np.ndarray):
            assert np.array_equal(a, b)


@pytest.mark.parametrize("registered", ["{'scene': 'table.yaml'}",
                                        "{'config': {'scene': 'table.yaml'}}"])
def test_a_variants_scene_file_is_recorded_with_the_run(user_module, capsys, registered):
    """A variant registered with ``scene="table.yaml"``: its run's ``config.yml`` recorded no
    scene, so after the file was edited ``evaluate`` silently rebuilt the edited table. The
    run records the scene as read; evaluating after an edit gives the same numbers. Registered
    in the env's ``config`` form, the record kept the path (RLlib walk W10: ``evaluate`` from
    another folder could not open it); the record now holds it flat, as read."""
    table = Path("table.yaml")
    source = (Path(__file__).resolve().parents[2] / "configs" / "scenes" / "rod_control.yaml")
    table.write_text(source.read_text())
    module = f"spinstrike_scene_lab{len(registered)}"
    user_module(module, (
        "import gymnasium as gym\n"
        "gym.register('SceneLab/Table-v0', entry_point='spinstrike.envs.control:RodSpinControlEnv',"
        f" kwargs={registered}, max_episode_steps=20)\n"))
    variant = f"{module}:SceneLab/Table-v0"
    assert main(["train", "--env", variant, "--timesteps", "128", "--n-envs", "2",
                 "--eval-episodes", "2", "--no-video", "--no-progress", "--out", "run"]) == 0
    recorded = yaml.safe_load(Path("run/config.yml").read_text())
    assert recorded["hyperparameters"][recorded["env"]]["env_kwargs"]["scene"] == \
        yaml.safe_load(source.read_text())
    capsys.readouterr()
    evaluate = ["evaluate", "run", "--episodes", "3", "--no-save", "--json"]
    assert main(evaluate) == 0
    before, note = capsys.readouterr()
    assert "note:" not in note
    # from another folder, where 'table.yaml' is not found, the registration did not change
    # (W17: the note said it had, "now 'table.yaml'"); it says the file is not compared
    elsewhere = Path("elsewhere").resolve()
    elsewhere.mkdir()
    os.chdir(elsewhere)
    try:
        assert main([*evaluate[:1], "../run", *evaluate[2:]]) == 0
    finally:
        os.chdir(elsewhere.parent)
    there, note = capsys.readouterr()
    assert there == before and "other arguments" not in note
    assert f"registers its scene as the file 'table.yaml', not found from {str(elsewhere)!r}" \
        in note, note
    table.write_text(source.read_text().replace("size: [1.2, 0.8]", "size: [3.0, 2.0]")
                     .replace("mass: 0.1}", "mass: 2.0}"))
    assert yaml.safe_load(table.read_text()) != yaml.safe_load(source.read_text())
    assert main(evaluate) == 0
    assert capsys.readouterr().out == before


def test_a_variants_default_run_folder_keeps_its_namespace(user_module):
    """``train --env mylab:MyLab/RodSpin-v0`` went to ``runs/ppo-RodSpin-v0-s0``, the shipped
    env's folder (which ``--force`` then replaced); it goes where ``baselines`` names it."""
    user_module("spinstrike_same_name_lab", (
        "import gymnasium as gym\n"
        "gym.register('SameLab/RodSpin-v0', entry_point='spinstrike.envs.strike:RodSpinEnv',"
        " kwargs={'restitution': 0.5})\n"))
    assert main(["train", "--env", "spinstrike_same_name_lab:SameLab/RodSpin-v0", "--timesteps",
                 "64", "--n-envs", "2", "--no-eval", "--no-video", "--no-progress"]) == 0
    assert [p.name for p in Path("runs").iterdir()] == ["ppo-SameLab-RodSpin-v0-s0"]


def test_a_variants_frames_are_titled_with_its_id(user_module):
    """A variant's video frames were captioned with its env class's id ("RodSpinControl-v0");
    they name the id it was made with, in ``gym.make``, ``gym.make_vec`` and a pickled copy."""
    import pickle

    user_module("spinstrike_title_lab", (
        "import gymnasium as gym\n"
        "gym.register('TitleLab/Big-v0', entry_point='spinstrike.envs.control:RodSpinControlEnv',"
        " vector_entry_point='spinstrike.envs.control:RodSpinControlVectorEnv',"
        " max_episode_steps=10)\n"))
    variant = "spinstrike_title_lab:TitleLab/Big-v0"
    frames = {}
    for env_id in (variant, "SpinStrike/RodSpinControl-v0"):
        env = gym.make(env_id, render_mode="rgb_array")
        env.reset(seed=3)
        frames[env_id] = env.render()
    assert gym.make(variant).unwrapped.task.title == "TitleLab/Big-v0"
    assert gym.make("SpinStrike/RodSpinControl-v0").unwrapped.task.title == "RodSpinControl-v0"
    differ = np.any(frames[variant] != frames["SpinStrike/RodSpinControl-v0"], axis=(1, 2))
    assert differ.any() and differ.mean() < 0.1  # the caption's rows only: the same scene
    assert gym.make_vec(variant, 2).unwrapped.task.title == "TitleLab/Big-v0"
    copy = pickle.loads(pickle.dumps(gym.make(variant).unwrapped))
    assert copy.task.title == "TitleLab/Big-v0"


def test_a_variants_step_limit_holds_when_max_episode_steps_is_none(user_module, capsys):
    """``max_episode_steps=None`` means the registered limit (``gym.make``'s reading): the
    native ``gym.make_vec`` of a variant registered with 12 steps truncated at the class's 250,
    as ``gym.make_vec`` passes None on (it fills in the registered limit only where the key is
    absent), while ``SyncVectorEnv`` of ``gym.make`` envs truncated at 12; ``train --env-kwargs
    '{max_episode_steps: null}'`` trained on 250-step episodes and evaluated on 12. A limit put
    among the registration's ``kwargs`` was refused by ``gym.make`` and taken by the native
    ``gym.make_vec``: refused by both."""
    user_module("spinstrike_limit_lab", (
        "import gymnasium as gym\n"
        "gym.register('LimitLab/Short-v0', entry_point='spinstrike.envs.control:RodSpinControlEnv',"
        " vector_entry_point='spinstrike.envs.control:RodSpinControlVectorEnv',"
        " kwargs={'dt': 0.05}, max_episode_steps=12)\n"
        "gym.register('LimitLab/InKwargs-v0',"
        " entry_point='spinstrike.envs.control:RodSpinControlEnv',"
        " vector_entry_point='spinstrike.envs.control:RodSpinControlVectorEnv',"
        " kwargs={'max_episode_steps': 60})\n"))
    variant = "spinstrike_limit_lab:LimitLab/Short-v0"
    actions = np.zeros((2, 2), np.float32)
    for kwargs, limit in (({}, 12), ({"max_episode_steps": None}, 12),
                          ({"max_episode_steps": 5}, 5), ({"max_episode_steps": -1}, None)):
        for mode in ("vector_entry_point", "sync"):
            vec = gym.make_vec(variant, 2, vectorization_mode=mode, **kwargs)
            vec.reset(seed=0)
            ends = [t for t in range(1, 31) if vec.step(actions)[3].any()]
            assert ends[:1] == ([limit] if limit else []), (kwargs, mode, ends)
    for make in (gym.make, lambda i: gym.make_vec(i, 2)):
        with pytest.raises(envs.ConfigError, match="max_episode_steps"):
            make("spinstrike_limit_lab:LimitLab/InKwargs-v0")
    # through the CLI: training and its evaluation run the same 12-step episodes
    assert main(["train", "--env", variant, "--timesteps", "256", "--n-envs", "2",
                 "--eval-episodes", "1", "--no-video", "--no-progress", "--out", "run",
                 "--env-kwargs", "{max_episode_steps: null}"]) == 0
    import csv
    rows = list(csv.DictReader(Path("run/progress.csv").open()))
    lengths = {float(r["rollout/ep_len_mean"]) for r in rows if r.get("rollout/ep_len_mean")}
    assert lengths == {12.0}, lengths


def test_a_variants_registered_arguments_are_recorded_with_the_run(user_module, capsys):
    """A run recorded a variant's scene file as read, and nothing else it registers: after the
    user's module was edited (dt 0.05 -> 0.01, another step limit, another ``randomize``
    range), ``evaluate RUN`` scored, and ``record RUN`` filmed, the edited env, with no word.
    The run records every registered argument (tuples as YAML lists); a new process rebuilds
    the env trained on and says what the registration changed."""
    def register(dt, steps, high):
        user_module("spinstrike_edit_lab", (
            "import gymnasium as gym\n"
            "gym.register('EditLab/Slow-v0',"
            " entry_point='spinstrike.envs.control:RodSpinControlEnv',"
            " vector_entry_point='spinstrike.envs.control:RodSpinControlVectorEnv',"
            f" kwargs={{'dt': {dt}, 'randomize': {{'mallet_mass': (0.2, {high})}}}},"
            f" max_episode_steps={steps})\n"))

    register(0.05, 60, 0.4)
    variant = "spinstrike_edit_lab:EditLab/Slow-v0"
    assert main(["train", "--env", variant, "--timesteps", "128", "--n-envs", "2",
                 "--eval-episodes", "1", "--no-video", "--no-progress", "--out", "run"]) == 0
    recorded = yaml.safe_load(Path("run/config.yml").read_text())
    assert recorded["hyperparameters"][recorded["env"]]["env_kwargs"] == {
        "dt": 0.05, "randomize": {"mallet_mass": [0.2, 0.4]}, "max_episode_steps": 60} \
        == recorded["registered"]
    script = Path(sys.executable).with_name("spinstrike")
    env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy")

    def run(*args):
        out = subprocess.run([str(script), *args], env=env, capture_output=True, text=True,
                             timeout=600)
        assert out.returncode == 0, out.stderr[-2000:]
        return out

    evaluate = ["evaluate", "run", "--episodes", "3", "--no-save", "--json"]
    before = run(*evaluate)
    assert "note:" not in before.stderr
    assert json.loads(before.stdout)["oracle"]["mean"] > 0  # scores that tell the envs apart
    # an argument the command line gave over the registration is no change of it
    assert main(["train", "--env", variant, "--timesteps", "128", "--n-envs", "2",
                 "--eval-episodes", "1", "--no-video", "--no-progress", "--out", "run2",
                 "--env-kwargs", "{dt: 0.02}"]) == 0
    assert "note:" not in run("evaluate", "run2", "--episodes", "1", "--no-save").stderr
    register(0.01, 30, 0.9)  # the user edits the module
    after = run(*evaluate)
    assert after.stdout == before.stdout
    note = after.stderr
    for change in ("dt (now 0.01, the run's 0.05)", "max_episode_steps (now 30, the run's 60)",
                   "randomize (now {'mallet_mass': [0.2, 0.9]}, the run's"):
        assert change in note, note
    filmed = run("record", "run", "--out", "v.mp4", "--episodes", "1")
    assert "at 20 fps" in filmed.stdout + filmed.stderr  # 1 / dt as trained, not 100
    # an argument the registration no longer gives (the note said nothing of it: W18a)
    user_module("spinstrike_edit_lab", (
        "import gymnasium as gym\n"
        "gym.register('EditLab/Slow-v0', entry_point='spinstrike.envs.control:RodSpinControlEnv',"
        " vector_entry_point='spinstrike.envs.control:RodSpinControlVectorEnv',"
        " kwargs={'dt': 0.05}, max_episode_steps=60)\n"))
    dropped = run(*evaluate)
    assert dropped.stdout == before.stdout
    assert "randomize (no longer registered, the run's {'mallet_mass': [0.2, 0.4]})" in \
        dropped.stderr and "dt (" not in dropped.stderr, dropped.stderr
