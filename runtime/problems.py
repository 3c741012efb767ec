"""The reference problems of shared/reference.md section 7, as data (for `dtdyn bench`).

P3: 15-DOF chain of Kumar & Sankar (1986), undamped, unit step on mass 15, T = 0.8 s.
P4: the nonlinear 4-DOF chain (the shape of Ahlin's example):

    ground --[k, k3]--(m0)--[k]--(m1)--[k, k3]--(m2)--[k]--(m3) <- f(t)

four unit masses, k = 1e4 N/m, C = 1.0 M + 2e-4 K, cubic springs k3 = 2e7 N/m^3 from DOF 0 to
ground and between DOFs 1 and 2 (0-based), white noise of 100 N standard deviation on DOF 3
(numpy.random.default_rng(0)), fs = 1000 Hz, force linear between samples.
"""
from __future__ import annotations

import numpy as np

P3_MASS = [10, 9, 8, 7, 6, 6, 5.5, 5, 4.5, 4, 3.5, 4, 2.5, 2, 2]
P3_STIFFNESS = [55000, 50000, 45000, 40000, 40000, 35000, 30000, 25000, 20000, 15000, 10000,
                9000, 8000, 7000, 6000]


def p3() -> dict:
    from .chain import chain_matrices
    mass, stiffness = np.array(P3_MASS, float), np.array(P3_STIFFNESS, float)
    damping = np.zeros(15)
    M, C, K = chain_matrices(mass, stiffness, damping, sparse=False)
    return dict(mass=mass, stiffness=stiffness, damping=damping, M=M, C=C, K=K, T=0.8,
                loaded=[14], output=14)


def p4(n_samples: int = 100_000) -> dict:
    from .chain import chain_matrices
    from .elements import Cubic
    k, k3 = 1e4, 2e7
    M, _, K = chain_matrices(np.ones(4), np.full(4, k), np.zeros(4), sparse=False)
    C = 1.0 * M + 2e-4 * K
    force = (np.random.default_rng(0).standard_normal(n_samples) * 100.0)[:, None]
    return dict(M=M, C=C, K=K, force=force, fs=1000.0, force_dofs=[3],
                elements=[Cubic(0, None, k3=k3), Cubic(1, 2, k3=k3)], k=k, k3=k3, output=3)
