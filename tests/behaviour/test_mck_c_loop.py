"""mck_response's generated C loop (dense matrices) against its NumPy loop, every scheme: the
same step in another summation order, so the same results to round-off amplified by the scheme:
1e-12 of the peak; 1e-11 for Houbolt, whose backward difference a_{n+1} = (2 x_{n+1} - 5 x_n +
4 x_{n-1} - x_{n-2}) / dt^2 turns the last bits of x into the next step's load."""
import numpy as np
import pytest

import dtdyn as dd
from dtdyn.generated.scheme_table import TABLE


@pytest.fixture(scope="module")
def model():
    rng = np.random.default_rng(0)
    n = 10
    M, C, K = dd.chain_matrices(rng.uniform(1, 2, n), rng.uniform(1e3, 2e3, n),
                                rng.uniform(0.1, 1, n), sparse=False)
    M[0, 3] = M[3, 0] = 0.2        # a consistent (non-diagonal) mass matrix
    return M, C, K, rng.standard_normal((3001, 2))


@pytest.mark.parametrize("scheme", sorted(TABLE))
def test_c_loop_equals_numpy_loop(model, scheme):
    M, C, K, f = model
    kw = dict(force_dofs=[3, 9], scheme=scheme, dt=1e-3, outputs=[0, 4, 9],
              x0=np.linspace(0, 1e-3, 10), v0=np.full(10, 1e-2))
    a = dd.mck_response(M, C, K, f, backend="numpy", **kw)
    b = dd.mck_response(M, C, K, f, backend="c", **kw)
    assert b.info["backend"] == "c" and a.info["backend"] == "numpy"
    t = 1e-11 if scheme == "houbolt" else 1e-12
    for q in "xva":
        ref = getattr(a, q)
        assert np.abs(getattr(b, q) - ref).max() <= t * np.abs(ref).max(), q
