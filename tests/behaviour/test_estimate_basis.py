"""The modal loop's embedded estimate with outputs of one kind: the C loop carries the recursion
in a basis where such outputs read one row of each 2 x 2 block (nl_loop.h, estimate_basis), so
its number must still equal the recursion as defined, evaluated here step by step on the full
modal block of the runtime's step, in the modes' own coordinates (the oracle of
test_nonlinear.py's test_quintic_embedded_estimate_is_its_recursion, for each set of stored
quantities). The solution itself does not depend on the outputs or on the estimate."""
import numpy as np
import pytest

from dtdyn import problem
from dtdyn.nonlinear import _response as NL

N_SAMPLES = 3000  # 23 full blocks of 128 steps and a partial one


@pytest.fixture(scope="module")
def P4():
    return problem("P4", n_samples=N_SAMPLES)


def _run(P4, scheme, **kw):
    return NL.nonlinear_mck_response(P4["M"], P4["C"], P4["K"], P4["force"], P4["dt"],
                                     force_dofs=P4["force_dofs"], elements=P4["elements"],
                                     scheme=scheme, **kw)


def _recursion(P4, scheme, full):
    """max over the samples of |Co e + Dog dg| per output row of the step (x, v, a of the 4
    DOFs), the recursion e_k = T e_{k-1} + Bs dg_{k-1} + Eg nabla^{NST-1} g_k with
    dg_k = K_k Cw e_k, K_k from the cubic springs' tangent 3 k3 y^2 at the stored response."""
    els = P4["elements"]
    L = NL.element_matrix(els, 4)
    step = NL.linear_step(scheme, P4["M"], P4["C"], P4["K"], P4["dt"],
                          np.array(P4["force_dofs"]), L, np.arange(4))
    md, ne = step.modal, L.shape[0]
    nm, nh = md["nm"], md["nh"]
    Am = step.A[:nm, :nm]
    Bs = step.Bg[:nm] + sum(step.A[:nm, nm + i:nm + i + ne] for i in range(0, nh, ne))
    Cw, Co, Dog, Dwg = step.Cw[:, :nm], step.Co[:, :nm], step.Dog, step.Dwg
    k3 = np.array([el.k3 for el in els])
    nst = md["stencil"].size
    past = np.vstack([np.repeat(full.g[:1], nst - 1, axis=0), full.g])  # at rest before t_0
    e, dg, worst = np.zeros(nm), np.zeros(ne), np.zeros(Co.shape[0])
    for k in range(full.g.shape[0]):
        dn = sum(c * past[k + nst - 1 - i] for i, c in enumerate(md["stencil"]))
        e = Am @ e + Bs @ dg + md["Eg"] @ dn
        kt = 3.0 * k3 * (L @ full.x[k]) ** 2  # dg/dy
        J = np.eye(ne) - Dwg * kt               # dr/du of r = w - Q - Dwg g(w) (explicit: I)
        dg = kt * np.linalg.solve(J, Cw @ e)
        worst = np.maximum(worst, np.abs(Co @ e + Dog @ dg))
    return worst


@pytest.mark.parametrize("scheme", ["modal_explicit", "modal_quintic"])
def test_estimate_with_outputs_of_one_kind_is_its_recursion(P4, scheme):
    """x alone (modal_explicit's x reads one combination of each block and no g_k: the
    estimate's own basis), v alone, a alone and x with v (the modes' coordinates): the number
    reported equals the recursion's, max over the stored quantities of the largest |error|
    relative to the largest |value|: within 3.2e-12 measured, in either basis (the oracle's
    x holds the springs' deformations to rounding), 1e-9 asserted as for the full outputs."""
    full = _run(P4, scheme, quantities=("x", "v", "a", "g"))
    worst = _recursion(P4, scheme, full)
    rows = {"x": slice(0, 4), "v": slice(4, 8), "a": slice(8, 12)}
    for quantities in (("x",), ("v",), ("a",), ("x", "v")):
        r = _run(P4, scheme, quantities=quantities)
        for q in quantities:
            assert np.array_equal(getattr(r, q), getattr(full, q)), (quantities, q)
        want = max(worst[rows[q]].max() / np.abs(getattr(full, q)).max() for q in quantities)
        assert r.info["error_estimate_kind"] == "embedded"
        assert r.info["error_estimate"] == pytest.approx(want, rel=1e-9), quantities


def test_estimate_does_not_change_the_solution(P4):
    """modal_explicit with outputs x only, with and without its estimate: the same x, bitwise
    (the estimate only reads the solution)."""
    a = _run(P4, "modal_explicit", quantities=("x",))
    b = _run(P4, "modal_explicit", quantities=("x",), estimate=False)
    assert np.array_equal(a.x, b.x)
    assert "error_estimate" in a.info and "error_estimate" not in b.info


@pytest.mark.parametrize("accuracy, own", [(1e-3, False), (1e-6, True)])
def test_window_confirming_run_without_its_estimate(accuracy, own):
    """The window (the record's first 2,000 samples) runs 1 and then 2 sub-steps. At 1e-3 the
    first run's estimate already meets the goal, so the second only confirms it and forms no
    estimate of its own (None in the log); at 1e-6 the second run's own estimate decides. The
    record then runs once, as before: 1 and 2 sub-steps, its estimate trusted."""
    P = problem("P4", n_samples=20_000)
    r = NL.nonlinear_mck_response(P["M"], P["C"], P["K"], P["force"], P["dt"],
                                  force_dofs=P["force_dofs"], elements=P["elements"],
                                  accuracy=accuracy, quantities=("x",))
    log = r.info["accuracy_log"]
    assert [e["substeps"] for e in log] == [1, 2, 1 if accuracy == 1e-3 else 2]
    assert r.info["estimate_window"] == {"samples": 2000, "substeps": [1, 2]}
    assert (log[1]["estimate"] is not None) == own
    assert ("its own estimate not formed" in log[1]["note"]) == (not own)
    assert r.info["accuracy_met"] and r.info["error_estimate"] <= accuracy
