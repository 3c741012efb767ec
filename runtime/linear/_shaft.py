"""Torsional shafts with disks, gears and branches: the model, assembly, DT-TMM time histories
and natural frequencies by the Wittrick-Williams count.

::

    wall |==k0==(J0)==k1==(J1)==k2==(J2)   main line (left = "clamped": k0 to the wall)
                         |
                       gear n            a branch at disk 1 of "main", through a gear
                         |
                         +==k0'==(J0')==k1'==(J1')

State [phi, T] per station; docs/shaft.md has the equations and generated/shaft.md the derived
station matrices (dtdyn.derive.shaft). The time loop and the count come from generated/.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sps

from dtdyn._engine import validate
from dtdyn._engine import kernels
from dtdyn._engine.kernels import params_array
from dtdyn._engine.public import public
from dtdyn.generated import c_api
from dtdyn.generated import shaft as gen
from dtdyn.linear._solver import (Model, Solver, check_backend, nonlinear_solver,
                                  schemes_of_run)
from dtdyn.linear._stability import highest_frequency

#: the ends a line of disks may have
ENDS = ("free", "clamped", "elastic")
#: the smallest |gear ratio| (and 1 / the largest): 1 / ratio^2 <= 1e200, so that a branch's
#: stiffness seen through the gear stays finite, and its square in the solvers too
MIN_RATIO = 1e-100
#: bytes the lumped tree holds per DOF while `Shaft` builds it (Python lists of its parent,
#: ratio, inertia, stiffness, damping, ground terms and name, then their arrays): 263 B
#: measured at the peak (tracemalloc, a ContinuousShaft of 2e5 elements)
SHAFT_BYTES_PER_DOF = 270


@dataclass(frozen=True)
class ContinuousShaft:
    """A uniform continuous shaft, for an entry of a line's ``stiffness``.

    Its exact field matrix serves `shaft_frequencies`; in time and in `shaft_matrices` it is
    ``elements`` lumped segments (stiffness G J_p elements / length, half a segment's inertia
    rho J_p length / elements at each of its ends).

    Attributes
    ----------
    length, G, Jp, rho : float
        Length (m), shear modulus (Pa), polar moment of area (m^4), density (kg/m^3), > 0.
    elements : int
        Lumped segments in time and in the matrices (16).
    damping : float
        The segment's torsional damping c_t as a whole, N m s/rad (each lumped segment gets
        c_t * elements).

    Examples
    --------
    >>> import dtdyn as dd
    >>> seg = dd.ContinuousShaft(length=1.0, G=8e10, Jp=1e-7, rho=7800.0)
    >>> round(seg.wave_speed, 1)                                   # sqrt(G / rho), m/s
    3202.6
    """

    length: float
    G: float
    Jp: float
    rho: float
    elements: int = 16
    damping: float = 0.0

    def __post_init__(self):
        for name in ("length", "G", "Jp", "rho"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"ContinuousShaft {name} = {v!r}: must be a finite number > 0")
        if not (isinstance(self.damping, (int, float)) and math.isfinite(self.damping)
                and self.damping >= 0):
            raise ValueError(f"ContinuousShaft damping = {self.damping!r}: must be finite, >= 0")
        if isinstance(self.elements, bool) or not isinstance(self.elements, (int, np.integer)) \
                or self.elements < 1:
            raise ValueError(f"ContinuousShaft elements = {self.elements!r}: must be an integer "
                             ">= 1")

    @property
    def wave_speed(self) -> float:
        """c = sqrt(G / rho), m/s."""
        return math.sqrt(self.G / self.rho)


class Branch:
    """A line of disks attached at disk ``at`` (0-based) of its parent line, through a gear
    mesh of ratio ``ratio`` (phi_branch_side = -phi_at / ratio, T_branch_side = -ratio T_at)
    or directly (``ratio=None``).

    ``stiffness[i]``, ``damping[i]``: the shaft from the previous disk (for i = 0: from the
    attachment point, i.e. the gear's driven side) to disk i: a number (k_t, N m/rad; c_t,
    N m s/rad) or a `ContinuousShaft`. ``ground_stiffness``, ``ground_damping``: springs and
    dampers from each disk to the ground. ``right``: "free", or "clamped" / "elastic" (a shaft or
    support of ``right_stiffness``, ``right_damping`` from the last disk to a wall).
    ``branches``: Branch objects attached to this line's disks (any depth). Names: "branch1",
    "branch2", ... in the order met (depth first) unless given.

    Parameters
    ----------
    at : int
        The parent line's 0-based disk it is attached to.
    inertia, stiffness, damping : sequence
        Its disks (kg m^2) and the shafts before them (above).
    ratio : float, optional
        A gear mesh between the parent and this line (None: a direct connection).
    ground_stiffness, ground_damping, right, right_stiffness, right_damping, branches, name
        As above.

    Examples
    --------
    >>> import dtdyn as dd
    >>> gear = dd.Branch(1, inertia=[0.5, 0.4], stiffness=[6e3, 5e3], ratio=2.0, name="out")
    >>> shaft = dd.Shaft([1.0, 0.3, 0.9], [1e4, 1.2e4, 9e3], branches=[gear])
    >>> shaft.dof_names
    ('main.0', 'main.1', 'main.2', 'out.0', 'out.1')
    """

    def __init__(self, at, inertia, stiffness, damping=None, *, ratio=None,
                 ground_stiffness=None, ground_damping=None, right="free", right_stiffness=0.0,
                 right_damping=0.0, branches=(), name=None):
        if isinstance(at, bool) or not isinstance(at, (int, np.integer)):
            raise ValueError(f"branch {name or ''!s} at = {at!r}: must be a 0-based disk "
                             "index".replace("  ", " "))
        self.at = int(at)
        if ratio is not None:
            if not (isinstance(ratio, (int, float, np.floating, np.integer))
                    and math.isfinite(ratio) and ratio != 0):
                raise ValueError(f"branch {name or ''} ratio = {ratio!r}: a gear ratio must be "
                                 "finite and != 0".replace("  ", " "))
            ratio = float(ratio)
            if not MIN_RATIO <= abs(ratio) <= 1.0 / MIN_RATIO:
                raise ValueError(f"branch {name or ''} ratio = {ratio!r}: a gear ratio must be "
                                 f"within {MIN_RATIO:g} .. {1.0 / MIN_RATIO:g} in magnitude (the "
                                 "branch's stiffness and inertia seen by its parent scale as "
                                 "1 / ratio^2, which must stay a finite, normal float with room "
                                 "for the solvers)".replace("  ", " "))
        self.ratio = ratio
        self.name = name
        self._args = (inertia, stiffness, damping, ground_stiffness, ground_damping, right,
                      right_stiffness, right_damping, branches)


class _Line:
    """A checked line of disks (the main line or a branch)."""

    def __init__(  # noqa: C901 (one check per argument)
            self, label, inertia, stiffness, damping, ground_stiffness, ground_damping, right,
            right_stiffness, right_damping, branches, first_connected: bool | None):
        self.label = label
        J = validate.vector(f"{label}inertia", inertia, nonnegative=True)
        N = J.size
        stiffness = list(np.atleast_1d(np.asarray(stiffness, dtype=object)))
        if len(stiffness) != N:
            raise ValueError(f"{label}stiffness has length {len(stiffness)}, expected {N} (one "
                             "shaft before each disk)")
        damping = ([0.0] * N if damping is None
                   else list(np.atleast_1d(np.asarray(damping, dtype=object))))
        if len(damping) != N:
            raise ValueError(f"{label}damping has length {len(damping)}, expected {N}")
        self.k, self.c, self.cont = [], [], []
        for i, (kv, cv) in enumerate(zip(stiffness, damping)):
            if isinstance(kv, ContinuousShaft):
                if _number(f"{label}damping[{i}]", cv) != 0.0:
                    raise ValueError(f"{label}damping[{i}] = {cv!r}: a ContinuousShaft carries its "
                                     "own damping; give 0 here")
                self.k.append(0.0)
                self.c.append(0.0)
                self.cont.append(kv)
            else:
                self.k.append(_number(f"{label}stiffness[{i}]", kv))
                self.c.append(_number(f"{label}damping[{i}]", cv))
                self.cont.append(None)
        for i in range(N):
            linked = self.cont[i] is not None or self.k[i] + self.c[i] > 0
            if i == 0 and first_connected is False:
                if linked:
                    raise ValueError(f"{label}stiffness[0] = {stiffness[0]!r}, damping[0] = "
                                     f"{damping[0]!r} with left = 'free': the first disk has no "
                                     "shaft to its left; give 0, 0 or left = 'clamped'")
            elif not linked:
                where = ("the wall" if i == 0 and first_connected else
                         "its attachment" if i == 0 else f"disk {i - 1}")
                raise ValueError(f"{label}stiffness[{i}] = damping[{i}] = 0: disk {i} is not "
                                 f"connected to {where}")
        self.J = J
        self.kg, self.cg = (np.zeros(N) if v is None else
                            validate.vector(f"{label}{nm}", v, nonnegative=True, length=N)
                            for nm, v in (("ground_stiffness", ground_stiffness),
                                          ("ground_damping", ground_damping)))
        self.kg, self.cg = self.kg.copy(), self.cg.copy()
        if right not in ENDS:
            raise ValueError(f"{label}right = {right!r}: must be one of {ENDS}")
        #: a continuous shaft from the last disk to the right wall, or None
        self.right_segment = None
        if isinstance(right_stiffness, ContinuousShaft):
            if right == "free":
                raise ValueError(f"{label}right_stiffness = {right_stiffness!r} with right = "
                                 "'free': a continuous shaft to the wall needs right = 'clamped'")
            if _number(f"{label}right_damping", right_damping) != 0.0:
                raise ValueError(f"{label}right_damping = {right_damping!r}: a ContinuousShaft "
                                 "carries its own damping; give 0 here")
            self.right_segment = right_stiffness
            right_stiffness = 0.0
        rk, rc = _number(f"{label}right_stiffness", right_stiffness), \
            _number(f"{label}right_damping", right_damping)
        if right == "free" and rk + rc > 0:
            raise ValueError(f"{label}right_stiffness = {rk!r}, right_damping = {rc!r} with right "
                             "= 'free': give right = 'clamped' or 'elastic', or zeros")
        if right != "free" and rk + rc == 0 and self.right_segment is None:
            raise ValueError(f"{label}right = {right!r} needs right_stiffness > 0 (the shaft or "
                             "support from the last disk to the wall), got 0")
        self.kg[-1] += rk
        self.cg[-1] += rc
        self.right = right
        if isinstance(branches, Branch):
            branches = (branches,)
        for j, br in enumerate(branches):
            if not isinstance(br, Branch):
                raise ValueError(f"{label}branches[{j}] = {br!r}: must be a Branch")
        self.branches = list(branches)


def _number(name, v) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {v!r}: must be a number (or a ContinuousShaft for a "
                         "stiffness)") from None
    if not math.isfinite(x) or x < 0:
        raise ValueError(f"{name} = {v!r}: must be finite and >= 0")
    return x


class Tree(NamedTuple):
    """Nodes numbered parent first: parent (-1: the wall or nothing), the gear ratio of the
    connection (NaN: none), inertia, shaft k and c to the parent, ground kg and cg, names."""

    parent: np.ndarray
    ratio: np.ndarray
    J: np.ndarray
    k: np.ndarray
    c: np.ndarray
    kg: np.ndarray
    cg: np.ndarray
    names: tuple
    segments: tuple  # exact trees: per node its ContinuousShaft connection or None
    #: exact trees: per node a ContinuousShaft from it to a wall (a clamped right end) or None
    ground_segments: tuple = ()


class Shaft(Model):
    """A torsional system: a main line of disks, optional branches (trees) and gears.

    The model of `shaft_response`; ``solver(dt, ...)`` prepares it for many load cases
    (`Solver`).

    Parameters
    ----------
    inertia : (N,) array_like
        Disk inertias J >= 0, kg m^2 (0 only where a continuous shaft ends: its segments'
        inertia is lumped there).
    stiffness, damping : (N,) sequences
        The shaft before each disk: stiffness[0], damping[0] join disk 0 to the wall (left =
        "clamped" or "elastic") and must be 0 for left = "free"; stiffness[i] joins disk i - 1 to
        disk i. A number (k_t >= 0, c_t >= 0) or a `ContinuousShaft`.
    left, right : {"free", "clamped", "elastic"}
        The ends. Left: the wall behind stiffness[0]. Right: "clamped"/"elastic" put
        ``right_stiffness``, ``right_damping`` (a shaft or a support) from the last disk to a wall;
        ``right_stiffness`` may be a `ContinuousShaft` (right = "clamped", right_damping 0): its
        lumped points are "<line>.right.e<j>", after the line's last disk.
    right_stiffness, right_damping : float or ContinuousShaft
        The shaft or support from the last disk to the right wall with right = "clamped" or
        "elastic": k_t >= 0 (N m/rad) or a `ContinuousShaft`, and c_t >= 0 (N m s/rad); 0, 0
        by default.
    ground_stiffness, ground_damping : (N,) array_like, optional
        Springs and dampers from each disk to the ground (bearings, supports).
    branches : sequence of Branch
        Lines attached to disks of this line (through gears or directly), any depth.
    name : str
        The main line's name in the DOF names ("main").

    Notes
    -----
    DOF names: "<line>.<i>" for disk i of a line, "<line>.<i>.e<j>" for the j-th lumped point
    inside a continuous shaft before disk i. Order (`dofs`): the main line station by station
    (a continuous shaft's points just before its disk), then each branch the same way, depth
    first in the order given.

    Examples
    --------
    >>> import dtdyn as dd
    >>> s = dd.Shaft([1.0, 2.0], [1e4, 2e4], left="clamped",
    ...              branches=[dd.Branch(1, [0.5], [5e3], ratio=2.0, name="out")])
    >>> s.dof_names
    ('main.0', 'main.1', 'out.0')
    """

    def __init__(self, inertia, stiffness, damping=None, *, left="clamped", right="free",
                 right_stiffness=0.0, right_damping=0.0, ground_stiffness=None,
                 ground_damping=None, branches=(), name="main"):
        if left not in ENDS:
            raise ValueError(f"left = {left!r}: must be one of {ENDS}")
        if not isinstance(name, str) or not name:
            raise ValueError(f"name = {name!r}: must be a non-empty string")
        self.left = left
        self.name = name
        self.lines = []  # (line, parent line index, at, ratio)
        main = _Line("", inertia, stiffness, damping, ground_stiffness, ground_damping, right,
                     right_stiffness, right_damping, branches, left != "free")
        main.name = name
        self.lines.append((main, -1, None, None))
        used = {name}
        stack = [(0, br) for br in reversed(main.branches)]
        count = 0
        while stack:
            pi, br = stack.pop()
            count += 1
            bname = br.name if br.name is not None else f"branch{count}"
            if not isinstance(bname, str) or not bname or bname in used:
                raise ValueError(f"branch name = {bname!r}: names must be unique non-empty strings")
            used.add(bname)
            parent = self.lines[pi][0]
            if not 0 <= br.at < parent.J.size:
                raise ValueError(f"branch {bname!r} at = {br.at}: outside 0..{parent.J.size - 1} "
                                 f"(the disks of {parent.name!r})")
            line = _Line(f"branch {bname!r} ", *br._args[:8], br._args[8], True)
            line.name = bname
            self.lines.append((line, pi, br.at, br.ratio))
            li = len(self.lines) - 1
            stack.extend((li, b) for b in reversed(line.branches))
        # before the lumped tree is built: its DOFs, a continuous shaft's points included
        lumped = sum(line.J.size + sum(seg.elements - 1 for seg in
                                       (*line.cont, line.right_segment) if seg is not None)
                     for line, *_ in self.lines)
        validate.memory(f"Shaft: its lumped model of {lumped:,} DOFs (the ContinuousShaft "
                        "elements)", lumped * SHAFT_BYTES_PER_DOF,
                        "give the ContinuousShaft fewer elements")
        self._lumped = self._build(exact=False)
        bad = np.flatnonzero(self._lumped.J <= 0)
        if bad.size:
            raise ValueError(f"disk {self._lumped.names[bad[0]]!r} has inertia 0: a disk needs "
                             "inertia > 0 unless a continuous shaft ends at it")

    # -- the trees ---------------------------------------------------------------------------
    def _build(self, exact: bool) -> Tree:
        parent, ratio, J, k, c, kg, cg, names, segs = [], [], [], [], [], [], [], [], []
        gsegs = []
        disk_node = {}  # (line index, disk) -> node
        for li, (line, pli, at, gear) in enumerate(self.lines):
            for i in range(line.J.size):
                if i == 0:
                    att = -1 if pli < 0 else disk_node[(pli, at)]
                    rat = np.nan if (pli < 0 or gear is None) else gear
                else:
                    att, rat = disk_node[(li, i - 1)], np.nan
                seg = line.cont[i]
                if seg is not None and not exact:
                    E = int(seg.elements)
                    ke = seg.G * seg.Jp * E / seg.length
                    ce = seg.damping * E
                    half = 0.5 * seg.rho * seg.Jp * seg.length / E
                    if att >= 0:  # half a segment at the attachment (through the gear)
                        gu = 1.0 if np.isnan(rat) else float(gen.gear_factors([rat])[0][0])
                        J[att] += gu * gu * half
                    for j in range(1, E):
                        parent.append(att)
                        ratio.append(rat if j == 1 else np.nan)
                        J.append(2 * half)
                        k.append(ke)
                        c.append(ce)
                        kg.append(0.0)
                        cg.append(0.0)
                        names.append(f"{line.name}.{i}.e{j}")
                        segs.append(None)
                        att, rat = len(names) - 1, np.nan
                    kcon, ccon, extra = ke, ce, half
                elif seg is not None:
                    kcon, ccon, extra = 0.0, 0.0, 0.0
                else:
                    kcon, ccon, extra = line.k[i], line.c[i], 0.0
                parent.append(att)
                ratio.append(rat)
                J.append(line.J[i] + extra)
                k.append(kcon)
                c.append(ccon)
                kg.append(line.kg[i])
                cg.append(line.cg[i])
                names.append(f"{line.name}.{i}")
                segs.append(seg if exact else None)
                gsegs.append(None)
                disk_node[(li, i)] = len(names) - 1
            end = line.right_segment
            if end is not None and exact:
                gsegs[-1] = end
            elif end is not None:  # lumped: a chain of points from the last disk, the last
                E = int(end.elements)  # one held by a segment's spring to the wall
                ke, ce = end.G * end.Jp * E / end.length, end.damping * E
                half = 0.5 * end.rho * end.Jp * end.length / E
                last = len(names) - 1
                J[last] += half
                for j in range(1, E):
                    parent.append(len(names) - 1)
                    ratio.append(np.nan)
                    J.append(2 * half)
                    k.append(ke)
                    c.append(ce)
                    kg.append(0.0)
                    cg.append(0.0)
                    names.append(f"{line.name}.right.e{j}")
                    segs.append(None)
                    gsegs.append(None)
                kg[-1] += ke
                cg[-1] += ce
        return Tree(np.array(parent, dtype=np.int64), np.array(ratio, float), np.array(J, float),
                    np.array(k, float), np.array(c, float), np.array(kg, float),
                    np.array(cg, float), tuple(names), tuple(segs), tuple(gsegs))

    @property
    def dof_names(self) -> tuple:
        """DOF names of the lumped model, in the order of `shaft_matrices` and the results."""
        return self._lumped.names

    def dof(self, name: str) -> int:
        """The index of a DOF by name ("main.3", "out.0"), e.g. for a nonlinear element's i, j."""
        if name not in self.dof_names:
            shown = ", ".join(self.dof_names[:8]) + (" ..." if len(self.dof_names) > 8 else "")
            raise ValueError(f"{name!r} is not a DOF of this shaft (the DOFs are {shown})")
        return self.dof_names.index(name)

    @property
    def tree(self) -> Tree:
        """The lumped tree the time loop runs on."""
        return self._lumped

    @property
    def n_dof(self) -> int:
        """The DOFs of the lumped model."""
        return len(self._lumped.names)

    @public
    def solver(self, dt, *, scheme="newmark", form=None, backend="c", outputs=None,
               quantities=("x", "v", "a"), unstable="raise", elements=None, substeps=None, tol=None,
               max_iter=None, **scheme_params) -> ShaftSolver:
        """Prepare the shaft for many load cases at the sample step ``dt``.

        Checks the options, the stability limit (the lumped model's highest mode) and each
        shaft's row of the sweep under the scheme, assembles the matrices of the initial
        acceleration, makes the sweep's gear factors and loads the C kernels of the scheme
        (and of its start-up scheme), once. Each ``run`` of the returned solver is then one
        load case, the results of `shaft_response` bitwise.

        Parameters
        ----------
        dt : float
            Sample step, s, > 0.
        scheme : str
            Any scheme of `chain_response`; its parameters (``beta``, ``gamma``, ``theta``,
            ``alpha``, ``rho_inf``) as keywords.
        form : {"displacement", "acceleration"} or None
            As `shaft_response` (None: the displacement form, or the acceleration form of an
            explicit scheme, its only one).
        backend : {"c", "numpy"}
            As `shaft_response`.
        outputs : sequence of int or DOF names, optional
            DOFs whose response is stored: indices into ``dof_names`` or the names
            ("main.3"); all by default.
        quantities : subset of ("x", "v", "a")
            What is stored; the others are None in the results.
        unstable : {"raise", "warn"}
            A conditionally stable scheme beyond its limit: refused here
            (DtdynUnstableError), or warned about.
        elements : sequence of elements, optional
            Localized nonlinear elements (`Cubic`, `Polynomial`, `Gap`, `Law`, `BoucWen`):
            the solver of `nonlinear_shaft_response` instead: the checks, the linear step, the
            elements' unit responses and the compiled loop prepared once, each ``run`` equal
            to the function bitwise.
        substeps, tol, max_iter : optional
            With ``elements`` only: as `nonlinear_shaft_response` (its defaults when None).
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
        >>> s = dd.Shaft([1.0, 2.0, 1.5], [1e4, 2e4, 2e4], [1.0, 1.0, 1.0])
        >>> solver = s.solver(1e-3, scheme="hht", alpha=-0.1, outputs=["main.2"])
        >>> r1, r2 = (solver.run(np.full(201, f), force_dofs=["main.2"]) for f in (1.0, 2.0))
        >>> r1.x.shape, bool(np.allclose(r2.x, 2 * r1.x))
        ((201, 1), True)
        """
        nonlinear = dict(substeps=substeps, tol=tol, max_iter=max_iter)
        if elements is not None:  # dtdyn.nonlinear's solver, by the registry (the layers)
            return nonlinear_solver(self, dt, elements, scheme=scheme, form=form,
                                    backend=backend, outputs=outputs, quantities=quantities,
                                    unstable=unstable, **nonlinear,
                                    **scheme_params)
        nonlinear_solver(self, dt, None, **nonlinear)  # none of them without elements
        return ShaftSolver(self, dt, scheme, form, backend, outputs, quantities, unstable,
                           scheme_params)

    @property
    def has_continuous(self) -> bool:
        return any(s is not None for line, *_ in self.lines
                   for s in (*line.cont, line.right_segment))

    def __repr__(self) -> str:
        return (f"Shaft({len(self.lines)} line(s), {len(self.dof_names)} DOFs, left={self.left!r}, "
                f"gears={sum(1 for *_, r in self.lines if r is not None)})")


def _check_shaft(shaft):
    if not isinstance(shaft, Shaft):
        raise TypeError(f"shaft must be a dtdyn.Shaft, got {type(shaft).__name__}")


def shaft_matrices(shaft: Shaft):
    """Assembled (M, C, K) of the lumped model, scipy.sparse CSR, rows in the order of
    ``shaft.dof_names``.

    A shaft k_t from node p (through a gear of factor g_u = -1/n, or g_u = 1) to node i stores
    1/2 k_t (phi_i - g_u phi_p)^2: K[i, i] += k_t, K[p, p] += g_u^2 k_t, K[i, p] = K[p, i] -=
    g_u k_t; C alike with c_t; ground springs and dampers on the diagonal; M = diag(J).
    Continuous shafts appear as their lumped segments.

    Parameters
    ----------
    shaft : Shaft

    Returns
    -------
    M, C, K : scipy.sparse.csr_matrix

    Examples
    --------
    >>> import dtdyn as dd
    >>> shaft = dd.Shaft([1.0, 1.0], [2.0, 3.0])
    >>> M, C, K = dd.shaft_matrices(shaft)
    >>> K.toarray().tolist(), shaft.dof_names
    ([[5.0, -3.0], [-3.0, 3.0]], ('main.0', 'main.1'))
    """
    _check_shaft(shaft)
    t = shaft.tree
    gu, gS, _ = gen.gear_factors(t.ratio)
    N = t.J.size
    i = np.arange(N)
    ch = t.parent >= 0
    p = t.parent[ch]

    def assemble(e, ground):
        rows = np.concatenate([i, p, i[ch], p])
        cols = np.concatenate([i, p, p, i[ch]])
        vals = np.concatenate([e + ground, gS[ch] * e[ch], -gu[ch] * e[ch], -gu[ch] * e[ch]])
        return sps.csr_matrix((vals, (rows, cols)), shape=(N, N))

    return sps.diags(t.J, format="csr"), assemble(t.c, t.cg), assemble(t.k, t.kg)


# -- time histories ------------------------------------------------------------------------------

def _c_function(scheme):
    """dtdyn_shaft_<scheme> (a name or a resolved scheme), or None when C is unavailable."""
    return kernels.c_scheme_function("shaft", scheme)


def _tree_operands(tree: Tree) -> tuple:
    """The load-independent arrays of the tree sweep: (parent, gu, gS, gR, kg, cg), the gear
    factors from the generated `gear_factors`, kg and cg None when no disk is grounded."""
    parent = np.ascontiguousarray(tree.parent, dtype=np.int64)
    gu, gS, gR = (np.ascontiguousarray(a) for a in gen.gear_factors(tree.ratio))
    grounded = tree.kg.any() or tree.cg.any()
    kg, cg = (tree.kg, tree.cg) if grounded else (None, None)
    return parent, gu, gS, gR, kg, cg


def _advance_factory(backend, tree, dt, loaded, outputs, form, operands=None):
    """``make_advance(scheme, coefficients)`` of stepping.integrate by the tree sweep (C or
    NumPy), force on ``loaded``, storing ``outputs``; ``operands``: `_tree_operands`, made
    once by a solver (None: made here). The advances of one call share its scratch."""
    parent, gu, gS, gR, kg, cg = operands or _tree_operands(tree)
    m, k, c = tree.J, tree.k, tree.c
    loaded64 = np.ascontiguousarray(loaded, dtype=np.int64)
    out64 = np.ascontiguousarray(outputs, dtype=np.int64)
    N = m.size
    work = np.empty(c_api.SHAFT_ROWS * N)  # rows from the one spec (dtdyn.derive.c_api)
    # the advance whose Riccati factors work holds: its next calls reuse them (SWEEP_REUSE:
    # the same numbers); another advance of this call computes its own
    owner = [None]

    def make_advance(sch, coeffs):
        fn = _c_function(sch) if backend == "c" else None
        if fn is None:
            def advance(force, H, xo, vo, ao):
                gen.run_tree(coeffs, sch.history, parent, gu, gS, gR, m, k, c, kg, cg, loaded,
                             force, H, outputs, xo, vo, ao)
                return 0.0
            return advance
        params = params_array(sch)

        def advance(force, H, xo, vo, ao):
            force = np.ascontiguousarray(force)
            assert H.flags.c_contiguous and H.dtype == np.float64
            p_ = lambda a: None if a is None else a.ctypes.data  # noqa: E731
            sweep = c_api.SWEEP_REUSE if owner[0] is advance else c_api.SWEEP_STABLE
            owner[0] = None  # work is being rewritten
            rc = fn(kernels.FORM_CODE[form], sweep, N, force.shape[0] - 1, parent.ctypes.data,
                    gu.ctypes.data, gS.ctypes.data, gR.ctypes.data, m.ctypes.data, k.ctypes.data,
                    c.ctypes.data, p_(kg), p_(cg), dt, params.ctypes.data, loaded64.size,
                    loaded64.ctypes.data, force.ctypes.data, H.ctypes.data, out64.size,
                    out64.ctypes.data, p_(xo), p_(vo), p_(ao), work.ctypes.data, work.size)
            if rc == c_api.ERR_FORM:
                raise ValueError(f"scheme {sch.name!r} has no {form} form")
            if rc != c_api.OK:
                raise kernels.DtdynKernelError(f"dtdyn_shaft_{sch.name}", rc,
                                               f"N = {N}, n_work = {work.size}")
            owner[0] = advance
            return 0.0
        return advance
    return make_advance


def rigid_rotation(shaft: Shaft) -> np.ndarray:
    """Each DOF's rotation when the supports turn by one radian and nothing deforms: 1 on the
    main line, times -1/n through each gear of ratio n (the default support-motion influence)."""
    tree = shaft.tree
    gu, _, _ = gen.gear_factors(tree.ratio)
    r = np.ones(tree.J.size)
    for i in range(tree.J.size):  # nodes are numbered parent first
        if tree.parent[i] >= 0:
            r[i] = gu[i] * r[tree.parent[i]]
    return r


def check_connections(tree: Tree, info, form: str, dt: float) -> None:
    """ValueError when a shaft's row of the sweep divides by k Dx + c Dv = 0 (an undamped
    shaft under an explicit scheme)."""
    kappa = np.min([np.abs(tree.k * K0["p"] + tree.c * K0["r"]) for K0 in
                    (s.coefficients(form, dt) for s in schemes_of_run(info))], axis=0)
    loose = np.flatnonzero((kappa == 0.0) & ((tree.k + tree.c) > 0))
    if loose.size:
        raise ValueError(f"shaft before {tree.names[loose[0]]!r} has damping 0 with the explicit "
                         f"scheme {info.name!r}: its row divides by k Dx + c Dv = 0; give every "
                         "shaft a damper or use an implicit scheme")


def shaft_response(shaft: Shaft, force, dt, *, force_dofs=None, scheme="newmark",
                   form=None, backend="c", outputs=None, quantities=("x", "v", "a"),
                   x0=None, v0=None, unstable="raise", progress=False, ground_acceleration=None,
                   ground_velocity=None, ground_displacement=None, influence=None,
                   **scheme_params):
    """Time history of a torsional shaft or tree by the DT-TMM (Riccati sweep on the tree).

    Parameters
    ----------
    shaft : Shaft
        The model (its lumped form: continuous shafts as segments).
    force : array_like, shape (n_steps + 1, len(force_dofs))
        Torque samples (N m) at t_k = k dt on the DOFs in ``force_dofs``; 1-D is one column.
    dt : float
        Time step, s.
    force_dofs : sequence of int or DOF names, optional
        0-based DOF indices or names (`Shaft.dof_names`); all DOFs when None.
    scheme, form, backend
        As `chain_response`: the integrator, "displacement" or "acceleration" form, "c"
        (generated C loop) or "numpy".
    outputs : sequence of int or DOF names, optional
        The DOFs stored, as ``force_dofs``; all DOFs when None.
    quantities, x0, v0, unstable, progress
        As `chain_response`: what to store, the initial rotations and rates (a_0 consistent),
        the stability check.
    ground_acceleration, ground_velocity, ground_displacement, influence : optional
        Support motion (angular, rad/s^2, rad/s, rad) as in `mck_response`: the rotations are
        then relative to the supports, which turn together; the default influence is
        `rigid_rotation` (1 on the main line, -1/n through each gear). ``force`` may be None.
    **scheme_params
        As `chain_response`: the integrator's parameters.

    Returns
    -------
    Response
        ``x``, ``v``, ``a``: rotation (rad), rate, angular acceleration of the outputs;
        ``dof_names`` their names.

    Each step carries T = S phi + R from the leaves to the root (S once per call, R every step;
    a junction sums its branches, a gear scales S by 1/n^2 and R by -1/n) and the unknowns back
    out to the leaves: O(N) per step. It equals `mck_response` on `shaft_matrices` (same scheme
    and dt) to rounding.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> s = dd.Shaft([1.0, 2.0, 1.5], [1e4, 2e4, 2e4], [1.0, 1.0, 1.0])
    >>> r = dd.shaft_response(s, np.ones(201), 1e-3, force_dofs=["main.2"])
    >>> r.x.shape
    (201, 3)
    """
    _check_shaft(shaft)
    solver = shaft.solver(dt, scheme=scheme, form=form, backend=backend, outputs=outputs,
                          quantities=quantities, unstable=unstable, **scheme_params)
    return solver.run(force, force_dofs=force_dofs, x0=x0, v0=v0, progress=progress,
                      ground_acceleration=ground_acceleration, ground_velocity=ground_velocity,
                      ground_displacement=ground_displacement, influence=influence)


class ShaftSolver(Solver):
    """The `Solver` of `Shaft`: the lumped tree checked against the scheme (an explicit scheme
    needs a damper on every shaft), its matrices assembled (for the stability limit and the
    initial acceleration), the sweep's gear factors made and the C kernels loaded, once; each
    run sweeps the tree (DT-TMM, T = S phi + R from the leaves to the root)."""

    def __init__(self, shaft, dt, scheme, form, backend, outputs, quantities, unstable,
                 scheme_params):
        M, C, K = shaft_matrices(shaft)
        super().__init__(shaft, dt, scheme, form, check_backend(backend), outputs, quantities,
                         unstable, lambda limit: highest_frequency(M, K, limit), scheme_params)
        tree = shaft.tree
        check_connections(tree, self._info, self.form, self.dt)
        self._C, self._K = C, K
        self._ground_mass = sps.diags(tree.J)
        self._rigid = lambda k: rigid_rotation(shaft)
        self._operands = _tree_operands(tree)
        self._dof_names = tuple(tree.names[i] for i in self.outputs)
        if backend == "c":  # compile or load the kernels now, not in the first run
            for sch in schemes_of_run(self._info):
                _c_function(sch)
        last = schemes_of_run(self._info)[-1]
        self._used = "c" if backend == "c" and _c_function(last) is not None else "numpy"

    def _initial_acceleration(self, case):
        f0 = case.f0 - self._C @ case.v0 - self._K @ case.x0
        return f0 / self.model.tree.J

    def _stepper(self, loaded):
        return _advance_factory(self.backend, self.model.tree, self.dt, loaded, self.outputs,
                                self.form, self._operands)

    def _annotate(self, res):
        res.info.update(method="DT-TMM (tree)", sweep="stable", backend=self._used)
        res.dof_names = self._dof_names
        res.dof_kinds = ("rotation",) * len(self._dof_names)  # rad, rad/s, rad/s^2


# -- frequencies ---------------------------------------------------------------------------------

def _connection_stiffness(tree: Tree, lam: np.ndarray):
    """a, b (N, len(lam)) of every node's connection and the continuous segments' J_0."""
    N = tree.J.size
    a = np.repeat(tree.k[:, None], lam.size, axis=1)
    b = -a.copy()
    j0 = np.zeros(lam.size, dtype=np.int64)
    omega = np.sqrt(np.maximum(lam, 0.0))
    for n in range(N):
        seg = tree.segments[n]
        if seg is None:
            continue
        beta = gen.continuous_beta(omega, seg.length, seg.G, seg.rho)
        a[n], b[n] = gen.continuous_stiffness(seg.G * seg.Jp / seg.length, beta)
        j0 += gen.clamped_clamped_count(beta).astype(np.int64)
    return a, b, j0


def _ground_stiffness(tree: Tree, lam: np.ndarray, j0: np.ndarray):
    """kg (N, len(lam)): the ground springs plus, where a continuous shaft runs to a wall, its
    a(omega) (the far end held); its clamped-clamped count added to j0 (in place)."""
    kg = np.repeat(tree.kg[:, None], lam.size, axis=1)
    omega = np.sqrt(np.maximum(lam, 0.0))
    for n, seg in enumerate(tree.ground_segments):
        if seg is None:
            continue
        beta = gen.continuous_beta(omega, seg.length, seg.G, seg.rho)
        kg[n] += gen.continuous_stiffness(seg.G * seg.Jp / seg.length, beta)[0]
        j0 += gen.clamped_clamped_count(beta).astype(np.int64)
    return kg


def _count(tree: Tree, gS, lam, pivmin):
    a, b, j0 = _connection_stiffness(tree, lam)
    kg = _ground_stiffness(tree, lam, j0)
    return gen.wittrick_williams(lam, tree.parent, gS, tree.J, kg, a, b, j0, pivmin)


def shaft_frequencies(shaft: Shaft, count=None, below=None, *,  # noqa: C901 (lumped and exact)
                      exact=True) -> np.ndarray:
    """Undamped natural frequencies (rad/s, ascending) by the Wittrick-Williams count.

    The count of frequencies below omega is the number of negative pivots of the tree's
    elimination from the leaves (the frequency-domain Riccati recursion, generated from
    dtdyn.derive.shaft) plus, with continuous shafts, J_0: the clamped-clamped frequencies of
    each continuous segment below omega. Each root is bisected on the count to the last bits:
    none missed, none doubled.

    Parameters
    ----------
    shaft : Shaft
        The torsional system.
    count : int, optional
        The lowest ``count`` frequencies (default: all of a lumped model; required or ``below``
        with continuous shafts, which have infinitely many).
    below : float, optional
        Every frequency below this (rad/s).
    exact : bool
        Continuous shafts by their exact field matrix (True) or as their lumped segments
        (False: the frequencies of `shaft_matrices`).

    Examples
    --------
    >>> import dtdyn as dd
    >>> seg = dd.ContinuousShaft(length=2.0, G=8e10, Jp=1e-6, rho=7800.0)
    >>> w = dd.shaft_frequencies(dd.Shaft([0.0], [seg]), count=2)     # clamped-free
    >>> (w / (3.141592653589793 * seg.wave_speed / (2 * 2.0))).round(9).tolist()
    [1.0, 3.0]
    """
    _check_shaft(shaft)
    tree = shaft._build(exact=True) if exact and shaft.has_continuous else shaft.tree
    infinite = exact and shaft.has_continuous
    if count is not None and (isinstance(count, bool) or not isinstance(count, (int, np.integer))
                              or count < 1):
        raise ValueError(f"count = {count!r}: must be an integer >= 1")
    if below is not None and not (np.isfinite(below) and below > 0):
        raise ValueError(f"below = {below!r}: must be a finite frequency > 0 (rad/s)")
    if count is not None and below is not None:
        raise ValueError("give count or below, not both")
    if infinite and count is None and below is None:
        raise ValueError("count or below is required: a continuous shaft has infinitely many "
                         "frequencies")
    _, gS, _ = gen.gear_factors(tree.ratio)
    scale = max(float(np.max(np.abs(tree.k))), float(np.max(tree.kg)), 1.0)
    for seg in (*tree.segments, *tree.ground_segments):
        if seg is not None:
            scale = max(scale, seg.G * seg.Jp / seg.length)
    pivmin = np.finfo(float).tiny / np.finfo(float).eps * scale

    def cnt(lam):
        return _count(tree, gS, np.atleast_1d(np.asarray(lam, float)), pivmin)

    # the bracket [0, hi]: hi a power of two above an upper bound (Gershgorin of M^-1 K for
    # the lumped part; doubled until it holds), the same whatever count or below, so each
    # root's bisection path and bits do not depend on them
    Jpos = np.where(tree.J > 0, tree.J, np.inf)
    bound = float(np.max(2.0 * (np.abs(tree.k) + tree.kg) / Jpos))
    if not infinite:
        M, _, K = shaft_matrices(shaft)
        bound = float(np.max(np.asarray(abs(K).sum(axis=1)).ravel() / tree.J))
    for seg in (*tree.segments, *tree.ground_segments):
        if seg is not None:
            bound = max(bound, (math.pi * seg.wave_speed / seg.length) ** 2)
    hi = 2.0 ** math.ceil(math.log2(max(bound, 1e-300) * 1.01))
    if below is not None:
        n_roots = int(cnt(float(below) ** 2)[0])
    else:
        n_total = None if infinite else tree.J.size
        if count is not None and n_total is not None and count > n_total:
            raise ValueError(f"count = {count!r}: the shaft has {n_total} DOFs")
        n_roots = n_total if count is None else count
    for _ in range(2000):
        if n_roots == 0 or cnt(hi)[0] >= n_roots:
            break
        hi *= 2.0
    else:
        raise RuntimeError("no upper bound for the frequencies found")
    if n_roots == 0:
        return np.zeros(0)
    idx = np.arange(1, n_roots + 1)
    lo = np.zeros(n_roots)
    up = np.full(n_roots, hi)
    for _ in range(2100):
        mid = 0.5 * (lo + up)
        done = (up - lo) <= 2.0 * np.finfo(float).eps * up + np.finfo(float).tiny
        if done.all():
            break
        c_mid = cnt(mid)
        above = c_mid >= idx
        up = np.where(above & ~done, mid, up)
        lo = np.where(~above & ~done, mid, lo)
    return np.sqrt(0.5 * (lo + up))
