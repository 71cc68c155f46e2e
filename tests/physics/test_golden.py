"""Optimisations leave the physics unchanged, bit for bit: the recorded golden trajectories
(``tests/physics/golden.py``: exact, coarse-tolerance and fixed solvers; cushions, static posts,
pivots, a driven mallet, cloth and contact friction, Newton's cradle) are reproduced exactly."""

import numpy as np
import pytest

from tests.physics import golden

GOLDEN = np.load(golden.PATH)


@pytest.mark.parametrize("name", list(golden.scenarios()))
def test_trajectories_are_bit_identical_to_the_recording(name):
    scene, solver = golden.scenarios()[name]
    now = golden.run(scene, solver)
    assert int(GOLDEN[f"{name}/counts"].sum()) > 0  # the scenario has contacts to get wrong
    for key, value in now.items():
        np.testing.assert_array_equal(value, GOLDEN[f"{name}/{key}"], err_msg=f"{name}/{key}")
