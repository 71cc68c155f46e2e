"""Long runs of a walled table (several bodies, e = 1, mu = 0): energy drift, escapes, NaN.

Cushions are static, so momentum is not conserved here; kinetic energy is, to round-off per
contact. The full 10^6-step run is behind ``-m slow``; the default suite runs 2 x 10^4 steps of
one world and 10^5 element-steps of a batch of 50.
"""

import pytest

from tests.stability.longrun import run

#: relative energy drift allowed per contact (float64 round-off), and its floor
PER_CONTACT = 1e-13


def _check(out):
    assert out["nonfinite"] == 0
    assert out["escapes"] == 0
    assert out["overlap"] <= 1e-9
    assert out["energy_drift"] <= max(1e-12, PER_CONTACT * out["contacts"] / out["batch"])
    assert out["contacts"] > out["element_steps"] / 20  # the bodies really did collide


def test_long_run_short():
    _check(run(20_000, batch=1, check_every=10))


def test_long_run_batched_short():
    _check(run(2_000, batch=50, check_every=10))


@pytest.mark.slow
def test_long_run_million_steps():
    _check(run(1_000_000, batch=1, check_every=100))


@pytest.mark.slow
def test_long_run_million_element_steps_batched():
    _check(run(2_000, batch=500, check_every=10))
