"""Nonlinear forced response (runtime/nonlinear.py) against independent truths.

Truths: exact_response (matrix exponential) and mck_response for the linear limit; the
solve_ivp reference (DOP853, rtol 1e-12, restarted at every sample) for nonlinear runs; the hand
formulas of reference.md section 6 for the condensed per-step problem.
"""
import numpy as np
import pytest
import sympy as sp

from dtdyn.derive import nonlinear as DN
from dtdyn import chain_matrices, exact_response
from dtdyn import load_result, mck_response
from dtdyn.nonlinear import _response as NL
from dtdyn.nonlinear._elements import BoucWen, Cubic, Gap, Law, Polynomial
from dtdyn.nonlinear._reference import reference_response
from problems import p4

N_SHORT = 3000


@pytest.fixture(scope="module")
def P4():
    return p4(N_SHORT)


@pytest.fixture(scope="module")
def P4_ref(P4):
    return reference_response(P4["M"], P4["C"], P4["K"], P4["force"], P4["dt"],
                              force_dofs=P4["force_dofs"], elements=P4["elements"], cache=False)


def _run(P, **kw):
    kw.setdefault("elements", P["elements"])
    return NL.nonlinear_mck_response(P["M"], P["C"], P["K"], P["force"], P["dt"],
                                 force_dofs=P["force_dofs"], **kw)


def _err(r, ref, dof=3):
    """max over time of |x - x_ref| at the last DOF, relative to its largest value."""
    return np.abs(r.x[:, dof] - ref.x[:, dof]).max() / np.abs(ref.x[:, dof]).max()


# --- tier 1: the derived per-step problem equals the hand formulas ------------------------------

def test_modal_B0_is_the_ramp_coefficient_N0():
    """reference.md section 6: B0 = R (e^{sT} - 1 - sT) / (s^2 T) with R = (L phi)(L psi)."""
    s, T = DN.s, DN.T
    hand = DN.phi_L * DN.psi_L * (sp.exp(s * T) - 1 - s * T) / (s**2 * T)
    assert sp.simplify(DN.modal_step()["B0"] - hand) == 0


@pytest.mark.parametrize("name, hand", [("newmark", "beta*dt**2"),
                                        ("average_acceleration", "dt**2/4"),
                                        ("fox_euler", "dt**2/2"),
                                        ("central_difference", "0")])
def test_scheme_B0_coefficient(name, hand):
    """Newmark: x_{n+1} = x~ + beta dt^2 a_{n+1} and w1 = 1, so B0 = beta dt^2 L K_eff^-1 L^T."""
    got = DN.scheme_coefficient(name)
    assert sp.simplify(got - sp.sympify(hand, locals={str(x): x for x in got.free_symbols})) == 0


def test_parabola_coefficient_series_and_closed_form():
    from dtdyn.generated.nl_modal import parabola_coefficient
    from scipy.integrate import quad
    T = 1e-2
    for s in (-3.0 + 80.0j, -0.5 + 20.0j, -40.0 + 300.0j, -2.0 + 0.0j):
        def part(u, f, s=s):
            return f(np.exp(s * (T - u)) * u * (u - T) / (2 * T**2))
        want = quad(part, 0, T, args=(np.real,), epsabs=0, epsrel=1e-13)[0] + 1j * quad(
            part, 0, T, args=(np.imag,), epsabs=0, epsrel=1e-13)[0]
        assert abs(parabola_coefficient(s, T) - want) <= 1e-12 * abs(want)


def test_step_matrices_match_hand_B0(P4):
    """The runtime's -Dwg equals the hand B0 of both families (numbers, not the code itself)."""
    from dtdyn.nonlinear._elements import element_matrix
    from dtdyn.modal._model import modal_factors
    M, C, K = P4["M"], P4["C"], P4["K"]
    L = element_matrix(P4["elements"], 4)
    h = 1e-3
    step = NL.linear_step("newmark", M, C, K, h, np.array([3]), L, np.arange(4))
    Keff = M + 0.5 * h * C + 0.25 * h**2 * K
    np.testing.assert_allclose(-step.Dwg, 0.25 * h**2 * L @ np.linalg.solve(Keff, L.T),
                               rtol=1e-12)
    step = NL.linear_step("modal_ramp", M, C, K, h, np.array([3]), L, np.arange(4))
    s, Psi, X = modal_factors(M, C, K)
    z = s * h
    N0 = (np.exp(z) - 1 - z) / (s**2 * h)
    B0 = np.einsum("r,er,rf->ef", N0, L @ Psi, X @ L.T).real  # all 2n poles: conjugates included
    np.testing.assert_allclose(-step.Dwg, B0, rtol=1e-10)


# --- the linear limit ---------------------------------------------------------------------------

LINEAR = [Cubic(0, k3=0.0), Cubic(1, 2, k3=0.0)]


@pytest.mark.parametrize("backend", ["c", "casadi"])
@pytest.mark.parametrize("method", ["modal_ramp", "modal_parabolic", "modal_quintic"])
def test_g_zero_modal_equals_matrix_exponential(P4, backend, method):
    """Ramp invariant = first-order hold: exact for the piecewise-linear force (1e-12)."""
    n = 1500
    r = NL.nonlinear_mck_response(P4["M"], P4["C"], P4["K"], P4["force"][:n], P4["dt"],
                              force_dofs=[3], elements=LINEAR, scheme=method, backend=backend)
    ex = exact_response(P4["M"], P4["C"], P4["K"], P4["force"][:n], P4["dt"], force_dofs=[3])
    for q in "xva":
        got, want = getattr(r, q), getattr(ex, q)
        assert np.abs(got - want).max() <= 1e-12 * np.abs(want).max(), q


@pytest.mark.parametrize("backend", ["c", "casadi"])
@pytest.mark.parametrize("method, params", [("newmark", {}), ("hht", {"alpha": -0.1}),
                                            ("generalized_alpha", {"rho_inf": 0.6}),
                                            ("wilson", {})])
def test_g_zero_scheme_equals_simulate_mck(P4, backend, method, params):
    n = 1500
    r = NL.nonlinear_mck_response(P4["M"], P4["C"], P4["K"], P4["force"][:n], P4["dt"],
                              force_dofs=[3], elements=LINEAR, scheme=method, backend=backend,
                              **params)
    mk = mck_response(P4["M"], P4["C"], P4["K"], P4["force"][:n], P4["dt"], force_dofs=[3],
                      scheme=method, **params)
    for q in "xva":
        got, want = getattr(r, q), getattr(mk, q)
        assert np.abs(got - want).max() <= 1e-12 * np.abs(want).max(), q


# --- P4 against the solve_ivp reference ---------------------------------------------------------

@pytest.mark.parametrize("method, order", [("modal_ramp", 2), ("modal_parabolic", 3),
                                           ("newmark", 2), ("generalized_alpha", 2)])
def test_p4_convergence_order(P4, P4_ref, method, order):
    """Error against the reference falls as h^order with sub-steps (slope fitted over 1, 2, 4)."""
    errs = [_err(_run(P4, scheme=method, substeps=S), P4_ref) for S in (1, 2, 4)]
    slope = -np.polyfit(np.log([1, 2, 4]), np.log(errs), 1)[0]
    assert order - 0.25 <= slope <= order + 0.35, (errs, slope)


def test_p4_published_prototype_numbers(P4_ref, P4):
    """The issue's NumPy prototype (full record): 4.6e-3 at fs, 1.2e-3 with 2 sub-steps. On this
    3000-sample window the errors are smaller but the ratio is the second-order 4."""
    e1, e2 = (_err(_run(P4, substeps=S), P4_ref) for S in (1, 2))
    assert 3.6 <= e1 / e2 <= 4.4


def test_backends_agree(P4):
    c = _run(P4, scheme="newmark", substeps=2)
    for kw in ({"solver": "newton"}, {"solver": "fast_newton"}):
        ca = _run(P4, scheme="newmark", substeps=2, backend="casadi", **kw)
        assert np.abs(ca.x - c.x).max() <= 1e-12 * np.abs(c.x).max()


def test_polynomial_and_law_equal_cubic(P4):
    base = _run(P4)
    poly = _run(P4, elements=[Polynomial(0, coeffs=[0, 0, 0, 2e7]),
                              Polynomial(1, 2, coeffs=[0.0, 0.0, 0.0, 2e7])])
    law = _run(P4, elements=[Law(0, expression="k3*x**3", k3=2e7),
                             Law(1, 2, expression="k3*x*x*x", k3=2e7)])
    for r in (poly, law):
        assert np.abs(r.x - base.x).max() <= 1e-13 * np.abs(base.x).max()


def test_velocity_law_against_reference():
    """A quadratic damper g = c v |v| (velocity enters the per-step unknowns)."""
    M, K, C = np.eye(2), np.array([[2e4, -1e4], [-1e4, 1e4]]), np.zeros((2, 2))
    fs, n = 500.0, 1500
    f = (np.random.default_rng(3).standard_normal(n) * 50)[:, None]
    els = [Law(0, 1, expression="c*v*abs(v)", c=20.0)]
    ref = reference_response(M, C, K, f, 1 / fs, force_dofs=[1], elements=els, cache=False)
    errs = [_err(NL.nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[1], elements=els,
                                           substeps=S), ref, dof=1)
            for S in (2, 4)]
    assert errs[1] < 2e-3 and 3.0 <= errs[0] / errs[1] <= 5.0, errs


def test_bouc_wen_hysteresis_matches_reference():
    """Bouc-Wen (memory): the loop closes on the reference, second order in the sub-steps."""
    M, K, C = np.array([[1.0]]), np.array([[100.0]]), np.array([[0.5]])
    fs, n = 200.0, 1000
    t = np.arange(n) / fs
    f = (50.0 * np.sin(2 * np.pi * t))[:, None]
    els = [BoucWen(0, stiffness=1e4, alpha=0.1, beta=50.0, gamma=50.0)]
    ref = reference_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els, cache=False)
    errs = []
    for S in (4, 8):
        r = NL.nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els, substeps=S)
        errs.append(_err(r, ref, dof=0))
    assert errs[1] < 1e-3 and 3.3 <= errs[0] / errs[1] <= 4.7, errs
    # the element force g = f - M a - C v - K y does net work over the closed loops: the
    # hysteretic dissipation, the same as the reference's to the method's error
    def dissipated(res):
        g = f[:, 0] - M[0, 0] * res.a[:, 0] - C[0, 0] * res.v[:, 0] - K[0, 0] * res.x[:, 0]
        return np.trapezoid(g, res.x[:, 0])
    assert dissipated(ref) > 0
    assert abs(dissipated(r) - dissipated(ref)) <= 1e-2 * dissipated(ref)


# --- failures are loud --------------------------------------------------------------------------

def _impact(method, substeps, smoothing=1e-4, stiffness=1e12, backend="c", **kw):
    M, K, C = np.array([[1.0]]), np.array([[1e4]]), np.array([[2.0]])
    fs, n = 100.0, 200
    f = (1e3 * np.sin(2 * np.pi * 5 * np.arange(n) / fs))[:, None]
    return NL.nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0],
                                 elements=[Gap(0, gap=1e-2, stiffness=stiffness,
                                                           smoothing=smoothing)],
                                 scheme=method, substeps=substeps, backend=backend, **kw)


def test_newton_failure_names_the_step_and_substeps_cure_it():
    with pytest.raises(NL.NewtonError, match=r"step \d+ \(sample \d+.*t = .* s\): residual"):
        _impact("newmark", 1)
    r = _impact("newmark", 16)
    assert np.isfinite(r.x).all() and np.abs(r.x).max() < 1.1e-2


@pytest.mark.parametrize("substeps", [1, 2, 16])
def test_one_newton_rule_on_the_stiff_gap(substeps):
    """The gap of 1e12 N/m: C and CasADi ("newton", its line search off) take the same plain
    Newton steps and accept by the same rule (|r| <= tol s_r or |J^-1 r| <= tol s_u), so they
    accept or refuse the same steps. At 1 sub-step the element's round-off floor (|r| ~ 2e-13,
    next step ~ 2e-12 |u|) is above tol = 1e-12 at step 20; at 2 sub-steps a step needs 32
    iterations (> max_iter = 30): both refuse the same step. At 16 both accept and agree to
    1e-6 of the peak (this map amplifies per-step differences of tol s: a force changed by 1e-15
    moves a 200-sample record by up to 2e-2 at 3 sub-steps); the largest residual accepted is
    1e-7 of the peak (before the rule, the C loop's floor 16 eps |J| s accepted 3.3e-4)."""
    runs = {}
    for backend in ("c", "casadi"):
        try:
            runs[backend] = _impact("newmark", substeps, backend=backend)
        except NL.NewtonError as exc:
            runs[backend] = str(exc).split(": residual")[0]
    if substeps < 16:
        assert runs["c"] == runs["casadi"] and "did not converge at step" in runs["c"]
        return
    peak = np.abs(runs["c"].x).max()
    assert np.abs(runs["casadi"].x - runs["c"].x).max() <= 1e-6 * peak
    for r in runs.values():
        assert r.info["max_residual"] <= 1e-7 * peak


@pytest.mark.parametrize("substeps", [1, 3])
def test_modal_method_beyond_its_stability_limit_is_refused(substeps):
    """Both backends measure theta = |B0 dg/dy| at every step and stop at the same one."""
    messages = []
    for backend in ("c", "casadi"):
        with pytest.raises(NL.DtdynStepStabilityError,
                           match=r"unstable at step \d+ .*substeps >=") as info:
            _impact("modal_ramp", substeps, smoothing=0.0, stiffness=1e8 * substeps**2,
                    backend=backend)
        messages.append(str(info.value))
    assert messages[0] == messages[1]


@pytest.mark.parametrize("method", ["newmark", "modal_ramp"])
@pytest.mark.parametrize("level", [1e9, 1e150])
def test_backends_report_the_same_failure(method, level):
    """A diverging Newton (1e9) or an overflowing element force (1e150: theta is NaN): both
    backends raise NewtonError naming the same step, not a stability error or a KeyError."""
    M, K, C = np.array([[1.0]]), np.array([[1e4]]), np.array([[2.0]])
    f = np.zeros((50, 1))
    f[1:] = level
    messages = []
    for backend in ("c", "casadi"):
        with pytest.raises(NL.NewtonError) as info:
            NL.nonlinear_mck_response(M, C, K, f, 0.01, force_dofs=[0],
                                  elements=[Cubic(0, k3=1e14)], scheme=method, backend=backend)
        messages.append(str(info.value).split(": residual")[0])
    assert messages[0] == messages[1]


def test_casadi_backend_runs_in_chunks(P4, monkeypatch):
    """The CasADi record runs in chunks of BLOCK * CHUNK_BLOCKS samples with the state carried:
    with chunks of 64 samples (N_SHORT = 3000 is not a multiple) it equals the C loop, and a
    failure in a later chunk is named by the same step as the C loop names it."""
    monkeypatch.setattr(NL, "BLOCK", 16)
    monkeypatch.setattr(NL, "CHUNK_BLOCKS", 4)
    kw = dict(scheme="modal_parabolic", substeps=2)
    c, ca = _run(P4, backend="c", **kw), _run(P4, backend="casadi", **kw)
    assert np.abs(ca.x - c.x).max() <= 1e-9 * np.abs(c.x).max()
    M, K, C = np.array([[1.0]]), np.array([[1e4]]), np.array([[2.0]])
    f = np.zeros((300, 1))
    f[201:] = 1e9
    messages = []
    for backend in ("c", "casadi"):
        with pytest.raises(NL.NewtonError, match=r"step 201 ") as info:
            NL.nonlinear_mck_response(M, C, K, f, 0.01, force_dofs=[0],
                                  elements=[Cubic(0, k3=1e14)], scheme="newmark", backend=backend)
        messages.append(str(info.value).split(": residual")[0])
    assert messages[0] == messages[1]


def test_casadi_backend_checks_every_step():
    M, K, C = np.array([[1.0]]), np.array([[1e4]]), np.array([[2.0]])
    fs, n = 100.0, 200
    f = (1e3 * np.sin(2 * np.pi * 5 * np.arange(n) / fs))[:, None]
    els = [Gap(0, gap=1e-2, stiffness=1e12, smoothing=1e-4)]
    with pytest.raises(NL.NewtonError, match="step"):
        NL.nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els,
                                  scheme="newmark", backend="casadi", solver="fast_newton",
                                  max_iter=5)


# --- bad input ----------------------------------------------------------------------------------

@pytest.mark.parametrize("change, match", [
    ({"dt": 0.0}, "dt"), ({"dt": np.nan}, "dt"),
    ({"force": np.full((10, 1), np.nan)}, r"force\[0, 0\]"),
    ({"force": np.zeros((10, 2))}, "force has shape"),
    ({"force_dofs": [7]}, "force_dofs"),
    ({"elements": []}, "elements is empty"),
    ({"elements": [Cubic(9, k3=1.0)]}, r"elements\[0\].*outside"),
    ({"elements": ["cubic"]}, "not a dtdyn element"),
    ({"scheme": "houbolt"}, "multistep"),
    ({"scheme": "nope"}, "unknown scheme"),
    ({"scheme": "newmark", "modes": [0]}, "modes"),
    ({"substeps": 0}, "substeps"),
    ({"backend": "fortran"}, "backend"),
    ({"backend": "casadi", "compiled": True, "solver": "newton"}, "fast_newton"),
])
def test_bad_inputs(P4, change, match):
    kw = dict(force=P4["force"][:10], dt=P4["dt"], M=P4["M"], C=P4["C"], K=P4["K"],
              force_dofs=P4["force_dofs"], elements=P4["elements"])
    kw.update(change)
    with pytest.raises(ValueError, match=match):
        NL.nonlinear_mck_response(**kw)


@pytest.mark.parametrize("make, match", [
    (lambda: Cubic(-1, k3=1.0), r"Cubic.i"), (lambda: Cubic(1, 1, k3=1.0), "both DOF 1"),
    (lambda: Cubic(0, k3=np.inf), "k3"), (lambda: Gap(0, gap=-1.0, stiffness=1.0), "Gap.gap"),
    (lambda: Gap(0, gap=1.0, stiffness=0.0), "stiffness"),
    (lambda: Law(0, expression='__import__("os").system("echo hi")'), "__import__"),
    (lambda: BoucWen(0, stiffness=1.0, beta=-1.0, gamma=0.5), "beta \\+ gamma"),
])
def test_bad_elements(make, match):
    with pytest.raises(ValueError, match=match):
        make()


# --- DT-TMM chains with nonlinear elements ------------------------------------------------------

def _chain_case(n=600):
    m, k, c = np.ones(4), np.full(4, 1e4), np.full(4, 2.0)
    f = (np.random.default_rng(0).standard_normal(n) * 100.0)[:, None]
    return m, k, c, f


@pytest.mark.parametrize("form", ["acceleration", "displacement"])
@pytest.mark.parametrize("scheme, params", [("newmark", {}), ("hht", {"alpha": -0.1}),
                                            ("generalized_alpha", {"rho_inf": 0.7})])
@pytest.mark.parametrize("elements", [[Cubic(0, k3=2e7), Cubic(1, 2, k3=2e7)],
                                      [BoucWen(1, 2, stiffness=1e4, beta=50.0, gamma=50.0)]])
def test_chain_equals_mck_path(form, scheme, params, elements):
    """The O(N) DT-TMM path and the M, C, K path solve the same per-step problem: equal to
    round-off in both forms (measured <= 1.1e-13; the displacement form solves for the increment,
    tests/test_dttmm.py)."""
    from dtdyn.linear._chain import chain_matrices
    from dtdyn.nonlinear._chain import nonlinear_chain_response
    m, k, c, f = _chain_case()
    M, C, K = chain_matrices(m, k, c, sparse=False)
    a = nonlinear_chain_response(m, k, c, f, 0.001, force_dofs=[3], elements=elements,
                                 scheme=scheme, form=form, substeps=2, **params)
    b = NL.nonlinear_mck_response(M, C, K, f, 0.001, force_dofs=[3], elements=elements,
                              scheme=scheme, substeps=2, **params)
    for q in "xva":
        assert np.abs(getattr(a, q) - getattr(b, q)).max() <= 1e-12 * np.abs(getattr(b, q)).max()


@pytest.mark.parametrize("elements", [[Cubic(0, k3=2e7), Cubic(1, 2, k3=2e7)],
                                      [BoucWen(1, 2, stiffness=1e4, beta=50.0, gamma=50.0),
                                       Cubic(3, k3=2e7)]])
def test_chain_c_loop_equals_python_loop(monkeypatch, elements):
    """generated/nl_chain.c runs the same steps as the Python loop around the same C sweep and
    the same compiled residual, but sums g U and solves J d = r in its own order (NumPy: BLAS
    and LAPACK), so the two differ by roundings, which the hysteresis carries along the record.
    Held to 1e-14 of the largest value, or to 4x what the Python loop itself moves when the
    force changes by one rounding (relative 2^-52): measured 0.97x (x) to 0.90x (a) of that
    with Bouc-Wen. A Newton failure names the same step."""
    import dtdyn.nonlinear._chain as NC
    m, k, c, f = _chain_case()
    a = NC.nonlinear_chain_response(m, k, c, f, 0.001, force_dofs=[3], elements=elements,
                                    substeps=2)
    monkeypatch.setattr(NC, "_c_driver", lambda *args: None)
    b = NC.nonlinear_chain_response(m, k, c, f, 0.001, force_dofs=[3], elements=elements,
                                    substeps=2)
    b1 = NC.nonlinear_chain_response(m, k, c, f * (1 + np.finfo(float).eps), 0.001,
                                     force_dofs=[3], elements=elements, substeps=2)
    assert (a.info["loop"], b.info["loop"]) == ("c", "python")
    assert a.info["newton_iterations"] == b.info["newton_iterations"]
    for q in "xva":
        spread = np.abs(getattr(b1, q) - getattr(b, q)).max()
        bound = max(1e-14 * np.abs(getattr(b, q)).max(), 4 * spread)
        assert np.abs(getattr(a, q) - getattr(b, q)).max() <= bound, q
    monkeypatch.undo()
    messages = []
    for driver in (NC._c_driver, lambda *args: None):
        monkeypatch.setattr(NC, "_c_driver", driver)
        with pytest.raises(NL.NewtonError) as info:
            NC.nonlinear_chain_response(m, k, c, 1e9 * f, 0.001, force_dofs=[3],
                                        elements=[Cubic(0, k3=1e14)], max_iter=3)
        messages.append(str(info.value))
    assert messages[0] == messages[1] and "step" in messages[0]


def test_long_chain_linear_limit_equals_simulate_chain():
    """20,000 masses: with zero nonlinear stiffness the chain path is chain_response's sweep."""
    from dtdyn import chain_response
    from dtdyn.nonlinear._chain import nonlinear_chain_response
    n = 20_000
    m, k, c = np.ones(n), np.full(n, 1e4), np.full(n, 1.0)
    f = (np.random.default_rng(1).standard_normal(30) * 100.0)[:, None]
    els = [Cubic(0, k3=0.0), Cubic(n - 3, n - 2, k3=0.0)]
    a = nonlinear_chain_response(m, k, c, f, 0.001, force_dofs=[n - 1], elements=els,
                                 outputs=[0, n - 2, n - 1], form="acceleration")
    s = chain_response(m, k, c, f, 1e-3, force_dofs=[n - 1], outputs=[0, n - 2, n - 1],
                       form="acceleration")
    assert np.abs(a.x - s.x).max() <= 1e-12 * np.abs(s.x).max()


def test_chain_refuses_multistep_and_bad_elements():
    from dtdyn.nonlinear._chain import nonlinear_chain_response
    m, k, c, f = _chain_case(10)
    with pytest.raises(ValueError, match="multistep"):
        nonlinear_chain_response(m, k, c, f, 0.001, force_dofs=[3],
                                 elements=[Cubic(0, k3=1.0)], scheme="houbolt")
    with pytest.raises(ValueError, match="outside the chain"):
        nonlinear_chain_response(m, k, c, f, 0.001, force_dofs=[3],
                                 elements=[Cubic(7, k3=1.0)])


# --- element forces and internal states ---------------------------------------------------------

@pytest.mark.parametrize("backend", ["c", "casadi"])
def test_element_forces_and_internal_states_are_stored_when_asked(backend, tmp_path):
    """quantities "g" and "z": the cubic's force equals k3 y^3 of the stored displacement, the
    Bouc-Wen force alpha k y + (1 - alpha) k z of the stored y and z, with z bounded by its
    ultimate value (A / (beta + gamma))^(1/n); both backends store the same; nothing else is
    stored; the result saves and loads them."""
    M, K, C = np.diag([1.0, 1.0]), np.array([[2e3, -1e3], [-1e3, 1e3]]), 0.5 * np.eye(2)
    f = 30.0 * np.sin(2 * np.pi * 2.0 * np.arange(3001) * 1e-3)
    bw = BoucWen(1, stiffness=2e3, alpha=0.1, beta=300.0, gamma=300.0)
    els = [Cubic(0, k3=1e6), bw]
    r = NL.nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=[1], elements=els, backend=backend,
                              scheme="newmark", quantities=("x", "g", "z"))
    assert r.v is None and r.a is None and r.g.shape == (3001, 2) and r.z.shape == (3001, 1)
    y0, y1 = r.x[:, 0], r.x[:, 1]
    np.testing.assert_allclose(r.g[:, 0], 1e6 * y0**3, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(r.g[:, 1], 0.1 * 2e3 * y1 + 0.9 * 2e3 * r.z[:, 0], rtol=1e-9,
                               atol=1e-9)
    assert np.abs(r.z).max() <= (1.0 / 600.0) * (1 + 1e-9) and np.abs(r.z).max() > 1e-3
    only = NL.nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=[1], elements=els,
                                 backend=backend, scheme="newmark", quantities=("g",))
    np.testing.assert_allclose(only.g, r.g, rtol=0, atol=1e-12 * np.abs(r.g).max())
    assert only.x is None and only.z is None
    for suffix in (".npz", ".csv"):
        back = load_result(r.save(tmp_path / f"r{suffix}"))
        np.testing.assert_allclose(back.g, r.g, rtol=1e-15)
        np.testing.assert_allclose(back.z, r.z, rtol=1e-15)
    with pytest.raises(ValueError, match="no element has internal states"):
        NL.nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=[1], elements=[Cubic(0, k3=1e6)],
                              quantities=("x", "z"))


def test_initial_conditions_linear_limit_and_duffing_orders():
    """x0, v0: with a negligible element the modal methods equal exact_response and the
    one-step schemes mck_response (same initial state, 1e-12); a Duffing oscillator released
    from x0, v0 converges to solve_ivp (DOP853, rtol 1e-12) at the methods' orders, 2 for
    Newmark and 3 for modal_parabolic, on both backends."""
    from scipy.integrate import solve_ivp

    M, C, K = np.diag([1.0, 2.0, 1.5]), np.diag([1.0, 2.0, 1.0]), np.array(
        [[3e4, -2e4, 0.0], [-2e4, 3e4, -1e4], [0.0, -1e4, 1e4]])
    x0, v0 = np.array([1e-3, -2e-3, 3e-3]), np.array([0.1, 0.0, -0.2])
    f = np.sin(np.arange(3001) * 1e-3 * 20)[:, None]
    ex = exact_response(M, C, K, f, 1e-3, force_dofs=[2], x0=x0, v0=v0)
    for scheme in ("modal_ramp", "newmark"):
        r = NL.nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=[2], scheme=scheme, x0=x0, v0=v0,
                                  elements=[Cubic(0, k3=1e-20)])
        ref = ex if scheme == "modal_ramp" else mck_response(M, C, K, f, 1e-3, force_dofs=[2],
                                                             x0=x0, v0=v0, scheme=scheme)
        for q in "xva":
            assert np.abs(getattr(r, q) - getattr(ref, q)).max() <= 1e-12 * np.abs(
                getattr(ref, q)).max(), (scheme, q)
    m, c, k, k3, a0, b0 = 1.0, 2.0, 1e4, 1e9, 1e-2, -0.5
    t = np.arange(501) * 1e-3
    sol = solve_ivp(lambda _, y: [y[1], -(c * y[1] + k * y[0] + k3 * y[0] ** 3) / m],
                    (0.0, t[-1]), [a0, b0], method="DOP853", rtol=1e-12, atol=1e-15, t_eval=t)
    peak = np.abs(sol.y[0]).max()
    for scheme, order in (("newmark", 2), ("modal_parabolic", 3)):
        for backend in ("c", "casadi"):
            errs = [np.abs(NL.nonlinear_mck_response(
                [[m]], [[c]], [[k]], np.zeros(501), 1e-3, elements=[Cubic(0, k3=k3)],
                scheme=scheme, substeps=S, x0=[a0], v0=[b0], backend=backend).x[:, 0]
                - sol.y[0]).max() / peak for S in (4, 8)]
            assert 0.8 * 2**order <= errs[0] / errs[1] <= 1.2 * 2**order, (scheme, errs)


@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_nonlinear_chain_initial_state_forces_and_states(backend):
    """nonlinear_chain_response with x0, v0 and quantities g, z: the same discrete equations
    as nonlinear_mck_response with the same scheme on the assembled matrices (x to 1e-10 of the
    peak, g and z alike), from both the C loop and the Python loop."""
    from dtdyn import chain_matrices, nonlinear_chain_response

    mass, stiff, damp = [1.0, 2.0, 1.5], [1e4, 2e4, 1e4], [1.0, 2.0, 1.0]
    els = [Cubic(0, k3=1e9), BoucWen(2, stiffness=5e3, alpha=0.1, beta=200.0, gamma=200.0)]
    x0, v0 = np.array([1e-3, -2e-3, 3e-3]), np.array([0.1, 0.0, -0.2])
    f = 20.0 * np.sin(np.arange(2001) * 1e-3 * 20)[:, None]
    kw = dict(force_dofs=[2], elements=els, scheme="newmark", x0=x0, v0=v0,
              quantities=("x", "g", "z"))
    r = nonlinear_chain_response(mass, stiff, damp, f, 1e-3, backend=backend, **kw)
    M, C, K = chain_matrices(mass, stiff, damp, sparse=False)
    ref = NL.nonlinear_mck_response(M, C, K, f, 1e-3, **kw)
    np.testing.assert_allclose(r.x[0], x0, rtol=0, atol=1e-15)
    for q in "xgz":
        a, b = getattr(r, q), getattr(ref, q)
        assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max(), q
    assert r.v is None and r.g.shape == (2001, 2) and r.z.shape == (2001, 1)


# --- modal_quintic: the force polynomial of degree 5 ---------------------------------------------

def _lagrange(j, v, nodes):
    """Hand-written Lagrange basis polynomial of node j at v (the oracle)."""
    out = 1.0
    for i in nodes:
        if i != j:
            out *= (v - i) / (j - i)
    return out


@pytest.mark.parametrize("method, nodes", [("modal_quintic", range(-4, 2)),
                                           ("modal_explicit", range(-6, 1))])
@pytest.mark.parametrize("pole", [-0.5 + 100j, -30 + 3000j, -100 + 1900j, -1e4 + 0j, -2e3 + 0j,
                                  -900 + 1700j])
def test_polynomial_weights_against_quadrature(pole, method, nodes):
    """W_j = integral_0^h e^{s(h-u)} l_j(u/h) du and the estimate's E (the polynomial
    prod (v - j) / (m + 1)!) by numerical quadrature, on both sides of the series/closed-form
    switch (|s h| = 2), for the implicit quintic and the explicit sextic."""
    from math import factorial

    from scipy.integrate import quad

    from dtdyn.generated.nl_modal import polynomial_coefficients
    h = 1e-3
    W, E = polynomial_coefficients(method, np.array([pole]), h)
    assert sorted(W) == list(nodes)

    def integral(fn):
        re = quad(lambda u: (np.exp(pole * (h - u)) * fn(u / h)).real, 0, h, epsabs=0,
                  epsrel=1e-13, limit=200)[0]
        im = quad(lambda u: (np.exp(pole * (h - u)) * fn(u / h)).imag, 0, h, epsabs=0,
                  epsrel=1e-13, limit=200)[0]
        return re + 1j * im
    for j in nodes:
        want = integral(lambda v, j=j: _lagrange(j, v, nodes))
        assert abs(W[j][0] - want) <= 1e-11 * abs(want), j
    want = integral(lambda v: np.prod([v - i for i in nodes]) / factorial(len(nodes)))
    assert abs(E[0] - want) <= 1e-11 * abs(want)


@pytest.mark.parametrize("method, degree, explicit", [("modal_quintic", 5, False),
                                                      ("modal_explicit", 6, True)])
def test_polynomial_stability_limit_is_the_runtime_step_s(method, degree, explicit):
    """The derived limit (the free mass's characteristic polynomial) against the runtime's own
    step: one mode (omega h = 0.01, undamped) with a linear element k_t, the closed loop
    A + Bg k_t (1 - Dwg k_t)^-1 Cw: every eigenvalue in the unit disk at 0.95 of the limit,
    one outside at 1.05; theta = |B0 k_t| with B0 = Dwg (implicit) or Cw Bg (explicit: Dwg = 0),
    as the loops measure it. The ramp's derived limit is its theta = 2 (Omega_t = sqrt 12)."""
    from dtdyn.nonlinear._linear_step import THETA_LIMIT, linear_step
    assert DN.polynomial_stability(1)["theta_limit"] == pytest.approx(2.0, rel=1e-9)
    limit = THETA_LIMIT[method]
    assert limit == pytest.approx(DN.polynomial_stability(degree, explicit)["theta_limit"])
    h, L = 0.01, np.eye(1)
    step = linear_step(method, np.eye(1), np.zeros((1, 1)), np.eye(1), h, [0], L,
                       np.array([0]))
    assert (step.Dwg[0, 0] == 0) == explicit
    B0 = -(step.Cw @ step.Bg)[0, 0] if explicit else -step.Dwg[0, 0]

    def radius(theta):
        kt = theta / B0
        A = step.A + step.Bg * kt @ np.linalg.inv(np.eye(1) - step.Dwg * kt) @ step.Cw
        return np.abs(np.linalg.eigvals(A)).max()
    assert radius(0.5 * limit) <= 1 + 1e-9
    assert radius(0.95 * limit) <= 1 + 1e-9
    assert radius(1.05 * limit) > 1 + 1e-6


def test_quintic_embedded_estimate_is_its_recursion(P4):
    """The C loop evaluates the embedded estimate a block of steps at a time, after the Newton
    solves of the block, with Cw e_k formed from e_{k-1} (generated/nonlinear.md): the number it
    reports equals the recursion as defined, evaluated here step by step on the full modal block
    of the runtime's step (A's modal rows, Bs = Bg + sum_i H_i, Eg, the stencil), with the
    cubic springs' tangent 3 k3 y^2 from the stored response (y = L x, to Newton's tolerance):
    4e-14 relative measured, 1e-9 asserted (without the tangent's feedback the number is 32%
    lower). 3,000 steps: 23 full blocks of 128 steps and a partial one."""
    M, C, K, f, dt = P4["M"], P4["C"], P4["K"], P4["force"], P4["dt"]
    els = P4["elements"]
    r = NL.nonlinear_mck_response(M, C, K, f, dt, force_dofs=P4["force_dofs"], elements=els,
                              scheme="modal_quintic", quantities=("x", "v", "a", "g"))
    L = NL.element_matrix(els, 4)
    step = NL.linear_step("modal_quintic", M, C, K, dt, np.array(P4["force_dofs"]), L,
                          np.arange(4))
    md, ne = step.modal, L.shape[0]
    nm, nh = md["nm"], md["nh"]
    Am, Bs = step.A[:nm, :nm], step.Bg[:nm] + sum(step.A[:nm, nm + i:nm + i + ne]
                                                   for i in range(0, nh, ne))
    Cw, Co, Dog, Dwg = step.Cw[:, :nm], step.Co[:, :nm], step.Dog, step.Dwg
    k3 = np.array([el.k3 for el in els])
    g = r.g
    past = np.vstack([np.repeat(g[:1], md["stencil"].size - 1, axis=0), g])  # at rest before t_0
    e, dg, worst = np.zeros(nm), np.zeros(ne), np.zeros(Co.shape[0])
    for k in range(g.shape[0]):
        dn = sum(c * past[k + md["stencil"].size - 1 - i] for i, c in enumerate(md["stencil"]))
        e = Am @ e + Bs @ dg + md["Eg"] @ dn
        kt = 3.0 * k3 * (L @ r.x[k]) ** 2  # dg/dy
        J = np.eye(ne) - Dwg * kt  # dr/du of r = w - Q - Dwg g(w)
        dg = kt * np.linalg.solve(J, Cw @ e)
        worst = np.maximum(worst, np.abs(Co @ e + Dog @ dg))
    want = max(worst[i * 4:(i + 1) * 4].max() / np.abs(getattr(r, q)).max()
               for i, q in enumerate("xva"))
    assert r.info["error_estimate_kind"] == "embedded"
    assert r.info["error_estimate"] == pytest.approx(want, rel=1e-9)


def test_quintic_backends_agree(P4):
    """The C loop's modal path (tridiagonal modal block, shifted force history) against the
    CasADi backend on the full matrices: the same step, so the same numbers to the Newton
    tolerance."""
    n = 3000
    runs = {b: NL.nonlinear_mck_response(P4["M"], P4["C"], P4["K"], P4["force"][:n], P4["dt"],
                                     force_dofs=[3], elements=P4["elements"],
                                     scheme="modal_quintic", backend=b) for b in ("c", "casadi")}
    peak = np.abs(runs["c"].x).max()
    assert np.abs(runs["casadi"].x - runs["c"].x).max() <= 1e-9 * peak
    assert runs["c"].info["error_estimate_kind"] == "embedded"



@pytest.mark.parametrize("method", ["modal_ramp", "modal_quintic"])
def test_modal_path_with_real_poles_agrees_with_casadi(method):
    """A mode beyond critical damping gives two real poles between the oscillating pairs: the
    C loop's modal path reorders the rows (2 x 2 blocks first, so a row's partner sits in its own
    vector) and pads them to vectors of 4; the CasADi backend steps the full matrices in A's
    order. Same step, so the same x, v, a and g to the Newton tolerance."""
    M = np.diag([1.0, 2.0, 1.5])
    K = np.array([[3e4, -1e4, 0.0], [-1e4, 2e4, -1e4], [0.0, -1e4, 1e4]])
    C = np.diag([900.0, 0.0, 0.0]) + 1e-4 * K  # mass 0 on a damper of 900 N s/m: overdamped
    force = np.random.default_rng(3).standard_normal((2000, 1)) * 50.0
    els = [Cubic(0, None, k3=1e7), Cubic(1, 2, k3=5e6)]
    L = NL.element_matrix(els, 3)
    step = NL.linear_step(method, M, C, K, 1e-3, np.array([2]), L, np.arange(3))
    assert step.modal is not None
    perm = step.modal["perm"]
    assert np.count_nonzero(step.modal["off"] == 0.0) >= 2  # real poles, moved behind the pairs
    assert not np.array_equal(perm, np.arange(perm.size))
    runs = {b: NL.nonlinear_mck_response(M, C, K, force, 1e-3, force_dofs=[2], elements=els,
                                     scheme=method, backend=b, quantities=("x", "v", "a", "g"))
            for b in ("c", "casadi")}
    for q in "xvag":
        a, b = getattr(runs["c"], q), getattr(runs["casadi"], q)
        assert np.abs(a - b).max() <= 1e-9 * np.abs(b).max(), q


def test_p4_explicit_convergence_order(P4, P4_ref):
    """Seventh order (the polynomial of degree 6 extrapolated over the step), approached from
    below on these 3,000 samples: 2^5.99 from 1 to 2 sub-steps, 2^6.75 from 2 to 4 (measured);
    the finest pair within 0.4 of 7 (the full record shows 6.96 and 7.05:
    tests/behaviour/test_accuracy_target.py)."""
    errs = [_err(_run(P4, scheme="modal_explicit", substeps=S), P4_ref) for S in (1, 2, 4)]
    slopes = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert 7 - 0.4 <= slopes[-1] <= 7 + 0.4, (errs, slopes)
    assert 5.5 <= slopes[0] <= slopes[-1], (errs, slopes)


def test_explicit_backends_agree(P4):
    """modal_explicit on the C loop (NL_EXPLICIT: one evaluation of the laws a step, no Newton
    solve, theta = |(Cw Bg) dg/dy|) against the CasADi backend (its rootfinder on w - Q = 0,
    theta from the same product): nothing is iterated, so they differ by rounding only (7e-15
    measured for x, v, a and g; 1e-11 asserted, room for the fused products of another CPU),
    with the same largest theta and no Newton iterations in C."""
    runs = {b: NL.nonlinear_mck_response(P4["M"], P4["C"], P4["K"], P4["force"], P4["dt"],
                                     force_dofs=[3], elements=P4["elements"],
                                     scheme="modal_explicit", backend=b,
                                     quantities=("x", "v", "a", "g")) for b in ("c", "casadi")}
    for q in "xvag":
        a, b = getattr(runs["c"], q), getattr(runs["casadi"], q)
        assert np.abs(a - b).max() <= 1e-11 * np.abs(b).max(), q
    assert runs["c"].info["max_theta"] == pytest.approx(runs["casadi"].info["max_theta"],
                                                        rel=1e-12)
    assert runs["c"].info["newton_iterations"]["max"] == 0
    assert runs["c"].info["error_estimate_kind"] == "embedded"


def test_explicit_with_internal_states_agrees_with_casadi():
    """Bouc-Wen has an internal state z, which still solves its trapezoidal update by Newton
    (w = Q exactly): the C loop's explicit path with internal states against CasADi, to the
    Newton tolerance (1.3e-13 measured, 1e-9 asserted as for the other Newton paths)."""
    M, K, C = np.array([[1.0]]), np.array([[100.0]]), np.array([[0.5]])
    fs, n = 200.0, 1000
    f = (50.0 * np.sin(2 * np.pi * np.arange(n) / fs))[:, None]
    els = [BoucWen(0, stiffness=1e4, alpha=0.1, beta=50.0, gamma=50.0)]
    runs = {b: NL.nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els,
                                     scheme="modal_explicit", substeps=4, backend=b,
                                     quantities=("x", "v", "a", "g", "z"))
            for b in ("c", "casadi")}
    for q in "xvagz":
        a, b = getattr(runs["c"], q), getattr(runs["casadi"], q)
        assert np.abs(a - b).max() <= 1e-9 * np.abs(b).max(), q
    assert runs["c"].info["max_theta"] == pytest.approx(runs["casadi"].info["max_theta"])


@pytest.mark.parametrize("backend", ["c", "casadi"])
def test_explicit_beyond_its_stability_limit_names_the_step(backend):
    """The stiff contact at 1 sub-step: theta = |(Cw Bg) dg/dy| far beyond modal_explicit's
    derived 0.264 at the first contact, a DtdynStepStabilityError naming the step, the measure
    and the sub-steps that would bring it within the limit, on both backends."""
    with pytest.raises(NL.DtdynStepStabilityError,
                       match=r"'modal_explicit' is unstable at step \d+ \(sample \d+.*theta = "
                             r"\|\(Cw Bg\) dg/dy\| = .* > 0\.2635.*use substeps >= \d+"):
        _impact("modal_explicit", 1, backend=backend)


@pytest.mark.parametrize("level", [10.0, 1e3, 1e150])
def test_explicit_checks_agree_with_casadi_mid_record(level):
    """modal_explicit's C loop checks theta and the forces' finiteness for a block of 256 steps
    at once (nl_loop.c, explicit_block), CasADi step by step: a Duffing oscillator (k = 1e4,
    k3 = 1e8, 4 sub-steps of 2.5 ms) under a small sine, then a force step at sample 700 (step
    2800, inside the eleventh block). Within the limit (10 N), both report the same largest theta;
    beyond it (1e3 N: theta = 0.52 > 0.264 at the step itself) and with forces that overflow
    (1e150 N: k3 y^3 = inf three steps before, the polynomial's extrapolation of the step), both
    name the same step, by the same error."""
    M, K, C = np.array([[1.0]]), np.array([[1e4]]), np.array([[2.0]])
    f = np.zeros((900, 1))
    f[:700, 0] = np.sin(0.3 * np.arange(700))
    f[700:] = level
    runs = {}
    for backend in ("c", "casadi"):
        try:
            runs[backend] = NL.nonlinear_mck_response(M, C, K, f, 0.01, force_dofs=[0],
                                                  elements=[Cubic(0, k3=1e8)],
                                                  scheme="modal_explicit", substeps=4,
                                                  backend=backend)
        except (NL.NewtonError, NL.DtdynStepStabilityError) as exc:
            runs[backend] = f"{type(exc).__name__}: {exc}"
    if level == 10.0:
        assert runs["c"].info["max_theta"] == pytest.approx(runs["casadi"].info["max_theta"],
                                                            rel=1e-12)
        return
    assert runs["c"] == runs["casadi"]
    expected = ("DtdynStepStabilityError", "step 2800 ") if level == 1e3 else \
        ("NewtonError: the element forces are not finite", "step 2797 ")
    assert all(part in runs["c"] for part in expected), runs["c"]


def _many_elements(kind):
    """A 24-DOF chain with 12 elements on its first stations (36 unknowns for Bouc-Wen: y, y', z;
    12 for a smoothed gap: y), 4000 steps of white noise on the top mass."""
    N = 24
    M, C, K = chain_matrices(np.ones(N), np.full(N, 1e4), np.full(N, 2.0), sparse=False)
    f = 30.0 * np.random.default_rng(0).standard_normal(4000)
    if kind == "boucwen":
        els = [BoucWen(i, i - 1 if i else None, stiffness=5e3, alpha=0.1, beta=50.0, gamma=50.0)
               for i in range(12)]
    else:
        els = [Gap(i, i - 1 if i else None, gap=2e-3, stiffness=1e7, smoothing=1e-4)
               for i in range(12)]
    return M, C, K, f, els


@pytest.mark.parametrize("kind, scheme, factorizations", [("boucwen", "newmark", 10),
                                                          ("boucwen", "modal_ramp", 10),
                                                          ("gap", "newmark", 4000)])
def test_kept_lu_converges_to_plain_newton(kind, scheme, factorizations, monkeypatch):
    """From LU_REUSE_MIN = 12 unknowns the C loop keeps the LU factors of the Newton Jacobian
    from step to step (nl_loop.c, newton_fixed: modified Newton, formed anew where it does not
    contract). Plain Newton and it accept every step within tol s_u, so they converge to the same
    discrete solution as tol falls: their difference shrinks with tol (Bouc-Wen, 36 unknowns:
    2.8e-8 at tol = 1e-10, 4.8e-10 at 1e-12; the gap, 12 unknowns, whose contacts change the
    Jacobian: 9.9e-7 and 2.6e-8; measured), held to a factor 10 for a factor 100 of tol. Bouc-Wen
    forms one LU for the 4000 steps (measured 1), the gap one at most steps (3047)."""
    M, C, K, f, els = _many_elements(kind)
    diff = []
    for tol in (1e-10, 1e-12):
        runs = {}
        for reuse in (None, 12):
            monkeypatch.setattr(NL, "LU_REUSE_MIN", reuse)
            runs[reuse] = NL.nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=[23], elements=els,
                                                scheme=scheme, tol=tol, quantities=("x",))
        peak = np.abs(runs[None].x).max()
        diff.append(np.abs(runs[12].x - runs[None].x).max() / peak)
        assert runs[12].info["newton_iterations"]["factorizations"] <= factorizations
        assert runs[None].info["newton_iterations"]["factorizations"] > 4000
    assert diff[1] <= diff[0] / 10, diff


def test_p4_quintic_convergence_order(P4, P4_ref):
    """Sixth order: the error falls by 2^6.4 from 1 to 2 sub-steps and by 2^6.3 from 2 to 4
    (measured): the finest pair's slope is the asymptotic claim (6 - 0.25 .. 6 + 0.35, as for
    the other methods), the coarser one approaches it from above."""
    errs = [_err(_run(P4, scheme="modal_quintic", substeps=S), P4_ref) for S in (1, 2, 4)]
    slopes = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert 6 - 0.25 <= slopes[-1] <= 6 + 0.35, (errs, slopes)
    assert slopes[0] >= slopes[-1] - 0.05, (errs, slopes)


def test_forces_before_start_continue_the_motion():
    """The force polynomials' past for a start away from rest (dtdyn.nonlinear._startup): the
    Duffing m x'' + c x' + k x + k3 x^3 = f0 + f1 t integrated forwards by hand (solve_ivp,
    DOP853 at rtol 1e-13) from a state at t = -4 h to t = 0 gives x0, v0 and the truth
    k3 x(-j h)^3. The returned values extrapolate the continuation's forces at t_0 .. t_0 + 4 h by
    the polynomial of degree 4, whose error is O(h^5 g^(5)): halving h divides it by 2^5 = 32
    (33.9 and 34.0 measured between h = 2e-4, 1e-4 and 5e-5; 4.8e-8 of g at 5e-5). The quintic
    asks for 6 values, so its polynomial has degree 6 and an error O(h^7)."""
    from scipy.integrate import solve_ivp

    from dtdyn.nonlinear._elements import element_matrix
    from dtdyn.nonlinear._startup import forces_before_start
    m, c, k, k3, f0, f1, dt = 2.0, 3.0, 1e4, 1e9, 5.0, 2e3, 1e-3
    els = [Cubic(0, k3=k3)]
    errs = []
    for h in (2e-4, 1e-4, 5e-5):
        times = -h * np.arange(4, -1, -1)
        sol = solve_ivp(lambda t, y: [y[1], (f0 + f1 * t - c * y[1] - k * y[0]
                                             - k3 * y[0] ** 3) / m],
                        (times[0], 0.0), [4e-3, 0.3], method="DOP853", rtol=1e-13, atol=1e-17,
                        t_eval=times)
        x = sol.y[0]
        g = forces_before_start(np.array([[m]]), np.array([[c]]), np.array([[k]]),
                                element_matrix(els, 1), els, np.array([0]),
                                np.array([[f0], [f0 + f1 * dt]]), dt, x[-1:], sol.y[1][-1:], h, 4)
        truth = k3 * x[-2::-1] ** 3
        errs.append(np.abs(g[:, 0] - truth).max() / np.abs(truth).max())
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert np.all((ratios > 24) & (ratios < 40)) and errs[-1] < 1e-7, (errs, ratios)


def test_forces_before_start_on_a_stiff_damped_model():
    """A stiff, damped second mode (omega = 1e5 rad/s, 10 % damping; 1e7 rad/s): the forwards
    continuation stays bounded (backwards, such a mode grows by e^{zeta omega n h}) and takes a
    fraction of a second; when it would need more than RHS_PER_STEP right-hand sides a step,
    the constant past is kept, with one warning saying so, and the run goes on."""
    import time
    import warnings

    from dtdyn import DtdynAccuracyWarning
    M, els, x0 = np.eye(2), [Cubic(0, k3=1e9)], [1e-3, 1.0001e-3]
    f = np.zeros((201, 1))
    for k2, expect_warning in ((5e9, False), (5e13, True)):
        K = np.array([[1e4 + k2, -k2], [-k2, k2]])
        t0 = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            r = NL.nonlinear_mck_response(M, 2e-6 * K, K, f, 1e-3, force_dofs=[0], elements=els,
                                      x0=x0, scheme="modal_quintic")
        said = [w for w in caught if issubclass(w.category, DtdynAccuracyWarning)
                and "constant past g_0" in str(w.message)]
        assert len(said) == expect_warning and time.perf_counter() - t0 < 10.0
        assert np.isfinite(r.x).all() and np.abs(r.x).max() < 2e-3


def test_start_away_from_rest_keeps_the_quintic_order():
    """A Duffing of moderate nonlinearity (k3 x0^2 = 0.3 k) released from x0, v0: modal_quintic
    converges at its sixth order (6.23 and 6.01 observed between 2, 4 and 8 sub-steps; 1.0e-10
    at 8), where a constant past g_{-j} = g_0 makes it a second-order method, and its embedded
    estimate is within 0.5-1.5x of the error against solve_ivp."""
    from scipy.integrate import solve_ivp
    m, c, k, k3, a0, b0 = 1.0, 2.0, 1e4, 1e9, 3e-3, -0.15
    t = np.arange(501) * 1e-3
    sol = solve_ivp(lambda _, y: [y[1], -(c * y[1] + k * y[0] + k3 * y[0] ** 3) / m],
                    (0.0, t[-1]), [a0, b0], method="DOP853", rtol=1e-13, atol=1e-16, t_eval=t)
    errs = []
    for S in (2, 4, 8):
        r = NL.nonlinear_mck_response([[m]], [[c]], [[k]], np.zeros(501), 1e-3,
                                  elements=[Cubic(0, k3=k3)], x0=[a0], v0=[b0],
                                  quantities=("x", "v"), scheme="modal_quintic", substeps=S)
        e = max(np.abs(r.x[:, 0] - sol.y[0]).max() / np.abs(sol.y[0]).max(),
                np.abs(r.v[:, 0] - sol.y[1]).max() / np.abs(sol.y[1]).max())
        assert 0.5 * e <= r.info["error_estimate"] <= 1.5 * e, (S, e, r.info["error_estimate"])
        errs.append(e)
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - 6) <= 0.4) and errs[-1] <= 1e-9, (orders, errs)
