"""Element and assembly checks of the nonlinear finite element chain (Chapter IV).

* the Gauss-point element against the dissertation's F-tensor form (Eq. 77):
  internal forces as contractions of nodal values with exact integrals of
  products of shape-function derivatives, built here with numpy polynomials;
* hand-coded tangents against central differences (element and chain, both
  tip-moment forms, cubic moment law on);
* the consistent mass integrates mass and second moments exactly.
"""
import functools
import itertools

import numpy as np
import pytest
from numpy.polynomial import Polynomial as P
from numpy.testing import assert_allclose

import beamid
from beamid import fe


# --- the F-tensor form (Eq. 77) -------------------------------------------------

def _shape_polys(h):
    """Hermite functions of Eq. 76 as polynomials in zeta = s/h."""
    z = P([0.0, 1.0])
    return [1 - 3 * z**2 + 2 * z**3, h * (z - 2 * z**2 + z**3), 3 * z**2 - 2 * z**3,
            h * (-z**2 + z**3)]


@functools.lru_cache(maxsize=None)
def _f_tensor(h, orders):
    """F_{j k ...} = int_0^1 prod_i f_{j_i}^{(orders_i)} dzeta, derivatives in s."""
    polys = _shape_polys(h)
    derivs = {o: [p.deriv(o) / h**o if o else p for p in polys] for o in set(orders)}
    out = np.empty((4,) * len(orders))
    for idx in itertools.product(range(4), repeat=len(orders)):
        prod = P([1.0])
        for o, j in zip(orders, idx):
            prod = prod * derivs[o][j]
        integral = prod.integ()
        out[idx] = integral(1.0) - integral(0.0)
    return out


def _tensor_force(h, ea, ei, qe):
    """Internal force of one element from F tensors (the structure of Eq. 77:
    N*_j, N**_jk, M*_j, M**_jk are contractions of U, W with F', F'')."""
    W, U = qe[[0, 1, 4, 5]], qe[[2, 3, 6, 7]]
    F = {}

    def T(*orders):
        if orders not in F:
            F[orders] = _f_tensor(h, orders)
        return F[orders]

    def c(orders, *vectors):
        """Contract the last len(vectors) indices of F[orders]... with vectors;
        the first index is the test function."""
        t = T(*orders)
        for v in reversed(vectors):
            t = t @ v
        return t

    # a = U.f', b = W.f', c = U.f'', d = W.f''; test index first in every tensor.
    # axial (EA e de/dq):   e (1+a) f_k'  and  e b f_k'
    fu = ea * (c((1, 1), U) + 1.5 * c((1, 1, 1), U, U) + 0.5 * c((1, 1, 1), W, W)
               + 0.5 * c((1, 1, 1, 1), U, U, U) + 0.5 * c((1, 1, 1, 1), U, W, W))
    fw = ea * (c((1, 1, 1), U, W) + 0.5 * c((1, 1, 1, 1), U, U, W)
               + 0.5 * c((1, 1, 1, 1), W, W, W))
    # bending (EI chi dchi/dq), chi = d + d a - b c:
    #   dchi/dU_k = d f_k' - b f_k'';  dchi/dW_k = (1+a) f_k'' - c f_k'
    fu += ei * (c((1, 2, 2), W, W) + c((1, 2, 1, 2), W, U, W) - c((1, 1, 2, 2), W, U, W)
                - c((2, 2, 1), W, W) - c((2, 2, 1, 1), W, U, W) + c((2, 1, 2, 1), W, U, W))
    fw += ei * (c((2, 2), W) + 2.0 * c((2, 2, 1), W, U) - c((1, 2, 2), W, U)
                + c((2, 2, 1, 1), W, U, U) - c((1, 2, 1, 2), W, U, U)
                - c((2, 1, 2), W, U) - c((2, 1, 2, 1), W, U, U) + c((1, 1, 2, 2), W, U, U))
    out = np.empty(8)
    out[[0, 1, 4, 5]] = h * fw
    out[[2, 3, 6, 7]] = h * fu
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_element_force_matches_f_tensor_form(seed):
    rng = np.random.default_rng(seed)
    h, ea, ei = 0.388, 1.37e7, 11.4
    qe = 0.3 * rng.standard_normal(8)
    got = fe.fe_element(h, ea, ei, qe)["force"]
    want = _tensor_force(h, ea, ei, qe)
    assert_allclose(got, want, rtol=1e-11, atol=1e-9 * np.abs(want).max())


# --- derivatives against central differences --------------------------------------

def _central_jacobian(func, x, step):
    # fourth-order central differences: with the cubic moment law on a short
    # element the second-order stencil's truncation error (C step^2 f''^4 h,
    # f'' ~ 6/h^2) reaches 1e-6 of the tangent (h = 0.0625, C = 8 at q = 0)
    cols = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = step
        cols.append((8 * (func(x + e) - func(x - e)) - (func(x + 2 * e) - func(x - 2 * e)))
                    / (12 * step))
    return np.array(cols).T


@pytest.mark.parametrize("cubic", [0.0, 7.5])
def test_element_tangent_and_force_central_differences(cubic):
    rng = np.random.default_rng(3)
    h, ea, ei = 0.25, 2.0e5, 11.3
    qe = 0.4 * rng.standard_normal(8)
    out = fe.fe_element(h, ea, ei, qe, cubic=cubic)
    energy = lambda q: np.array([fe.fe_element(h, ea, ei, q, cubic=cubic)["energy"]])
    force = lambda q: fe.fe_element(h, ea, ei, q, cubic=cubic)["force"]
    assert_allclose(out["force"], _central_jacobian(energy, qe, 1e-6)[0],
                    rtol=1e-7, atol=1e-7 * np.abs(out["force"]).max())
    k_fd = _central_jacobian(force, qe, 1e-6)
    assert_allclose(out["tangent"], k_fd, atol=1e-7 * np.abs(out["tangent"]).max())
    assert_allclose(out["tangent"], out["tangent"].T, atol=1e-9 * np.abs(out["tangent"]).max())


@pytest.mark.parametrize("form", ["eq78", "exact"])
def test_chain_newton_matrix_central_differences(form):
    """d(NLT - Q)/dq of the assembled chain, tip force and moment, both moment forms."""
    model = beamid.pace(C1=3.0, C2=1.0)
    load = beamid.TipForce(fx=-2.0, fy=3.0) + beamid.TipMoment(4.0)
    nepb = 2
    n = 4 * (2 * nepb + 1) - 3
    q = 0.2 * np.random.default_rng(5).standard_normal(n)

    def residual(x):
        s = fe.fe_system(model, x, load, nepb, moment_form=form)
        return s["force"] - s["load"]

    sys = fe.fe_system(model, q, load, nepb, moment_form=form)
    jac_fd = _central_jacobian(residual, q, 1e-6)
    scale = np.abs(sys["jacobian"]).max()
    assert_allclose(sys["jacobian"], jac_fd, atol=1e-8 * scale)
    # the Jacobian is banded: half-bandwidth 7 (cost linear in the elements)
    i, j = np.nonzero(sys["jacobian"])
    assert np.max(np.abs(i - j)) <= 7


def test_taylor_remainder_is_second_order():
    """|R(q + t d) - R(q) - t J d| falls like t^2 (PETSc-style Taylor test)."""
    model = beamid.pace()
    load = beamid.TipMoment(5.0)
    n = 4 * 5 - 3
    rng = np.random.default_rng(11)
    q, d = 0.2 * rng.standard_normal(n), rng.standard_normal(n)
    base = fe.fe_system(model, q, load, 2)
    r0, jac = base["force"] - base["load"], base["jacobian"]
    errs = []
    for t in (1e-2, 5e-3, 2.5e-3):
        s = fe.fe_system(model, q + t * d, load, 2)
        errs.append(np.linalg.norm(s["force"] - s["load"] - r0 - t * jac @ d))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(orders > 1.9)


# --- mass -----------------------------------------------------------------------------

def test_element_mass_integrates_exactly():
    h, rho = 0.37, 0.53
    m = fe.fe_element(h, 1.0, 1.0, np.zeros(8), rho=rho)["mass"]
    one = np.array([1, 0, 0, 0, 1, 0, 0, 0.0])         # w = 1
    ramp = np.array([0, 1, 0, 0, h, 1, 0, 0.0])        # w = s
    assert_allclose(one @ m @ one, rho * h, rtol=1e-14)
    assert_allclose(ramp @ m @ ramp, rho * h**3 / 3, rtol=1e-14)
    assert_allclose(one @ m @ ramp, rho * h**2 / 2, rtol=1e-14)
    assert_allclose(m, m.T)


def test_chain_mass_has_total_mass_and_second_moment():
    """u = s (u' = 1) is admissible under the clamp (u(0) = 0, u'(0) free):
    q^T M q = sum rho_i int s^2 ds + m_elbow L1^2 + m_tip (L1 + L2)^2."""
    model = beamid.pace()
    p = model.params
    nepb = 3
    n = 4 * (2 * nepb + 1) - 3
    m = fe.fe_system(model, np.zeros(n), None, nepb)["mass"]
    l1, l2 = p["L1"], p["L2"]
    s = np.concatenate([np.linspace(0, l1, nepb + 1), np.linspace(l1, l1 + l2, nepb + 1)[1:]])
    table = np.zeros((s.size, 4))
    table[:, 2], table[:, 3] = s, 1.0
    q = table.ravel()[3:]
    want = (p["rho1"] * l1**3 / 3 + p["rho2"] * ((l1 + l2)**3 - l1**3) / 3
            + p["m_elbow"] * l1**2 + p["m_tip"] * (l1 + l2)**2)
    assert_allclose(q @ m @ q, want, rtol=1e-13)
    assert_allclose(m, m.T)
    assert np.all(np.linalg.eigvalsh(m) > 0)


def test_rotary_inertia_enters_the_slope_unknowns():
    model = beamid.pace()
    n = 4 * 3 - 3
    plain = fe.fe_system(model, np.zeros(n), None, 1)["mass"]
    rot = fe.fe_system(model, np.zeros(n), None, 1, rotary_inertia=True)["mass"]
    diff = rot - plain
    # tip node 3: free indices of w' (node 3, comp 2) and of the elbow w' (node 2)
    tip_dw, elbow_dw = 4 * 2 + 1 - 3, 4 * 1 + 1 - 3
    assert_allclose(diff[tip_dw, tip_dw], model.params["J_tip"])
    assert_allclose(diff[elbow_dw, elbow_dw], model.params["J_elbow"])
    assert np.count_nonzero(diff) == 2


try:
    from hypothesis import given, settings, strategies as st
except ImportError:  # pragma: no cover - hypothesis is a test extra
    given = None

if given is not None:
    @settings(max_examples=25, deadline=None)
    @given(st.lists(st.floats(-0.6, 0.6), min_size=8, max_size=8),
           st.floats(0.05, 1.0), st.floats(0.0, 20.0))
    def test_element_tangent_property(values, h, cubic):
        """At random states, lengths and cubic coefficients the tangent is the
        central-difference derivative of the force (relative 1e-6)."""
        qe = np.array(values)
        ea, ei = 1.0e4, 10.0
        out = fe.fe_element(h, ea, ei, qe, cubic=cubic)
        force = lambda q: fe.fe_element(h, ea, ei, q, cubic=cubic)["force"]
        k_fd = _central_jacobian(force, qe, 1e-6)
        scale = max(np.abs(out["tangent"]).max(), 1.0)
        assert np.abs(out["tangent"] - k_fd).max() <= 1e-6 * scale
