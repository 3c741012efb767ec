"""Transfer matrix method in the Laplace domain, numerically: frequency responses and poles.

Uses the generated element matrices (dtdyn.generated.tmm); U = prod_{n=N..1} P_n G_n M_n S_n
(force, ground spring-damper, mass, station spring-damper), the poles are the roots of U22(s).
"""
from __future__ import annotations

import numpy as np

from dtdyn.generated import tmm as elements

from dtdyn._engine import validate
from dtdyn._engine.frf import receptance_matrix
from dtdyn._engine.public import public
from dtdyn.linear._chain import chain_parameters


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


@public(renamed={"force_dof": "force_dofs", "output": "outputs"})
def chain_frequency_response(mass, stiffness, damping, omega, force_dofs, outputs, *,
                             ground_stiffness=None, ground_damping=None) -> np.ndarray:
    """Receptances x_o / F_i at s = j omega for unit forces on the masses ``force_dofs``
    (0-based), by the Laplace-domain transfer matrices with the boundary conditions
    x_base = 0, f_end = 0; O(N) per frequency and pair.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> H = dd.chain_frequency_response([2.0, 3.0], [20.0, 15.0], [5.0, 6.0], [1.0, 2.0],
    ...                                 force_dofs=1, outputs=0)
    >>> H.shape
    (2,)
    >>> dd.chain_frequency_response([2.0, 3.0], [20.0, 15.0], [5.0, 6.0], [1.0, 2.0],
    ...                             force_dofs=[1], outputs=[0, 1]).shape   # (omega, out, in)
    (2, 2, 1)

    Parameters
    ----------
    mass, stiffness, damping : (N,) array_like
        The chain (as `chain_response`).
    omega : array_like
        Circular frequencies, rad/s.
    force_dofs, outputs : int or sequence of int
        The loaded masses and the masses whose displacements are returned (0-based).
    ground_stiffness, ground_damping : (N,) array_like, optional
        Springs and dampers from the masses to the ground (as `chain_response`).

    Returns
    -------
    complex ndarray
        The receptances x_o / F_i, m/N: shape (len(omega), len(outputs), len(force_dofs)), or
        (len(omega),) when both ``force_dofs`` and ``outputs`` are single ints.
    """
    chain = chain_parameters(mass, stiffness, damping, ground_stiffness, ground_damping)
    omega = validate.frequencies("omega", omega)

    def index(name, value):
        return int(validate.dof_indices(name, [value], chain.m.size)[0])

    return receptance_matrix(lambda i, o: _receptance(chain, omega, i, o), force_dofs, outputs,
                             index)


def _receptance(chain, omega, force_dof: int, output: int) -> np.ndarray:
    """x_output / F at s = j omega, (len(omega),) complex, for one loaded mass."""
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

