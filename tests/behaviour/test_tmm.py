"""Laplace-domain TMM: poles and frequency responses against independent linear algebra."""
import numpy as np
import scipy.linalg as sla

from dtdyn.linear.chain import chain_matrices
from dtdyn.linear.tmm import frequency_response, undamped_poles

from problems import P2, P3


def test_p3_poles_equal_generalized_eigenvalues():
    w = undamped_poles(P3["mass"], P3["stiffness"])
    M, _, K = chain_matrices(P3["mass"], P3["stiffness"], P3["damping"], sparse=False)
    w_ref = np.sqrt(sla.eigh(K, M, eigvals_only=True))
    np.testing.assert_allclose(w, w_ref, rtol=1e-10)
    assert abs(w[0] - 9.49) < 0.01 and abs(w[-1] - 148.2) < 0.05  # reference.md section 7


def test_frequency_response_equals_dynamic_stiffness_solve():
    omega = np.array([0.3, 1.7, 2.9, 10.0])
    M, C, K = chain_matrices(P2["mass"], P2["stiffness"], P2["damping"], sparse=False)
    for load in (0, 1):
        for out in (0, 1):
            H = frequency_response(P2["mass"], P2["stiffness"], P2["damping"], omega, load, out)
            ref = [np.linalg.solve(-w * w * M + 1j * w * C + K, np.eye(2)[load])[out]
                   for w in omega]
            np.testing.assert_allclose(H, ref, rtol=1e-12)
