"""Transfer matrix method in the Laplace domain, numerically: frequency responses and poles.

Uses the generated element matrices (dtdyn.generated.tmm); U = prod_{n=N..1} P_n G_n M_n S_n
(force, ground spring-damper, mass, station spring-damper), the poles are the roots of U22(s).
"""
from __future__ import annotations

import numpy as np

from dtdyn.generated import tmm as elements

from dtdyn._engine import validate
from dtdyn.linear.chain import chain_parameters


def station(chain, n: int, s: complex) -> np.ndarray:
    """G_n M_n S_n(s) of station n of a checked chain (linear.chain.Chain), 3 x 3 complex."""
    m, k, c, kg, cg = (a[n] for a in chain)
    return (elements.ground_spring_damper(kg, cg, s) @ elements.mass(m, s)
            @ elements.spring_damper(k, c, s))


def system_matrix(chain, s: complex) -> np.ndarray:
    """U(s) of the unloaded chain, 3 x 3 complex."""
    U = np.eye(3, dtype=complex)
    for n in range(chain.m.size):
        U = station(chain, n, s) @ U
    return U


def frequency_response(mass, stiffness, damping, omega, force_dof: int, output: int, *,
                       ground_stiffness=None, ground_damping=None) -> np.ndarray:
    """x_output / F at s = j omega for a unit force on mass ``force_dof`` (0-based masses), by
    the Laplace-domain transfer matrices with the boundary conditions x_base = 0, f_end = 0.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> H = dd.frequency_response([2.0, 3.0], [20.0, 15.0], [5.0, 6.0], np.array([1.0, 2.0]),
    ...                           force_dof=1, output=0)
    >>> H.shape
    (2,)

    Parameters
    ----------
    mass, stiffness, damping : (N,) array_like
        The chain (as `chain_response`).
    ground_stiffness, ground_damping : (N,) array_like, optional
        Springs and dampers from the masses to the ground (as `chain_response`).
    omega : array_like
        Circular frequencies, rad/s.
    force_dof, output : int
        The loaded mass and the mass whose displacement is returned (0-based).

    Returns
    -------
    (len(omega),) complex ndarray
        The receptance x_output / F, m/N.
    """
    chain = chain_parameters(mass, stiffness, damping, ground_stiffness, ground_damping)
    for name, value in (("force_dof", force_dof), ("output", output)):
        validate.dof_indices(name, [value], chain.m.size)
    out = np.empty(np.size(omega), dtype=complex)
    for i, w in enumerate(np.atleast_1d(omega)):
        s = 1j * w
        U = np.eye(3, dtype=complex)
        partial = []
        for n in range(chain.m.size):
            U = station(chain, n, s) @ U
            if n == force_dof:
                U = elements.force(1.0) @ U
            partial.append(U)
        f_base = -U[1, 2] / U[1, 1]
        out[i] = (partial[output] @ np.array([0.0, f_base, 1.0]))[0]
    return out


def undamped_poles(mass, stiffness) -> np.ndarray:
    """Natural frequencies omega_n (rad/s, ascending) of an undamped chain: roots of U22(j omega).

    U22 is a polynomial of degree N in lambda = omega^2 whose N roots are simple (an irreducible
    tridiagonal pencil has distinct eigenvalues). They are found by `chain_frequencies`: bisection
    on the Wittrick-Williams count of the same chain, O(N) per evaluation, so no root is missed
    or doubled and nothing overflows, however long the chain.

    Parameters
    ----------
    mass, stiffness : (N,) array_like
        m_n > 0, k_n > 0 of the chain.

    Returns
    -------
    (N,) ndarray
        omega_n in rad/s, ascending.

    Examples
    --------
    >>> import dtdyn as dd
    >>> w = dd.undamped_poles([10, 9, 8, 7, 6, 6, 5.5, 5, 4.5, 4, 3.5, 4, 2.5, 2, 2],
    ...                       [55000, 50000, 45000, 40000, 40000, 35000, 30000, 25000, 20000,
    ...                        15000, 10000, 9000, 8000, 7000, 6000])          # P3
    >>> round(float(w[0]), 2), round(float(w[-1]), 1)
    (9.49, 148.2)
    """
    from dtdyn.linear.frequencies import chain_frequencies

    return chain_frequencies(mass, stiffness)
