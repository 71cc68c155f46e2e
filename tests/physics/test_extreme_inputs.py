"""Inputs too large for a step get a clear error or a warning, never a silent NaN or tunnel.

A speed of 1e160 m/s overflows float64 within a step (its square is infinite): the step raises
``SimulationError`` naming the elements and bodies. A force so large that the exact solver's
settling would need more than its cap of substeps loses the bound that keeps bodies from passing
through each other: the step warns and ``last_step.capped`` says which elements.
"""

import warnings

import numpy as np
import pytest

from spinstrike import physics
from spinstrike.physics.world import PARALLEL_BATCH


@pytest.mark.parametrize("batch", [4, PARALLEL_BATCH])  # the serial and the parallel kernel
@pytest.mark.parametrize("solver", [None, {"mode": "fixed", "substeps": 4}])
def test_a_state_that_overflows_raises_naming_element_and_body(batch, solver):
    world = physics.World("rod_control", batch_size=batch, solver=solver)
    velocities = np.zeros((batch, 2, 2))
    velocities[2, 0] = [1e160, 0.0]  # element 2's rod
    world.set_state(velocities=velocities)
    with pytest.raises(physics.SimulationError,
                       match=r"element\(s\) \[2\] is no longer finite \(bodies \['rod'\]\)") as err:
        world.step(0.02)
    assert err.value.elements.tolist() == [2]
    assert isinstance(err.value, physics.SceneError)  # the physics' one error type
    # the other elements stepped normally
    assert np.isfinite(np.delete(world.state.positions, 2, axis=0)).all()


def test_a_large_but_finite_speed_steps_without_error():
    """1e100 m/s squares to 1e200: finite, so the step runs (the rod rattles between the
    cushions and loses its speed to their restitution of 0.9)."""
    world = physics.World("rod_control")
    world.set_state(velocities=[[[1e100, 0.0], [0.0, 0.0]]])
    for _ in range(3):
        world.step(0.02)
    assert np.isfinite(world.state.velocities).all()
    assert abs(world.state.velocities[0, 0, 0]) < 1e3


def test_a_restored_snapshot_recovers_from_the_error():
    world = physics.World("rod_control")
    snapshot = world.get_state()
    world.set_state(velocities=[[[1e160, 0.0], [0.0, 0.0]]])
    with pytest.raises(physics.SimulationError):
        world.step(0.02)
    world.restore(snapshot)
    world.step(0.02)
    assert np.isfinite(world.state.positions).all()


def test_a_force_beyond_what_the_step_resolves_warns_and_flags_the_element():
    """1e15 N on the 0.3 kg mallet, the rod between it and the cushion: the settling needs
    ~1e13 substeps and takes 1e6; the mallet ends up past the rod (a tunnel), and the step says
    so. An ordinary step leaves the flag off."""
    world = physics.World("rod_control", batch_size=2)
    world.step(0.02)
    assert not world.last_step.capped.any()
    world.set_force("mallet", [[1e15, 0.0], [1.0, 0.0]])
    with pytest.warns(RuntimeWarning, match=r"element\(s\) \[0\]: .* cap of 1,000,000 substeps"):
        world.step(0.02)
    assert world.last_step.capped.tolist() == [True, False]
    assert world.last_step.fallback[0] and world.last_step.substeps[0] == 1_000_000
    assert not world.last_step.capped.flags.writeable


def test_a_force_the_settling_can_resolve_does_not_warn():
    """1e6 N on the mallet squeezing the rod against the cushion: ~5e4 settling substeps, within
    the cap; no warning, and no tunnel."""
    world = physics.World("rod_control")
    world.set_force("mallet", [1e6, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        world.step(0.02)
    assert world.last_step.fallback[0] and not world.last_step.capped[0]
    rod, mallet = world.state.positions[0, :, 0]
    assert mallet < rod
