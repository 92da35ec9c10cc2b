"""The reduced element kernels (fortran/beamid_fe_element.f90) rest on
f1 + f3 = 1 (Eq. 76): a rigid translation of the element changes neither e
(Eq. 70) nor chi (Eq. 72), so the w2 and u2 entries of the force and of the
tangent are minus those of w1 and u1. Checked here against the energy, which
is evaluated from the full shape functions."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from beamid import fe


@pytest.mark.parametrize("cubic", [0.0, 7.5])
def test_rigid_translation_leaves_element_unchanged(cubic):
    rng = np.random.default_rng(11)
    h, ea, ei = 0.31, 2.0e5, 11.3
    qe = 0.3 * rng.standard_normal(8)
    shift = np.array([0.7, 0.0, -0.4, 0.0, 0.7, 0.0, -0.4, 0.0])
    out = fe.fe_element(h, ea, ei, qe, cubic=cubic)
    moved = fe.fe_element(h, ea, ei, qe + shift, cubic=cubic)
    assert_allclose(moved["energy"], out["energy"], rtol=1e-11)
    assert_allclose(moved["force"], out["force"], atol=1e-10 * np.abs(out["force"]).max())
    assert_allclose(moved["tangent"], out["tangent"],
                    atol=1e-10 * np.abs(out["tangent"]).max())


@pytest.mark.parametrize("cubic", [0.0, 7.5])
def test_node_two_entries_mirror_node_one(cubic):
    """Energy gradient along a rigid translation is zero: f_w1 + f_w2 = 0 and
    f_u1 + f_u2 = 0, here by central differences of the energy."""
    rng = np.random.default_rng(12)
    h, ea, ei = 0.22, 1.0e5, 9.0
    qe = 0.3 * rng.standard_normal(8)
    out = fe.fe_element(h, ea, ei, qe, cubic=cubic)
    energy = lambda q: fe.fe_element(h, ea, ei, q, cubic=cubic)["energy"]
    step = 1e-6
    for dofs in ([0, 4], [2, 6]):
        e = np.zeros(8)
        e[dofs] = step
        slope = (energy(qe + e) - energy(qe - e)) / (2 * step)
        scale = np.abs(out["force"]).max()
        assert abs(slope) <= 1e-7 * scale
        assert_allclose(out["force"][dofs[1]], -out["force"][dofs[0]],
                        atol=1e-12 * scale)
