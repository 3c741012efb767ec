"""The beam's block-tridiagonal C kernel (generated/block_chain.c, beam_response backend="c").

Truths: mck_response on the assembled matrices of beam_matrices (the same scheme and dt: the same
linear system each step, so equal to rounding), and the previous solver path, the generic C loop
mck_loop.c with its 2 x 2 block Riccati solve (solver 2) on the node system. Ends with one DOF
(pinned, sliding), point masses, supports with dampers, Rayleigh damping, several blocks of
nodes with an odd remainder, every unconditionally stable scheme in both forms.
"""
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.generated import scheme_newmark
from dtdyn.generated.scheme_table import TABLE  # the built-in schemes, in order
from dtdyn.linear import _beam as beam_mod
from dtdyn.linear import _mck as mck


def _kernel_loads() -> bool:
    """Whether block_chain.c compiles and loads here (no compiler or DTDYN_NO_C: no)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dd.DtdynFallbackWarning)
        return beam_mod._block_library() is not None


pytestmark = pytest.mark.skipif(not _kernel_loads(), reason="no C compiler")

E, I, RHO_A = 2.1e11, 8.0e-6, 20.0  # noqa: E741
#: the unconditionally stable schemes (a beam's highest mode is far beyond the others' limits)
STABLE = [s for s in TABLE if s not in ("central_difference", "linear_acceleration",
                                        "fox_goodwin", "newmark_1_8")]


def _beam(elements=40, **kw):
    args = dict(E=E, I=I, rho_A=RHO_A, length=3.0, elements=elements, left="pinned",
                right="sliding", rayleigh=(0.5, 1e-5),
                point_masses=[dd.PointMass(elements // 3, 4.0, 0.3)],
                supports=[dd.Support(elements // 2, k_w=3e5, k_psi=2e3, c_w=40.0, c_psi=1.0)])
    return dd.Beam(**(args | kw))


class _PreviousPath(beam_mod.BeamSolver):
    """The beam's solver on its NumPy path (the node system, a_0 by the assembled M) with each
    step by mck_loop.c's 2 x 2 block Riccati solve (solver 2): the kernel beam_response used
    before."""

    def _stepper(self, loaded):
        Mg, Cg, Kg = beam_mod.node_system(self.model)
        free = self.model.free

        def advance_for(sch, coeffs):
            return mck.make_advance(self.form, sch, coeffs, Mg, Cg, Kg, free[loaded],
                                    self._stored, mck._c_loop(), blocks=True)
        return advance_for


def _previous_path(beam, force, dt, force_dofs, form, scheme):
    """The time history of every DOF by mck_loop.c's block solve (`_PreviousPath`)."""
    solver = _PreviousPath(beam, dt, scheme, form, "numpy", None, ("x", "v", "a"), "raise", {})
    return solver.run(force, force_dofs=force_dofs)


def _rel(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


def test_node_blocks_equal_the_sparse_assembly_bit_for_bit():
    """The blocks built from the element matrices are the node system's sparse entries, held
    DOFs decoupled (a unit mass and stiffness), for every kind of end and nodal item."""
    cases = [dict(), dict(left="clamped", right="free", mass_matrix="lumped"),
             dict(left=(1e6, 1e4), right="pinned", rayleigh=None),
             dict(left="sliding", right="clamped", elements=1, point_masses=(), supports=())]
    for kw in cases:
        beam = _beam(12, **kw) if "elements" not in kw else _beam(**kw)
        Mg, Cg, Kg = beam_mod.node_system(beam)
        for built, A in zip(beam_mod.node_blocks(beam), (Kg, Cg, Mg)):
            np.testing.assert_array_equal(built, beam_mod.block_storage(A))


def test_block_storage_refuses_other_matrices():
    with pytest.raises(ValueError, match="not symmetric"):
        beam_mod.block_storage(np.triu(np.ones((4, 4))))
    with pytest.raises(ValueError, match="not block tridiagonal"):
        beam_mod.block_storage(np.ones((6, 6)))


@pytest.mark.parametrize("scheme", STABLE)
@pytest.mark.parametrize("form", ["displacement", "acceleration"])
def test_kernel_equals_assembled_newmark_and_the_previous_path(scheme, form):
    """x, v, a of every DOF against mck_response to 1e-9 (measured <= 3.3e-11) and against the
    mck_loop.c block solve to the same (the two differ from each other by the same rounding
    as either from mck_response)."""
    beam = _beam()
    dt, n = 2e-5, 600
    F = np.ones(n + 1)
    mid = f"w{beam.elements // 2}"
    r = dd.beam_response(beam, F, dt, force_dofs=[mid], form=form, scheme=scheme)
    assert r.info["backend"] == "c" and r.info["method"].startswith("DT-TMM")
    M, C, K = dd.beam_matrices(beam)
    ref = dd.mck_response(M, C, K, F, dt, force_dofs=[beam.dof(mid)], scheme=scheme)
    old = _previous_path(beam, F, dt, [mid], form, scheme)
    for q in "xva":
        assert _rel(getattr(r, q), getattr(ref, q)) < 1e-9, (q, "mck_response")
        assert _rel(getattr(r, q), getattr(old, q)) < 1e-9, (q, "mck_loop.c")


@pytest.mark.parametrize("elements", [514, 257])
@pytest.mark.parametrize("form", ["displacement", "acceleration"])
def test_several_blocks_of_nodes(elements, form):
    """515 nodes (blocks of 256, 256 and 3) and 258 nodes (256 and 2): the recurrences cross the
    blocks and end on an odd or even remainder. Every DOF loaded (force_dofs default): forces on
    the w, moments on the psi. x to 1e-9 of mck_response (measured <= 3.0e-10); v and a, which
    keep the rounding of the undamped highest modes, to n_steps eps cond(A) as in test_beam.py
    (6e-8 here; measured <= 3.4e-9, scipy's own LU differs from SuperLU's by 1.3e-9)."""
    beam = _beam(elements, left="clamped", right="free", length=0.03 * elements)
    dt, steps = 1e-4, 300
    t = dt * np.arange(steps + 1)
    on_w = np.array([name.startswith("w") for name in beam.dof_names])
    F = np.outer(1.0 + np.sin(200.0 * t), np.where(on_w, 10.0, 0.01))
    r = dd.beam_response(beam, F, dt, form=form)
    M, C, K = dd.beam_matrices(beam)
    ref = dd.mck_response(M, C, K, F, dt)
    omega_max = dd.beam_frequencies(beam)[-1]
    bound = steps * np.finfo(float).eps * (1 + (omega_max * dt) ** 2 / 4)
    for q, tol in (("x", 1e-9), ("v", bound), ("a", bound)):
        assert _rel(getattr(r, q), getattr(ref, q)) < tol, q


def test_loads_in_any_order_initial_state_and_outputs():
    """force_dofs given out of order (the kernel sorts them), a moment and a force, x0 and v0
    (a_0 by the block solve with the C v0 and K x0 products), outputs on w and psi."""
    beam = _beam(30, left="clamped", right="pinned")
    n = beam.n_dof
    dt, steps = 1e-4, 300
    t = dt * np.arange(steps + 1)
    F = np.column_stack([np.sin(40 * t), 50 * np.cos(25 * t), np.ones_like(t)])
    dofs = ["psi30", "w5", "w17"]
    rng = np.random.default_rng(3)
    x0, v0 = 1e-4 * rng.standard_normal(n), 1e-2 * rng.standard_normal(n)
    out = ["psi30", "w10", "psi1"]
    kw = dict(x0=x0, v0=v0, scheme="hht", outputs=[beam.dof(d) for d in out])
    r = dd.beam_response(beam, F, dt, force_dofs=dofs, **kw)
    M, C, K = dd.beam_matrices(beam)
    ref = dd.mck_response(M, C, K, F, dt, force_dofs=[beam.dof(d) for d in dofs], **kw)
    assert r.dof_names == tuple(out)
    for q in "xva":
        assert _rel(getattr(r, q), getattr(ref, q)) < 1e-9, q


def test_history_rows_of_any_number():
    """The kernel's loop for history lengths other than 3, 5, 7 (terms_any) and its lag shift:
    the Newmark history with an unused lagged row (zero coefficients) steps as the plain one."""
    beam = _beam(20)
    stored = beam_mod.node_blocks(beam)
    lib = beam_mod._block_library()
    # Newmark at its defaults, from its generated module: of a scheme the kernel reads the
    # history names, and the coefficients of the form
    K_ = scheme_newmark.coefficients("displacement", 1e-4, *(scheme_newmark.DEFAULTS[p]
                                                            for p in scheme_newmark.PARAMS))
    nodes = beam.elements + 1
    loaded = outputs = np.array([2 * 10])

    class Plain:  # Newmark's history
        history = scheme_newmark.HISTORY

    class Padded:  # the same scheme with a fourth history row, v one step back
        history = Plain.history + ("vm1",)

    steps = 50
    F = np.ones((steps + 1, 1))
    runs = []
    for s in (Plain, Padded):
        adv = beam_mod._block_advance(lib, "displacement", s, K_, stored, nodes, loaded,
                                      outputs)
        H = np.zeros((len(s.history), 2 * nodes))
        xo = np.zeros((steps + 1, 1))
        adv(F[:steps], H, xo, None, None)
        v_before = H[1].copy()
        adv(F[steps - 1:], H, xo[steps - 1:], None, None)
        runs.append((xo, H, v_before))
    np.testing.assert_allclose(runs[1][0], runs[0][0], rtol=1e-13, atol=0)
    (_, H, v_before) = runs[1]
    assert np.abs(v_before).max() > 0
    np.testing.assert_array_equal(H[3], v_before)  # the lag holds v of the step before


SCRIPT = r"""
import warnings
import numpy as np
import dtdyn as dd
beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=30, right="pinned")
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    r = dd.beam_response(beam, np.ones(201), 1e-4, force_dofs=["w15"], outputs=["w15"])
    r = dd.beam_response(beam, np.ones(201), 1e-4, force_dofs=["w15"], outputs=["w15"])
ours = [w for w in caught if "C backend unavailable" in str(w.message)]
print(r.info["backend"], len(ours), repr(float(r.x[-1, 0])))
"""


def test_without_a_compiler_numpy_runs_with_one_warning():
    runs = []
    for extra in ({}, {"DTDYN_NO_C": "1"}):
        proc = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                              env=dict(os.environ, **extra), timeout=300)
        assert proc.returncode == 0, proc.stderr
        runs.append(proc.stdout.split())
    (b_c, w_c, x_c), (b_np, w_np, x_np) = runs
    assert (b_c, w_c, b_np, w_np) == ("c", "0", "numpy", "1")
    assert abs(float(x_np) - float(x_c)) <= 1e-9 * abs(float(x_c))


@pytest.mark.parametrize("left, right", [("pinned", "pinned"), ("clamped", "free")])
def test_micro_beam_units_do_not_make_a_pivot_singular(left, right):
    """A silicon micro-beam (100 um long, 10 x 2 um section, dt = 1 ns): stiffnesses of order
    1e-2 N/m and 1e-12 N m/rad next to held DOFs' unit entries. The kernel's singular-pivot test
    is relative to each pivot block's own diagonal, so the run is not refused, and it equals
    mck_response on the assembled matrices (1e-9, as the other beam tests)."""
    E, rho, b, h, L = 169e9, 2329.0, 10e-6, 2e-6, 100e-6
    beam = dd.Beam(E=E, I=b * h**3 / 12, rho_A=rho * b * h, length=L, elements=100, left=left,
                   right=right)
    M, C, K = dd.beam_matrices(beam)
    f = np.full(201, 1e-9)
    r = dd.beam_response(beam, f, 1e-9, force_dofs=["w50"])
    ref = dd.mck_response(M, C, K, f, 1e-9, force_dofs=[beam.dof("w50")])
    assert r.info["backend"] == "c"
    assert np.abs(r.x - ref.x).max() <= 1e-9 * np.abs(ref.x).max()
