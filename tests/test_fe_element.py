"""Assembly checks of the nonlinear finite element chain (Chapter IV) through
the public fe_system: the Newton matrix against central differences (both
tip-moment forms, cubic moment law on) and a Taylor test, the chain mass.
The element kernels themselves (the F-tensor form of Eq. 77, element force
and tangent against central differences, the exact mass, the reduced
element) are tested in Fortran: tests/fortran/test_fe_element.f90.
"""
import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid
from beamid import fe


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
