"""Every catalogue case on every solver that claims it: the measured worst error respects the
claim (a physical law or an exact expected value; see ``tests/stability/catalogue.py``)."""

import pytest

from tests.stability.catalogue import CASES, SOLVERS, by_name

PAIRS = [(case.name, solver) for case in CASES for solver in case.claims]


@pytest.mark.parametrize(("name", "solver"), PAIRS, ids=[f"{n}-{s}" for n, s in PAIRS])
def test_case(name, solver):
    case = by_name(name)
    claim = case.claims[solver]
    m = case.measure(solver)
    relation = ">=" if claim.at_least else "<="
    assert claim.holds(m.worst), (f"{name} on {solver}: worst {m.worst:.3e} {case.unit}, "
                                  f"claim {relation} {claim.bound:g} ({m.notes})")


def test_catalogue_is_well_formed():
    names = [c.name for c in CASES]
    assert len(names) == len(set(names))
    for case in CASES:
        assert "exact" in case.claims, f"{case.name}: every case runs on the exact solver"
        assert set(case.claims) <= set(SOLVERS)
        assert case.title and case.checks and case.unit and case.brief
    with pytest.raises(KeyError, match="no case"):
        by_name("nope")
