"""Tests of dtdyn.linear._discretize against scipy.signal.cont2discrete and exact_response."""
from __future__ import annotations

import sys
import warnings

import numpy as np
import pytest
import scipy.signal
import scipy.sparse

from dtdyn.linear._discrete_model import DiscreteModel
from dtdyn.linear._discretize import discretize, first_order_form
from dtdyn.linear._exact import exact_response

SIZES = (1, 3, 10)
HOLDS = ("zoh", "foh", "impulse", "tustin", "bilinear")
SCIPY_METHOD = {"zoh": "zoh", "foh": "foh", "impulse": "impulse", "tustin": "bilinear",
                "bilinear": "bilinear"}
DT = 0.05


def spd(rng, n, scale=1.0):
    X = rng.standard_normal((n, n))
    return scale * (X @ X.T / n + np.eye(n))


def system(n, seed=0):
    """Random SPD M, K and a non-proportional SPD C (natural frequencies of order 1..10 rad/s)."""
    rng = np.random.default_rng(seed + 100 * n)
    M = spd(rng, n)
    K = spd(rng, n, 20.0)
    C = 0.02 * M + 0.01 * K + spd(rng, n, 0.05)
    return M, C, K


def assert_rel(actual, desired, tol, what=""):
    """Norm-wise relative agreement; an all-zero reference must be matched exactly."""
    actual, desired = np.asarray(actual), np.asarray(desired)
    assert actual.shape == desired.shape, (what, actual.shape, desired.shape)
    ref = np.linalg.norm(desired)
    err = np.linalg.norm(actual - desired)
    assert err <= tol * ref if ref > 0 else err == 0.0, f"{what}: error {err:.3e}, norm {ref:.3e}"


def simulate(Ad, Bd, Cd, Dd, f, x0):
    """x_{n+1} = Ad x_n + Bd f_n, y_n = Cd x_n + Dd f_n; returns y of shape (len(f), rows of Cd)."""
    x = x0.copy()
    y = np.empty((f.shape[0], Cd.shape[0]))
    for n in range(f.shape[0]):
        y[n] = Cd @ x + Dd @ f[n]
        x = Ad @ x + Bd @ f[n]
    return y


def freq_response(Ad, Bd, Cd, Dd, z):
    """H(z) = Cd (z I - Ad)^{-1} Bd + Dd."""
    return Cd @ np.linalg.solve(z * np.eye(Ad.shape[0]) - Ad, Bd) + Dd


# ------------------------------------------------------------- first-order form
@pytest.mark.parametrize("n", SIZES)
def test_first_order_form_blocks(n):
    M, C, K = system(n)
    A, B = first_order_form(M, C, K)
    Minv = np.linalg.inv(M)
    Z, I = np.zeros((n, n)), np.eye(n)
    assert_rel(A, np.block([[Z, I], [-Minv @ K, -Minv @ C]]), 1e-12, "A")
    assert_rel(B, np.vstack([Z, Minv]), 1e-12, "B")


def test_first_order_form_lu_paths_and_sparse():
    rng = np.random.default_rng(7)
    n = 4
    _, C, K = system(n)
    Minv_ref = None
    for M in (spd(rng, n) + 0.3 * rng.standard_normal((n, n)),       # non-symmetric: LU
              np.diag([2.0, -1.0, 3.0, 1.5])):                         # symmetric indefinite: LU
        A, B = first_order_form(M, C, K)
        Minv_ref = np.linalg.inv(M)
        assert_rel(A[n:, :n], -Minv_ref @ K, 1e-12, "A21")
        assert_rel(A[n:, n:], -Minv_ref @ C, 1e-12, "A22")
        assert_rel(B[n:], Minv_ref, 1e-12, "B2")
    M, C, K = system(n)
    dense = first_order_form(M, C, K)
    sparse = first_order_form(scipy.sparse.csr_matrix(M), scipy.sparse.csc_array(C),
                              scipy.sparse.coo_matrix(K))
    for a, b in zip(dense, sparse):
        np.testing.assert_array_equal(a, b)


# ------------------------------------------------------------- equality with cont2discrete
@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("hold", HOLDS)
def test_matches_cont2discrete(hold, n):
    M, C, K = system(n)
    A, B = first_order_form(M, C, K)
    ns = 2 * n
    ref = scipy.signal.cont2discrete((A, B, np.eye(ns), np.zeros((ns, n))), DT,
                                     method=SCIPY_METHOD[hold])
    assert ref[4] == DT
    ours = discretize(M, C, K, DT, hold=hold)
    assert len(ours) == 4
    for name, a, b in zip(("Ad", "Bd", "Cd", "Dd"), ours, ref[:4]):
        assert isinstance(a, np.ndarray) and a.dtype == float
        assert_rel(a, b, 1e-12, f"{hold} {name}")


def test_default_hold_is_zoh_and_hold_case_insensitive():
    M, C, K = system(3)
    zoh = discretize(M, C, K, DT)
    for a, b in zip(zoh, discretize(M, C, K, DT, hold="ZOH")):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(discretize(M, C, K, DT, "tustin"), discretize(M, C, K, DT, "bilinear")):
        np.testing.assert_array_equal(a, b)


# ------------------------------------------------------------- responses vs exact_response
@pytest.mark.parametrize("n", SIZES)
def test_foh_response_equals_exact(n):
    M, C, K = system(n)
    rng = np.random.default_rng(3 + n)
    n_steps = 200
    f = rng.standard_normal((n_steps + 1, n))          # piecewise-linear force samples
    q0, v0 = rng.standard_normal(n), rng.standard_normal(n)
    ex = exact_response(M, C, K, f, DT, x0=q0, v0=v0)

    Ad, Bd, Cd, Dd = discretize(M, C, K, DT, hold="foh")
    z0 = np.concatenate([q0, v0])
    x0 = np.linalg.solve(Cd, z0 - Dd @ f[0])            # foh state x_n = z_n - Gamma_2 f_n
    y = simulate(Ad, Bd, Cd, Dd, f, x0)
    ref = np.hstack([ex.x, ex.v])
    err = np.max(np.abs(y - ref)) / np.max(np.abs(ref))
    assert err <= 1e-10, err


@pytest.mark.parametrize("n", (1, 3))
def test_zoh_response_to_constant_force_equals_exact(n):
    M, C, K = system(n)
    n_steps = 100
    f = np.tile(np.linspace(1.0, 2.0, n), (n_steps + 1, 1))   # constant: zoh == foh exactly
    ex = exact_response(M, C, K, f, DT)
    y = simulate(*discretize(M, C, K, DT, "zoh"), f, np.zeros(2 * n))
    ref = np.hstack([ex.x, ex.v])
    assert np.max(np.abs(y - ref)) <= 1e-10 * np.max(np.abs(ref))


@pytest.mark.parametrize("n", (1, 3))
def test_impulse_response_is_dt_times_sampled_impulse_response(n):
    """scipy's convention: discrete unit-pulse response = dt * e^{A t_k} B, from k = 0."""
    M, C, K = system(n)
    n_steps = 80
    Ad, Bd, Cd, Dd = discretize(M, C, K, DT, "impulse")
    j = n - 1
    f = np.zeros((n_steps + 1, n))
    f[0, j] = 1.0
    y = simulate(Ad, Bd, Cd, Dd, f, np.zeros(2 * n))
    # continuous impulse on DOF j = free response from q = 0, q' = M^{-1} e_j
    v0 = np.linalg.solve(M, np.eye(n)[j])
    ex = exact_response(M, C, K, np.zeros((n_steps + 1, n)), DT, v0=v0)
    ref = DT * np.hstack([ex.x, ex.v])
    assert np.max(np.abs(y - ref)) <= 1e-10 * np.max(np.abs(ref))


# ------------------------------------------------------------- tustin transfer function
@pytest.mark.parametrize("n", SIZES)
def test_tustin_transfer_function(n):
    M, C, K = system(n)
    A, B = first_order_form(M, C, K)
    ns = 2 * n
    ref = scipy.signal.cont2discrete((A, B, np.eye(ns), np.zeros((ns, n))), DT, method="bilinear")
    ours = discretize(M, C, K, DT, "tustin")
    for w in (0.1, 1.0, 5.0, 30.0):                      # rad/s, below Nyquist (62.8 rad/s)
        z = np.exp(1j * w * DT)
        H = freq_response(*ours, z)
        assert_rel(H, freq_response(*ref[:4], z), 1e-10, f"w={w}")
        s = 2.0 / DT * (z - 1.0) / (z + 1.0)             # Tustin map of the continuous H(s)
        assert_rel(H, np.linalg.solve(s * np.eye(ns) - A, B), 1e-10, f"H(s) w={w}")


@pytest.mark.parametrize("n", (1, 3))
def test_tustin_dlti_freqresp_siso(n):
    """Same check through scipy's dlti.freqresp, one (output, input) pair at a time."""
    M, C, K = system(n)
    A, B = first_order_form(M, C, K)
    ns = 2 * n
    ref = scipy.signal.cont2discrete((A, B, np.eye(ns), np.zeros((ns, n))), DT, method="bilinear")
    Ad, Bd, Cd, Dd = discretize(M, C, K, DT, "bilinear")
    w = np.array([0.2, 2.0, 8.0, 20.0]) * DT            # rad/sample
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", scipy.signal.BadCoefficients)
        for i, j in ((0, 0), (ns - 1, n - 1), (n, 0)):
            sl = (slice(None), slice(j, j + 1))
            ours = DiscreteModel(Ad, Bd[sl], Cd[i:i + 1], Dd[i:i + 1, j:j + 1], DT).to_dlti()
            theirs = scipy.signal.dlti(ref[0], ref[1][sl], ref[2][i:i + 1],
                                       ref[3][i:i + 1, j:j + 1], dt=DT)
            _, h1 = ours.freqresp(w=w)
            _, h2 = theirs.freqresp(w=w)
            assert_rel(h1, h2, 1e-8, f"({i}, {j})")


# ------------------------------------------------------------- errors
def test_singular_mass():
    _, C, K = system(3)
    for M in (np.zeros((3, 3)), np.diag([1.0, 0.0, 2.0]), np.ones((3, 3))):
        with pytest.raises(ValueError, match="^M is singular.*invertible mass matrix"):
            first_order_form(M, C, K)
        with pytest.raises(ValueError, match="^M is singular"):
            discretize(M, C, K, DT)


@pytest.mark.parametrize("which", (0, 1, 2))
def test_bad_matrices_name_the_argument(which):
    name = "MCK"[which]
    good = list(system(3))
    cases = [
        (np.ones((3, 2)), "non-empty square"),              # non-square
        (np.ones(3), "non-empty square"),                   # 1-D
        (np.zeros((0, 0)), "non-empty square"),             # empty
        ([["a", "b"], ["c", "d"]], "numeric"),              # not numeric
    ]
    if which:                                               # size mismatch with M
        cases.append((np.eye(2), "expected \\(3, 3\\) to match M"))
    for bad, msg in cases:
        args = list(good)
        args[which] = bad
        with pytest.raises(ValueError, match=f"^{name} .*{msg}"):
            first_order_form(*args)
        with pytest.raises(ValueError, match=f"^{name} "):
            discretize(*args, DT, "foh")
    for value in (np.nan, np.inf):
        args = [a.copy() for a in good]
        args[which][1, 2] = value
        with pytest.raises(ValueError, match=rf"^{name}\[1, 2\] = .*finite"):
            discretize(*args, DT)


def test_mismatched_m_and_c_names_c():
    M, C, K = system(3)
    with pytest.raises(ValueError, match="^C has shape"):
        discretize(np.eye(4), C, K, DT)


@pytest.mark.parametrize("dt", (0.0, -0.1, np.nan, np.inf, "x", None))
def test_bad_dt(dt):
    M, C, K = system(1)
    with pytest.raises(ValueError, match="^dt "):
        discretize(M, C, K, dt)
    with pytest.raises(ValueError, match="^dt "):
        DiscreteModel(*discretize(M, C, K, DT), dt)


@pytest.mark.parametrize("hold", ("euler", "gbt", "backward_diff", "", None, 1))
def test_unknown_hold(hold):
    M, C, K = system(1)
    with pytest.raises(ValueError, match="^hold must be one of"):
        discretize(M, C, K, DT, hold=hold)


# ------------------------------------------------------------- wrappers
def test_to_dlti():
    M, C, K = system(3)
    model = discretize(M, C, K, DT, "foh")
    Ad, Bd, Cd, Dd = model
    sys_d = model.to_dlti()
    assert isinstance(sys_d, scipy.signal.dlti)
    assert isinstance(sys_d, scipy.signal.StateSpace)
    assert sys_d.dt == DT
    for a, b in zip((sys_d.A, sys_d.B, sys_d.C, sys_d.D), (Ad, Bd, Cd, Dd)):
        np.testing.assert_array_equal(a, b)
    rng = np.random.default_rng(11)
    f = rng.standard_normal((50, 3))
    x0 = rng.standard_normal(6)
    _, y, _ = scipy.signal.dlsim(sys_d, f, x0=x0)
    np.testing.assert_allclose(y, simulate(Ad, Bd, Cd, Dd, f, x0), rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="^D has shape"):
        DiscreteModel(Ad, Bd, Cd, Dd[:, :2], DT)
    with pytest.raises(ValueError, match="^B has"):
        DiscreteModel(Ad, Bd[:5], Cd, Dd, DT)


def test_to_control_missing_package(monkeypatch):
    monkeypatch.setitem(sys.modules, "control", None)        # import control -> ImportError
    M, C, K = system(1)
    with pytest.raises(ImportError, match="pip install control"):
        discretize(M, C, K, DT).to_control()


def test_to_control():
    control = pytest.importorskip("control")
    M, C, K = system(3)
    model = discretize(M, C, K, DT, "zoh")
    Ad, Bd, Cd, Dd = model
    sys_c = model.to_control()
    assert isinstance(sys_c, control.StateSpace)
    assert sys_c.dt == DT and control.isdtime(sys_c, strict=True)
    for a, b in zip((sys_c.A, sys_c.B, sys_c.C, sys_c.D), (Ad, Bd, Cd, Dd)):
        np.testing.assert_allclose(np.asarray(a), b, rtol=0, atol=0)
    z = np.exp(1j * 1.0 * DT)
    np.testing.assert_allclose(np.asarray(sys_c(z)), freq_response(Ad, Bd, Cd, Dd, z), rtol=1e-12)


def test_runtime_module_avoids_sympy_and_jinja2():
    import subprocess
    code = ("import sys; sys.modules['sympy'] = None; sys.modules['jinja2'] = None; "
            "import dtdyn.linear._discretize")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
