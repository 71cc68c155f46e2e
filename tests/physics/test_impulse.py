"""Laws of the impulse law itself, over random geometry and mass ratios 1e-9..1e9 (hypothesis).

Calls the numba kernel ``physics.impulse.resolve`` directly on random state rows.
"""

import math

import numpy as np
from hypothesis import example, given
from hypothesis import strategies as st

from spinstrike.physics.impulse import apply_impulse, relative_velocity, resolve
from spinstrike.physics.layout import INV_INERTIA, INV_MASS, OMEGA, PARAM_COLUMNS, VX, VY

finite = st.floats(-10.0, 10.0, allow_nan=False)
log_mass = st.floats(-4.5, 4.5)  # masses 10^-4.5..10^4.5: ratios up to 1e9
angle = st.floats(0.0, 2 * math.pi)
unit = st.floats(0.0, 1.0)


def _body(log_m, size, v, w):
    m = 10.0**log_m
    inertia = m * size**2 / 3.0
    s = np.zeros(6)
    s[VX], s[VY], s[OMEGA] = v[0], v[1], w
    p = np.zeros(PARAM_COLUMNS)
    p[INV_MASS], p[INV_INERTIA] = 1.0 / m, 1.0 / inertia
    return s, p, m, inertia


def _energy(bodies):
    return sum(0.5 * m * (s[VX] ** 2 + s[VY] ** 2) + 0.5 * i * s[OMEGA] ** 2 for s, m, i in bodies)


contact = st.fixed_dictionaries({
    "la": log_mass, "lb": log_mass, "size_a": st.floats(0.01, 1.0), "size_b": st.floats(0.01, 1.0),
    "va": st.tuples(finite, finite), "vb": st.tuples(finite, finite),
    "wa": finite, "wb": finite, "normal": angle,
    "oa": st.tuples(st.floats(-1, 1), st.floats(-1, 1)),
    "ob": st.tuples(st.floats(-1, 1), st.floats(-1, 1)),
    "ka": st.floats(0.0, 0.1), "kb": st.floats(0.0, 0.1),
    "e": unit, "mu": st.floats(0.0, 2.0), "wall": st.booleans(),
})


def _run(c, friction):
    """One contact through the kernel; body a is row 0, body b row 1 (ignored for a cushion)."""
    sa, pa, ma, ia = _body(c["la"], c["size_a"], c["va"], c["wa"])
    if c["wall"]:
        sb, pb, mb, ib = np.zeros(6), np.zeros(PARAM_COLUMNS), 0.0, 0.0
    else:
        sb, pb, mb, ib = _body(c["lb"], c["size_b"], c["vb"], c["wb"])
    S = np.stack([sa, sb])
    Pm = np.stack([pa, pb])
    nx, ny = math.cos(c["normal"]), math.sin(c["normal"])
    geo = (nx, ny, *c["oa"], c["ka"], *c["ob"], c["kb"])
    before = [S[0].copy(), S[1].copy()]
    vn0, vt0, _ = relative_velocity(S, 0, 1, c["wall"], *geo)
    j, jt, vn = resolve(S, Pm, 0, 1, c["wall"], *geo, c["e"], c["mu"], True, friction)
    vn1, vt1, _ = relative_velocity(S, 0, 1, c["wall"], *geo)
    sa, sb = S[0], S[1]
    bodies = [(before[0], ma, ia), (before[1], mb, ib)], [(sa, ma, ia), (sb, mb, ib)]
    return locals()


@given(contact)
def test_impulse_conserves_momentum_and_never_gains_energy(c):
    r = _run(c, friction=True)
    sa, sb, (a0, b0) = r["sa"], r["sb"], r["before"]
    ma, mb = r["ma"], r["mb"]
    assert r["j"] >= 0.0
    e0, e1 = _energy(r["bodies"][0]), _energy(r["bodies"][1])
    assert e1 <= e0 * (1 + 1e-12) + 1e-300
    if not c["wall"]:
        scale = (ma * math.hypot(a0[VX], a0[VY]) + mb * math.hypot(b0[VX], b0[VY])
                 + r["j"] + abs(r["jt"]))
        for k in (VX, VY):
            assert abs(ma * (sa[k] - a0[k]) + mb * (sb[k] - b0[k])) <= 1e-12 * scale


@given(contact)
def test_restitution_law_along_the_normal_without_friction(c):
    r = _run(c, friction=False)
    vn0, vn1 = r["vn0"], r["vn1"]
    scale = sum(abs(x) for x in (*c["va"], *c["vb"], c["wa"], c["wb"])) * 2 + abs(vn1) + 1e-300
    if vn0 < 0:
        assert abs(vn1 + c["e"] * vn0) <= 1e-9 * scale
        if c["e"] == 1.0:
            e0, e1 = _energy(r["bodies"][0]), _energy(r["bodies"][1])
            assert abs(e1 - e0) <= 1e-12 * e0
    else:  # separating or resting pair: no impulse at all
        assert r["j"] == 0.0 and vn1 == vn0


@example(c={"la": 0.0, "lb": 2.0, "size_a": 0.8203125, "size_b": 1.0, "va": (0.0, 4.0),
            "vb": (0.0, 4.0), "wa": -0.5, "wb": 0.0, "normal": 1.0, "oa": (-0.5625, 0.53125),
            "ob": (0.0, 0.0), "ka": 0.0, "kb": 0.0, "e": 0.390625, "mu": 1.0, "wall": False})
@given(contact)
def test_friction_bounded_by_mu_j_and_never_reverses_slip(c):
    """The tangential stage opposes the slip it meets (after the normal impulse), is at most
    mu * j, and at most stops the slip; the contact is left not approaching."""
    normal_only = _run(c, friction=False)
    full = _run(c, friction=True)
    if normal_only["vn0"] >= 0:
        assert full["j"] == 0.0 and full["jt"] == 0.0
        return
    S, Pm = normal_only["S"], normal_only["Pm"]
    geo = (math.cos(c["normal"]), math.sin(c["normal"]), *c["oa"], c["ka"], *c["ob"], c["kb"])
    _, vt_mid, _ = relative_velocity(S, 0, 1, c["wall"], *geo)
    jt = full["jt"]
    j_normal = normal_only["j"]
    assert abs(jt) <= c["mu"] * j_normal * (1 + 1e-12)
    assert jt * vt_mid <= 0.0
    # apply the tangential impulse alone: the slip shrinks but keeps its sign
    nx, ny = geo[0], geo[1]
    tx, ty = -ny, nx
    rta = c["oa"][0] * ty - c["oa"][1] * tx + c["ka"]
    rtb = c["ob"][0] * ty - c["ob"][1] * tx - c["kb"]
    apply_impulse(S, Pm, 0, 1, c["wall"], jt, tx, ty, rta, rtb, True)
    _, vt_after, _ = relative_velocity(S, 0, 1, c["wall"], *geo)
    # (a slip friction stops exactly ends at zero up to the rounding of the velocities it came
    # from: a sign flip is allowed only at that size)
    scale = sum(abs(x) for x in (*c["va"], *c["vb"], c["wa"], c["wb"])) * 2 + abs(vt_mid)
    assert vt_after * vt_mid >= 0.0 or abs(vt_after) <= 1e-13 * scale
    assert abs(vt_after) <= abs(vt_mid) * (1 + 1e-12)
    scale = 1.0 + abs(normal_only["vn0"]) + abs(vt_mid)
    assert full["vn1"] >= -1e-12 * scale  # left not approaching
