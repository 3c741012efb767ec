"""The reference problems P1-P4, as data: one home for the tests, the benchmarks, `dtdyn bench`
and the scenes.

P1: 1-DOF, m = 2 kg, k = 12 N/m, c = 3 N s/m, unit step force, dt = 0.02 s, T = 10 s.
P2: 2-DOF chain, m = [2, 3] kg, k = [20, 15] N/m, c = [5, 6] N s/m, unit step on the last mass,
dt = 0.02 s, T = 10 s.
P3: 15-DOF chain of Kumar & Sankar (1986), undamped, unit step on mass 15, T = 0.8 s.
P4: the nonlinear 4-DOF chain (the shape of Ahlin's example):

    ground --[k, k3]--(m0)--[k]--(m1)--[k, k3]--(m2)--[k]--(m3) <- f(t)

four unit masses, k = 1e4 N/m, C = 1.0 M + 2e-4 K, cubic springs k3 = 2e7 N/m^3 from DOF 0 to
ground and between DOFs 1 and 2 (0-based), white noise of 100 N standard deviation on DOF 3
(numpy.random.default_rng(0)), dt = 1 ms (fs = 1000 Hz), force linear between samples.
P4L: P4 without the cubic springs (the same M, C, K, force and record): the linear baseline
that `dtdyn bench P4` measures the price of the nonlinearity against.
"""
from __future__ import annotations

import numpy as np

P3_MASS = [10, 9, 8, 7, 6, 6, 5.5, 5, 4.5, 4, 3.5, 4, 2.5, 2, 2]
P3_STIFFNESS = [55000, 50000, 45000, 40000, 40000, 35000, 30000, 25000, 20000, 15000, 10000,
                9000, 8000, 7000, 6000]


def _chain(mass, stiffness, damping, **extra) -> dict:
    from dtdyn.linear._chain import chain_matrices
    mass, stiffness, damping = (np.array(v, float) for v in (mass, stiffness, damping))
    M, C, K = chain_matrices(mass, stiffness, damping, sparse=False)
    return dict(mass=mass, stiffness=stiffness, damping=damping, M=M, C=C, K=K, **extra)


def p1() -> dict:
    """P1: one DOF, m = 2 kg, k = 12 N/m, c = 3 N s/m, unit step, dt = 0.02 s, T = 10 s.

    Parameters
    ----------
    None

    Returns
    -------
    dict
        mass, stiffness, damping, M, C, K, dt, T, force_dofs, output.

    Examples
    --------
    >>> import dtdyn as dd
    >>> dd.problem("P1")["K"]
    array([[12.]])
    """
    return _chain([2.0], [12.0], [3.0], dt=0.02, T=10.0, force_dofs=[0], output=0)


def p2() -> dict:
    """P2: two-DOF chain, m = [2, 3] kg, k = [20, 15] N/m, c = [5, 6] N s/m, unit step on the
    last mass, dt = 0.02 s, T = 10 s.

    Parameters
    ----------
    None

    Returns
    -------
    dict
        mass, stiffness, damping, M, C, K, dt, T, force_dofs, output.

    Examples
    --------
    >>> import dtdyn as dd
    >>> dd.problem("P2")["force_dofs"]
    [1]
    """
    return _chain([2.0, 3.0], [20.0, 15.0], [5.0, 6.0], dt=0.02, T=10.0, force_dofs=[1], output=1)


def p3() -> dict:
    """P3: the undamped 15-DOF chain of Kumar & Sankar (1986), unit step on mass 15 (0-based
    14), T = 0.8 s; natural frequencies 9.49 to 148.2 rad/s.

    Parameters
    ----------
    None

    Returns
    -------
    dict
        mass, stiffness, damping, M, C, K, T, force_dofs, output.

    Examples
    --------
    >>> import dtdyn as dd
    >>> p = dd.problem("P3")
    >>> p["M"].shape, p["T"]
    ((15, 15), 0.8)
    """
    from dtdyn.linear._chain import chain_matrices
    mass, stiffness = np.array(P3_MASS, float), np.array(P3_STIFFNESS, float)
    damping = np.zeros(15)
    M, C, K = chain_matrices(mass, stiffness, damping, sparse=False)
    return dict(mass=mass, stiffness=stiffness, damping=damping, M=M, C=C, K=K, T=0.8,
                force_dofs=[14], output=14)


def p4(n_samples: int = 100_000) -> dict:
    """P4: the nonlinear 4-DOF chain, the shape of the source's example.

    ::

        ground --[k, k3]--(m0)--[k]--(m1)--[k, k3]--(m2)--[k]--(m3) <- f(t)

    Four unit masses, every linear spring k = 1e4 N/m, C = 1.0 M + 2e-4 K (Rayleigh; modal
    damping 1.5 % to 2.1 % over the linear modes at 5.5, 15.9, 24.4 and 29.9 Hz), cubic springs
    k3 = 2e7 N/m^3 from DOF 0 to ground and between DOFs 1 and 2 (0-based; the source counts
    from 1), white noise of 100 N standard deviation on DOF 3 sampled every dt = 1 ms
    (numpy default_rng(0)).

    The cubic forces matter: they are tens of percent of the linear ones in RMS and comparable
    at the peaks. Measured with dtdyn.nonlinear._reference over all 100,000 samples
    (y = relative displacement of the spring):

        spring             max|k3 y^3| / max|k y|    rms(k3 y^3) / rms(k y)    max |y|
        DOF 0 - ground     342 N / 258 N = 1.33       0.39                      0.026 m
        DOF 1 - DOF 2      176 N / 206 N = 0.85       0.24                      0.021 m

    (first 5000 samples: peak ratios 0.72 and 0.51; tests/test_nl_reference.py checks them.)

    Parameters
    ----------
    n_samples : int
        Length of the white-noise force record.

    Returns
    -------
    dict
        M, C, K, force, dt, force_dofs, elements, k, k3, output.

    Examples
    --------
    >>> import dtdyn as dd
    >>> p = dd.problem("P4", n_samples=1000)
    >>> p["force"].shape, p["dt"], p["force_dofs"]
    ((1000, 1), 0.001, [3])
    """
    from dtdyn.linear._chain import chain_matrices
    from dtdyn.nonlinear._elements import Cubic
    k, k3 = 1e4, 2e7
    M, _, K = chain_matrices(np.ones(4), np.full(4, k), np.zeros(4), sparse=False)
    C = 1.0 * M + 2e-4 * K
    force = (np.random.default_rng(0).standard_normal(n_samples) * 100.0)[:, None]
    return dict(M=M, C=C, K=K, force=force, dt=1e-3, force_dofs=[3],
                elements=[Cubic(0, None, k3=k3), Cubic(1, 2, k3=k3)], k=k, k3=k3, output=3)


def p4l(n_samples: int = 100_000) -> dict:
    """P4L: P4 without its cubic springs, the linear model M q'' + C q' + K q = f on the same
    record (the baseline of `dtdyn bench P4`'s time ratios).

    Parameters
    ----------
    n_samples : int
        Length of the white-noise force record (the same samples as ``p4(n_samples)``).

    Returns
    -------
    dict
        As `p4`, with ``elements`` empty and ``k3`` = 0.

    Examples
    --------
    >>> from dtdyn.app._problems import p4, p4l
    >>> import numpy as np
    >>> P, L = p4(100), p4l(100)
    >>> L["elements"], bool(np.array_equal(P["force"], L["force"]))
    ([], True)
    """
    return {**p4(n_samples), "elements": [], "k3": 0.0}


PROBLEMS = {"P1": p1, "P2": p2, "P3": p3, "P4": p4, "P4L": p4l}


def problem(name: str, **options) -> dict:
    """A reference problem as a dict of its data: the chain (``"mass"``, ``"stiffness"``,
    ``"damping"``), its matrices ``"M"``, ``"C"``, ``"K"``, the duration ``"T"``, the loaded
    DOFs ``"force_dofs"``; P4 also ``"force"``, ``"dt"`` and ``"elements"``. The module
    docstring says what each problem is.

    Parameters
    ----------
    name : {"P1", "P2", "P3", "P4", "P4L"}
        The problem (case-insensitive).
    **options
        ``n_samples`` for P4 and P4L (default 100,000).

    Examples
    --------
    >>> import dtdyn as dd
    >>> p = dd.problem("P3")
    >>> p["M"].shape, p["T"]
    ((15, 15), 0.8)
    """
    key = str(name).upper()
    if key not in PROBLEMS:
        raise ValueError(f"problem {name!r} is not one of {', '.join(PROBLEMS)}")
    if options and key not in ("P4", "P4L"):
        raise TypeError(f"problem {key!r} takes no options, got {', '.join(options)}")
    unknown = set(options) - {"n_samples"}
    if unknown:
        from dtdyn._engine.public import unknown_keyword
        raise unknown_keyword("problem", sorted(unknown)[0], {"name", "n_samples"})
    return PROBLEMS[key](**options)
