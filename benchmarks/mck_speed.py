"""mck_response's C loop against a lean NumPy loop with a prefactored LU (the peer), same run.

A 10-DOF chain (random masses 1..2 kg, springs 1e3..2e3 N/m, dampers 0.1..1 N s/m), a random
force on two DOFs, 200,000 steps of dt = 1e-3 s, average acceleration (Newmark beta = 1/4,
gamma = 1/2), all DOFs' x, v, a stored. The peer is the textbook incremental-free Newmark step
written as tightly as NumPy allows: a_{n+1} = LU^-1 (f_{n+1} - C v* - K x*), the effective
matrix M + gamma dt C + beta dt^2 K factorized once (scipy.linalg.lu_factor). Times: median
[min, max] of 3 runs after a warm-up, BLAS pinned to one thread (dtdyn.app.pin_blas).

    python benchmarks/mck_speed.py [n_steps]
"""
import sys

import numpy as np
import scipy.linalg as sla

import dtdyn as dd
from dtdyn.app import measure, pin_blas


def peer(M, C, K, f, dt, loaded):
    """Newmark average acceleration, the lean NumPy way."""
    n, beta, gamma = M.shape[0], 0.25, 0.5
    lu = sla.lu_factor(M + gamma * dt * C + beta * dt * dt * K)
    x, v = np.zeros(n), np.zeros(n)
    F = np.zeros(n)
    F[loaded] = f[0]
    a = np.linalg.solve(M, F)
    X = np.empty((f.shape[0], n))
    X[0] = x
    for k in range(1, f.shape[0]):
        xs = x + dt * v + (0.5 - beta) * dt * dt * a
        vs = v + (1 - gamma) * dt * a
        F[loaded] = f[k]
        a = sla.lu_solve(lu, F - C @ vs - K @ xs, check_finite=False)
        x, v = xs + beta * dt * dt * a, vs + gamma * dt * a
        X[k] = x
    return X


def main(n_steps=200_000):
    rng = np.random.default_rng(0)
    n = 10
    M, C, K = dd.chain_matrices(rng.uniform(1, 2, n), rng.uniform(1e3, 2e3, n),
                                rng.uniform(0.1, 1, n), sparse=False)
    f = rng.standard_normal((n_steps + 1, 2))
    kw = dict(force_dofs=[3, 9], scheme="average_acceleration")
    dd.mck_response(M, C, K, f[:100], 1e-3, **kw)  # compile or load the kernel
    r, t_c = measure(lambda: dd.mck_response(M, C, K, f, 1e-3, **kw), 3)
    X, t_peer = measure(lambda: peer(M, C, K, f, 1e-3, [3, 9]), 3)
    err = np.abs(r.x - X).max() / np.abs(X).max()
    print(f"{n}-DOF model, {n_steps:,} steps, average acceleration, x v a of every DOF stored")
    print(f"mck_response (C loop):            {t_c.format():>26s}  "
          f"({t_c / n_steps * 1e6:.3f} us per step)")
    print(f"lean NumPy loop, prefactored LU:  {t_peer.format():>26s}  "
          f"({t_peer / n_steps * 1e6:.3f} us per step)")
    print(f"ratio: {t_peer / t_c:.1f}x; the two agree to {err:.1e} (relative to max |x|)")


if __name__ == "__main__":
    with pin_blas(1) as pin:
        print(f"{pin.describe()}; times: median [min, max] of the repeats")
        main(int(float(sys.argv[1])) if len(sys.argv) > 1 else 200_000)
