"""The default hypothesis profile (tests/conftest.py) draws the same examples in any test order:
Hypothesis's drawing of numbers from the project's loaded modules is off. A canary: if a new
Hypothesis renames what conftest turns off, this fails instead of the suite's examples quietly
depending on its xdist workers' imports again."""

import os

import pytest


@pytest.mark.skipif(os.environ.get("HYPOTHESIS_PROFILE", "default") != "default",
                    reason="only the default profile turns it off")
def test_no_numbers_are_drawn_from_the_projects_modules():
    from hypothesis.internal.conjecture import providers

    import spinstrike.physics.solvers  # noqa: F401  (a module full of constants, loaded)

    assert len(providers._get_local_constants()) == 0
