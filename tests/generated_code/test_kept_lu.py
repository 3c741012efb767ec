"""The chain, beam and shaft loops' Newton with its LU factors kept (newton_kept in newton.h,
DTDYN_NEWTON_KEPT_LU from dtdyn.nonlinear._chain.LU_KEPT_MIN unknowns on) against plain Newton
(newton_solve, an LU at every iteration), the same generated loops.

Truth: both accept every step by the rule of docs/newton.md, so both approach the same discrete
solution as tol falls. Plain Newton converges quadratically: the Newton step its step test does
not take leaves an error far below tol s_u (its records move by 7e-15 to 2e-12 of their peak from
tol = 1e-12 to 1e-15, measured). The kept factors converge linearly: an iterate is accepted when
the step |d| <= tol s_u after an iteration that contracted by KEPT_CONTRACT = 0.25, so that its
error is below |d| / (1 - 0.25), up to 1.33 tol s_u per step; the dynamics carry those errors
along the record (the hysteresis of Bouc-Wen accumulates them). The difference of the two runs
is that error, proportional to tol. Measured, as the largest of x, v, a and g over its peak, at
tol = 1e-10 and 1e-12: 784 and 484 tol (30-mass chain, 12 Bouc-Wen elements, 2,000 steps), 332
and 307 tol (the same chain, 30 cubic springs), 47 and 144 tol (beam, 20 cubic springs: its
accelerations; x, v and g <= 4 tol), 100 and 63 tol (shaft, 26 cubic couplings). Held to
BOUND = 2000 tol, and the largest of x, v and g to a fall by at least 30 when tol falls by 100
(measured 92 to 162).
"""
import numpy as np
import pytest

import dtdyn as dd
from dtdyn.generated import c_api
from dtdyn.nonlinear import _chain as NC
from dtdyn.nonlinear import _response as NL

BOUND = 2000.0  # the kept factors' error over a record, in units of tol (module docstring)


def _chain(kind):
    N = 30
    m, k, c = np.ones(N), np.full(N, 1e4), np.full(N, 2.0)
    f = 30.0 * np.random.default_rng(0).standard_normal(2001)
    if kind == "boucwen":  # 12 elements, 36 unknowns (y, y', z)
        els = [dd.BoucWen(i, i - 1 if i else None, stiffness=5e3, alpha=0.1, beta=50.0,
                          gamma=50.0) for i in range(12)]
    else:  # 30 springs, 30 unknowns (y)
        els = [dd.Cubic(i, i - 1 if i else None, k3=1e10) for i in range(N)]
    return m, k, c, f, els


def _differences(a, b):
    """max |a - b| / max |b| of x, v, a, g"""
    return {q: np.abs(getattr(a, q) - getattr(b, q)).max() / np.abs(getattr(b, q)).max()
            for q in "xvag"}


@pytest.mark.parametrize("kind, factorizations", [("boucwen", 1), ("cubic", 2000)])
def test_chain_kept_lu_converges_to_plain_newton(kind, factorizations, monkeypatch):
    """Kept against plain Newton on the chain loop (module docstring): within BOUND tol of the
    peak at tol = 1e-10 and 1e-12, falling with tol. Bouc-Wen's Jacobian hardly moves: one LU
    for the whole record (measured 1); the cubic springs' follows the state: 922 LU for 2,000
    steps at 1e-12 (measured), held to one a step."""
    m, k, c, f, els = _chain(kind)
    worst = []
    for tol in (1e-10, 1e-12):
        runs = {}
        for least in (None, 24):
            monkeypatch.setattr(NC, "LU_KEPT_MIN", least)
            runs[least] = NC.nonlinear_chain_response(m, k, c, f, 1e-3, force_dofs=[29],
                                                      elements=els, tol=tol,
                                                      quantities=("x", "v", "a", "g"))
        kept, plain = runs[24], runs[None]
        assert (kept.info["loop"], plain.info["loop"]) == ("c", "c")
        assert "factorizations" not in plain.info["newton_iterations"]
        assert 1 <= kept.info["newton_iterations"]["factorizations"] <= factorizations
        diff = _differences(kept, plain)
        assert max(diff.values()) <= BOUND * tol, (tol, diff)
        worst.append(max(diff[q] for q in "xvg"))
    assert worst[1] <= worst[0] / 30, worst


def test_below_the_threshold_the_loops_take_plain_newton_steps(monkeypatch):
    """Below LU_KEPT_MIN unknowns the C loop solves with the Jacobian at every iterate (the
    Python loop's steps, no factorization count); from it on, it keeps the factors."""
    m, k, c, f, els = _chain("cubic")
    codes = []
    monkeypatch.setattr(NC, "newton_code", lambda sz, code=NC.newton_code: codes.append(
        code(sz)) or codes[-1])
    for n_el in (NC.LU_KEPT_MIN - 1, NC.LU_KEPT_MIN):
        r = NC.nonlinear_chain_response(m, k, c, f[:201], 1e-3, force_dofs=[29],
                                        elements=els[:n_el])
        assert ("factorizations" in r.info["newton_iterations"]) == (n_el >= NC.LU_KEPT_MIN)
    assert codes == [c_api.NEWTON_PLAIN, c_api.NEWTON_KEPT_LU]


def test_kept_lu_names_the_step_where_newton_fails(monkeypatch):
    """A Newton failure on the kept path (not converged in max_iter iterations) is a
    NewtonError naming the step, as on the plain path; not the same step (the iterates differ:
    plain Newton fails at step 9 here, the kept factors, formed at larger deformations of the
    hardening springs, damp the steps and carry it to step 11; measured)."""
    m, k, c, f, _ = _chain("cubic")
    els = [dd.Cubic(i, i - 1 if i else None, k3=1e14) for i in range(24)]
    messages = []
    for least in (None, 24):
        monkeypatch.setattr(NC, "LU_KEPT_MIN", least)
        with pytest.raises(NL.NewtonError) as info:
            NC.nonlinear_chain_response(m, k, c, 1e9 * f, 1e-3, force_dofs=[29], elements=els,
                                        max_iter=3)
        messages.append(str(info.value))
    assert all(msg.startswith("Newton did not converge at step ") for msg in messages), messages


def _beam():
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=20, rayleigh=(0.0, 2e-6))
    els = [dd.Cubic(beam.dof(f"w{i}"), k3=1e12) for i in range(1, 21)]  # 20 unknowns
    f = (2e3 * np.sin(2 * np.pi * 15 * np.arange(1001) * 1e-4))[:, None]
    return lambda tol: dd.nonlinear_beam_response(beam, f, 1e-4, force_dofs=[beam.dof("w20")],
                                                  elements=els, tol=tol,
                                                  quantities=("x", "v", "a", "g"))


def _shaft():
    shaft = dd.Shaft(np.ones(30), np.full(30, 1e4), np.full(30, 2.0))
    els = [dd.Cubic(i, i + 1, k3=1e10) for i in range(26)]  # 26 unknowns
    f = 30.0 * np.random.default_rng(1).standard_normal(2001)
    return lambda tol: dd.nonlinear_shaft_response(shaft, f, 1e-3, force_dofs=[29],
                                                   elements=els, tol=tol,
                                                   quantities=("x", "v", "a", "g"))


@pytest.mark.parametrize("model", [_beam, _shaft], ids=["beam", "shaft"])
def test_stations_kept_lu_converges_to_plain_newton(model, monkeypatch):
    """The beam and shaft loop (nl_stations.h) with the kept factors (from 1 unknown on here):
    as the chain's."""
    run = model()
    worst = []
    for tol in (1e-10, 1e-12):
        runs = {}
        for least in (None, 1):
            monkeypatch.setattr(NC, "LU_KEPT_MIN", least)
            runs[least] = run(tol)
        assert runs[1].info["loop"] == "c"
        assert runs[1].info["newton_iterations"]["factorizations"] >= 1
        diff = _differences(runs[1], runs[None])
        assert max(diff.values()) <= BOUND * tol, (tol, diff)
        worst.append(max(diff[q] for q in "xvg"))
    assert worst[1] <= worst[0] / 30, worst


def test_kept_lu_work_is_counted_and_checked(monkeypatch):
    """With the kept factors the loop's work holds nu^2 + nu doubles more (the factors and the
    step d: dtdyn_nl_chain_work from dims' Newton code); one double short is refused before
    anything is written."""
    from dtdyn._engine.kernels import DtdynKernelError
    from dtdyn.nonlinear._response import _sizes

    m, k, c, f, els = _chain("cubic")
    els = tuple(els[:24])
    sz = _sizes(els)
    driver = NC._c_driver(els, sz)
    if driver is None:
        pytest.skip("no C compiler on this machine")
    run, n_w, n_iw, lib = driver
    dims = np.zeros(16, dtype=np.int64)
    dims[[0, 2, 4, 5, 6]] = [30, 24, sz.ne, sz.nw, sz.nz]
    sizes = []
    for code in (c_api.NEWTON_PLAIN, c_api.NEWTON_KEPT_LU):
        dims[15] = code
        sizes.append(lib.dtdyn_nl_chain_work(dims.ctypes.data))
    nu = sz.nw + sz.nz
    assert sizes[1] - sizes[0] == nu * nu + nu

    class Short:  # the library, its work size one double short
        def __getattr__(self, name):
            return getattr(lib, name)

        def dtdyn_nl_chain_work(self, p):
            return lib.dtdyn_nl_chain_work(p) - 1
    monkeypatch.setattr(NC, "_c_driver", lambda *args: (run, n_w, n_iw, Short()))
    with pytest.raises(DtdynKernelError, match="work array is too short"):
        NC.nonlinear_chain_response(m, k, c, f[:11], 1e-3, force_dofs=[29], elements=els)
