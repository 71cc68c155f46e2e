"""Shared test set-up: headless rendering, hypothesis profiles (``--hypothesis-profile``), and a
user's own module in the working directory (``user_module``)."""

import os
import sys

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

# The default suite (CI's) draws the same examples every run, so a red CI names a reproducible
# case, not a lucky draw; the `slow` profile (`pytest -m slow --hypothesis-profile slow`) explores
# fresh random examples, 33x as many, and found the cases pinned as @example in the tests.
settings.register_profile("default", deadline=None, max_examples=150, derandomize=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("slow", deadline=None, max_examples=5000,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


def _same_examples_whatever_was_imported() -> None:
    """Hypothesis (6.131 on) also draws the numbers written in the project's own modules, those
    imported so far in the process: which examples a derandomized test draws then depends on
    which modules its xdist worker had imported (a run with one more module loaded drew two
    degenerate stalled-search cases that the suite's runs never drew). The default profile draws
    without them, so a test draws what its own strategy gives, in any order; the ``slow``
    profile keeps them (they find edge cases: the two are pinned in test_stalled_search)."""
    try:
        from hypothesis.internal.conjecture import providers
    except ImportError:  # pragma: no cover  (a Hypothesis without the feature)
        return
    if hasattr(providers, "_get_local_constants"):
        empty = type(providers._local_constants)()
        providers._get_local_constants = lambda: empty


if os.environ.get("HYPOTHESIS_PROFILE", "default") == "default":
    _same_examples_whatever_was_imported()


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_pytest_tmp(tmp_path_factory):
    """SB3 models built without a logger make an empty ``SB3-<date>`` folder in ``/tmp`` on every
    ``learn()`` (hundreds a run); ``SB3_LOGDIR`` sends them into pytest's own, pruned, temp dir."""
    os.environ.setdefault("SB3_LOGDIR", str(tmp_path_factory.mktemp("sb3-logs")))


@pytest.fixture
def user_module(tmp_path, monkeypatch):
    """``write(name, source)``: a module of the user's own (one registering env variants with
    ``gym.register``, say) written into the working directory, ``tmp_path``, which it returns,
    and importable from there, as a user would have it. Afterwards the ids registered meanwhile
    and the modules written are gone from Gymnasium's registry and ``sys.modules``."""
    import gymnasium as gym

    before = set(gym.registry)
    written = []
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))

    def write(name: str, source: str):
        (tmp_path / f"{name}.py").write_text(source)
        written.append(name)
        return tmp_path

    yield write
    for env_id in set(gym.registry) - before:
        del gym.registry[env_id]
    for name in written:
        sys.modules.pop(name, None)


def pytest_collection_modifyitems(config, items):
    """The Ray tests share one xdist worker (``--dist loadgroup`` in pyproject.toml): each starts
    a local Ray of 2 CPUs, or a two-node cluster, and two of them at once would fight for the
    machine's cores and Ray's session directory."""
    for item in items:
        if item.get_closest_marker("rllib") or "tests/rllib/" in item.path.as_posix():
            item.add_marker(pytest.mark.xdist_group("ray"))  # the slow RLlib run too
