"""An SB3 user's own scripts meeting SpinStrike's CLI (walk W21a): a model trained outside
``spinstrike train`` is scored by ``spinstrike evaluate`` as the README says."""

import yaml

from spinstrike.agents.cli import main


def test_evaluate_scores_a_her_model_of_the_user_s_own_run_folder(tmp_path, capsys):
    """``spinstrike train`` sends HER to SB3 or rl-zoo3 directly; ``evaluate`` and ``record``
    of such a run then crashed with a traceback (SB3's load asserts an env to rebuild the
    HER buffer, which acting does not need). It is scored as any dict-mode model."""
    import torch
    from stable_baselines3 import SAC, HerReplayBuffer

    from spinstrike.envs.sb3 import make_sb3_vec_env

    torch.set_num_threads(1)
    kwargs = {"obs_mode": "dict", "goal": "target"}
    model = SAC("MultiInputPolicy", make_sb3_vec_env("SpinStrike/RodSpin-v0", 2, seed=0,
                                                     env_kwargs=kwargs),
                replay_buffer_class=HerReplayBuffer, learning_starts=20, gamma=0.0,
                buffer_size=500, seed=0)
    model.learn(40)
    run = tmp_path / "her"
    run.mkdir()
    model.save(run / "model.zip")
    (run / "config.yml").write_text(yaml.safe_dump({
        "algo": "sac", "env": "SpinStrike/RodSpin-v0",
        "hyperparameters": {"SpinStrike/RodSpin-v0": {"env_kwargs": kwargs}}}))
    assert main(["evaluate", str(run), "--episodes", "3", "--no-save", "--json"]) == 0
    out = capsys.readouterr().out
    assert '"agent": {"mean": ' in out and '"episodes": 3' in out
