"""DT-TMM chains against the assembled-matrix solution of the same scheme (reference sec. 3).

Both solve the same linear system each step (a tridiagonal one), so they agree to rounding: 1e-10
relative, both forms, every implicit scheme, dt = 1e-2 .. 1e-5. The reference (`mck_response`)
works in the acceleration form. The displacement form's unknown is the increment
u = x_e - x_n (dtdyn.derive.dttmm): with x_e itself, a = A x_e + B with A = 1/(beta dt^2) is a
difference of terms of size |x| / dt^2, and its rounding cost up to 5.7e-10 in x here (P3,
Park; benchmarks/dttmm_vs_mck.py at commit 99ff3e0); in the increment the terms are of size
|v| / dt. Measured now (docs/dttmm_accuracy.md): at most 5.1e-11 over x, v, a (Houbolt, whose
absolute-x recursion has a double root at z = 1 and rounds a little worse in both forms).
"""
import warnings

import numpy as np
import pytest

from dtdyn.linear._chain import DtdynAccuracyWarning, chain_matrices, chain_response
from dtdyn.linear._mck import mck_response
from dtdyn.generated.scheme_table import TABLE  # the built-in schemes, in order

from problems import P1, P2, P3, PROBLEMS, rel_error, uniform_chain

TOL = 1e-10
IMPLICIT = [s for s in TABLE if s != "central_difference"]


def _run_both(prob, dt, n_steps, scheme, forms=("displacement", "acceleration"),
              backends=("c", "numpy"), **kw):
    F = np.ones((n_steps + 1, 1))
    M, C, K = chain_matrices(prob["mass"], prob["stiffness"], prob["damping"])
    ref = mck_response(M, C, K, F, dt, force_dofs=prob["force_dofs"], scheme=scheme, **kw)
    for form in forms:
        for backend in backends:
            r = chain_response(prob["mass"], prob["stiffness"], prob["damping"], F, dt,
                               force_dofs=prob["force_dofs"], scheme=scheme, form=form,
                               backend=backend, **kw)
            for q in "xva":
                err = rel_error(getattr(r, q), getattr(ref, q))
                assert err < TOL, (scheme, form, backend, dt, q, err)


@pytest.mark.parametrize("scheme", IMPLICIT)
@pytest.mark.parametrize("name", ["P1", "P2", "P3"])
@pytest.mark.parametrize("dt", [1e-2, 1e-3, 1e-4, 1e-5])
def test_reference_problems_equal_assembled(name, dt, scheme):
    prob = PROBLEMS[name]
    # the full duration where it is at most 3,000 steps, else the first 3,000 steps
    n_steps = min(int(round(prob["T"] / dt)), 3000)
    _run_both(prob, dt, n_steps, scheme)


def test_central_difference_acceleration_form():
    prob = dict(P2)
    _run_both(prob, 1e-3, 3000, "central_difference", forms=("acceleration",))


def test_parameterised_schemes():
    for scheme, kw in (("newmark", dict(beta=0.3, gamma=0.6)), ("wilson", dict(theta=1.37)),
                       ("hht", dict(alpha=-0.3)), ("generalized_alpha", dict(rho_inf=0.3))):
        _run_both(P2, 1e-2, 1000, scheme, **kw)


@pytest.mark.parametrize("n_mass, backends", [(1000, ("c", "numpy")),
                                             pytest.param(100_000, ("c", "numpy"),
                                                          marks=pytest.mark.slow)])
def test_long_uniform_chain(n_mass, backends):
    prob = uniform_chain(n_mass)
    dt, n_steps = 1e-4, 1000
    F = np.ones((n_steps + 1, 1))
    outputs = np.unique(np.r_[0, n_mass // 2, np.arange(n_mass - 50, n_mass)])
    M, C, K = chain_matrices(prob["mass"], prob["stiffness"], prob["damping"], sparse=True)
    ref = mck_response(M, C, K, F, dt, force_dofs=prob["force_dofs"], scheme="newmark",
                       outputs=outputs, quantities=("x",))
    for form in ("displacement", "acceleration"):
        for backend in backends:
            r = chain_response(prob["mass"], prob["stiffness"], prob["damping"], F, dt,
                               force_dofs=prob["force_dofs"], outputs=outputs, form=form,
                               backend=backend, quantities=("x",))
            assert r.x.shape == (n_steps + 1, outputs.size)
            assert r.v is None and r.a is None
            assert rel_error(r.x, ref.x) < TOL, (form, backend)


def _plain_vs_stable(prob, dt, n_steps):
    F = np.ones((n_steps + 1, 1))
    args = (prob["mass"], prob["stiffness"], prob["damping"], F, dt)
    stable = chain_response(*args, force_dofs=prob["force_dofs"], scheme="average_acceleration")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plain = chain_response(*args, force_dofs=prob["force_dofs"], scheme="average_acceleration",
                               sweep="plain")
    warned = [w for w in caught if issubclass(w.category, DtdynAccuracyWarning)]
    return rel_error(plain.x, stable.x), plain.info["error_estimate"], warned


def test_plain_sweep_fine_on_short_chain():
    err, est, warned = _plain_vs_stable(uniform_chain(2), 1e-3, 500)
    assert err < 1e-9 and est < 1e-9 and not warned


@pytest.mark.parametrize("n_mass", [3, 4, 5])
def test_plain_sweep_error_estimate(n_mass):
    """The estimate (each step's rounding error carried on through the scheme, derive/dttmm.py)
    tracks the real error: measured est / err 1.1, 1.9, 1.5 for 3, 4, 5 masses."""
    err, est, warned = _plain_vs_stable(uniform_chain(n_mass), 1e-3, 500)
    assert 0.1 < est / err < 10
    assert bool(warned) == (est > 1e-6)


@pytest.mark.parametrize("n_mass, at_least", [(10, 1e10), (15, 1e30)])
def test_plain_sweep_fails_as_measured(n_mass, at_least):
    """reference.md sec. 3: m = 1, k = 1e4, c = 1, dt = 1e-3 gives 1e17 (N = 10), 1e40 (N = 15);
    with the increment unknown (dtdyn.derive.dttmm) 2e54 and 3e111."""
    err, est, warned = _plain_vs_stable(uniform_chain(n_mass), 1e-3, 500)
    assert err > at_least
    assert warned and "sweep='stable'" in str(warned[0].message)
    assert est > 1.0  # the computed x is then mostly rounding error (measured: inf for both)


def test_plain_sweep_fails_on_p3():
    """reference.md sec. 3: P3 with dt = 1e-2 gives 37 % error; dt = 5e-3 gives 1e27. (Those
    were measured with the source's unknown x_n+1; with the increment x_n+1 - x_n of
    dtdyn.derive.dttmm each step's sweep error adds up in x: 6.9 and 4e30 here.)"""
    err, est, warned = _plain_vs_stable(P3, 1e-2, 80)
    assert err > 0.05 and warned
    err, est, warned = _plain_vs_stable(P3, 5e-3, 160)
    assert err > 1e20 and warned


def test_initial_acceleration_and_startup():
    """A step force at t_0 gives a_0 = F/m; multistep schemes still converge at order 2."""
    r = chain_response(P1["mass"], P1["stiffness"], P1["damping"], np.ones((11, 1)), 0.01,
                       scheme="houbolt")
    assert r.a[0, 0] == pytest.approx(0.5)
    assert r.x[0, 0] == 0.0 and r.v[0, 0] == 0.0


def test_only_loaded_columns_and_requested_outputs():
    prob = uniform_chain(50)
    F = np.random.default_rng(1).standard_normal((101, 2))
    r = chain_response(prob["mass"], prob["stiffness"], prob["damping"], F, 1e-3,
                       force_dofs=[3, 40], outputs=[7], quantities=("v",))
    assert r.v.shape == (101, 1) and r.x is None and r.a is None
    full = np.zeros((101, 50))
    full[:, [3, 40]] = F
    r2 = chain_response(prob["mass"], prob["stiffness"], prob["damping"], full, 1e-3)
    np.testing.assert_allclose(r.v[:, 0], r2.v[:, 7], rtol=1e-13, atol=1e-300)


@pytest.mark.parametrize("force_dofs", [[0], [699, 0, 256, 255, 511, 512], list(range(0, 700, 7))])
@pytest.mark.parametrize("grounded", [False, True])
def test_block_kernel_loads_at_block_edges(force_dofs, grounded):
    """The C stable sweep works in blocks of 256 masses and, when fewer than N / 8 masses are
    loaded, skips the force row and redoes the loaded masses: loads on the first mass, on
    both sides of block edges, in any order, and on every seventh mass (the full force row):
    equal to mck_response on the assembled matrices (the module's TOL)."""
    rng = np.random.default_rng(11)
    n = 700
    m, k, c = rng.uniform(0.5, 2.0, n), rng.uniform(1e3, 1e5, n), rng.uniform(0.0, 2.0, n)
    kg = rng.uniform(0.0, 1e3, n) if grounded else None
    F = rng.standard_normal((301, len(force_dofs)))
    M, C, K = chain_matrices(m, k, c, ground_stiffness=kg)
    ref = mck_response(M, C, K, F, 1e-3, force_dofs=force_dofs, scheme="hht")
    for form in ("displacement", "acceleration"):
        r = chain_response(m, k, c, F, 1e-3, force_dofs=force_dofs, scheme="hht", form=form,
                           ground_stiffness=kg)
        for q in "xva":
            assert rel_error(getattr(r, q), getattr(ref, q)) < TOL, (form, q)


def _newmark_extended(m, k, c, F, dofs, dt, beta=0.25, gamma=0.5):
    """Newmark's scheme on the chain in numpy.longdouble (64-bit mantissa on x86): each step's
    tridiagonal system (M + gamma dt C + beta dt^2 K) a = f - C v_p - K x_p solved by Thomas'
    algorithm. Independent of the sweep: the assembled matrices' rows, written out here."""
    L = np.longdouble
    N = len(m)
    m, k, c = (np.asarray(a, dtype=L) for a in (m, k, c))
    dt, beta, gamma = L(dt), L(beta), L(gamma)

    def band(e):  # station n joins mass n to mass n - 1 (station 0 to the ground)
        return e + np.append(e[1:], L(0)), -e[1:]

    (Kd, Ks), (Cd, Cs) = band(k), band(c)

    def apply(d, s, x):
        y = d * x
        y[1:] += s * x[:-1]
        y[:-1] += s * x[1:]
        return y

    Ad, As = m + gamma * dt * Cd + beta * dt * dt * Kd, gamma * dt * Cs + beta * dt * dt * Ks
    piv, low = Ad.copy(), np.zeros(N - 1, dtype=L)
    for i in range(1, N):
        low[i - 1] = As[i - 1] / piv[i - 1]
        piv[i] -= low[i - 1] * As[i - 1]

    def solve(r):
        for i in range(1, N):
            r[i] -= low[i - 1] * r[i - 1]
        r[-1] /= piv[-1]
        for i in range(N - 2, -1, -1):
            r[i] = (r[i] - As[i] * r[i + 1]) / piv[i]
        return r

    def force(n):
        f = np.zeros(N, dtype=L)
        f[dofs] = np.asarray(F[n], dtype=L)
        return f

    x, v, a = np.zeros(N, dtype=L), np.zeros(N, dtype=L), force(0) / m
    xs = [x.copy()]
    for n in range(len(F) - 1):
        xp, vp = x + dt * v + (L(0.5) - beta) * dt * dt * a, v + (1 - gamma) * dt * a
        a = solve(force(n + 1) - apply(Cd, Cs, vp) - apply(Kd, Ks, xp))
        x, v = xp + beta * dt * dt * a, vp + gamma * dt * a
        xs.append(x.copy())
    return np.array(xs, dtype=float)


@pytest.mark.skipif(np.finfo(np.longdouble).eps > 1e-18, reason="no extended precision")
def test_stiff_chain_against_extended_precision():
    """Stiff stations at a large dt (kappa / mu = 2.5e7, every g within 1e-7 of 1), against the
    same scheme in extended precision: measured 5.7e-12 (displacement form) and 1.5e-11
    (acceleration form), both backends. The bound 1e-10 keeps a factor 6 and fails the form
    h = Delta + g ((F - beta) - Delta), equal to the kernels' but cancelling where g is close
    to 1: it reached 1.8e-9 to 2.3e-9 here in the acceleration form."""
    rng = np.random.default_rng(1)
    N, dt = 500, 1e-2
    m, k, c = 1 + 0.1 * rng.random(N), 1e12 * (1 + 0.1 * rng.random(N)), np.ones(N)
    F = rng.standard_normal((201, 3))
    dofs = [N // 3, N // 2, N - 1]
    ref = _newmark_extended(m, k, c, F, dofs, dt)
    for form in ("displacement", "acceleration"):
        for backend in ("c", "numpy"):
            r = chain_response(m, k, c, F, dt, force_dofs=dofs, form=form, backend=backend,
                               quantities=("x",))
            err = np.max(np.abs(r.x - ref)) / np.max(np.abs(ref))
            assert err < 1e-10, (form, backend, err)


@pytest.mark.parametrize("scheme", list(TABLE))
def test_two_threads_equal_one(scheme):
    """workers=2 splits the stable sweep in two parts (the lower part's b corrected by the
    upper part's R, the upper part's forward pass started from the lower part's u): the same
    solution, only the order of its sums changed. Chains of 2, 7 and 700 masses (the split at
    every size, a few loaded masses and every mass loaded, with and without ground springs),
    both forms: at most 1e-11 apart (measured: at most 2.6e-14, but 2.4e-13 for Houbolt, whose
    recursion amplifies rounding: the two backends differ by 1.1e-12 on it, docs/chain_speed.md),
    and each within TOL of the assembled solution."""
    rng = np.random.default_rng(7)
    forms = ("acceleration",) if scheme == "central_difference" else ("displacement",
                                                                      "acceleration")
    for N, all_loaded in ((2, True), (7, False), (700, False), (700, True)):
        m, k, c = 1 + rng.random(N), 1e4 * (1 + rng.random(N)), 1 + rng.random(N)
        dofs = list(range(N)) if all_loaded else sorted({0, N // 2, N - 1})
        F = rng.standard_normal((401, len(dofs)))
        for kg in (None, 1e2 * rng.random(N)):
            ref = mck_response(*chain_matrices(m, k, c, ground_stiffness=kg), F, 1e-3,
                               force_dofs=dofs, scheme=scheme)
            for form in forms:
                kw = dict(force_dofs=dofs, scheme=scheme, form=form, ground_stiffness=kg)
                one = chain_response(m, k, c, F, 1e-3, workers=1, **kw)
                two = chain_response(m, k, c, F, 1e-3, workers=2, **kw)
                assert one.info["workers"] == 1 and two.info["workers"] == 2
                for q in "xva":
                    a, b = getattr(one, q), getattr(two, q)
                    assert rel_error(b, a) < 1e-11, (N, form, q, rel_error(b, a))
                    assert rel_error(b, getattr(ref, q)) < TOL, (N, form, q)


def test_workers_default_and_checks(monkeypatch):
    from dtdyn.linear._chain import SPLIT_MASSES, sweep_threads

    monkeypatch.delenv("DTDYN_THREADS", raising=False)
    monkeypatch.setattr("os.sched_getaffinity", lambda pid: {0, 1, 2, 3}, raising=False)
    assert sweep_threads(None, SPLIT_MASSES) == 2 and sweep_threads(None, SPLIT_MASSES - 1) == 1
    assert sweep_threads(5, 10) == 2 and sweep_threads(1, 10 ** 6) == 1
    monkeypatch.setenv("DTDYN_THREADS", "1")
    assert sweep_threads(None, 10 ** 6) == 1
    monkeypatch.setenv("DTDYN_THREADS", "two")
    with pytest.raises(ValueError, match="DTDYN_THREADS = 'two'"):
        sweep_threads(None, 10 ** 6)
    for bad in (0, 1.5, True, "2"):
        with pytest.raises(ValueError, match="workers = "):
            sweep_threads(bad, 10)
    r = chain_response([1.0, 2.0], [10.0, 20.0], [0.1, 0.1], np.ones(11), 0.01, force_dofs=[1],
                       workers=2, backend="numpy")
    assert r.info["workers"] == 1   # the NumPy backend runs on one thread
