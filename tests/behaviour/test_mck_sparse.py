"""mck_response on scipy.sparse matrices: the generated C loop (SuperLU's factors of the
effective matrix, sparse products and substitutions in C) against the NumPy/scipy.sparse loop and
against the dense C loop on the same model densified, every scheme: the same step in another
summation order, so 1e-12 of the peak (1e-11 for Houbolt, as in test_mck_c_loop.py: its
backward difference turns the last bits of x into the next step's load, amplified by about
max|x| / (dt^2 max|a|); the models are stiff enough for that to stay small: on a chain a hundred
times softer the dense C and NumPy loops already differ by 1e-11 after 600 steps)."""
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import scipy.sparse as sps

import dtdyn as dd
from dtdyn.generated.scheme_table import TABLE


def _laplacian(n, density, rng):
    """A random weighted graph Laplacian (symmetric, positive semi-definite, off-band)."""
    W = sps.triu(sps.random(n, n, density=density, random_state=rng), 1)
    W = W + W.T
    return sps.diags(np.asarray(W.sum(axis=1)).ravel()) - W


@pytest.fixture(scope="module")
def chain():
    rng = np.random.default_rng(1)
    n = 200
    M, C, K = dd.chain_matrices(rng.uniform(1, 2, n), rng.uniform(1e5, 2e5, n),
                                rng.uniform(0.1, 1, n), sparse=True)
    return M, C, K


@pytest.fixture(scope="module")
def coupled():
    """A chain plus random off-band springs, a consistent mass matrix and a gyroscopic
    (skew) damping term: a non-symmetric effective matrix with fill."""
    rng = np.random.default_rng(2)
    n = 150
    M, C, K = dd.chain_matrices(rng.uniform(1, 2, n), rng.uniform(1e5, 2e5, n),
                                rng.uniform(0.1, 1, n), sparse=True)
    K = K + 5e4 * _laplacian(n, 0.02, rng)
    M = M + 0.05 * _laplacian(n, 0.01, rng)
    G = sps.triu(sps.random(n, n, density=0.01, random_state=rng), 1)
    C = C + 1e-3 * K + 0.5 * (G - G.T)
    return sps.csr_matrix(M), sps.csr_matrix(C), sps.csr_matrix(K)


def _compare(a, b, scheme, what):
    t = 1e-11 if scheme == "houbolt" else 1e-12
    for q in ("x", "v", "a", "a_abs"):
        ref = getattr(a, q)
        if ref is None:
            assert getattr(b, q) is None, (what, q)
            continue
        err = np.abs(getattr(b, q) - ref).max() / np.abs(ref).max()
        assert err <= t, (what, q, err)


@pytest.mark.parametrize("model", ["chain", "coupled"])
@pytest.mark.parametrize("scheme", sorted(TABLE))
def test_sparse_c_loop_equals_numpy_and_dense_loops(request, model, scheme):
    M, C, K = request.getfixturevalue(model)
    n = M.shape[0]
    rng = np.random.default_rng(3)
    n_steps = 600
    f = rng.standard_normal((n_steps + 1, 2))
    ag = np.sin(np.arange(n_steps + 1) * 0.013)
    kw = dict(force_dofs=[3, n - 2], scheme=scheme, dt=1e-3, outputs=[0, 7, n // 2, n - 1],
              x0=rng.uniform(-1e-3, 1e-3, n), v0=rng.uniform(-1e-2, 1e-2, n),
              ground_acceleration=ag)
    a = dd.mck_response(M, C, K, f, backend="numpy", **kw)
    b = dd.mck_response(M, C, K, f, backend="c", **kw)
    c = dd.mck_response(M.toarray(), C.toarray(), K.toarray(), f, backend="c", **kw)
    assert a.info["backend"] == "scipy.sparse" and a.info["sparse"]
    assert b.info["backend"] == "c" and b.info["sparse"]
    assert c.info["backend"] == "c" and not c.info["sparse"]
    _compare(a, b, scheme, "sparse C vs scipy.sparse")
    _compare(b, c, scheme, "sparse C vs dense C")


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_singular_sparse_effective_matrix_is_named(backend):
    # DOF 2 has neither mass, damper nor spring: M + Dv C + Dx K has a zero row
    M = sps.diags([1.0, 1.0, 0.0, 1.0]).tocsr()
    K = sps.csr_matrix(np.array([[2.0, -1, 0, 0], [-1, 2, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1.0]]))
    C = sps.csr_matrix((4, 4))
    with pytest.raises(ValueError, match=r"the effective matrix M \+ Dv C \+ Dx K is singular"):
        dd.mck_response(M, C, K, np.ones(11), 1e-2, force_dofs=[0], backend=backend,
                        scheme="average_acceleration", unstable="warn")
    # a pivot below eps of the largest: nothing of the solve would be left
    M = sps.diags([1.0, 1e-20]).tocsr()
    with pytest.raises(ValueError, match=r"effective matrix .* numerically singular"):
        dd.mck_response(M, sps.csr_matrix((2, 2)), sps.csr_matrix((2, 2)), np.zeros(11), 1e-2,
                        force_dofs=[0], backend=backend, scheme="average_acceleration")


def test_sparse_c_loop_stops_at_the_first_non_finite_step(chain):
    M, C, K = chain
    with pytest.warns(dd.DtdynStabilityWarning), np.errstate(over="ignore", invalid="ignore"):
        with pytest.raises(FloatingPointError, match=r"not finite from step \d+ \(t = "):
            dd.mck_response(M, C, K, np.ones(20001), 0.05, force_dofs=[1],
                            scheme="central_difference", unstable="warn")


LONG_RUN = """
import time, numpy as np, scipy.sparse as sps, dtdyn as dd
import signal
signal.signal(signal.SIGINT, signal.default_int_handler)  # ignored in a shell's background job
M, C, K = dd.chain_matrices([1.0] * 3000, [1e3] * 3000, [0.1] * 3000, sparse=True)
run = lambda f: dd.mck_response(M, C, K, f, 1e-3, force_dofs=[2999], outputs=[0],
                                quantities=("x",))
short = run(np.ones(200)).x
print("start", flush=True)
t = time.time()
try:
    run(np.ones(2_000_000))
    print("finished", flush=True)
except KeyboardInterrupt:
    print("interrupted %.3f" % (time.time() - t), flush=True)
print("again", np.abs(run(np.ones(200)).x - short).max(), flush=True)
"""


@pytest.mark.slow
def test_ctrl_c_stops_the_sparse_c_loop_and_the_next_run_is_right():
    """SIGINT one second into a long sparse run stops it within a second; the stop flag is
    cleared, so the next run of the library gives the same numbers as before."""
    p = subprocess.Popen([sys.executable, "-c", LONG_RUN], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "start"
    time.sleep(1.0)
    t = time.perf_counter()
    p.send_signal(signal.SIGINT)
    out, _ = p.communicate(timeout=60)
    waited = time.perf_counter() - t
    lines = out.splitlines()
    assert p.returncode == 0 and lines[0].startswith("interrupted"), out
    assert waited < 1.0, waited
    assert lines[1] == "again 0.0", out
