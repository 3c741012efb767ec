r"""Euler-Bernoulli beams in planar bending: the model, its matrices, its natural frequencies.

::

    left |==e0==o==e1==o== ... ==e(N-1)==| right        nodes 0 .. N, DOFs [w_i, psi_i]

A uniform beam (E, I, rho_A, length) of N Hermite cubic elements (generated/beam.py: stiffness,
consistent or HRZ-lumped mass, derived in dtdyn.derive.beam), with point masses (mass and
rotary inertia) and springs and dampers to the ground at any node, Rayleigh damping, and the
ends clamped (w = psi = 0), pinned (w = 0), sliding (psi = 0), free, or elastic (a spring pair
(k_w, k_psi) to the ground). Constrained DOFs are removed; the others keep the node order,
[w_i, psi_i] per node (`Beam.dof_names`).

The natural frequencies come from the Wittrick-Williams count: the number of eigenvalues of
(K, M) below lambda is the inertia of K - lambda M, here taken in mixed form (each element's
deformation and flexibility as unknowns, so flexibilities add node by node instead of
element stiffnesses cancelling; `wittrick_williams_counts`); each root is isolated by that
count and converged by regula falsi on det(K - lambda M), which the same recursion gives,
then finished on (K, M) by inverse iteration and residual correction (`beam_frequencies`);
rigid-body modes are exact zeros (`rigid_body_modes`).
docs/beam.md has the equations.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from functools import cached_property, cache

import numpy as np
import scipy.sparse as sps

from dtdyn.generated import beam as derived

from dtdyn._engine import cbuild
from dtdyn._engine import ground as support
from dtdyn._engine import linalg, validate
from dtdyn._engine.twofold import add_product, two_sum
from dtdyn._engine.public import public
from dtdyn.linear import _mck as mck
from dtdyn.linear._solver import (Model, Solver, check_backend, nonlinear_solver, scheme_key,
                                  schemes_of_run)

__all__ = ["Beam", "PointMass", "Support", "beam_matrices", "beam_frequencies", "beam_response"]

#: end conditions: which of (w, psi) is held
BOUNDARIES = {"clamped": (True, True), "pinned": (True, False), "sliding": (False, True),
              "free": (False, False)}


@dataclass(frozen=True)
class PointMass:
    """A point mass at a node of a `Beam`.

    Attributes
    ----------
    node : int
        0-based node (0 .. elements).
    mass, inertia : float
        Mass (kg, on w) and rotary inertia (kg m^2, on psi), >= 0.

    Examples
    --------
    >>> import dtdyn as dd
    >>> beam = dd.Beam(E=1.0, I=1.0, rho_A=1.0, length=1.0, elements=4,
    ...                point_masses=[dd.PointMass(4, mass=0.5)])
    >>> round(float(dd.beam_matrices(beam)[0].diagonal()[-2]), 4)  # 13/35 h + 0.5 at w4
    0.5929
    """

    node: int
    mass: float = 0.0
    inertia: float = 0.0


@dataclass(frozen=True)
class Support:
    """An elastic support of a `Beam`: springs and dampers from a node to the ground.

    Attributes
    ----------
    node : int
        0-based node (0 .. elements).
    k_w, k_psi : float
        Translational (N/m) and rotational (N m/rad) springs, >= 0.
    c_w, c_psi : float
        Translational (N s/m) and rotational (N m s/rad) dampers, >= 0.

    Examples
    --------
    >>> import dtdyn as dd
    >>> beam = dd.Beam(E=1.0, I=1.0, rho_A=1.0, length=1.0, elements=4,
    ...                supports=[dd.Support(2, k_w=10.0, c_w=0.1)])
    >>> float(dd.beam_matrices(beam)[1].diagonal()[2])                  # C at w2
    0.1
    """

    node: int
    k_w: float = 0.0
    k_psi: float = 0.0
    c_w: float = 0.0
    c_psi: float = 0.0


#: bytes a Beam holds per DOF: its held flag (1), kept index (8), name pointer (8) and name
#: string (~57): 150 B per element measured (tracemalloc, 2e5 elements)
BEAM_BYTES_PER_DOF = 75
#: the most elements `beam_frequencies` counts on: Hermite elements' frequency error of mode j
#: falls as (j / elements)^4, below double round-off (1e-16) for every j < elements / 1e4, so
#: more elements only add round-off and time (each count is a sweep over every node)
MAX_FREQUENCY_ELEMENTS = 10**6


def _number(name, value, positive=False):
    v = validate.vector(name, [value], positive=positive, nonnegative=not positive)
    return float(v[0])


class Beam(Model):
    """A uniform Euler-Bernoulli beam of Hermite cubic elements (module docstring).

    The model of `beam_response`; ``solver(dt, ...)`` prepares it for many load cases
    (`Solver`).

    Parameters
    ----------
    E, I, rho_A, length : float
        Young's modulus (Pa), second moment of area (m^4), mass per length (kg/m), length (m).
    elements : int
        Number of elements N (nodes 0 .. N).
    left, right : str or (k_w, k_psi)
        "clamped", "pinned", "sliding", "free", or an elastic end: springs to the ground.
    mass_matrix : {"consistent", "lumped"}
        Element mass matrix: consistent, or HRZ-lumped (diagonal).
    rayleigh : (alpha, beta), optional
        C = alpha M + beta K (before the dampers of ``supports``).
    point_masses, supports : sequence of PointMass, Support
        At any node.

    Examples
    --------
    >>> import dtdyn as dd
    >>> beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=200)
    >>> beam.n_dof, beam.dof_names[:2]
    (400, ('w1', 'psi1'))
    """

    def __init__(self, *, E, I, rho_A, length, elements, left="clamped", right="free",  # noqa: E741
                 mass_matrix="consistent", rayleigh=None, point_masses=(), supports=()):
        self.E, self.I = _number("E", E, True), _number("I", I, True)
        self.rho_A = _number("rho_A", rho_A, True)
        self.length = _number("length", length, True)
        if isinstance(elements, bool) or not isinstance(elements, (int, np.integer)) \
                or elements < 1:
            raise ValueError(f"elements = {elements!r}: must be an integer >= 1")
        # before anything is allocated: per DOF its held flag, its index and its name
        validate.memory(f"Beam(elements={int(elements):,}): {2 * (int(elements) + 1):,} DOFs "
                        "(their flags, indices and names)",
                        2 * (int(elements) + 1) * BEAM_BYTES_PER_DOF, "use fewer elements")
        self.elements = int(elements)
        if mass_matrix not in ("consistent", "lumped"):
            raise ValueError(f"mass_matrix = {mass_matrix!r}: must be 'consistent' or 'lumped'")
        self.mass_matrix = mass_matrix
        self.rayleigh = None if rayleigh is None else tuple(
            float(v) for v in validate.vector("rayleigh", rayleigh, nonnegative=True, length=2))
        supports = list(supports)
        self.ends = {}
        for side, node, bc in (("left", 0, left), ("right", self.elements, right)):
            if isinstance(bc, str):
                if bc not in BOUNDARIES:
                    raise ValueError(f"{side} = {bc!r}: must be one of {', '.join(BOUNDARIES)} "
                                     "or an elastic end (k_w, k_psi)")
                self.ends[side] = bc
            else:
                k = validate.vector(side, bc, nonnegative=True, length=2)
                supports.append(Support(node, k_w=float(k[0]), k_psi=float(k[1])))
                self.ends[side] = "elastic"
        self.point_masses = tuple(self._checked(p, PointMass, "point_masses") for p in point_masses)
        self.supports = tuple(self._checked(s, Support, "supports") for s in supports)
        held = np.zeros((self.elements + 1, 2), dtype=bool)
        held[0] = BOUNDARIES.get(self.ends["left"], (False, False))
        held[-1] |= BOUNDARIES.get(self.ends["right"], (False, False))
        for name, items, fields in (("point_masses", self.point_masses, ("mass", "inertia")),
                                    ("supports", self.supports, ("k_w", "k_psi"))):
            for item in items:  # what acts on a held DOF would silently vanish
                for j, f in enumerate(fields):
                    if held[item.node, j] and getattr(item, f) != 0.0:
                        raise ValueError(f"{name}: {f} = {getattr(item, f)!r} at node "
                                         f"{item.node}, where {('w', 'psi')[j]} is held")
        #: the kept DOFs as global indices 2 node + (0: w, 1: psi)
        self.free = np.flatnonzero(~held.ravel())

    @cached_property
    def dof_names(self) -> tuple:
        """The kept DOFs' names, "w<node>" and "psi<node>" (built at first use: a long beam's
        frequencies never need them)."""
        return tuple(f"{'w' if d % 2 == 0 else 'psi'}{d // 2}" for d in self.free)

    def _checked(self, item, cls, name):
        if not isinstance(item, cls):
            raise ValueError(f"{name} entries must be {cls.__name__} objects, got {item!r}")
        if not (isinstance(item.node, (int, np.integer)) and 0 <= item.node <= self.elements):
            raise ValueError(f"{name}: node = {item.node!r} is outside 0..{self.elements}")
        for f in item.__dataclass_fields__:
            if f != "node":
                _number(f"{name}[node {item.node}].{f}", getattr(item, f))
        return item

    @property
    def n_dof(self) -> int:
        return int(self.free.size)

    def dof(self, name: str) -> int:
        """The index of a DOF by name ("w12", "psi3")."""
        if name not in self.dof_names:
            raise ValueError(f"{name!r} is not a DOF of this beam (constrained or out of range)")
        return self.dof_names.index(name)

    def __repr__(self):
        return (f"Beam(E={self.E:g}, I={self.I:g}, rho_A={self.rho_A:g}, length={self.length:g}, "
                f"elements={self.elements}, left={self.ends['left']!r}, "
                f"right={self.ends['right']!r}, mass_matrix={self.mass_matrix!r})")

    def nodal_diagonals(self) -> dict:
        """The point masses' and supports' diagonals over all 2 (N + 1) DOFs: {"m", "k", "c"}."""
        n = 2 * (self.elements + 1)
        diag = {name: np.zeros(n) for name in ("m", "k", "c")}
        for p in self.point_masses:
            diag["m"][2 * p.node] += p.mass
            diag["m"][2 * p.node + 1] += p.inertia
        for s in self.supports:
            diag["k"][2 * s.node] += s.k_w
            diag["k"][2 * s.node + 1] += s.k_psi
            diag["c"][2 * s.node] += s.c_w
            diag["c"][2 * s.node + 1] += s.c_psi
        return diag

    def global_matrices(self):
        """(M, C, K) over all 2 (N + 1) DOFs (constrained ones included), scipy.sparse CSR."""
        n = 2 * (self.elements + 1)
        h = self.length / self.elements
        Ke = derived.element_stiffness(self.E * self.I, h)
        Me = (derived.element_mass if self.mass_matrix == "consistent"
              else derived.element_mass_lumped)(self.rho_A, h)
        first = 2 * np.arange(self.elements)
        rows = (first[:, None, None] + np.arange(4)[None, :, None]).repeat(4, axis=2)
        cols = rows.transpose(0, 2, 1)

        def assemble(Ae):
            data = np.broadcast_to(Ae, (self.elements, 4, 4))
            return sps.csr_matrix((data.ravel(), (rows.ravel(), cols.ravel())), shape=(n, n))

        K, M = assemble(Ke), assemble(Me)
        C = sps.csr_matrix((n, n))
        if self.rayleigh is not None:
            C = self.rayleigh[0] * M + self.rayleigh[1] * K
        diag = self.nodal_diagonals()
        M, C, K = (A + sps.diags(diag[d]) for A, d in ((M, "m"), (C, "c"), (K, "k")))
        return M.tocsr(), C.tocsr(), K.tocsr()

    @public
    def solver(self, dt, *, scheme="newmark", form=None, backend="c", outputs=None,
               quantities=("x", "v", "a"), unstable="raise", elements=None, substeps=None, tol=None,
               max_iter=None, refine="auto", **scheme_params) -> BeamSolver:
        """Prepare the beam for many load cases at the sample step ``dt``.

        Checks the options and the stability limit (a bound of the beam's highest mode),
        stores the node blocks of M, C, K, factorizes M and the effective matrix of each scheme
        the run steps with (the start-up scheme of a multistep scheme too) by the matrix
        Riccati sweep and loads the C kernel, once (backend "numpy": the sparse LUs of M and of
        the effective matrix). Each ``run`` of the returned solver is then one load case, the
        results of `beam_response` bitwise.

        Parameters
        ----------
        dt : float
            Sample step, s, > 0.
        scheme : str
            Any scheme of `chain_response`; its parameters (``beta``, ``gamma``, ``theta``,
            ``alpha``, ``rho_inf``) as keywords.
        form : {"displacement", "acceleration"} or None
            As `beam_response` (None: the displacement form, or the acceleration form of an
            explicit scheme, its only one).
        backend : {"c", "numpy"}
            As `beam_response`.
        outputs : sequence of int or DOF names, optional
            DOFs whose response is stored: indices into ``dof_names`` or the names ("w12");
            all by default.
        quantities : subset of ("x", "v", "a")
            What is stored; the others are None in the results.
        unstable : {"raise", "warn"}
            A conditionally stable scheme beyond its limit: refused here
            (DtdynUnstableError), or warned about.
        elements : sequence of elements, optional
            Localized nonlinear elements (`Cubic`, `Polynomial`, `Gap`, `Law`, `BoucWen`):
            the solver of `nonlinear_beam_response` instead: the checks, the linear step, the
            elements' unit responses and the compiled loop prepared once, each ``run`` equal
            to the function bitwise.
        substeps, tol, max_iter : optional
            With ``elements`` only: as `nonlinear_beam_response` (its defaults when None).
        refine : {"auto", True, False}
            Iterative refinement of every step's solve: "auto" from 2,000 elements on
            (``REFINE_MIN_ELEMENTS``), where the double-precision step's rounding
            nears 1e-6 of a static deflection (docs/beam_conditioning.md); below it the
            results are bitwise those without.
        **scheme_params
            The scheme's parameters.

        Returns
        -------
        Solver
            ``run(force, force_dofs=..., x0=..., v0=..., ground_acceleration=...)`` per load
            case (``force_dofs`` by index or name); safe to call from several threads at once.

        Examples
        --------
        >>> import numpy as np, dtdyn as dd
        >>> beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=100)
        >>> solver = beam.solver(1e-4, outputs=["w100"])
        >>> r1, r2 = (solver.run(np.full(201, f), force_dofs=["w100"]) for f in (1.0, 2.0))
        >>> r1.x.shape, bool(np.allclose(r2.x, 2 * r1.x))
        ((201, 1), True)
        """
        nonlinear = dict(substeps=substeps, tol=tol, max_iter=max_iter)
        if elements is not None:  # dtdyn.nonlinear's solver, by the registry (the layers)
            return nonlinear_solver(self, dt, elements, scheme=scheme, form=form,
                                    backend=backend, outputs=outputs, quantities=quantities,
                                    unstable=unstable, refine=refine, **nonlinear,
                                    **scheme_params)
        nonlinear_solver(self, dt, None, **nonlinear)  # none of them without elements
        return BeamSolver(self, dt, scheme, form, backend, outputs, quantities, unstable,
                          scheme_params, refine)


def beam_matrices(beam: Beam):
    """The assembled (M, C, K) of a `Beam`, constrained DOFs removed, scipy.sparse CSR, in the
    order of ``beam.dof_names`` ([w_i, psi_i] node by node).

    Parameters
    ----------
    beam : Beam

    Returns
    -------
    M, C, K : scipy.sparse.csr_matrix

    Examples
    --------
    >>> import dtdyn as dd
    >>> M, C, K = dd.beam_matrices(dd.Beam(E=1.0, I=1.0, rho_A=1.0, length=1.0, elements=2))
    >>> K.shape
    (4, 4)
    """
    if not isinstance(beam, Beam):
        raise ValueError(f"beam must be a Beam, got {type(beam).__name__}")
    f = beam.free
    return tuple(A[f][:, f].tocsr() for A in beam.global_matrices())


def _count_blocks(beam: Beam):
    """The data of `wittrick_williams_counts` in element units (lengths in h = length /
    elements, stiffness in EI / h, mass in rho_A h^3, lambda in EI / (rho_A h^4)):
    (m, em, kg, held, scale) with m (nodes, 3) the node mass blocks [m_ww, m_wpsi, m_psipsi]
    (point masses included), em the 2 x 2 coupling of the element mass matrix between its
    nodes, kg (nodes, 2) the springs to the ground, held (nodes, 2), and scale = rho_A h^4 / EI
    (lambda in these units is scale lambda)."""
    N, nodes = beam.elements, beam.elements + 1
    h = beam.length / N
    EI = beam.E * beam.I
    s_k, s_m = EI / h, beam.rho_A * h ** 3
    Me = (derived.element_mass if beam.mass_matrix == "consistent"
          else derived.element_mass_lumped)(beam.rho_A, h)
    unit = np.array([h, 1.0, h, 1.0])        # w = h w_hat
    Me = Me * unit[:, None] * unit[None, :] / s_m
    diag = {k: v.reshape(nodes, 2) for k, v in beam.nodal_diagonals().items()}
    m = np.zeros((nodes, 3))
    for k, (a, b) in enumerate(((0, 0), (0, 1), (1, 1))):
        m[:N, k] += Me[a, b]                  # node i as the left node of element i
        m[1:, k] += Me[2 + a, 2 + b]          # ... and as the right node of element i - 1
    m[:, 0] += diag["m"][:, 0] * h * h / s_m
    m[:, 2] += diag["m"][:, 1] / s_m
    kg = np.stack([diag["k"][:, 0] * h * h / s_k, diag["k"][:, 1] / s_k], axis=1)
    held = np.ones(2 * nodes, dtype=bool)
    held[beam.free] = False
    return m, Me[:2, 2:].copy(), kg, held.reshape(nodes, 2), s_m / s_k


#: the element's flexibility F (a cantilever held at its right node, element units) and F^-1
_FLEX = (1.0 / 3.0, -0.5, 1.0)
_STIFF = (12.0, 6.0, 4.0)
#: the count's arithmetic: extended precision where the platform has it (x86: 64-bit mantissa)
_WIDE = np.longdouble


#: pivots whose signs are kept before they are added to the count (memory: 2 x this x lambdas)
_SIGN_ROWS = 64


def _pivot_inverse(a, b, c, pivmin, signs, guard=False):
    """Determinant and inverse [[g00, -q], [-q, g11]] of the symmetric block [[a, b], [b, c]]
    (returned: det, g00, q, g11), its inertia recorded in ``signs`` (rows: a < 0, det < 0; the
    block has (a < 0) + (a < 0 xor det < 0) negative eigenvalues, its LDL^T's pivots being a
    and det / a). det = a c - b^2 carries the rounding of p (q - b^2 / p) with either pivot;
    pivmin is subtracted from it (a determinant that cancels exactly, which happens within
    rounding of a root, becomes -pivmin; any other is unchanged), and with ``guard`` (a pass
    that met a non-finite value) every determinant below pivmin in magnitude is -pivmin."""
    det = a * c - b * b - pivmin
    if guard:
        det = np.where(np.abs(det) < pivmin, -pivmin, det)
    np.less(a, 0, out=signs[0])
    np.less(det, 0, out=signs[1])
    r = 1.0 / det
    return det, c * r, b * r, a * r


def _inertia(blocks, lam, det=False, guard=False):
    """The negative pivots of A(lambda) less 2N (`wittrick_williams_counts`) at the scaled
    lam (a longdouble array), and with ``det`` also log2 |det A(lambda)| (a float array; det A
    is det(K - lambda M) times a constant, its sign (-1)^count). A pivot that vanishes
    to a non-finite result sends that lambda through a guarded pass."""
    m, em, kg, held, _ = blocks
    N = m.shape[0] - 1
    pivmin = _WIDE(np.finfo(float).tiny) / np.finfo(float).eps
    f00, f01, f11 = _FLEX
    keep = (~held).astype(float)
    one, zero = np.ones_like(lam), np.zeros_like(lam)
    # the node blocks' own terms, once per distinct node (a uniform beam has few)
    rows, which = np.unique(np.concatenate([m, kg], axis=1), axis=0, return_inverse=True)
    which = which.ravel()
    own = [(r[3] - lam * r[0], -lam * r[1], r[4] - lam * r[2]) for r in rows]
    E = [[float(v) for v in row] for row in em]
    # the pivots' signs, 2 x 2 per pivot, reduced to the count every _SIGN_ROWS pivots
    signs = np.zeros((_SIGN_ROWS, 2, lam.size), dtype=bool)
    neg = np.zeros(lam.size, dtype=np.int64)

    def reduce(rows):
        nonlocal neg
        neg_a, neg_d = signs[:rows, 0], signs[:rows, 1]
        neg = neg + np.count_nonzero(neg_a, axis=0) + np.count_nonzero(neg_a ^ neg_d, axis=0)

    def held_identity(i, a, b, c):
        if held[i, 0]:
            a, b = one, zero
        if held[i, 1]:
            b, c = zero, one
        return a, b, c

    a, b, c = held_identity(0, *own[which[0]])
    prod, exponent = np.ones_like(lam), np.zeros(lam.size)
    with np.errstate(all="ignore"):
        for i in range(N):
            # pivot x_i: G = P_i^-1 = [[g00, -q01], [-q01, g11]] (held DOFs decoupled)
            row = (2 * i) % _SIGN_ROWS
            d_x, g00, q01, g11 = _pivot_inverse(a, b, c, pivmin, signs[row], guard)
            k0, k1 = keep[i]
            j0, j1 = keep[i + 1]
            if k0 * k1 * j0 * j1 == 1.0:  # the interior: no DOF held
                (e00, e01), (e10, e11) = E
            else:
                g00, q01, g11 = g00 * k0, q01 * (k0 * k1), g11 * k1
                e00, e01 = E[0][0] * k0 * j0, E[0][1] * k0 * j1
                e10, e11 = E[1][0] * k1 * j0, E[1][1] * k1 * j1
            # lam G E, then the coupling of the next node to y_i (-T^T + lam E^T G) and its
            # block
            w00, w01 = lam * (g00 * e00 - q01 * e10), lam * (g00 * e01 - q01 * e11)
            w10, w11 = lam * (g11 * e10 - q01 * e00), lam * (g11 * e11 - q01 * e01)
            c00, c10, c11 = w00 - j0, w01 + j1, w11 - j1   # c01 = w10
            o00, o01, o11 = own[which[i + 1]]
            x00 = o00 - lam * (e00 * w00 + e10 * w10)
            x01 = o01 - lam * (e00 * w01 + e10 * w11)
            x11 = o11 - lam * (e01 * w01 + e11 * w11)
            # pivot y_i: -F - G (flexibilities added), its inverse [[h00, -p01], [-p01, h11]]
            d_y, h00, p01, h11 = _pivot_inverse(-f00 - g00, q01 - f01, -f11 - g11, pivmin,
                                                signs[row + 1], guard)
            if row + 2 == _SIGN_ROWS:
                reduce(_SIGN_ROWS)
            u00, u01 = c00 * h00 - w10 * p01, w10 * h11 - c00 * p01
            u10, u11 = c10 * h00 - c11 * p01, c11 * h11 - c10 * p01
            a, b, c = held_identity(i + 1, x00 - (u00 * c00 + u01 * w10),
                                    x01 - (u00 * c10 + u01 * c11),
                                    x11 - (u10 * c10 + u11 * c11))
            if det:
                prod = prod * (d_x * d_y)
                if i % 16 == 15:  # renormalized long before the long double range is left
                    prod, e = np.frexp(prod)
                    exponent += e
        d_n = _pivot_inverse(a, b, c, pivmin, signs[(2 * N) % _SIGN_ROWS], guard)[0]
        reduce((2 * N) % _SIGN_ROWS + 1)
        bad = ~np.isfinite(d_n)
        if det:
            prod, e = np.frexp(prod * d_n)
            logdet = exponent + e + np.log2(np.abs(prod).astype(float))
            bad |= ~np.isfinite(logdet)
    neg -= 2 * N
    if bad.any() and not guard:
        neg[bad], redo = _inertia(blocks, lam[bad], det, guard=True)
        if det:
            logdet[bad] = redo
    return neg, (logdet if det else None)


def wittrick_williams_counts(beam: Beam, lam, blocks=None) -> np.ndarray:
    r"""The number of eigenvalues of (K, M) below each lam (rad^2/s^2), from the inertia of
    K - lam M in mixed form (``blocks``: `_count_blocks` of the beam, when the caller keeps
    them).

    Each Hermite element's stiffness is exactly :math:`K_e = [I, -T]^T F^{-1} [I, -T]`: its
    deformation :math:`y_e = x_i - T x_{i+1}` (the left node against the right node's rigid
    extension, :math:`T = [[1, -h], [0, 1]]`) and its flexibility F (a cantilever). With the
    deformations as unknowns,

    .. math::

        A(\lambda) = \begin{bmatrix} -F^{-1}_{\rm all} & Q \\ Q^T & K_g - \lambda M
        \end{bmatrix}, \qquad \operatorname{neg}(A) = 2N + \operatorname{neg}(K - \lambda M)

    (Haynsworth: the Schur complement on the deformations is K - lambda M). A is eliminated
    in the order x_0, y_0, x_1, y_1, ..., x_N (2 x 2 pivots): the flexibilities of the part
    already eliminated add to the next element's, as the series springs of `chain_frequencies`
    do, instead of the element stiffnesses (of order EI/h^3) being added and then cancelled
    down to the stiffness of the whole (of order EI/L^3), which is what limits the node-block
    count of K - lambda M to about eps lambda_max absolute. The rigid motions stay exact
    (no rounding of K_e's entries spoils its null space); the recursion runs in element
    units in extended precision (`numpy.longdouble`; on platforms where that is double,
    the count is about 2,000 times noisier near each root).
    """
    blocks = _count_blocks(beam) if blocks is None else blocks
    lam = np.atleast_1d(np.asarray(lam, dtype=float)).astype(_WIDE) * _WIDE(blocks[-1])
    return _inertia(blocks, lam)[0]


def rigid_body_modes(beam: Beam) -> int:
    """The number of rigid-body modes of a beam (0, 1 or 2): the motions w = a + b x,
    psi = b that no end and no spring holds (their frequencies are exactly 0)."""
    rows = []
    x = np.linspace(0.0, 1.0, beam.elements + 1)  # node positions over the length
    for side, node in (("left", 0), ("right", beam.elements)):
        w_held, psi_held = BOUNDARIES.get(beam.ends[side], (False, False))
        if w_held:
            rows.append((1.0, x[node]))
        if psi_held:
            rows.append((0.0, 1.0))
    for s in beam.supports:
        if s.k_w > 0.0:
            rows.append((1.0, x[s.node]))
        if s.k_psi > 0.0:
            rows.append((0.0, 1.0))
    return 2 - (np.linalg.matrix_rank(np.array(rows)) if rows else 0)


#: brackets narrower than this (relative) are tested for the count's rounding floor
_FLOOR_WIDTH = 1e-9


def beam_frequencies(beam: Beam, count=None, below=None) -> np.ndarray:
    r"""Natural frequencies (rad/s, ascending) of a `Beam` by the Wittrick-Williams count.

    Each root :math:`\lambda_j = \omega_j^2` is bracketed by the count (no root missed or
    found twice): all wanted roots at once, every bracket starting from :math:`[0,
    \lambda_{\rm top}]` (:math:`\lambda_{\rm top}` above the highest root), stepping down by
    :math:`2^{-8}` a pass while its lower end is 0, then halved at the geometric mean while
    :math:`h > 4 l` and at the arithmetic mean after, until the bracket :math:`(l_j, h_j]`
    holds root j alone (count j at :math:`l_j`, j + 1 at :math:`h_j`). Inside it
    :math:`p(\lambda) \propto \det(K - \lambda M)` changes sign once, and the same recursion
    gives it (the product of the pivots, kept as its base-2 logarithm): regula falsi,

    .. math::

        \lambda \leftarrow h - (h - l) \frac{|p(h)|}{|p(l)| + |p(h)|},

    with the Anderson-Bjorck weights (an end kept twice in a row has its :math:`|p|` scaled by
    :math:`1 - p(\lambda) / p(\text{the end replaced})`, or by 1/2), converges superlinearly.
    Each trial point stays an ulp inside the bracket; three steps in a row that shrink it by
    less than half are followed by a bisection. The iteration ends at a bracket of two ulps,
    or at the count's rounding floor: once the bracket is narrower than 1e-9 relative, p is
    linear in it unless rounding dominates, and then :math:`(|p(l)| + |p(h)|) / (h - l)`
    grows as the bracket shrinks (16 times its least value ends it). The bracket's midpoint
    sigma is then finished on the (K, M) of `beam_matrices` themselves, O(N) per root: two
    steps of inverse iteration with the banded LU of :math:`K - \sigma M` (LAPACK dgbtrf,
    partial pivoting), then three corrections :math:`x \leftarrow x - (z - \alpha y)` with
    :math:`(K - \sigma M) z = r = (K - \rho M) x`, :math:`(K - \sigma M) y = M x`,
    :math:`\alpha` making the step M-orthogonal to x and :math:`\rho` the Rayleigh quotient
    (Newton's method for the eigenpair with the Jacobian frozen at sigma; Dongarra, Moler &
    Wilkinson 1983). K x is summed with exact products and compensated sums (Dekker,
    Knuth), so r keeps its digits where K x and rho M x cancel, and the final Rayleigh
    quotient is good to a few ulps (docs/frequency_accuracy.md). The count confirms it:
    exactly root j in :math:`\rho (1 \mp \delta)` (delta four times its distance from
    sigma, and at least the lesser of 1e-7 and a quarter of the relative gap to the next root
    found); a root it cannot confirm (a pair the count cannot part) keeps sigma. So the
    accuracy does not rest on the count's extended precision (long double is double on some
    platforms). About 25 counts
    find the lowest ten of a 1,000-element cantilever (bisection to adjacent floats took about
    100). Every root's path depends on the beam and its index alone, so its bits do not
    depend on ``count`` or ``below``. Rigid-body modes
    (`rigid_body_modes`) are exact zeros.

    Parameters
    ----------
    beam : Beam
    count : int, optional
        The lowest ``count`` frequencies.
    below : float, optional
        All frequencies below this (rad/s). Default (neither): all ``beam.n_dof``.

    Returns
    -------
    ndarray
        omega_j, rad/s, ascending.

    Examples
    --------
    >>> import dtdyn as dd
    >>> beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=50)
    >>> w = dd.beam_frequencies(beam, count=2)
    >>> round(float(w[0] / (1.875104**2 * (2.1e11 * 8e-6 / (20.0 * 3.0**4)) ** 0.5)), 6)
    1.0
    """
    if count is not None and below is not None:
        raise ValueError("give count or below, not both")
    if not isinstance(beam, Beam):
        raise ValueError(f"beam must be a Beam, got {type(beam).__name__}")
    if beam.elements > MAX_FREQUENCY_ELEMENTS:
        raise ValueError(f"beam_frequencies: the beam has {beam.elements:,} elements, more than "
                         f"{MAX_FREQUENCY_ELEMENTS:,} (each count sweeps every node): mode j's "
                         "discretization error falls as (j / elements)^4, so more elements "
                         "add round-off and time, not accuracy; use fewer elements")
    blocks = _count_blocks(beam)
    if below is not None:
        lam_below = _number("below", below, True) ** 2
        wanted = int(wittrick_williams_counts(beam, [lam_below], blocks)[0])
    else:
        wanted = beam.n_dof if count is None else int(validate.step_count("count", count))
        if wanted > beam.n_dof:
            raise ValueError(f"count = {count!r}: the beam has {beam.n_dof} DOFs")
    if wanted == 0:
        return np.zeros(0)
    # rigid-body modes (free, sliding or one pinned end, no spring holding them): exact zeros,
    # not iterated (their lambda = 0 lies below every bracket's lower end)
    rigid = min(rigid_body_modes(beam), wanted)
    if wanted == rigid:
        return np.zeros(wanted)
    top = 1.01 * _highest_frequency_bound(beam) ** 2
    scale = blocks[-1]

    def evaluate(points):
        """count and log2 |det| at the points (rad^2/s^2), shared where points coincide"""
        points, where = np.unique(points, return_inverse=True)
        c, logdet = _inertia(blocks, points.astype(_WIDE) * _WIDE(scale), det=True)
        return c[where.ravel()], logdet[where.ravel()]

    j = np.arange(rigid, wanted)
    n = j.size
    # every bracket from the same start, whatever count or below: root j's path depends on
    # the beam and j alone
    lo, hi = np.zeros(n), np.full(n, top)
    clo, chi = np.full(n, rigid), np.full(n, beam.n_dof)  # the counts at lo, hi
    tlo, thi = np.full(n, np.nan), np.full(n, np.nan)  # log2 |p| at lo, hi
    llo, lhi = tlo.copy(), thi.copy()                  # ... as regula falsi weighs them
    slope = np.full(n, np.inf)  # log2 of the least (|p(l)| + |p(h)|) / (h - l) seen
    side = np.zeros(n, dtype=np.int64)  # the end the last step replaced: -1 lo, 1 hi
    slow = np.zeros(n, dtype=np.int64)  # consecutive regula falsi steps that kept over half
    done = np.zeros(n, dtype=bool)
    eps = np.finfo(float).eps
    while True:
        width = hi - lo
        done |= width <= 2.0 * eps * hi
        isolated = (clo == j) & (chi == j + 1)
        # the rounding floor: in a bracket this narrow p is linear unless rounding dominates
        # it, and then (|p(l)| + |p(h)|) / (h - l) grows as the bracket shrinks
        floor = isolated & (width <= _FLOOR_WIDTH * hi) & np.isfinite(tlo) & np.isfinite(thi)
        with np.errstate(divide="ignore", invalid="ignore"):
            s_now = (np.maximum(tlo, thi) + np.log2(1.0 + np.exp2(-np.abs(tlo - thi)))
                     - np.log2(width))
        slope = np.where(floor, np.minimum(slope, s_now), slope)
        done |= floor & (s_now > slope + 4.0)
        geometric = (lo > 0.0) & (hi > 4.0 * lo)
        mid = np.where(geometric, np.sqrt(lo) * np.sqrt(hi), 0.5 * lo + 0.5 * hi)
        mid = np.where(lo > 0.0, mid, np.ldexp(hi, -8))  # down from the top: 2^-8 a pass
        done |= ~isolated & ~((mid > lo) & (mid < hi))  # adjacent floats (a multiple root)
        if done.all():
            break
        with np.errstate(over="ignore"):
            weight = 1.0 / (1.0 + np.exp2(llo - lhi))  # |p(h)| / (|p(l)| + |p(h)|)
        tol = eps * hi
        x = np.clip(hi - weight * width, lo + tol, hi - tol)
        falsi = isolated & (slow < 3) & np.isfinite(llo) & np.isfinite(lhi)
        x = np.where(falsi, x, mid)
        idx = np.flatnonzero(~done)
        c, logdet = evaluate(x[idx])
        up = c > j[idx]
        i_hi, i_lo = idx[up], idx[~up]
        # Anderson-Bjorck: an end kept a second time has its |p| scaled by 1 - p(x) / p(end
        # replaced) (by 1/2 if that is not positive)
        with np.errstate(over="ignore", invalid="ignore"):
            m_hi = 1.0 - np.exp2(logdet[up] - lhi[i_hi])
            m_lo = 1.0 - np.exp2(logdet[~up] - llo[i_lo])
        m_hi, m_lo = np.where(m_hi > 0.0, m_hi, 0.5), np.where(m_lo > 0.0, m_lo, 0.5)
        again = falsi[i_hi] & (side[i_hi] == 1)
        llo[i_hi[again]] += np.log2(m_hi[again])
        again = falsi[i_lo] & (side[i_lo] == -1)
        lhi[i_lo[again]] += np.log2(m_lo[again])
        side[i_hi], side[i_lo] = 1, -1
        hi[i_hi], chi[i_hi], lhi[i_hi], thi[i_hi] = x[i_hi], c[up], logdet[up], logdet[up]
        lo[i_lo], clo[i_lo], llo[i_lo], tlo[i_lo] = x[i_lo], c[~up], logdet[~up], logdet[~up]
        shrunk = hi[idx] - lo[idx] <= 0.5 * width[idx]
        slow[idx] = np.where(falsi[idx] & ~shrunk, slow[idx] + 1, 0)
    from dtdyn.linear._beam_frequency import refined_roots  # (it imports this module)

    lam = refined_roots(beam, 0.5 * lo + 0.5 * hi, j, blocks)
    return np.concatenate([np.zeros(rigid), np.sqrt(lam)])


def _highest_frequency_bound(beam: Beam) -> float:
    """An upper bound of the highest natural frequency (rad/s): the largest eigenvalue of the
    element pencils (K_e + the springs assigned to the element, M_e) bounds the assembled one's
    (Irons & Treharne; point masses only lower it)."""
    import scipy.linalg as sla

    h = beam.length / beam.elements
    Ke = derived.element_stiffness(beam.E * beam.I, h)
    Me = (derived.element_mass if beam.mass_matrix == "consistent"
          else derived.element_mass_lumped)(beam.rho_A, h)
    extra = {}
    for s in beam.supports:  # each node's springs go to one element containing it
        e = min(s.node, beam.elements - 1)
        j = 2 * (s.node - e)
        extra.setdefault(e, np.zeros((4, 4)))[[j, j + 1], [j, j + 1]] += [s.k_w, s.k_psi]
    lam = [sla.eigh(Ke + S, Me, eigvals_only=True)[-1] for S in [np.zeros((4, 4)),
                                                                 *extra.values()]]
    return float(np.sqrt(max(lam)))


def rigid_translation(beam: Beam, n_dir: int = 1) -> np.ndarray:
    """The default support-motion influence: a rigid translation, w 1 and psi 0, per ground
    direction (n_dof, n_dir)."""
    return np.repeat((beam.free % 2 == 0).astype(float)[:, None], n_dir, axis=1)


def node_system(beam: Beam):
    """(M, C, K) of the whole node-by-node system the sweep runs on, a held DOF decoupled with a
    unit mass and stiffness: its history and load are zero, so it stays at rest. Rows
    2 node + (0: w, 1: psi); ``beam.free`` maps ``beam.dof_names`` into them."""
    Mg, Cg, Kg = beam.global_matrices()
    held = np.ones(Mg.shape[0])
    held[beam.free] = 0.0
    keep = sps.diags(1.0 - held)
    return tuple((keep @ A @ keep + sps.diags(held * unit)).tocsr()
                 for A, unit in ((Mg, 1.0), (Cg, 0.0), (Kg, 1.0)))


def beam_response(beam: Beam, force, dt, *, force_dofs=None, scheme="newmark",
                  form=None, outputs=None, quantities=("x", "v", "a"), x0=None,
                  v0=None, unstable="raise", backend="c", progress=False,
                  ground_acceleration=None, ground_velocity=None, ground_displacement=None,
                  influence=None, refine="auto", **scheme_params):
    """Time history of a `Beam` by the DT-TMM with the matrix Riccati sweep.

    Each step the scheme makes every DOF's x, v, a affine in its unknown u (the increment
    x_e - x_n in the displacement form, a_e in the acceleration form); the elements' equations
    are then block tridiagonal in 2 x 2 node blocks, and the sweep condenses the beam from the
    free (right) end onto each node, P_i = D_i - E_i P_{i+1}^-1 F_i once per run, the load
    y_i = b_i - E_i P_{i+1}^-1 y_{i+1} every step, then the unknowns forward from the left:
    O(N) per step, equal to `mck_response` on `beam_matrices` (same scheme) to rounding
    (docs/beam.md: the kernel and its speed).

    Parameters
    ----------
    beam : Beam
    force : array_like, shape (n_steps + 1, len(force_dofs))
        Force (N) or moment (N m) samples at t_k = k dt on the DOFs ``force_dofs``.
    dt : float
    force_dofs : sequence of int or DOF names, optional
        Indices into ``beam.dof_names`` or the names themselves ("w200"); default every DOF.
    scheme, form
        As `chain_response` (None: the displacement form, or the acceleration form of an
        explicit scheme, its only one).
    outputs : sequence of int or DOF names, optional
        The DOFs stored, as ``force_dofs``; default every DOF.
    quantities, x0, v0, unstable
        As `chain_response` (x0, v0 over ``beam.dof_names``).
    backend : {"c", "numpy"}
        The C kernel of 2 x 2 node-block chains (generated/block_chain.c: the node blocks of
        M, C, K, the scheme's history terms, the sweep and the update fused block by block of
        nodes; NumPy with one warning where no compiler exists), or NumPy with a sparse LU of
        the same effective matrix.
    progress
        As `chain_response`.
    ground_acceleration, ground_velocity, ground_displacement, influence : optional
        Support motion as in `mck_response` (one record; ``force`` may then be None): the DOFs
        are relative to the supports, which move together; the default influence r is the
        rigid translation (1 on every w, 0 on every psi).
    refine : {"auto", True, False}
        Iterative refinement of every step's solve, the residual element by element in
        double-double: "auto" from 2,000 elements on; below that the results are bitwise
        those of ``refine=False``.
    **scheme_params
        The scheme's parameters by name (``beta``, ``gamma`` of "newmark", ``theta`` of
        "wilson", ``alpha`` of "hht", ``rho_inf`` of "generalized_alpha"; `dtdyn show` lists
        them; defaults as there); a misspelled name is a TypeError that names the closest one.

    Returns
    -------
    Response
        ``x``, ``v``, ``a`` of shape (n_steps + 1, len(outputs)), ``dof_names`` of the outputs
        (and ``a_abs``, ``x_abs`` under support motion).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=100)
    >>> r = dd.beam_response(beam, np.ones(201), 1e-4, force_dofs=[beam.dof("w100")],
    ...                      outputs=[beam.dof("w100")])
    >>> r.x.shape
    (201, 1)
    """
    if not isinstance(beam, Beam):
        raise ValueError(f"beam must be a Beam, got {type(beam).__name__}")
    solver = beam.solver(dt, scheme=scheme, form=form, backend=backend, outputs=outputs,
                         quantities=quantities, unstable=unstable, refine=refine,
                         **scheme_params)
    return solver.run(force, force_dofs=force_dofs, x0=x0, v0=v0, progress=progress,
                      ground_acceleration=ground_acceleration, ground_velocity=ground_velocity,
                      ground_displacement=ground_displacement, influence=influence)


class BeamSolver(Solver):
    """The `Solver` of `Beam`: the DT-TMM with the matrix Riccati sweep on the node system
    (`node_system`; a held DOF decoupled, at rest). Backend "c": the node blocks of M, C, K
    stored once (`node_blocks`), M and each scheme's effective matrix factorized once by the
    block sweep (`_block_operator`); "numpy": the sparse LUs of M and of the effective
    matrices (`dtdyn.linear._mck.step_operator`). The assembled M of a ground record's load is
    made at the first run that has one."""

    def __init__(self, beam, dt, scheme, form, backend, outputs, quantities, unstable,
                 scheme_params, refine="auto"):
        lib = _block_library() if check_backend(backend) == "c" else None
        self._corrections = refinements(beam, refine)
        super().__init__(beam, dt, scheme, form, backend, outputs, quantities, unstable,
                         lambda limit: _highest_frequency_bound(beam), scheme_params)
        self._lib = lib
        self._rigid = lambda k: rigid_translation(beam, k)
        self._stored = beam.free[self.outputs]
        self._dof_names = tuple(beam.dof_names[i] for i in self.outputs)
        self._dof_kinds = tuple("rotation" if n.startswith("psi") else "translation"
                                for n in self._dof_names)
        self._full = 2 * (beam.elements + 1)
        nodes = beam.elements + 1
        runs = schemes_of_run(self._info)
        if lib is not None:
            self._blocks = node_blocks(beam)
            self._mass = _mass_factor(lib, beam, self._blocks)
            self._coeffs = {scheme_key(s): s.coefficients(self.form, self.dt) for s in runs}
            self._ops = {key: _block_operator(lib, self.form, s, self._coeffs[key], self._blocks,
                                              nodes, refine_data(beam, s, self._coeffs[key],
                                                                 self._corrections))
                         for s in runs for key in [scheme_key(s)]}
        else:
            M, self._C, self._K = beam_matrices(beam)
            self._ground_mass = M
            self._mass_solve = linalg.solver(M, "M")
            Mg, Cg, Kg = node_system(beam)
            self._ops = {scheme_key(s): refined_step_operator(
                beam, self.form, s, s.coefficients(self.form, self.dt), Mg, Cg, Kg, self._stored,
                self._corrections) for s in runs}

    def _load_case(self, force, force_dofs, x0, v0, *ground):
        if self._ground_mass is None and support.given(*ground[:3]):
            self._ground_mass = beam_matrices(self.model)[0]  # (two threads: made twice)
        return super()._load_case(force, force_dofs, x0, v0, *ground)

    def _initial_state(self, case):
        beam = self.model
        full = [np.zeros(self._full) for _ in range(3)]
        for z, part in zip(full, (case.x0, case.v0)):
            z[beam.free] = part
        if self._lib is not None:
            full[2] = _initial_acceleration(self._lib, beam, self._blocks, case.f0, full[0],
                                            full[1], self._mass)
        else:
            full[2][beam.free] = self._mass_solve(case.f0 - self._C @ case.v0
                                                  - self._K @ case.x0)
        return full

    def _stepper(self, loaded):
        lib, form, ops, free = self._lib, self.form, self._ops, self.model.free
        nodes = self.model.elements + 1
        if lib is None:
            return lambda sch, coeffs: ops[scheme_key(sch)](free[loaded])

        def make_advance(sch, coeffs):
            key = scheme_key(sch)
            return _block_advance(lib, form, sch, self._coeffs[key], self._blocks, nodes,
                                  free[loaded], self._stored, ops[key])
        return make_advance

    def _annotate(self, res):
        res.outputs = self.outputs
        res.dof_names = self._dof_names
        res.dof_kinds = self._dof_kinds
        c = self._lib is not None
        res.info.update(method="DT-TMM (matrix Riccati sweep)" if c else
                        "assembled matrices (sparse LU)", form=self.form,
                        backend="c" if c else "numpy", refinements=self._corrections)


@cache
def _block_library():
    """The library of generated/block_chain.c, or None without a compiler (one warning)."""
    lib = cbuild.load_library(cbuild.generated_source("block_chain.c"), "block_chain")
    if lib is not None:
        for kernel in ("dtdyn_block_chain_factor", "dtdyn_block_chain_solve",
                       "dtdyn_block_chain_loop"):
            cbuild.bind(lib, kernel)
    return lib


def _stride(nodes: int) -> int:
    """The stride of block_chain.c's per-node arrays: nodes + 1 rounded up to
    BLOCK_CHAIN_ALIGN doubles (generated/c_api.py, the same constant as the C side's)."""
    from dtdyn.generated.c_api import BLOCK_CHAIN_ALIGN as align
    return (nodes + align) // align * align


def _aligned(shape) -> np.ndarray:
    """Zeros of ``shape`` starting on a 64-byte boundary (the kernel's vector loads)."""
    size = int(np.prod(shape))
    buf = np.zeros(size + 8)
    start = (-buf.ctypes.data % 64) // 8
    return buf[start:start + size].reshape(shape)


def block_storage(A, held=None, unit=1.0) -> np.ndarray:
    """A symmetric matrix block tridiagonal in 2 x 2 node blocks (DOF 2 i + c: component c of
    node i; scipy.sparse) in the layout of block_chain.c, rows of `_stride` doubles: the
    diagonal blocks' d00, d01, d11 over the nodes, then e00, e01, e10, e11 of
    E_i = A[node i, node i + 1] at i + 1 (zero at 0 and N). ``held`` (nodes, 2), optional: those
    DOFs decoupled, with ``unit`` on the diagonal (as `node_system`). ValueError when A is not
    symmetric or couples nodes further apart."""
    A = sps.csr_matrix(A)
    nodes = A.shape[0] // 2
    diags = [A.diagonal(k) for k in range(4)]
    inside = sum(np.count_nonzero(A.diagonal(k)) for k in range(-3, 4))
    if A.shape[0] % 2 or A.count_nonzero() != inside or np.any(diags[3][1::2] != 0.0):
        raise ValueError("not block tridiagonal in 2 x 2 node blocks")
    if any(np.any(A.diagonal(-k) != diags[k]) for k in (1, 2, 3)):
        raise ValueError("not symmetric")
    out = _aligned((7, _stride(nodes)))
    out[:3, :nodes] = [diags[0][0::2], diags[1][0::2], diags[0][1::2]]
    out[3:, 1:nodes] = [diags[2][0::2], diags[3][0::2], diags[1][1::2], diags[2][1::2]]
    return _decoupled(out, held, unit)


def _decoupled(out, held, unit):
    """The storage ``out`` with the ``held`` DOFs decoupled and ``unit`` on their diagonal."""
    if held is not None:
        for i, c in np.argwhere(held):  # a few nodes: the supports
            out[1, i] = 0.0                                 # d01
            out[2 * c, i] = unit                            # d00 or d11
            out[3 + 2 * c:5 + 2 * c, i + 1] = 0.0           # row c of E_i
            out[[3 + c, 5 + c], i] = 0.0                    # column c of E_{i-1}
    return out


def node_blocks(beam: Beam):
    """(K, C, M) of `node_system` in the layout of block_chain.c (`block_storage`), straight
    from the element matrices: each node block is the sum of its two elements' blocks and the
    node's point masses, supports and dampers, in the order of the sparse assembly (so equal to
    it bit for bit)."""
    nodes, N = beam.elements + 1, beam.elements
    h = beam.length / beam.elements
    Ke = derived.element_stiffness(beam.E * beam.I, h)
    Me = (derived.element_mass if beam.mass_matrix == "consistent"
          else derived.element_mass_lumped)(beam.rho_A, h)
    diag = {k: v.reshape(nodes, 2) for k, v in beam.nodal_diagonals().items()}
    held = np.ones(2 * nodes, dtype=bool)
    held[beam.free] = False
    held = held.reshape(nodes, 2)

    def blocks(Ae):
        out = np.zeros((7, _stride(nodes)))
        for k, (a, b) in enumerate(((0, 0), (0, 1), (1, 1))):
            out[k, :N] = Ae[a, b]             # node i as the left node of element i
            out[k, 1:nodes] += Ae[2 + a, 2 + b]  # ... and as the right node of element i - 1
        for k, (a, b) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
            out[3 + k, 1:nodes] = Ae[a, 2 + b]
        return out

    K, M = blocks(Ke), blocks(Me)
    C = np.zeros_like(K)
    if beam.rayleigh is not None:
        C = beam.rayleigh[0] * M + beam.rayleigh[1] * K
    stored = []
    for A, name, unit in ((K, "k", 1.0), (C, "c", 0.0), (M, "m", 1.0)):
        out = _aligned(A.shape)
        out[...] = A
        out[0, :nodes] += diag[name][:, 0]
        out[2, :nodes] += diag[name][:, 1]
        stored.append(_decoupled(out, held, unit))
    return tuple(stored)


def _to_kernel(z, nodes):
    """Node-system rows (..., 2 nodes; DOF 2 i + c) as block_chain.c stores them: component 0
    of every node, then component 1, each in a row of `_stride` doubles (64-byte aligned)."""
    shape = z.shape[:-1] + (2, _stride(nodes))
    buf = _aligned((int(np.prod(shape)) + 16,))  # zeros around the rows (nodes -1 and N)
    out = buf[8:8 + int(np.prod(shape))].reshape(shape)
    out[..., :nodes] = np.swapaxes(z.reshape(z.shape[:-1] + (nodes, 2)), -1, -2)
    return out


def _from_kernel(zs, nodes):
    """The inverse of `_to_kernel`."""
    return np.swapaxes(zs[..., :nodes], -1, -2).reshape(zs.shape[:-2] + (2 * nodes,))


def _mass_factor(lib, beam, stored):
    """M factorized once for `_initial_acceleration`: (its block Riccati factors, None), or,
    where the block sweep meets a singular pivot, (None, the sparse solve of M), which is a
    ValueError naming M when M is singular."""
    nodes = beam.elements + 1
    fac = _aligned((11, _stride(nodes)))
    if lib.dtdyn_block_chain_factor(nodes, stored[2].ctypes.data, fac.ctypes.data) >= 0:
        return None, linalg.solver(beam_matrices(beam)[0], "M")
    return fac, None


def _initial_acceleration(lib, beam, stored, f0, x0, v0, mass=None):
    """a_0 over the node system from M a_0 = f_0 - C v_0 - K x_0 by the block Riccati solve
    (zero on the held DOFs); a singular M falls back to the sparse solve, which names it.
    ``mass``: `_mass_factor`, made once by a solver (None: made here)."""
    fac, mass_solve = mass or _mass_factor(lib, beam, stored)
    bK, bC, bM = stored
    nodes = beam.elements + 1
    rhs = np.zeros(2 * nodes)
    rhs[beam.free] = f0
    for b, z in ((bC, v0), (bK, x0)):
        if z.any():
            rhs -= _block_product(b, z, nodes)
    held = np.ones(2 * nodes, dtype=bool)
    held[beam.free] = False
    rhs[held] = 0.0
    if fac is None:
        a = np.zeros(2 * nodes)  # the sparse solve of M
        a[beam.free] = mass_solve(rhs[beam.free])
        return a
    a = _to_kernel(rhs, nodes)
    lib.dtdyn_block_chain_solve(nodes, fac.ctypes.data, a.ctypes.data)
    return _from_kernel(a, nodes)


def _block_product(b, z, nodes):
    """A z for A in the layout of block_chain.c and z over the node system (2 i + c)."""
    d00, d01, d11 = b[:3, :nodes]
    e00, e01, e10, e11 = b[3:, 1:nodes]     # E_i, i = 0 .. nodes - 2
    z0, z1 = z.reshape(nodes, 2).T
    out = np.empty((nodes, 2))
    out[:, 0] = d00 * z0 + d01 * z1
    out[:, 1] = d01 * z0 + d11 * z1
    out[:-1, 0] += e00 * z0[1:] + e01 * z1[1:]      # E_i z_{i+1}
    out[:-1, 1] += e10 * z0[1:] + e11 * z1[1:]
    out[1:, 0] += e00 * z0[:-1] + e10 * z1[:-1]     # E_{i-1}^T z_{i-1}
    out[1:, 1] += e01 * z0[:-1] + e11 * z1[:-1]
    return out.ravel()


#: ``refine="auto"`` refines the step's solves from this many elements on (measured,
#: docs/beam_conditioning.md: without refinement a held tip load's static deflection is off by
#: 1e-7 at 1,000 elements, 3e-7 .. 8e-7 at 2,000, 1e-5 .. 1e-4 at 5,000, 1e-3 at 10,000, where
#: beta K damping alone makes the plain step unstable; a refined step costs about 3 plain
#: ones); below it the step is bitwise the unrefined one
REFINE_MIN_ELEMENTS = 2000
#: the most corrections per step (each: a residual and a solve with the kept factors); fewer
#: once the next one is predicted below REFINE_TOL times the displacements (block_chain.h):
#: three for the 10,000-element cantilever of docs/beam_conditioning.md at dt = 1e-4 (each
#: contracts by ~3e-4), five when beta K damps its first mode critically (~1.5e-2 each). What
#: a step leaves adds up over the slowest mode's decay time (measured: 1e-10 a step left 9e-8
#: of a static deflection, 1e-12 left 7e-10)
REFINE_CORRECTIONS = 8
REFINE_TOL = 1e-12


def refinements(beam: Beam, refine) -> int:
    """The corrections per step ``refine`` asks for: "auto" `REFINE_CORRECTIONS` from
    `REFINE_MIN_ELEMENTS` elements on (else 0), True always, False never."""
    if isinstance(refine, str) and refine == "auto":
        return REFINE_CORRECTIONS if beam.elements >= REFINE_MIN_ELEMENTS else 0
    if refine is True or refine is False:
        return REFINE_CORRECTIONS if refine else 0
    raise ValueError(f"refine = {refine!r}: must be 'auto', True or False")


def block_work(nodes: int, refined: bool) -> int:
    """The doubles of block_chain.c's work for ``nodes`` (with the refinement's rows)."""
    from dtdyn.generated import c_api

    P = _stride(nodes)
    refine_rows = c_api.BLOCK_CHAIN_REFINE_ROWS if refined else 0
    return c_api.BLOCK_CHAIN_ROWS * (P + c_api.BLOCK_CHAIN_GAP) + refine_rows * P


def _element_terms(beam: Beam):
    """(h, F^-1 as (f00, f01, f11), Me): the element's length, the stiffness block of its left
    node (its flexibility's inverse: K_e = [I, -T]^T F^-1 [I, -T], T = [[1, -h], [0, 1]]) and
    its mass matrix, from the generated element matrices."""
    h = beam.length / beam.elements
    Ke = derived.element_stiffness(beam.E * beam.I, h)
    Me = (derived.element_mass if beam.mass_matrix == "consistent"
          else derived.element_mass_lumped)(beam.rho_A, h)
    return h, (float(Ke[0, 0]), float(Ke[0, 1]), float(Ke[1, 1])), np.asarray(Me, dtype=float)


def _point_terms(beam: Beam):
    """(dofs, k, c, m) of the nodes' springs, dampers and masses (node-system indices, the
    nonzero ones), and the held DOFs."""
    diag = beam.nodal_diagonals()
    held = np.ones(2 * (beam.elements + 1), dtype=bool)
    held[beam.free] = False
    dofs = np.flatnonzero((diag["k"] != 0) | (diag["c"] != 0) | (diag["m"] != 0))
    return dofs, diag["k"][dofs], diag["c"][dofs], diag["m"][dofs], np.flatnonzero(held)


def refine_data(beam: Beam, sch, K_, corrections: int):
    """The refinement's data of block_chain.c (its layout: block_chain.h, BR_HEAD) for one
    scheme's coefficients ``K_``, or None when ``corrections`` is 0."""
    if not corrections:
        return None
    h, (f00, f01, f11), Me = _element_terms(beam)
    dofs, k, c, m, held = _point_terms(beam)
    alpha, beta = beam.rayleigh or (0.0, 0.0)
    head = [corrections, REFINE_TOL, dofs.size, held.size, h, f00, f01, f11, alpha, beta,
            K_["p"], K_["r"], K_["alpha_u"], *Me.ravel()]
    pts = np.column_stack([dofs, k, c, m]).ravel()
    return np.ascontiguousarray(np.concatenate([head, pts, held]), dtype=float)


def refined_residual(beam, K_, L, H, u, F, terms):
    """block_chain.h's refinement residual in NumPy: F - K (q + p u) - C (s + r u) -
    M (b + alpha u) over the node system (2 i + c), element by element with the deformations in
    double-double, zero on the held DOFs, and max |x + beta_R v| per component (w, psi). L: the
    rows q, s, b over the history H (n_hist, 2 nodes); ``terms``: (`_element_terms`,
    `_point_terms`)."""
    (h, (f00, f01, f11), Me), (dofs, k, c, m, held) = terms
    alpha, beta = beam.rayleigh or (0.0, 0.0)
    eq = []
    for t, coef in enumerate((K_["p"], K_["r"], K_["alpha_u"])):
        hi, lo = np.zeros_like(u), np.zeros_like(u)
        for j in np.flatnonzero(L[t]):
            hi, lo = add_product(hi, lo, L[t, j], H[j])
        eq.append(add_product(hi, lo, coef, u))
    (xh, xl), (vh, vl), (ah, al) = eq
    xh, xl = add_product(xh, xl, beta, vh)
    Xh, Xl = two_sum(xh, xl + beta * vl)
    xmax = np.abs(Xh).reshape(-1, 2).max(axis=0)
    Y = (ah + al) + alpha * (vh + vl)
    wh, wl, ph, pl = Xh[0::2], Xl[0::2], Xh[1::2], Xl[1::2]
    yh, e = two_sum(wh[:-1], -wh[1:])
    yh, yl = add_product(yh, e + (wl[:-1] - wl[1:]), h, ph[1:])
    yw = yh + (yl + h * pl[1:])
    yh, e = two_sum(ph[:-1], -ph[1:])
    yp = yh + (e + (pl[:-1] - pl[1:]))
    fw, fp = f00 * yw + f01 * yp, f01 * yw + f11 * yp
    mass = Me @ np.stack([Y[0:-2:2], Y[1:-1:2], Y[2::2], Y[3::2]])
    r = F.copy()
    r[0:-2:2] -= fw + mass[0]
    r[1:-1:2] -= fp + mass[1]
    r[2::2] -= mass[2] - fw
    r[3::2] -= mass[3] + (h * fw - fp)
    x = eq[0][0][dofs] + eq[0][1][dofs]
    r[dofs] -= k * x + c * (vh[dofs] + vl[dofs]) + m * (ah[dofs] + al[dofs])
    r[held] = 0.0
    return r, xmax


def refined_step_operator(beam, form, sch, K_, M, C, K, outputs, corrections):
    """`dtdyn.linear._mck.step_operator` (NumPy, sparse LU) on the node system, each step's
    solve refined ``corrections`` times by `refined_residual` (0: that operator itself)."""
    if not corrections:
        return mck.step_operator(form, sch, K_, M, C, K, outputs, None)
    from dtdyn.generated.dttmm_sweep import error_history_maps

    L = error_history_maps(K_, list(sch.history))[0]
    terms = (_element_terms(beam), _point_terms(beam))

    def correct(u, H, Fe, solve):
        prev = 0.0
        for c in range(corrections):  # as block_chain.h: stop when the next is small
            r, xmax = refined_residual(beam, K_, L, H, u, Fe, terms)
            du = solve(r)
            u = u + du
            d = np.abs(K_["p"] * du).reshape(-1, 2).max(axis=0)
            e = max(d[k] / xmax[k] if d[k] > 0 else 0.0 for k in (0, 1))
            if e == 0.0 or (c > 0 and e * (e / prev) <= REFINE_TOL):
                break
            prev = e
        return u
    return mck.step_operator(form, sch, K_, M, C, K, outputs, None, correct=correct)


def _block_operator(lib, form, sch, K_, stored, nodes, refine=None):
    """The load-independent operands of `_block_advance` for one scheme: the effective matrix
    factorized by the matrix Riccati sweep (a ValueError when it is singular), the step's maps
    on the history rows and the kernel's pointer array ``mats``. Returns (mats, L, c_u, shift,
    rows, keep, names): ``keep`` the arrays ``mats`` points to; every array is only read by
    the kernel, so one operator serves any number of runs, at once in several threads.
    ``refine``: `refine_data` (None: no refinement), the last of ``mats``."""
    from dtdyn.generated.dttmm_sweep import error_history_maps
    from dtdyn.linear._mck import EFFECTIVE

    bK, bC, bM = stored
    A = np.ascontiguousarray(K_["alpha_u"] * bM + K_["r"] * bC + K_["p"] * bK)
    fac = _aligned((11, _stride(nodes)))
    bad = lib.dtdyn_block_chain_factor(nodes, A.ctypes.data, fac.ctypes.data)
    if bad >= 0:
        raise ValueError(f"{EFFECTIVE[form]} is singular at node {bad} (condensed pivot)")
    with_m = form != "acceleration"  # the acceleration form has b = 0
    names = list(sch.history)
    L_qsb, L_upd, c_u, shifts, rows = error_history_maps(K_, names)
    L = np.ascontiguousarray(np.vstack([L_qsb, L_upd]), dtype=float)
    c_u = np.ascontiguousarray(c_u.ravel(), dtype=float)
    shift = np.array(shifts, dtype=np.int64).reshape(-1, 2)
    rows = np.arange(len(names), dtype=np.int64)[rows]
    # the right side of a one-step scheme (history x0, v0, a0) as sum_h B_h H_h with
    # B_h = L_q[h] K + L_s[h] C + L_b[h] M once per run (no pass for q, s, b); a multistep
    # scheme's q, s, b are differences of lags, formed first, so that K, C, M multiply what
    # is left of the cancellation (as mck_response does)
    used = np.flatnonzero(np.any(L_qsb != 0.0, axis=0))
    direct = not shifts
    B = [None] * len(names)
    if direct:
        for h in used:
            B[h] = _aligned(bK.shape)
            B[h][...] = L_qsb[0, h] * bK + L_qsb[1, h] * bC + L_qsb[2, h] * bM
    keep = (bK, bC, bM, fac, B, refine)
    ptr = lambda a: None if a is None else a.ctypes.data  # noqa: E731
    mats = (ctypes.c_void_p * (5 + len(names)))(
        None if direct else bK.ctypes.data, bC.ctypes.data, bM.ctypes.data if with_m else None,
        fac.ctypes.data, *[ptr(b) for b in B], ptr(refine))
    return mats, L, c_u, shift, rows, keep, names


def _block_advance(lib, form, sch, K_, stored, nodes, loaded, outputs, operator=None):
    """advance() of stepping.integrate by block_chain.c: the step of `mck.make_advance` on the
    node system stored by `node_blocks` (K, C, M), for the force on the node-system rows
    ``loaded``, storing the rows ``outputs``. ``operator``: the scheme's `_block_operator`,
    made once by a solver (None: made here, the effective matrix factorized per call). The
    advance allocates its own scratch."""
    mats, L, c_u, shift, rows, keep, names = operator or _block_operator(lib, form, sch, K_,
                                                                         stored, nodes)
    order = np.argsort(loaded, kind="stable")
    loaded = np.ascontiguousarray(np.asarray(loaded, dtype=np.int64)[order])
    out_idx = np.ascontiguousarray(outputs, dtype=np.int64)
    from dtdyn.generated import c_api  # the work's rows (z), each after its gap

    work = _aligned((block_work(nodes, mats[len(names) + 4] is not None),))
    n_hist = len(names)
    run = lib.dtdyn_block_chain_loop

    def advance(frc, H, xo, vo, ao):
        frc = np.ascontiguousarray(frc[:, order], dtype=float)
        Hs = _to_kernel(H, nodes)
        ptr = [0 if a is None else a.ctypes.data for a in (xo, vo, ao)]
        args = (nodes, n_hist, frc.shape[0] - 1, loaded.size, loaded.ctypes.data,
                frc.ctypes.data, ctypes.addressof(mats), L.ctypes.data, c_u.ctypes.data,
                K_["w0"], K_["w1"], shift.shape[0], shift.ctypes.data, rows.ctypes.data,
                Hs.ctypes.data, out_idx.size, out_idx.ctypes.data, *ptr, work.ctypes.data,
                work.size)
        rc = cbuild.interruptible(lib, lambda: run(*args),
                                  work=(frc.shape[0] - 1) * 100 * nodes)
        if rc == c_api.ERR_WORK:
            from dtdyn._engine.kernels import DtdynKernelError

            raise DtdynKernelError("dtdyn_block_chain_loop", rc, f"N = {nodes}, "
                                   f"n_work = {work.size}")
        if rc != 0:
            raise RuntimeError(f"dtdyn_block_chain_loop returned {rc} (stopped by its stop flag)")
        H[...] = _from_kernel(Hs, nodes)
        return 0.0
    advance.arrays = keep  # what mats points to lives as long as advance
    return advance
