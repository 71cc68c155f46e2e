"""Real training (marked slow: run with ``pytest -m slow``; minutes each on 2 cores)."""

import pytest

from spinstrike.agents.train import train

pytestmark = pytest.mark.slow


def test_ppo_reaches_90_percent_of_the_oracle_on_rodspin(tmp_path):
    """Within the budget of configs/agents/ppo.yml."""
    result = train("ppo", "SpinStrike/RodSpin-v0", seed=0, out=tmp_path / "run", progress=False,
                   video=False, eval_episodes=50)
    ev = result["evaluations"]
    assert ev["agent"][0] >= 0.9 * ev["oracle"][0], ev


@pytest.mark.parametrize("env_id", ["SpinStrike/RodSpinControl-v0",
                                    "SpinStrike/PuckSpeedControl-v0"])
def test_control_agent_beats_random_by_a_wide_margin(env_id, tmp_path):
    """PPO against the random policy (at least twice its mean return and four of its standard
    deviations above); the scripted chase-and-hit policy is reported beside both."""
    result = train("ppo", env_id, seed=0, out=tmp_path / "run", progress=False, video=False,
                   eval_episodes=20)
    ev = result["evaluations"]
    agent, random, scripted = ev["agent"], ev["random"], ev["oracle"]
    print(f"{env_id}: agent {agent}, random {random}, chase-and-hit {scripted}")
    assert agent[0] >= 2.0 * random[0] and agent[0] >= random[0] + 4.0 * random[1], ev


def test_ppo_reaches_93_percent_of_the_oracle_on_puckspeed_v1_over_3_seeds(tmp_path):
    """The shipped config (configs/agents/ppo.yml, PuckSpeed-v1: 300k steps, about 50 s a seed
    on 2 cores), seeds 0-2, each evaluated on the same 50 episodes."""
    agent, oracle = [], []
    for seed in range(3):
        result = train("ppo", "SpinStrike/PuckSpeed-v1", seed=seed, out=tmp_path / f"s{seed}",
                       progress=False, video=False, eval_episodes=50)
        ev = result["evaluations"]
        agent.append(ev["agent"][0])
        oracle.append(ev["oracle"][0])
    print(f"PPO on PuckSpeed-v1: {agent} (oracle {oracle})")
    assert sum(agent) / 3 >= 0.93 * sum(oracle) / 3, (agent, oracle)


@pytest.mark.parametrize("algo", ["td3", "sac"])
@pytest.mark.parametrize("env_id", ["SpinStrike/RodSpinControl-v0",
                                    "SpinStrike/PuckSpeedControl-v0"])
def test_off_policy_agent_beats_chase_and_hit_on_control_envs(algo, env_id, tmp_path):
    """Issue 16: SAC and TD3 with the shipped control entries (60k/80k steps, about 3 min each
    on 2 cores) above the scripted chase-and-hit on the same 50 episodes (seed 0 in
    docs/baselines.md: RodSpinControl TD3 2.19, SAC 3.53 against 1.61; PuckSpeedControl TD3
    7.23, SAC 6.81 against 3.10)."""
    result = train(algo, env_id, seed=0, out=tmp_path / "run", progress=False, video=False,
                   eval_episodes=50)
    ev = result["evaluations"]
    print(f"{algo} on {env_id}: agent {ev['agent']}, chase-and-hit {ev['oracle']}")
    assert ev["agent"][0] > ev["oracle"][0], ev


def test_ppo_started_from_the_planner_beats_ppo_alone_on_puckspeedcontrol(tmp_path):
    """``--imitate planner`` (20 DAgger rounds of 16 episodes, ~10 min on 2 cores, then the
    shipped 500k PPO steps): above the best PPO from scratch reached (IQM 7.83 over 5 seeds;
    8.90 for seed 0 after 2M steps) by a clear margin, on the same 50 evaluation episodes.
    Measured: 14.53 (an earlier cut of the code: 13.87)."""
    result = train("ppo", "SpinStrike/PuckSpeedControl-v0", seed=0, out=tmp_path / "run",
                   progress=False, video=False, eval_episodes=50, imitate="planner")
    ev = result["evaluations"]
    print(f"agent {ev['agent']}, chase-and-hit {ev['oracle']}")
    assert ev["agent"][0] >= 11.0, ev
