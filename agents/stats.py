"""Statistics as the field reports them (Agarwal et al., 2021, "Deep RL at the edge of the
statistical precipice"): the interquartile mean (IQM) over runs with a 95% stratified-bootstrap
confidence interval, beside mean +/- std, and learning curves with IQM bands.

The bootstrap is ``rliable``'s (``pip install "spinstrike[stats]"``); without it,
:func:`interval` raises ``ImportError`` naming the extra. Scores are ``[runs, tasks]`` arrays
(one row per seed; one column per env, or a single column), and the bootstrap resamples runs
within each task (stratified), as rliable does.

    from spinstrike.agents.stats import summary
    summary(np.array([[0.97], [0.99], [0.98], [0.95], [0.99]]))
    # {'iqm': 0.98, 'iqm_low': ..., 'iqm_high': ..., 'mean': 0.976, 'std': 0.015, 'runs': 5}
"""

from __future__ import annotations

import numpy as np

__all__ = ["curve_bands", "interval", "iqm", "summary"]

#: bootstrap replications (rliable's papers use 50,000; 2,000 keeps a table under a second)
REPS = 2000


def iqm(scores) -> float:
    """Interquartile mean of all scores: the mean of the middle 50% (``scipy``'s trim_mean,
    0.25 cut from each end, as ``rliable.metrics.aggregate_iqm``)."""
    from scipy.stats import trim_mean

    a = np.asarray(scores, float).ravel()
    if a.size == 0:
        raise ValueError("scores: at least one score is needed")
    return float(trim_mean(a, 0.25))


def _rliable():
    try:
        from rliable import library, metrics
    except ImportError as exc:
        raise ImportError("confidence intervals need rliable: pip install "
                          f"'spinstrike[stats]' ({exc})") from None
    return library, metrics


def _as_runs_tasks(scores) -> np.ndarray:
    a = np.asarray(scores, float)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"scores: expected [runs] or [runs, tasks], got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("scores: must be finite")
    return a


def interval(scores, reps: int = REPS, seed: int = 0, confidence: float = 0.95,
             ) -> tuple[float, float, float]:
    """IQM of ``scores`` ([runs] or [runs, tasks]) and its stratified-bootstrap confidence
    interval: ``(iqm, low, high)`` (rliable's percentile bootstrap, ``reps`` replications,
    seeded, so a table is reproducible)."""
    library, metrics = _rliable()
    a = _as_runs_tasks(scores)
    if a.shape[0] < 2:
        value = iqm(a)
        return value, value, value
    state = np.random.get_state()
    np.random.seed(seed)  # rliable's bootstrap draws from numpy's global generator
    try:
        point, ci = library.get_interval_estimates(
            {"x": a}, lambda x: np.array([metrics.aggregate_iqm(x)]), reps=reps,
            confidence_interval_size=confidence)
    finally:
        np.random.set_state(state)
    return float(point["x"][0]), float(ci["x"][0, 0]), float(ci["x"][1, 0])


def summary(scores, reps: int = REPS, seed: int = 0) -> dict:
    """IQM with its 95% CI, beside mean and std over runs (of each run's mean over tasks)."""
    a = _as_runs_tasks(scores)
    value, low, high = interval(a, reps, seed)
    per_run = a.mean(1)
    return {"iqm": value, "iqm_low": low, "iqm_high": high, "mean": float(per_run.mean()),
            "std": float(per_run.std()), "runs": int(a.shape[0])}


def curve_bands(curves, reps: int = REPS, seed: int = 0):
    """Learning curves ``[runs, points]`` (one row per seed): IQM per point with its 95%
    bootstrap band, ``(iqm [points], low [points], high [points])``."""
    c = np.asarray(curves, float)
    if c.ndim != 2:
        raise ValueError(f"curves: expected [runs, points], got shape {c.shape}")
    out = np.array([interval(c[:, k], reps, seed) for k in range(c.shape[1])])
    return out[:, 0], out[:, 1], out[:, 2]
