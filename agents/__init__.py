"""SpinStrike baselines: train, evaluate and film SB3 agents; analytic oracle policies; the CLI.

    spinstrike train --algo ppo --env SpinStrike/RodSpin-v0
    spinstrike evaluate runs/ppo-RodSpin-v0-s0
    spinstrike record runs/ppo-RodSpin-v0-s0 --out rollout.mp4
    spinstrike envs
"""
