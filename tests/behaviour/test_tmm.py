"""Laplace-domain TMM: poles and frequency responses against independent linear algebra."""
import numpy as np
import pytest
import scipy.linalg as sla

from dtdyn.linear._chain import chain_matrices
import dtdyn as dd
from dtdyn.linear._frequencies import chain_frequencies
from dtdyn.linear._tmm import chain_frequency_response

from problems import P2, P3


def test_p3_poles_equal_generalized_eigenvalues():
    w = chain_frequencies(P3["mass"], P3["stiffness"])
    M, _, K = chain_matrices(P3["mass"], P3["stiffness"], P3["damping"], sparse=False)
    w_ref = np.sqrt(sla.eigh(K, M, eigvals_only=True))
    np.testing.assert_allclose(w, w_ref, rtol=1e-10)
    assert abs(w[0] - 9.49) < 0.01 and abs(w[-1] - 148.2) < 0.05  # reference.md section 7


def test_frequency_response_equals_dynamic_stiffness_solve():
    omega = np.array([0.3, 1.7, 2.9, 10.0])
    M, C, K = chain_matrices(P2["mass"], P2["stiffness"], P2["damping"], sparse=False)
    for load in (0, 1):
        for out in (0, 1):
            H = chain_frequency_response(P2["mass"], P2["stiffness"], P2["damping"], omega, load,
                                         out)
            ref = [np.linalg.solve(-w * w * M + 1j * w * C + K, np.eye(2)[load])[out]
                   for w in omega]
            np.testing.assert_allclose(H, ref, rtol=1e-12)
    # every pair at once: (omega, outputs, force_dofs), the dense solve's columns
    H = chain_frequency_response(P2["mass"], P2["stiffness"], P2["damping"], omega, [0, 1],
                                 [1, 0])
    ref = np.array([np.linalg.inv(-w * w * M + 1j * w * C + K)[[1, 0]] for w in omega])
    np.testing.assert_allclose(H, ref, rtol=1e-12)


def test_old_names_warn_and_agree():
    omega = np.array([0.3, 1.7])
    new = dd.chain_frequency_response(P2["mass"], P2["stiffness"], P2["damping"], omega,
                                      force_dofs=1, outputs=0)
    with pytest.warns(DeprecationWarning, match="chain_frequency_response"):
        old_function = dd.frequency_response
    with pytest.warns(DeprecationWarning, match="'force_dof' is now 'force_dofs'"):
        old = old_function(P2["mass"], P2["stiffness"], P2["damping"], omega, force_dof=1,
                           outputs=0)
    np.testing.assert_array_equal(old, new)
    with pytest.warns(DeprecationWarning, match="chain_frequencies"):
        np.testing.assert_array_equal(dd.undamped_poles(P3["mass"], P3["stiffness"]),
                                      dd.chain_frequencies(P3["mass"], P3["stiffness"]))
