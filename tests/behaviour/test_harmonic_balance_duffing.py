"""The Duffing oscillator of issue 31 by harmonic balance against periodic orbits by shooting.

x'' + 0.02 x' + x + 0.5 x^3 = F cos(omega t) (m = 1, c = 0.02, k = 1, ``Cubic(0, k3=0.5)``) for
F = 0.1, 0.3 and 1, each curve continued from 0.15 to 1.2 Hz: from just below the linear natural
frequency (0.159 Hz) to above the jump-down fold at F = 1 (0.891 Hz), so it holds the primary
resonance and both folds at every force. Below 0.15 Hz the orbit's higher harmonics grow (at
F = 1 the 9th+ harmonics are 1e-5 of the amplitude at 0.1 Hz, and the superharmonic resonance
near 0.069 Hz needs 23 harmonics for 1e-6; benchmarks/duffing_shooting.py).

The truth: shooting, solve_ivp DOP853 at rtol 1e-12 over one period with the variational
equations, Newton on the period map (its Jacobian the monodromy matrix Phi, whose eigenvalues
are the Floquet multipliers), started from the curve's orbit; the shooting orbit's Fourier
coefficients from 64 samples of its dense output; folds by Newton on the augmented system
P(z0, omega) - z0 = 0, det(Phi - I) = 0 in z0 and omega.

What holds (measured by benchmarks/duffing_shooting.py at every point of the curves):

- the curve's 8 harmonics 0 .. 7 equal the shooting orbit's, sum |dX_k| / x_max <= 2.1e-8,
  1.1e-7, 1.9e-7 at F = 0.1, 0.3, 1 (the Galerkin error of the kept harmonics, of higher order
  than the truncation), including the points within 1 % of each fold;
- the whole orbit x(t) cannot be closer to the truth than the harmonics it drops, the shooting
  orbit's 9th and higher: 9.5e-7, 2.3e-6, 3.2e-6 of the amplitude at F = 0.1, 0.3, 1 (at the
  upper fold); the whole orbit's error equals that. So 1e-6 of the whole orbit holds at F = 0.1
  only; with 9 harmonics it holds at every force (1.3e-7 at F = 1);
- the stable flags equal max |multiplier| < 1 at every point farther than 1e-4 (relative) from
  a fold, and Hill's multipliers equal the monodromy's to 3.4e-8;
- the fold frequencies equal shooting's to 1.1e-9 (the issue asks for 1e-5).

At a fixed frequency within ~1e-5 of a fold the amplitude moves as the square root of the
distance, so the fold's own shift (1e-9) becomes 1e-6 of the amplitude 2e-6 from the fold, and
the stability label flips at the fold: the points checked here are farther than 1e-4 from the
folds (and the folds themselves are checked by their frequency).
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import dtdyn as dd

C, K3 = 0.02, 0.5
FORCES = (0.1, 0.3, 1.0)
RANGE = (0.15, 1.2)
#: about 280 points per curve, so that points within 1 % of each fold lie on both its sides
MAX_STEP = 0.02
#: points this close to a fold frequency (relative) are not compared at a fixed frequency
NEAR_FOLD = 1e-4
RTOL, ATOL = 1e-12, 1e-13
N_FFT = 64          # harmonics above 32 are below 1e-20 of the amplitude here: no aliasing


# ----------------------------------------------------------------------------------------------
# shooting (also used by benchmarks/duffing_shooting.py)


def _rhs(F, w, sensitivity):
    """x, v, Phi (row by row) and, with ``sensitivity``, d(x, v)/d omega."""
    def rhs(t, y):
        x, v, p11, p12, p21, p22 = y[:6]
        kt = 1.0 + 3.0 * K3 * x * x
        out = [v, F * np.cos(w * t) - C * v - x - K3 * x * x * x,
               p21, p22, -kt * p11 - C * p21, -kt * p12 - C * p22]
        if sensitivity:
            s1, s2 = y[6], y[7]
            out += [s2, -kt * s1 - C * s2 - F * t * np.sin(w * t)]
        return out
    return rhs


def period_map(F, w, z, sensitivity=False, dense=False):
    """One period from z = (x, v): solve_ivp's solution (y[:2] the state, y[2:6] Phi)."""
    y0 = [z[0], z[1], 1.0, 0.0, 0.0, 1.0] + ([0.0, 0.0] if sensitivity else [])
    return solve_ivp(_rhs(F, w, sensitivity), (0.0, 2 * np.pi / w), y0, method="DOP853",
                     rtol=RTOL, atol=ATOL, dense_output=dense)


def periodic_orbit(F, w, z0, max_iter=12):
    """Newton on the period map from z0: (z0, the orbit's dense output, Floquet multipliers)."""
    z, prev = np.asarray(z0, dtype=float), np.inf
    for _ in range(max_iter):
        s = period_map(F, w, z, dense=True)
        Phi = s.y[2:6, -1].reshape(2, 2)
        dz = np.linalg.solve(Phi - np.eye(2), s.y[:2, -1] - z)
        z = z - dz
        step = np.abs(dz).max()
        # converged, or stalled at the integration's noise (next to a fold Phi - I is nearly
        # singular); the last run's orbit starts within |dz| of z
        if step <= 1e-12 * np.abs(z).max() or step >= 0.5 * prev:
            break
        prev = step
    return z, s.sol, np.linalg.eigvals(Phi)


def fourier(sol, w, n=N_FFT):
    """X_k, k = 0 .. n/2, of x(t) = Re sum_k X_k e^{i k w t} from n samples of one period."""
    x = sol(np.arange(n) * (2 * np.pi / w) / n)[0]
    X = 2 * np.fft.rfft(x) / n
    X[0] /= 2
    return X


def series(X, w, t):
    """x(t) = Re sum_k X_k e^{i k w t}."""
    return np.real(np.exp(1j * w * np.multiply.outer(t, np.arange(X.size))) @ X)


def start(X, w):
    """(x(0), v(0)) of the orbit with harmonics X."""
    k = np.arange(X.size)
    return [np.sum(X).real, np.sum(1j * k * w * X).real]


def _fold_residual(F, u):
    y = period_map(F, u[2], u[:2], sensitivity=True).y[:, -1]
    w, T = u[2], 2 * np.pi / u[2]
    Phi = y[2:6].reshape(2, 2)
    zdot = np.array([y[1], F * np.cos(w * T) - C * y[1] - y[0] - K3 * y[0] ** 3])
    dP_dw = y[6:8] - zdot * T / w        # d/d omega of z(T(omega); omega), T = 2 pi / omega
    return np.concatenate([y[:2] - u[:2], [np.linalg.det(Phi - np.eye(2))]]), Phi, dP_dw


def fold(F, z0, w0, max_iter=30):
    """A fold of the periodic orbits, (z0, omega): P(z0) = z0 and det(Phi - I) = 0. Newton with
    the period map's exact rows; det's row by forward differences (at the start and once more
    after three iterations; the rest converges linearly, ~30x per iteration)."""
    u = np.array([z0[0], z0[1], w0], dtype=float)
    row = np.empty(3)
    for it in range(max_iter):
        R, Phi, dP_dw = _fold_residual(F, u)
        if it in (0, 3):
            for j in range(3):
                e = u.copy()
                e[j] += 1e-6 * max(abs(u[j]), 1e-3)
                row[j] = (_fold_residual(F, e)[0][2] - R[2]) / (e[j] - u[j])
        J = np.zeros((3, 3))
        J[:2, :2], J[:2, 2], J[2] = Phi - np.eye(2), dP_dw, row
        du = np.linalg.solve(J, R)
        u = u - du
        if abs(du[2]) <= 1e-13 * u[2] and np.abs(du[:2]).max() <= 1e-10 * np.abs(u[:2]).max():
            return u[:2], u[2]
    raise AssertionError(f"fold by shooting: no convergence at F = {F}")


def curve(F, harmonics, freqs_hz=RANGE, **kw):
    """The Duffing curve by dd.harmonic_balance."""
    return dd.harmonic_balance(np.eye(1), [[C]], np.eye(1), elements=[dd.Cubic(0, k3=K3)],
                               force_dofs=[0], force=[F], freqs_hz=freqs_hz,
                               harmonics=harmonics, max_step=MAX_STEP, **kw)


def compare(r, F, i, t_points=513):
    """The curve's point i against the shooting orbit at its frequency (errors relative to
    x_max): kept (sum_{k <= H} |dX_k|), whole (max_t |dx(t)|), dropped (sum_{k > H} |X_k| of
    the shooting orbit), the multipliers, the distance to the nearest fold frequency."""
    w, X = r.omega[i], r.harmonics[i, 0]
    H = X.size - 1
    _, sol, mu = periodic_orbit(F, w, start(X, w))
    Xs = fourier(sol, w)
    amp = r.x_max[i, 0]
    t = np.linspace(0, 2 * np.pi / w, t_points)
    out = dict(kept=np.abs(Xs[:H + 1] - X).sum() / amp,
               whole=np.abs(sol(t)[0] - series(X, w, t)).max() / amp,
               dropped=np.abs(Xs[H + 1:]).sum() / amp, x9=abs(Xs[9]) / amp, mu=mu,
               near=np.abs(r.frequency_hz[i] / r.fold_frequency_hz - 1).min())
    if r.floquet_exponents is not None:
        hill = np.sort(np.abs(np.exp(r.floquet_exponents[i] * 2 * np.pi / w)))
        out["hill"] = np.abs(hill - np.sort(np.abs(mu))).max()
    return out


# ----------------------------------------------------------------------------------------------
# the checked points: 20 spread along the curve, and the nearest on each side of each fold


def _picks(r, n_spread=20):
    f = r.frequency_hz
    near = np.abs(f[:, None] / r.fold_frequency_hz[None, :] - 1).min(axis=1)
    far = np.flatnonzero(near >= NEAR_FOLD)
    spread = far[np.round(np.linspace(0, far.size - 1, n_spread)).astype(int)]
    sides = []
    for j, ff in zip(r.folds, r.fold_frequency_hz):
        # j is the point next to the fold, on either side: the fold lies between a and a + 1,
        # where the stability changes (checked against shooting below)
        a = j - 1 if r.stable[j - 1] != r.stable[j] else j
        assert r.stable[a] != r.stable[a + 1], (ff, r.stable[j - 1:j + 2])
        for i, step in ((a, -1), (a + 1, 1)):
            while abs(f[i] / ff - 1) < NEAR_FOLD:
                i += step
            assert abs(f[i] / ff - 1) <= 1e-2, (ff, f[i])     # within 1 % of the fold
            sides.append(i)
    return spread, np.array(sides)


@pytest.fixture(scope="module", params=FORCES, ids=lambda F: f"F={F}")
def checked(request):
    F = request.param
    r = curve(F, 7, convergence_points=0)
    spread, sides = _picks(r)
    picks = sorted(set(spread) | set(sides))
    rows = {i: compare(r, F, i) for i in picks}
    return F, r, spread, sides, rows


def test_checked_points_cover_three_branches_and_both_sides_of_each_fold(checked):
    F, r, spread, sides, rows = checked
    assert r.folds.size == 2 and r.info["stop"] == "end of the range"
    up, down = r.folds              # the jump-down fold (upper frequency) comes first
    assert r.fold_frequency_hz[0] > r.fold_frequency_hz[1]
    branches = [spread < up, (spread > up) & (spread <= down), spread > down]
    assert all(b.sum() >= 3 for b in branches), [b.sum() for b in branches]
    # one point on each side of each fold within 1 %, the stable and the unstable one
    assert sides.size == 4
    assert r.stable[sides[0]] != r.stable[sides[1]] and r.stable[sides[2]] != r.stable[sides[3]]
    assert len(rows) >= 20


def test_kept_harmonics_equal_shooting(checked):
    """Harmonics 0 .. 7 of the curve against the shooting orbit's: sum |dX_k| <= 1e-6 of the
    amplitude (measured 2.1e-8, 1.1e-7, 1.9e-7 at F = 0.1, 0.3, 1), also next to the folds."""
    F, r, _, sides, rows = checked
    for i, q in rows.items():
        assert q["kept"] < 1e-6, (F, r.frequency_hz[i], q["kept"])
    assert max(rows[i]["kept"] for i in sides) < 1e-6


def test_whole_orbit_error_is_the_dropped_harmonics(checked):
    """The whole orbit x(t) is off by the harmonics 7 cannot hold: max_t |dx| equals the
    shooting orbit's 9th+ harmonics (sum |X_k|, k > 7) within 10 % plus the kept error. That
    is below 1e-6 of the amplitude at F = 0.1 (9.7e-7 at the upper fold), not at F = 0.3 and
    1 (2.4e-6, 3.3e-6: the 9th harmonic alone is 2.2e-6, 3.0e-6 there)."""
    F, r, _, _, rows = checked
    for i, q in rows.items():
        assert abs(q["whole"] - q["dropped"]) <= q["kept"] + 0.1 * q["dropped"] + 1e-11, \
            (F, r.frequency_hz[i], q)
    whole = max(q["whole"] for q in rows.values())
    x9 = max(q["x9"] for q in rows.values())
    if F == 0.1:
        assert whole < 1e-6, whole
    else:
        assert x9 > 1e-6 and whole > 1e-6, (whole, x9)     # the limit of 7 harmonics


def test_stability_labels_equal_the_floquet_multipliers(checked):
    """The stable flag against max |multiplier| < 1 of the monodromy matrix, and Hill's
    multipliers |exp(lambda T)| against the monodromy's (measured <= 3.4e-8), at every checked
    point (both sides of each fold within 1 % of it)."""
    F, r, _, _, rows = checked
    for i, q in rows.items():
        assert r.stable[i] == (np.abs(q["mu"]).max() < 1), (F, r.frequency_hz[i], q["mu"])
        assert q["hill"] < 1e-6, (F, r.frequency_hz[i], q["hill"])
    assert not all(r.stable[i] for i in rows) and any(r.stable[i] for i in rows)


def test_fold_frequencies_equal_shooting_folds(checked):
    """Folds located by shooting itself (the augmented Newton system) against
    fold_frequency_hz: 1e-8 relative asserted (measured 1.1e-9 at most; the issue asks 1e-5)."""
    F, r, _, _, _ = checked
    for j, ff in zip(r.folds, r.fold_frequency_hz):
        z, w = fold(F, start(r.harmonics[j, 0], r.omega[j]), 2 * np.pi * ff)
        # it is a fold: one multiplier 1, and a periodic orbit
        mu = np.linalg.eigvals(period_map(F, w, z).y[2:6, -1].reshape(2, 2))
        assert np.abs(mu - 1).min() < 1e-8, mu
        assert abs(ff / (w / (2 * np.pi)) - 1) < 1e-8, (F, ff, w / (2 * np.pi))


def test_nine_harmonics_reach_1e6_on_the_whole_orbit_at_the_largest_force():
    """F = 1 with 9 harmonics: the whole orbit within 1e-6 of the amplitude at the same kind
    of points (measured 1.3e-7 at most: the 11th+ harmonics), the labels as the multipliers."""
    r = curve(1.0, 9, convergence_points=0)
    spread, sides = _picks(r)
    for i in sorted(set(spread) | set(sides)):
        q = compare(r, 1.0, i)
        assert q["whole"] < 1e-6 and q["kept"] < 1e-8, (r.frequency_hz[i], q)
        assert r.stable[i] == (np.abs(q["mu"]).max() < 1), (r.frequency_hz[i], q["mu"])
