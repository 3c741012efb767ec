r"""Mode shapes and frequency responses of torsional shafts and trees, by the tree's sweep.

Both solve the tree's dynamic-stiffness system :math:`Z(s) \phi = F`,
:math:`Z(s) = K + s C + s^2 M`, node by node from the leaves to the root and back (the
frequency-domain form of the DT-TMM's Riccati sweep, generated from dtdyn.derive.shaft:
`generated/shaft.md`), O(N) per value of s:

- `shaft_frequency_response`: :math:`s = i\omega`, F a unit torque; continuous shafts by their
  exact dynamic stiffness (damping as a Kelvin-Voigt modulus :math:`G (1 + \tau s)`,
  :math:`\tau = c_t L / (G J_p)`), or as their lumped segments;
- `shaft_modes`: inverse iteration :math:`x \leftarrow Z(i\omega_r)^{-1} M x` at each root of
  the Wittrick-Williams count (`dtdyn.linear._sweep_modes`), on the lumped model of
  `shaft_matrices`.
"""
from __future__ import annotations

import numpy as np

from dtdyn._engine import validate
from dtdyn._engine.frf import receptance_matrix
from dtdyn._engine.public import public
from dtdyn.generated import shaft as gen
from dtdyn.linear import _sweep_modes as sweep_modes
from dtdyn.linear._shaft import (Shaft, _check_shaft, rigid_rotation, shaft_frequencies,
                                shaft_matrices)
from dtdyn.modal._modes import Modes

__all__ = ["shaft_modes", "shaft_frequency_response"]


def shaft_modes(shaft: Shaft, count=None, below=None) -> Modes:
    """Natural frequencies and mass-normalized mode shapes of the lumped model (the model of
    `shaft_matrices`), from the tree's sweep.

    The frequencies are `shaft_frequencies` (``exact=False``): the Wittrick-Williams count,
    bisected to the last bits. Each shape is two steps of inverse iteration with the tree's
    O(N) solve of (K - omega_r^2 M) x = M x_k at the root itself (close or repeated roots
    together, by Rayleigh-Ritz on their subspace: `dtdyn.linear._sweep_modes`), scaled to
    phi^T M phi = 1 with its largest entry positive. No dense eigensolver: O(N) per mode and
    step.

    Parameters
    ----------
    shaft : Shaft
    count : int, optional
        The lowest ``count`` modes (default: all).
    below : float, optional
        Every mode below this frequency (rad/s).

    Returns
    -------
    Modes
        ``omega`` (rad/s), ``shapes`` (n, m) over ``dof_names`` (the order of
        `shaft_matrices`), the influence r = `rigid_rotation` (1 on the main line, -1/n
        through each gear), participation factors phi^T M r and effective inertias.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> m = dd.shaft_modes(dd.Shaft([1.0, 1.0], [2.0, 1.0]))
    >>> np.round(m.omega ** 2, 6)          # 2 -+ sqrt(2), as dd.modes on the matrices
    array([0.585786, 3.414214])
    >>> m.dof_names
    ('main.0', 'main.1')
    """
    _check_shaft(shaft)
    w = shaft_frequencies(shaft, count=count, below=below, exact=False)
    tree = shaft.tree
    M, _, K = shaft_matrices(shaft)
    gu, gS, gR = gen.gear_factors(tree.ratio)
    pivmin = np.finfo(float).eps * max(float(np.abs(K.diagonal()).max()), np.finfo(float).tiny)
    k = tree.k[:, None]

    def solve(lam, F):
        s = 1j * np.sqrt(lam)[None, :]  # undamped, s^2 = -lam (to an ulp)
        mu = gen.node_terms(s, tree.J[:, None], tree.kg[:, None], 0.0).real
        a, b = (np.broadcast_to(v, F.shape) for v in gen.spring_stiffness_s(0.0, k, 0.0))
        return gen.tree_solve(tree.parent, gu, gS, gR, mu, a, b, F, pivmin)[0]

    lam = w**2
    phi = (sweep_modes.inverse_iteration(lam, solve, lambda X: M @ X, lambda X: K @ X,
                                         tree.J.size) if lam.size else np.zeros((tree.J.size, 0)))
    r = rigid_rotation(shaft)
    Mr = M @ r
    gamma = phi.T @ Mr
    return Modes(omega=w, shapes=phi, influence=r, participation=gamma,
                 effective_mass=gamma**2, total_mass=float(r @ Mr), dof_names=tree.names)


def _node(name, value, tree, shaft):
    """The tree node of a DOF given by name or by index into ``shaft.dof_names``."""
    names = shaft.dof_names
    if isinstance(value, (str, int, np.integer)) and not isinstance(value, bool):
        if isinstance(value, str):
            label = value
            if label not in names:
                shown = ", ".join(names[:8]) + (" ..." if len(names) > 8 else "")
                raise ValueError(f"{name}: no DOF named {label!r} (the DOFs are {shown})")
        else:
            if not 0 <= value < len(names):
                raise ValueError(f"{name} = {value!r}: outside 0..{len(names) - 1}")
            label = names[int(value)]
        if label not in tree.names:
            raise ValueError(f"{name} = {value!r} ({label!r}) is a point inside a lumped "
                             "continuous shaft: with exact=True give a disk, or exact=False")
        return tree.names.index(label)
    raise ValueError(f"{name} = {value!r}: must be one DOF, an index or a name")


@public(renamed={"force_dof": "force_dofs", "output": "outputs"})
def shaft_frequency_response(shaft: Shaft, omega, force_dofs, outputs, *,
                             exact=True) -> np.ndarray:
    """Receptances phi_o / T_i (rad / N m) at s = i omega for a unit torque on each of
    ``force_dofs``, with the shaft's damping, by the tree's sweep (O(N) per frequency and
    loaded DOF).

    Each disk contributes mu = J s^2 + c_g s + k_g, each shaft its dynamic stiffness (a, b)
    (a spring-damper: a = -b = k_t + c_t s); eliminating from the leaves gives per node the pivot
    D = mu + a - S_R, the relation S_L = -(a - b^2 / D) and the condensed load R_L = -b y / D
    into its parent (through a gear times 1/n^2 and -1/n), then the rotations from the root,
    phi_n = (y - b g_u phi_parent) / D (docs/shaft.md).

    Parameters
    ----------
    shaft : Shaft
    omega : array_like
        Circular frequencies, rad/s, finite and >= 0.
    force_dofs, outputs : int or str, or a sequence of them
        The loaded DOFs and the DOFs whose rotations are returned: indices into
        ``shaft.dof_names`` or names ("main.2", "out.0").
    exact : bool
        Continuous shafts by their exact dynamic stiffness, damped as G (1 + tau s),
        tau = c_t L / (G J_p) (True; only disks can then be loaded or observed), or as their
        lumped segments (False: the model of `shaft_matrices`).

    Returns
    -------
    complex ndarray
        Shape (len(omega), len(outputs), len(force_dofs)), or (len(omega),) when both are
        single DOFs. The receptances; equal to (K + i omega C - omega^2 M)^-1 on
        `shaft_matrices` (lumped).
        At a natural frequency of an undamped shaft it is infinite.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> s = dd.Shaft([2.0], [8.0], [0.0])                  # 1 / (k - omega^2 J)
    >>> dd.shaft_frequency_response(s, [0.0, 1.0], "main.0", "main.0").real.tolist()
    [0.125, 0.16666666666666666]
    """
    _check_shaft(shaft)
    w = validate.frequencies("omega", omega)
    validate.flag("exact", exact)
    tree = shaft._build(exact=True) if exact and shaft.has_continuous else shaft.tree
    columns = {}

    def pair(i, o):
        if i not in columns:
            columns[i] = _all_receptances(tree, w, i)
        return columns[i][o]

    return receptance_matrix(pair, force_dofs, outputs,
                             lambda name, v: _node(name, v, tree, shaft))


def _all_receptances(tree, w, i_f) -> np.ndarray:
    """Every node's rotation per unit torque on node ``i_f``: (nodes, len(w)) complex."""
    s = 1j * w
    N = tree.J.size
    mu = gen.node_terms(s[None, :], tree.J[:, None], tree.kg[:, None], tree.cg[:, None])
    a, b = (np.array(np.broadcast_to(v, (N, s.size)), dtype=complex)
            for v in gen.spring_stiffness_s(s[None, :], tree.k[:, None], tree.c[:, None]))
    for segs, into in ((tree.segments, "connection"), (tree.ground_segments, "ground")):
        for n, seg in enumerate(segs):
            if seg is None:
                continue
            tau = gen.continuous_tau(seg.damping, seg.length, seg.G, seg.Jp)
            an, bn = gen.continuous_stiffness_s(s, seg.G * seg.Jp / seg.length, tau, seg.length,
                                                seg.G, seg.rho)
            if into == "connection":
                a[n], b[n] = an, bn
            else:
                mu[n] = mu[n] + an
    F = np.zeros((N, s.size), dtype=complex)
    F[i_f] = 1.0
    gu, gS, gR = gen.gear_factors(tree.ratio)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi, _ = gen.tree_solve(tree.parent, gu, gS, gR, mu, a, b, F)
    return phi
