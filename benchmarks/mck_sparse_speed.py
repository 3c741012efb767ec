"""mck_response on sparse matrices: the C loop against the NumPy/scipy.sparse loop, same run.

Two sparse models of 10,000 DOFs: a chain (random masses 1..2 kg, springs 1e5..2e5 N/m,
dampers 0.1..1 N s/m; tridiagonal) and a 100 x 100 grid of masses, each tied to its four
neighbours and, along the edges, to the ground by springs (a membrane-like 2-D model: banded
with bandwidth 100, the sparse LU fills in), Rayleigh damping. A random force on two DOFs,
average acceleration (Newmark 1/4, 1/2), dt = 1e-3 s; x, v, a of every 100th DOF stored.
Then a 1,000-DOF chain over ten times the steps, where the per-step cost of Python shows.

Three runs of the same record: mck_response with backend="c" (the effective matrix factorized
once by SuperLU, least-fill ordering; products and substitutions in C, whole blocks of steps
per call), backend="numpy" (the same factors, stepped with scipy.sparse products and
SuperLU's solve), and a lean textbook Newmark loop in NumPy/scipy.sparse with its own
prefactored splu (the peer). Times: median [min, max] of 3 runs (the C kernel compiled or
loaded first), BLAS pinned to one thread (dtdyn.app.pin_blas, threadpoolctl).

    python benchmarks/mck_sparse_speed.py [n_steps]
"""
import sys

import numpy as np
import scipy.sparse as sps
import scipy.sparse.linalg as spla

import dtdyn as dd
from dtdyn.app import measure, pin_blas


def peer(M, C, K, f, dt, loaded, outputs):
    """Newmark average acceleration, the lean NumPy/scipy.sparse way (x at ``outputs``)."""
    n, beta, gamma = M.shape[0], 0.25, 0.5
    lu = spla.splu(sps.csc_matrix(M + gamma * dt * C + beta * dt * dt * K),
                   permc_spec="MMD_AT_PLUS_A")
    x, v = np.zeros(n), np.zeros(n)
    F = np.zeros(n)
    F[loaded] = f[0]
    a = spla.splu(sps.csc_matrix(M)).solve(F)
    X = np.empty((f.shape[0], len(outputs)))
    X[0] = x[outputs]
    for k in range(1, f.shape[0]):
        xs = x + dt * v + (0.5 - beta) * dt * dt * a
        vs = v + (1 - gamma) * dt * a
        F[loaded] = f[k]
        a = lu.solve(F - C @ vs - K @ xs)
        x, v = xs + beta * dt * dt * a, vs + gamma * dt * a
        X[k] = x[outputs]
    return X


def chain(rng, n=10_000):
    return dd.chain_matrices(rng.uniform(1, 2, n), rng.uniform(1e5, 2e5, n),
                             rng.uniform(0.1, 1, n), sparse=True)


def grid(rng, side=100):
    n = side * side
    ids = np.arange(n).reshape(side, side)
    pairs = np.vstack([np.c_[ids[:, :-1].ravel(), ids[:, 1:].ravel()],
                       np.c_[ids[:-1, :].ravel(), ids[1:, :].ravel()]])
    k = rng.uniform(1e5, 2e5, len(pairs))
    W = sps.coo_matrix((k, (pairs[:, 0], pairs[:, 1])), shape=(n, n)).tocsr()
    W = W + W.T
    edge = np.zeros((side, side))
    edge[0, :] = edge[-1, :] = edge[:, 0] = edge[:, -1] = 2e5
    K = (sps.diags(np.asarray(W.sum(axis=1)).ravel() + edge.ravel()) - W).tocsr()
    M = sps.diags(rng.uniform(1, 2, n)).tocsr()
    return M, (0.5 * M + 1e-4 * K).tocsr(), K


def run(name, M, C, K, f, dt):
    n = M.shape[0]
    loaded, outputs = [n // 3, n - 1], np.arange(0, n, 100)
    kw = dict(force_dofs=loaded, outputs=outputs, scheme="average_acceleration")
    dd.mck_response(M, C, K, f[:50], dt, **kw)  # compile or load the kernel
    rc, t_c = measure(lambda: dd.mck_response(M, C, K, f, dt, **kw), 3, warmup=False)
    rn, t_np = measure(lambda: dd.mck_response(M, C, K, f, dt, backend="numpy", **kw), 3,
                       warmup=False)
    X, t_peer = measure(lambda: peer(M, C, K, f, dt, loaded, outputs), 3, warmup=False)
    n_steps = f.shape[0] - 1
    A = sps.csc_matrix(M + 0.5 * dt * C + 0.25 * dt * dt * K)
    lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A")
    err_np = max(np.abs(getattr(rc, q) - getattr(rn, q)).max() / np.abs(getattr(rn, q)).max()
                 for q in "xva")
    err_peer = np.abs(rc.x - X).max() / np.abs(X).max()
    us = 1e6 / n_steps
    print(f"{name}: {n:,} DOFs, nnz(K) = {K.nnz:,}, nnz(L + U) = {lu.L.nnz + lu.U.nnz:,}; "
          f"{n_steps:,} steps, average acceleration, x v a of {outputs.size} DOFs stored")
    print(f"  mck_response, C loop:                {t_c.format():>26s}  ({t_c * us:.1f} us/step)")
    print(f"  mck_response, NumPy/scipy.sparse:    {t_np.format():>26s}  ({t_np * us:.1f} us/step)"
          f"  {t_np / t_c:.1f}x the C loop; agree to {err_np:.1e} (x, v, a; relative to max)")
    print(f"  lean NumPy/scipy.sparse Newmark:     {t_peer.format():>26s}  "
          f"({t_peer * us:.1f} us/step)  {t_peer / t_c:.1f}x the C loop; agree to "
          f"{err_peer:.1e} (x)")


def main(n_steps=2_000):
    rng = np.random.default_rng(0)
    f = rng.standard_normal((n_steps + 1, 2))
    run("chain", *chain(rng), f, 1e-3)
    run("2-D grid 100 x 100", *grid(rng), f, 1e-3)
    f = rng.standard_normal((10 * n_steps + 1, 2))
    run("small chain", *chain(rng, 1_000), f, 1e-3)


if __name__ == "__main__":
    with pin_blas(1) as pin:
        print(f"{pin.describe()}; times: median [min, max] of the repeats")
        main(int(float(sys.argv[1])) if len(sys.argv) > 1 else 2_000)
