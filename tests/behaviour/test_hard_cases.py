"""Hard cases (issue 6, item 3): where integrators and sweeps usually break.

Every test compares numbers with theory or an independent reference (the matrix exponential
`exact_response`, closed forms, the amplification matrices of `stability`), with the tolerance
derived in a comment from the method's known error. The cases:

1. stiff chains, frequency ratio ~1e4 (DT-TMM stable sweep = assembled matrices; unconditionally
   stable schemes bounded; the plain sweep warns);
2. long chains, 100,000 masses, loaded at one mass (memory, agreement with sparse matrices);
3. 1,000,000 undamped steps of a 1-DOF oscillator (energy and phase of the conservative schemes);
4. dt far above the shortest period, Omega = 100 and 1000 (the high mode decays like rho^n);
5. overdamped and rigid-body modes (modal filters; free-free chain under a constant force);
6. a massless DOF in a stiff chain (against the statically condensed model);
7. strong nonlinearity: a hardening spring whose cubic force is ~50x the linear one, and a stiff
   contact (gap) at a large step, against the solve_ivp reference (DOP853, rtol 1e-12).

Relative errors are max over time and outputs of |x - ref| / max |ref| (problems.rel_error).
"""
import importlib
import tracemalloc
import warnings

import numpy as np
import pytest
import scipy.linalg as sla

from dtdyn.linear._chain import DtdynAccuracyWarning, chain_matrices, chain_response
from dtdyn.linear._exact import exact_response
from dtdyn.linear._mck import mck_response
from dtdyn.modal._model import modal_model
from dtdyn.modal._filters import modal_filter_response
from dtdyn.generated.scheme_table import TABLE  # the built-in schemes, in order
from dtdyn.linear._stability import stability
from dtdyn.linear._state_space import discrete_state_space, state_space_response

from problems import rel_error

EPS = np.finfo(float).eps
IMPLICIT = [s for s in TABLE if s != "central_difference"]
#: critical Omega = inf in docs/stability.md ("newmark" defaults to average acceleration)
UNCONDITIONAL = ["newmark", "average_acceleration", "fox_euler", "wilson", "houbolt", "park", "hht",
                 "generalized_alpha"]


def _natural_frequencies(M, K):
    return np.sqrt(sla.eigh(K, M, eigvals_only=True))


def _coefficients(scheme, dt):
    """The acceleration form's coefficients of ``scheme`` at its default parameters at ``dt``
    (its generated module, dtdyn.generated.scheme_<name>)."""
    module = importlib.import_module(f"dtdyn.generated.scheme_{scheme}")
    return module.coefficients("acceleration", dt, *(module.DEFAULTS[p] for p in module.PARAMS))


def _effective_condition(M, C, K, scheme, dt):
    """2-norm condition number of the matrix each step solves, M + Dv C + Dx K (acceleration
    form; the displacement form solves the same matrix divided by Dx)."""
    coef = _coefficients(scheme, dt)
    return np.linalg.cond(M + coef["r"] * C + coef["p"] * K)


# --- 1. stiff chains ------------------------------------------------------------------------
def _stiff_chain(n_mass=20):
    """A soft spring (k = 1) to ground carrying 19 stiff springs (k = 1e6), unit masses, dampers
    c = 1e-3 k on the stiff stations only: omega from 0.224 to 1994 rad/s, ratio 8.9e3."""
    m = np.ones(n_mass)
    k = np.full(n_mass, 1e6)
    k[0] = 1.0
    c = 1e-3 * k
    c[0] = 0.0
    return m, k, c


def test_stiff_chain_ratio_1e4_frequencies():
    m, k, c = _stiff_chain()
    M, _, K = chain_matrices(m, k, c, sparse=False)
    w = _natural_frequencies(M, K)
    assert 5e3 < w[-1] / w[0] < 2e4  # "~1e4": 8.9e3


@pytest.mark.parametrize("scheme", IMPLICIT)
def test_stiff_chain_ratio_1e4_stable_sweep_equals_assembled(scheme):
    """DT-TMM (Riccati sweep) = mck_response on the same chain, both forms, C kernel.

    dt = 1e-2: Omega_max = 19.9 (stiff modes unresolved), Omega_min = 2.2e-3, 1,000 steps, step
    force on the free end; dt = 1e-3 (Omega_max = 2.0) for the conditionally stable schemes
    (limits 2.449 .. 3.464). Both solve the same tridiagonal system every step, by different
    eliminations; each solve is exact to about kappa eps relative (kappa: condition number of
    M + Dv C + Dx K, ~4 at dt = 1e-3, 120..240 at dt = 1e-2), and the schemes have rho <= 1, so
    the rounding errors of the two computations add up without growth: bound 2 n_steps kappa eps
    (5e-11..1e-10 at dt = 1e-2), in both forms (the displacement form solves for the increment
    x_e - x_n, so it has no cancellation floor: tests/test_dttmm.py). Measured: acceleration form
    <= 1.6e-11, displacement form <= 1.5e-11 (Houbolt).
    """
    m, k, c = _stiff_chain()
    dt, n = (1e-2 if scheme in UNCONDITIONAL else 1e-3), 1000
    M, C, K = chain_matrices(m, k, c, sparse=False)
    kappa = _effective_condition(M, C, K, scheme, dt)
    F = np.ones((n + 1, 1))
    ref = mck_response(M, C, K, F, dt, force_dofs=[19], scheme=scheme, quantities=("x",))
    for form in ("acceleration", "displacement"):
        r = chain_response(m, k, c, F, dt, force_dofs=[19], scheme=scheme, form=form,
                           quantities=("x",))
        assert r.info["sweep"] == "stable" and r.info["backend"] == "c"
        err = rel_error(r.x, ref.x)
        assert err < 2 * n * kappa * EPS, (form, err, 2 * n * kappa * EPS)


@pytest.mark.parametrize("scheme", UNCONDITIONAL)
def test_stiff_chain_ratio_1e4_unconditionally_stable_bounded(scheme):
    """dt = 0.5: Omega from 0.11 to 997, 4,000 steps (71 periods of the soft mode), unit step
    force on the free end.

    Theory: rho <= 1 at every mode's Omega (checked with `stability`). The bound on the response:
    with y = x - x_static, average acceleration conserves 1/2 v'Mv + 1/2 y'Ky up to the
    (non-negative) damper dissipation, so ||y||_K <= ||x_static||_K, and for the loaded DOF l
    this gives |x_l| <= 2 F (K^-1)_ll, the exact solution's bound too (a theorem, up to rounding:
    margin 1e-9). For the other schemes it is not a theorem, but they only add algorithmic
    damping (docs/stability.md: damping >= 0, rho < 1 at high Omega), so exceeding the physical
    bound would mean the scheme injects energy: the same bound is asserted. Measured: max |x_l|
    / bound = 0.999996 (average acceleration) down to 0.958 (Fox-Euler).
    """
    m, k, c = _stiff_chain()
    dt, n = 0.5, 4000
    M, C, K = chain_matrices(m, k, c, sparse=False)
    w = _natural_frequencies(M, K)
    assert stability(scheme, w * dt).spectral_radius.max() <= 1.0 + 1e-12
    r = chain_response(m, k, c, np.ones((n + 1, 1)), dt, force_dofs=[19], scheme=scheme,
                       outputs=[19], quantities=("x",))
    bound = 2.0 * np.linalg.inv(K)[19, 19]
    assert np.all(np.isfinite(r.x))
    assert np.abs(r.x).max() <= bound * (1 + 1e-9), np.abs(r.x).max() / bound


def _plain_and_stable(m, k, c, dt, n):
    F = np.ones((n + 1, 1))
    stable = chain_response(m, k, c, F, dt, force_dofs=[m.size - 1], scheme="average_acceleration")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plain = chain_response(m, k, c, F, dt, force_dofs=[m.size - 1],
                               scheme="average_acceleration", sweep="plain")
    warned = [w for w in caught if issubclass(w.category, DtdynAccuracyWarning)]
    return rel_error(plain.x, stable.x), plain.info["error_estimate"], warned


def test_stiff_chain_ratio_1e4_plain_sweep_warns():
    """dt = 1e-3: each stiff station multiplies the product by m A / k = 4 (the soft one by 4e6),
    so the plain sweep loses ~4^19 4e6 eps: measured error 2.0e-3 against the stable sweep
    (itself equal to mck_response to < 1e-10, test above), and it must say so."""
    err, est, warned = _plain_and_stable(*_stiff_chain(), 1e-3, 500)
    assert err > 1e-4  # the warning is deserved
    assert warned and "sweep='stable'" in str(warned[0].message)
    assert est > 1e-6


def test_stiff_chain_plain_sweep_warns_whenever_inaccurate():
    """The documented promise of sweep='plain': a warning whenever the result is worse than 1e-6,
    and an estimate that tracks the error (tests/test_dttmm.py: within 10x on uniform chains)."""
    err, est, warned = _plain_and_stable(*_stiff_chain(), 1.55e-3, 500)
    assert err > 1e-6  # 8.2e-6 (stable sweep: < 1e-10)
    assert 0.1 < est / err < 10, (est, err)
    assert warned


# --- 2. long chains --------------------------------------------------------------------------
def _long_chain(n_mass=100_000, seed=6):
    """Masses 0.1..10, springs 1e3..1e5 (log-uniform, seeded), dampers c = 1e-4 k."""
    rng = np.random.default_rng(seed)
    m = 10.0 ** rng.uniform(-1, 1, n_mass)
    k = 10.0 ** rng.uniform(3, 5, n_mass)
    return m, k, 1e-4 * k


@pytest.mark.parametrize("scheme", ["generalized_alpha", "houbolt"])
def test_long_chain_1e5_masses(scheme):
    """100,000 random masses, force on the middle mass, 200 steps of 1e-3 s, 5 outputs.

    Memory: the result holds only (201, 5) arrays of the asked quantities; the run's peak
    allocation (tracemalloc) is the O(N) working set (m, k, c, the history rows, the C kernel's
    12 N scratch: measured 22 N doubles for generalized-alpha, 42 N for Houbolt and its lags),
    far below the 201 N doubles that storing every mass at every step would take: assert < 100 N.

    Agreement with mck_response on scipy.sparse matrices at the outputs: the same tridiagonal
    system is solved each step; M + Dv C + Dx K is diagonally dominant with margin min(m) by
    rows, so its infinity-norm condition number is at most ||S||_inf / min(m) (101), and the
    rounding of the two computations over 200 steps stays below 2 n_steps kappa eps (9e-12), in
    both forms. Measured: x <= 1.1e-13, a <= 2.7e-12 (Houbolt) in the displacement form,
    x <= 9.7e-14, a <= 2.1e-12 in the acceleration form.
    """
    m, k, c = _long_chain()
    N = m.size
    L = N // 2
    dt, n = 1e-3, 200
    F = 10.0 * np.sin(np.linspace(0.0, 3.0, n + 1))[:, None]
    outputs = [0, L - 1, L, L + 1, N - 1]
    Ms, Cs, Ks = chain_matrices(m, k, c, sparse=True)
    ref = mck_response(Ms, Cs, Ks, F, dt, force_dofs=[L], outputs=outputs, quantities=("x", "a"),
                       scheme=scheme)
    coef = _coefficients(scheme, dt)
    S = Ms + coef["r"] * Cs + coef["p"] * Ks
    kappa = abs(S).sum(axis=1).max() / m.min()  # ||S||_inf ||S^-1||_inf, the latter <= 1/min(m)
    for form in ("displacement", "acceleration"):
        tracemalloc.start()
        try:
            r = chain_response(m, k, c, F, dt, force_dofs=[L], outputs=outputs,
                               quantities=("x", "a"), scheme=scheme, form=form)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert r.x.shape == r.a.shape == (n + 1, len(outputs)) and r.v is None
        assert peak < 100 * N * 8, peak / (8 * N)
        bound = 2 * n * kappa * EPS
        assert rel_error(r.x, ref.x) < bound, (form, rel_error(r.x, ref.x), bound)
        assert rel_error(r.a, ref.a) < bound, (form, rel_error(r.a, ref.a), bound)
    # the wave has not reached the ends: exactly at rest there (implicit schemes couple every
    # mass each step, but the influence decays geometrically and underflows within 50,000 masses)
    assert np.abs(r.x[:, [0, 4]]).max() < 1e-200


# --- 3. a million undamped steps -------------------------------------------------------------
#: (scheme, beta, Omega): gamma = 1/2 schemes, Omega inside the stability limit
#: 1/sqrt(1/4 - beta) (2, 2.449, 2.828, 3.464; average acceleration: any Omega)
CONSERVATIVE = [("average_acceleration", 0.25, 1.0), ("average_acceleration", 0.25, 100.0),
                ("linear_acceleration", 1 / 6, 3.3), ("fox_goodwin", 1 / 12, 2.3),
                ("newmark_1_8", 0.125, 2.7), ("central_difference", 0.0, 1.9)]


def _undamped_run(scheme, dt, n):
    """x, v of m = k = 1 (omega = 1) after a force sample F(t_1) = 1; free from step 2 on."""
    F = np.zeros((n + 1, 1))
    F[1] = 1.0
    if scheme == "central_difference":
        # the DT-TMM acceleration form divides by c Dv = 0 without a damper: use the state-space
        # model of the same scheme and its generated C time loop
        model = discrete_state_space([[1.0]], [[0.0]], [[1.0]], dt, scheme=scheme)
        r = state_space_response(model, F)
        return r.x[:, 0], r.v[:, 0], "state space"
    r = chain_response([1.0], [1.0], [0.0], F, dt, scheme=scheme, quantities=("x", "v"))
    return r.x[:, 0], r.v[:, 0], r.info["backend"]


@pytest.mark.parametrize("scheme, beta, Omega", CONSERVATIVE)
def test_undamped_1e6_steps(scheme, beta, Omega):
    """1,000,000 steps of x'' + x = 0 after a force pulse (Newmark, gamma = 1/2).

    Theory (derived with SymPy for this test; cf. Krenk 2006, CMAME 195): with
    a_n = -omega^2 x_n the step conserves
        E = 1/2 m v^2 + 1/2 k x^2 (1 + (beta - 1/4) Omega^2)
    exactly (the physical energy for average acceleration, a modified one otherwise; positive
    exactly inside the stability limit), and x_j = Re(c lambda^j), lambda = exp(i Omega_bar),
        cos Omega_bar = 1 - Omega^2 / (2 (1 + beta Omega^2)),
    so |lambda| = 1 (the spectral radius must be 1) and the period elongation is
    Omega / Omega_bar - 1 (Omega^2/12 for small Omega, average acceleration).

    Tolerances, n = 1e6 steps:
    - energy drift: rounding changes E by a few eps per step; worst case (all of one sign)
      4 n eps = 8.9e-10 < 1e-9. Measured: 1.8e-13 (average acceleration, Omega = 1; 2.6e-13 at
      100, a random walk ~ sqrt(n) eps), 5.4e-11..9.1e-11 (Fox-Goodwin, 1/8, linear
      acceleration), 1.4e-10 (central difference through its state-space matrix, a product of
      rounded matrices whose eigenvalues sit O(eps) off the unit circle: a drift linear in n).
    - phase: cos Omega_bar is formed by a few rounded operations (|error| <~ 10 eps), which moves
      Omega_bar by 10 eps / sin Omega_bar per step: after n steps the record differs from the
      closed form by <= 10 n eps / sin(Omega_bar) of the amplitude (2.8e-9..6.2e-9, and 5.6e-8
      for average acceleration at Omega = 100 where Omega_bar = pi - 0.02). Measured 1e-10..1e-9.
    - amplitude: the maxima of |x| over the first and the last 10 % (100,000 samples each, the
      phases equidistributed) equal |c| to within the sampling deficit 1 - cos(gap) < 1e-6
      (measured <= 2.7e-10).
    """
    n = 10**6
    st = stability(scheme, [Omega])
    assert abs(st.spectral_radius[0] - 1.0) < 1e-12
    Omega_bar = np.arccos(1 - Omega**2 / (2 * (1 + beta * Omega**2)))
    assert Omega / Omega_bar - 1 == pytest.approx(st.period_elongation[0], rel=1e-10, abs=1e-14)

    x, v, backend = _undamped_run(scheme, Omega, n)
    assert backend in ("c", "state space")
    x, v = x[2:], v[2:]
    E = 0.5 * v**2 + 0.5 * x**2 * (1 + (beta - 0.25) * Omega**2)
    drift = np.abs(E - E[0]).max() / E[0]
    assert drift < 1e-9, drift

    j = np.arange(x.size)
    cr, ci = np.linalg.solve([[1.0, 0.0], [np.cos(Omega_bar), -np.sin(Omega_bar)]], x[:2])
    closed = cr * np.cos(Omega_bar * j) - ci * np.sin(Omega_bar * j)
    amp = np.hypot(cr, ci)
    phase_err = np.abs(x - closed).max() / amp
    assert phase_err < 10 * n * EPS / np.sin(Omega_bar), phase_err

    w = x.size // 10
    first, last = np.abs(x[:w]).max(), np.abs(x[-w:]).max()
    assert first == pytest.approx(amp, rel=1e-6) and last == pytest.approx(amp, rel=1e-6)


# --- 4. dt far above the shortest period -----------------------------------------------------
def _two_dof():
    """Two unit masses, a soft spring to ground (1) and a stiff one between them (1e6):
    omega = 0.707 and 1414 rad/s."""
    M = np.eye(2)
    K = np.array([[1.0 + 1e6, -1e6], [-1e6, 1e6]])
    return M, np.zeros((2, 2)), K


def _decay_factor(q, order):
    """Largest |root| of the linear recurrence q[j+p] = sum_i a_i q[j+p-1-i] fitted (least
    squares) to the sequence: the decay factor per step of a free response."""
    rows = np.array([q[j:j + order][::-1] for j in range(q.size - order)])
    a, *_ = np.linalg.lstsq(rows, q[order:], rcond=None)
    return np.abs(np.roots(np.r_[1.0, -a])).max()


#: nonzero eigenvalues of the amplification matrix (the order of the recurrence q_n obeys)
RECURRENCE_ORDER = {"newmark": 2, "average_acceleration": 2, "fox_euler": 2, "wilson": 3,
                    "hht": 3, "generalized_alpha": 3, "houbolt": 3, "park": 6}


@pytest.mark.parametrize("Omega", [100.0, 1000.0])
@pytest.mark.parametrize("scheme", UNCONDITIONAL)
def test_dt_far_above_shortest_period(scheme, Omega):
    """dt = Omega / omega_2 with Omega = 100, 1000 (Omega_1 = 0.05, 0.5); a force pulse at t_1
    in the shape of mode 2 (M phi_2, so mode 1 is not excited), 300 steps, mck_response.

    The modal displacement q_2 = phi_2' M x of a free response obeys the linear recurrence whose
    roots are the nonzero eigenvalues of the scheme's amplification matrix at Omega; the largest
    |root| fitted to the simulated q_2 (from step 3, after the pulse and the multistep start-up,
    while |q_2| > 1e-20 max |q_2|) is the factor by which the mode's amplitude shrinks per step,
    and must equal `stability(...).spectral_radius`: 1 for average acceleration (the mode is
    kept), (1 + alpha)/(1 - alpha) = 0.905 for HHT, -> rho_inf = 0.8 for generalized-alpha,
    0.048 / 0.010 (Houbolt), 0.149 / 0.061 (Park). Tolerance 1e-6: the fit uses samples >= 1e-20
    of the peak while the rounding floor of q_2 is ~eps^2 of it (mode 1 is only polluted at
    eps); a nearly double root (the principal pair near Omega -> inf) moves by the square root of
    a perturbation, ~1e-8 for eps. Measured <= 9e-9.
    Average acceleration, rho = 1: the modal energy 1/2 (q_2'^2 + omega_2^2 q_2^2) is conserved
    up to rounding. In the acceleration form x_{n+1} = x_pred + beta dt^2 a cancels terms
    ~beta Omega^2 times larger than x, so each step rounds E by ~(1 + beta Omega^2) eps: bound
    4 n (1 + beta Omega^2) eps (6.7e-10 at Omega = 100, 6.7e-8 at 1000); measured 1.1e-12 and
    6.4e-11.
    """
    M, C, K = _two_dof()
    w2, Phi = sla.eigh(K, M)
    omega = np.sqrt(w2)
    dt, n = Omega / omega[1], 300
    F = np.zeros((n + 1, 2))
    F[1] = M @ Phi[:, 1]
    r = mck_response(M, C, K, F, dt, scheme=scheme)
    assert np.all(np.isfinite(r.x)) and np.all(np.isfinite(r.v))
    q = r.x @ M @ Phi[:, 1]
    rho = stability(scheme, [Omega]).spectral_radius[0]
    assert rho <= 1.0 + 1e-12
    live = np.flatnonzero(np.abs(q[3:]) < 1e-20 * np.abs(q).max())
    end = 3 + live[0] if live.size else n + 1
    fitted = _decay_factor(q[3:end], RECURRENCE_ORDER[scheme])
    assert fitted == pytest.approx(rho, rel=1e-6), (fitted, rho)
    if rho == pytest.approx(1.0, abs=1e-12):
        qd = r.v @ M @ Phi[:, 1]
        E = 0.5 * (qd[2:] ** 2 + omega[1] ** 2 * q[2:] ** 2)
        drift = np.abs(E - E[0]).max() / E[0]
        assert drift < 4 * n * (1 + 0.25 * Omega**2) * EPS, drift


# --- 5. overdamped and rigid-body modes ------------------------------------------------------
def _free_free_chain():
    """Four masses joined by springs and dampers, nothing to ground: K and C are singular (rows
    sum to 0), one rigid-body mode; the stiff link (1e6) makes omega_max = 1082 rad/s."""
    m = np.array([1.0, 2.0, 1.5, 0.5])
    links = np.array([1e4, 1e6, 3e3])  # between masses 0-1, 1-2, 2-3
    K = np.zeros((4, 4))
    for i, kl in enumerate(links):
        K[np.ix_([i, i + 1], [i, i + 1])] += kl * np.array([[1.0, -1.0], [-1.0, 1.0]])
    return m, np.diag(m), 1e-3 * K, K


def test_rigid_body_mode_refused_by_modal_filters():
    m, M, C, K = _free_free_chain()
    with pytest.raises(ValueError, match=r"rigid-body mode\(s\) are not supported by the modal "
                                         r"filters: 2 pole\(s\) at s = 0.*add a ground spring"):
        modal_filter_response(M, C, K, np.zeros((10, 1)), 0.001, force_dofs=[0], outputs=[3],
                              quantities=("x",))


def test_overdamped_mode_modal_filters_equal_exact():
    """A mass on a soft spring with a heavy damper (c = 400) at the end of a stiff chain: two
    real poles (-0.25 and -1197 rad/s, a 5,000:1 spread) beside two lightly damped pairs. With
    every mode the ramp invariant is exact for a piecewise-linear force (reference.md sec. 6):
    the only error is the eigen-decomposition's, eps kappa^2 < 1e-8 (modal_model would warn
    otherwise; it must not here). Assert 1e-10 (measured 4e-14..7e-14)."""
    M, C, K = chain_matrices([1.0, 1.0, 0.5], [1e4, 1e4, 1e2], [0.5, 0.5, 400.0], sparse=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DtdynAccuracyWarning)
        model = modal_model(M, C, K, [2], [0, 1, 2])
    real = model.poles[~model.oscillatory].real
    assert real.size == 2 and np.all(model.poles[~model.oscillatory].imag == 0)
    assert real.min() < -1e3 and -1.0 < real.max() < 0.0
    assert model.oscillatory.sum() == 2
    fs, N = 500.0, 5000
    t = np.arange(N) / fs
    f = np.sin(2 * np.pi * 3 * t) * (1 - np.exp(-t))
    f += 0.3 * np.random.default_rng(5).standard_normal(N)
    f[0] = 0.0  # the filters start at rest with x_{-1} = 0
    ex = exact_response(M, C, K, f[:, None], 1 / fs, force_dofs=[2])
    for quantity, key in (("displacement", "x"), ("velocity", "v"), ("acceleration", "a")):
        with warnings.catch_warnings():
            warnings.simplefilter("error", DtdynAccuracyWarning)
            r = modal_filter_response(M, C, K, f[:, None], 1 / fs, force_dofs=[2],
                                      outputs=[0, 1, 2], quantities=(key,))
        err = rel_error(getattr(r, key), getattr(ex, key))
        assert err < 1e-10, (quantity, err)


FREE_FREE_SCHEMES = ["average_acceleration", "fox_goodwin", "hht", "generalized_alpha", "houbolt",
                     "park", "wilson", "fox_euler"]


@pytest.mark.parametrize("scheme", FREE_FREE_SCHEMES)
def test_free_free_chain_constant_force(scheme):
    """Free-free chain (K singular), constant force F = 2 on mass 0 from t = 0, T = 0.5 s.

    Rigid body: the mass-weighted mean x_c = sum m_i x_i / m_total obeys m_total x_c'' = F
    (internal forces cancel), so x_c = F t^2 / (2 m_total). Every scheme here integrates a
    constant acceleration exactly (x1 = x0 + dt v0 + dt^2/2 a for Newmark-type updates; Houbolt
    and Park difference formulas are exact for quadratics; start-up and Wilson too), so x_c
    equals the closed form to rounding. The rigid mode is a double eigenvalue 1: a rounding
    error in the velocity at step j grows linearly, giving a relative error <= c n eps with c
    the size of the scheme's history coefficients (<= 10): assert 10 n eps = 5.6e-12 at n = 2,500
    (measured <= 2.9e-12, Houbolt).
    Vibration part x - x_c: against exact_response (matrix exponential, M nonsingular is all it
    needs) at the scheme's order: the slope of log(error) over dt = 4e-4, 2e-4, 1e-4
    (Omega_max = 0.43 .. 0.11, asymptotic) is the order (1 for Fox-Euler, else 2) within 0.1
    (measured within 0.055).
    """
    m, M, C, K = _free_free_chain()
    assert np.linalg.matrix_rank(K) == 3  # one null direction: the rigid-body mode
    F0, T = 2.0, 0.5
    dts = [4e-4, 2e-4, 1e-4]
    errs = []
    for dt in dts:
        n = int(round(T / dt))
        t = dt * np.arange(n + 1)
        F = np.full((n + 1, 1), F0)
        r = mck_response(M, C, K, F, dt, force_dofs=[0], scheme=scheme, quantities=("x",))
        xc = r.x @ m / m.sum()
        if dt == 2e-4:
            closed = F0 * t**2 / (2 * m.sum())
            assert np.abs(xc - closed).max() / closed.max() < 10 * n * EPS
        ex = exact_response(M, C, K, F, dt, force_dofs=[0])
        vib = r.x - xc[:, None]
        vib_ex = ex.x - (ex.x @ m / m.sum())[:, None]
        errs.append(rel_error(vib, vib_ex))
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    order = TABLE[scheme]["order"]
    assert abs(slope - order) < 0.1, (slope, errs)


# --- 6. a massless DOF in a stiff chain ------------------------------------------------------
def _massless_stiff_chain():
    """Six DOFs: DOF 2 is massless between a stiff spring (1e6, to DOF 1) and a soft one (50, to
    DOF 3), with no damper on either (pure static condensation); c = 1e-4 k elsewhere."""
    m = np.ones(6)
    k = np.array([1e6, 2e5, 1e6, 50.0, 1e6, 1e6])
    c = 1e-4 * k
    c[2] = c[3] = 0.0
    M, C, K = chain_matrices(m, k, c, sparse=False)
    M[2, 2] = 0.0
    return M, C, K


def test_massless_dof_in_stiff_chain():
    """mck_response and discrete_state_space against the condensed model.

    Condensation: the massless DOF j has no damper, so its equation is K_j x = f_j = 0 at every
    instant and every step (each scheme enforces the equilibrium at t_{n+1} for a zero-mass row);
    eliminating x_j = -K_jr x_r / K_jj gives K_red = K_rr - K_rj K_jr / K_jj, M_rr, C_rr: omega
    4.1 .. 1732 rad/s (ratio 424).
    - mck_response = discrete_state_space (+ state_space_response): two paths of one
      recursion, each rounding ~kappa eps per step (kappa = cond(M + Dv C + Dx K) = 10..18),
      without growth (rho = 1): 2 n kappa eps (4.0e-12..8.8e-12); measured 1.2e-12..2.4e-12.
    - the massless DOF sits at its condensed position to rounding (measured 3e-16; assert
      100 eps, the size of one K_j x evaluation).
    - the kept DOFs = exact_response of the reduced nonsingular system at second order
      (average acceleration): slope over dt = 4e-3, 2e-3, 1e-3 in 2 +- 0.1 (measured 2.0000).
    """
    M, C, K = _massless_stiff_chain()
    j, kept = 2, [0, 1, 3, 4, 5]
    K_red = K[np.ix_(kept, kept)] - np.outer(K[kept, j], K[j, kept]) / K[j, j]
    M_red, C_red = M[np.ix_(kept, kept)], C[np.ix_(kept, kept)]
    assert not C[j].any() and not C[:, j].any()
    w = _natural_frequencies(M_red, K_red)
    assert w[-1] / w[0] > 400
    T = 2.0
    dts = [4e-3, 2e-3, 1e-3]
    errs = []
    for dt in dts:
        n = int(round(T / dt))
        t = dt * np.arange(n + 1)
        F = (np.sin(3 * t) * t)[:, None]  # on the free end, zero at t = 0 (consistent with M)
        r = mck_response(M, C, K, F, dt, force_dofs=[5], scheme="average_acceleration")
        model = discrete_state_space(M, C, K, dt, scheme="average_acceleration")
        y = state_space_response(model, F, force_dofs=[5], quantities=("x",)).x
        kappa = _effective_condition(M, C, K, "average_acceleration", dt)
        assert rel_error(y, r.x) < 2 * n * kappa * EPS, rel_error(y, r.x)
        condensed = -(r.x[:, kept] @ K[j, kept]) / K[j, j]
        assert np.abs(r.x[:, j] - condensed).max() < 100 * EPS * np.abs(r.x[:, j]).max()
        ex = exact_response(M_red, C_red, K_red, F, dt, force_dofs=[4])
        errs.append(rel_error(r.x[:, kept], ex.x))
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert abs(slope - 2.0) < 0.1, (slope, errs)


# --- 7. strong nonlinearity ---------------------------------------------------------------------

def _duffing(n=1000):
    """m = 1, k = 400, c = 20 (zeta 0.5 of the linear part), k3 = 1e8: at the 200 N, 2 Hz drive
    the cubic force is ~50x the linear one (peaks 272 N vs 5.6 N; tangent frequency up to ~140
    rad/s vs 20)."""
    M, K, C = np.array([[1.0]]), np.array([[400.0]]), np.array([[20.0]])
    fs = 1000.0
    f = (200.0 * np.sin(2 * np.pi * 2.0 * np.arange(n) / fs))[:, None]
    return M, C, K, f, fs


@pytest.mark.parametrize("method", ["average_acceleration", "modal_ramp", "generalized_alpha"])
def test_strong_hardening_converges_at_second_order(method):
    from dtdyn.nonlinear._elements import Cubic
    from dtdyn.nonlinear._reference import reference_response
    from dtdyn.nonlinear._response import nonlinear_mck_response
    M, C, K, f, fs = _duffing()
    els = [Cubic(0, k3=1e8)]
    ref = reference_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els, cache=False)
    y = ref.x[:, 0]
    assert (1e8 * np.abs(y) ** 3).max() > 40 * (400.0 * np.abs(y)).max()
    errs = [rel_error(nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els,
                                         scheme=method, substeps=S).x, ref.x) for S in (1, 2, 4)]
    # second order: each halving of h divides the error by 4 (+-15 %); first error < 1e-2
    assert errs[0] < 1e-2 and all(3.4 < a / b < 4.6 for a, b in zip(errs, errs[1:])), errs


def test_stiff_contact_at_large_step():
    """A contact 1e4 times stiffer than the structure (Omega_contact = 10 at fs): impacts make the
    time history itself sensitive (errors of the impact times accumulate: the max error over time
    stays O(1) at every step size), so the checks are the ones theory gives: every scheme stays
    bounded (below the no-contact static deflection F/k = 0.1 m), the largest displacement (gap +
    penetration) matches the reference within 1 % once sub-steps resolve the contact
    (Omega_contact <= 0.6), and the modal ramp method refuses the unresolved step (beyond its
    stability limit) and runs with the sub-steps it asks for."""
    import re

    from dtdyn.nonlinear._elements import Gap
    from dtdyn.nonlinear._reference import reference_response
    from dtdyn.nonlinear._response import DtdynStepStabilityError, nonlinear_mck_response
    M, K, C = np.array([[1.0]]), np.array([[1e4]]), np.array([[2.0]])
    fs, n = 1000.0, 1000
    f = (1e3 * np.sin(2 * np.pi * 5 * np.arange(n) / fs))[:, None]
    els = [Gap(0, gap=1e-2, stiffness=1e8)]
    peak = np.abs(reference_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els,
                                     cache=False).x).max()
    for method in ("average_acceleration", "generalized_alpha"):
        coarse = nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els,
                                        scheme=method)
        assert np.isfinite(coarse.x).all() and np.abs(coarse.x).max() < 0.1
        fine = nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els,
                                      scheme=method, substeps=16)
        assert abs(np.abs(fine.x).max() - peak) <= 1e-2 * peak
    with pytest.raises(DtdynStepStabilityError, match=r"substeps >= \d+") as err:
        nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els,
                               scheme="modal_ramp")
    need = int(re.search(r"substeps >= (\d+)", str(err.value)).group(1))
    assert need > 1
    # resolved: Omega_contact = 10 / S <= 0.6 from 17 sub-steps (0.02 % to 0.55 % at 17 to 32
    # measured); at the 6 = 2 need that had been used here (Omega 1.7) the peak moved with the
    # rounding of the modal loop: 0.2 %, then 1.4 % with its fused products
    r = nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els,
                               scheme="modal_ramp", substeps=max(2 * need, 17))
    assert abs(np.abs(r.x).max() - peak) <= 1e-2 * peak
