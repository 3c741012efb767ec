"""Backbones (runtime/nonlinear/_backbone.py) against independent truths.

Truths: the Duffing oscillator x'' + x + k3 x^3 = 0 has the exact period
T = 4 K(m) / sqrt(1 + k3 A^2), m = k3 A^2 / (2 (1 + k3 A^2)) at the amplitude A (scipy's
complete elliptic integral; the formula itself is checked here against solve_ivp's quarter
period), energy E = A^2 / 2 + k3 A^4 / 4; a 2-DOF system's free periodic orbits found by
shooting (solve_ivp DOP853 at rtol 1e-12, Gauss-Newton on the period map with the monodromy
matrix, unknowns the other DOF's start and the period).
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import ellipk

from dtdyn.nonlinear._backbone import backbone
from dtdyn.nonlinear._elements import BoucWen, Cubic, Law
from dtdyn.nonlinear._harmonic_balance import harmonic_balance

K3 = 0.5


def _duffing_period(A, k3=K3):
    return 4.0 / np.sqrt(1 + k3 * A * A) * ellipk(k3 * A * A / (2 * (1 + k3 * A * A)))


def test_the_elliptic_period_formula_against_solve_ivp():
    for A in (0.1, 1.0, 3.0):
        def crossing(t, z):
            return z[0]
        crossing.terminal, crossing.direction = True, -1
        s = solve_ivp(lambda t, z: [z[1], -z[0] - K3 * z[0] ** 3], (0, 100), [A, 0.0],
                      method="DOP853", rtol=1e-12, atol=1e-14, events=crossing)
        assert abs(4 * s.t_events[0][0] / _duffing_period(A) - 1) < 1e-11


def test_duffing_backbone_equals_the_elliptic_period_and_converges_in_H():
    """The frequency at every point against the exact one at the computed x_max; the error
    falls geometrically with H (the harmonics of the cn function decay geometrically)."""
    errors = []
    for H in (3, 5, 7, 9):
        bb = backbone(np.eye(1), K=np.eye(1), elements=[Cubic(0, k3=K3)],
                      amplitudes=(0.01, 2.0), harmonics=H)
        A = bb.x_max[:, 0]
        exact = 2 * np.pi / _duffing_period(A)
        errors.append(np.abs(bb.omega / exact - 1).max())
        assert bb.amplitude[0] == pytest.approx(0.01, rel=1e-14)
        assert bb.amplitude[-1] == pytest.approx(2.0, rel=1e-12)
        assert np.all(np.diff(bb.amplitude) > 0) and np.all(np.diff(bb.omega) > 0)
        assert np.allclose(bb.energy, A ** 2 / 2 + K3 * A ** 4 / 4, rtol=1e-12)
        assert np.abs(bb.damping_ratio).max() < 1e-12
        # x(t) is even and holds odd harmonics only (the law is odd)
        assert np.abs(bb.harmonics[:, 0, 0::2]).max() < 1e-12
        assert np.abs(bb.harmonics[:, 0].imag).max() < 1e-12
    assert errors[-1] < 1e-8, errors
    assert all(e1 < 0.05 * e0 for e0, e1 in zip(errors, errors[1:])), errors


def test_energies_range_hits_its_ends():
    bb = backbone(np.eye(1), K=np.eye(1), elements=[Cubic(0, k3=K3)], energies=(1e-3, 5.0),
                  harmonics=9)
    assert bb.energy[0] == pytest.approx(1e-3, rel=1e-12)
    assert bb.energy[-1] == pytest.approx(5.0, rel=1e-12)
    A = bb.x_max[:, 0]
    assert np.allclose(bb.energy, A ** 2 / 2 + K3 * A ** 4 / 4, rtol=1e-10)
    assert np.abs(bb.omega / (2 * np.pi / _duffing_period(A)) - 1).max() < 1e-8


def _shoot_free(M, K, cubic, x0, T0, ref):
    """A free periodic orbit x(0) = x0 (x0[ref] held), v(0) = 0: (x0, T, dense solution)."""
    n = M.shape[0]
    Minv = np.linalg.inv(M)

    def rhs(t, z):
        x, v = z[:n], z[n:2 * n]
        f, Kt = np.zeros(n), np.zeros((n, n))
        for i, j, k3 in cubic:
            lv = np.zeros(n)
            lv[i] = 1.0
            if j is not None:
                lv[j] = -1.0
            y = lv @ x
            f += lv * k3 * y ** 3
            Kt += np.outer(lv, lv) * 3 * k3 * y * y
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ (K + Kt), np.zeros((n, n))]])
        Phi = z[2 * n:].reshape(2 * n, 2 * n)
        return np.concatenate([v, -Minv @ (K @ x + f), (A @ Phi).ravel()])

    free = [i for i in range(n) if i != ref]
    x0, T = np.array(x0, dtype=float), float(T0)
    for _ in range(30):
        z0 = np.concatenate([x0, np.zeros(n), np.eye(2 * n).ravel()])
        s = solve_ivp(rhs, (0, T), z0, method="DOP853", rtol=1e-12, atol=1e-14)
        zT = s.y[:, -1]
        r = np.concatenate([zT[:n] - x0, zT[n:2 * n]])
        Phi = zT[2 * n:].reshape(2 * n, 2 * n)
        J = np.column_stack([Phi[:, free] - np.eye(2 * n)[:, free], rhs(T, zT)[:2 * n]])
        d = np.linalg.lstsq(J, r, rcond=None)[0]
        x0[free] -= d[:-1]
        T -= d[-1]
        if np.abs(d).max() < 1e-13:
            break
    z0 = np.concatenate([x0, np.zeros(n), np.eye(2 * n).ravel()])
    s = solve_ivp(rhs, (0, T), z0, method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True)
    assert np.abs(s.y[:2 * n, -1] - z0[:2 * n]).max() < 1e-9
    return x0, T, s.sol


@pytest.mark.parametrize("mode", [0, 1])
def test_two_dofs_backbone_against_shooting(mode):
    """Both modes of a 2-DOF chain with a cubic spring to ground and one between the masses:
    the orbit at five points of the backbone equals the shooting orbit started at the same
    reference displacement (period to 1e-9, motion to 1e-8 of the amplitude with H = 15)."""
    M = np.diag([1.0, 0.5])
    K = np.array([[2.0, -1.0], [-1.0, 1.0]])
    elements = [Cubic(0, 1, k3=2.0), Cubic(1, k3=0.5)]
    cubic = [(0, 1, 2.0), (1, None, 0.5)]
    bb = backbone(M, K=K, elements=elements, mode=mode, amplitudes=(0.02, 1.0), harmonics=15)
    # the start, at a small amplitude, is next to the linear mode (a 0.2 % shift here)
    assert abs(bb.omega[0] - 2 * np.pi * bb.linear_frequency_hz) < 1e-2 * bb.omega[0]
    for i in np.linspace(0, bb.omega.size - 1, 5).astype(int):
        X, w = bb.harmonics[i], bb.omega[i]
        x0 = X.sum(axis=1).real
        _, T, sol = _shoot_free(M, K, cubic, x0, 2 * np.pi / w, bb.reference)
        assert abs(T * w / (2 * np.pi) - 1) < 1e-9, (i, T, w)
        t = np.linspace(0, T, 301)
        k = np.arange(X.shape[1])
        x_hb = np.real(np.exp(1j * w * np.multiply.outer(t, k)) @ X.T)
        err = np.abs(sol(t)[:2].T - x_hb).max() / bb.x_max[i].max()
        assert err < 1e-8, (i, err)


def test_viscous_law_gives_the_modal_damping_ratio():
    """A law c v + k3 x^3 on a unit mass: -xi M q' of the extended periodic motion concept
    cancels c q' exactly, so damping_ratio = c / (2 omega), and the motion is the undamped
    backbone's (the same frequencies)."""
    c = 0.03
    law = backbone(np.eye(1), K=np.eye(1), elements=[Law(0, expression="c*v + k3*x**3", c=c,
                                                         k3=K3)], amplitudes=(0.05, 1.5),
                   harmonics=7)
    plain = backbone(np.eye(1), K=np.eye(1), elements=[Cubic(0, k3=K3)],
                     amplitudes=(0.05, 1.5), harmonics=7)
    assert np.allclose(law.damping_ratio, c / (2 * law.omega), rtol=1e-9)
    assert np.allclose(np.interp(plain.amplitude, law.amplitude, law.omega), plain.omega,
                       rtol=1e-6)


def test_model_object_reference_outputs_and_overlay(tmp_path):
    """A Chain as the model, outputs by index, a chosen reference DOF; the backbone drawn over
    the forced curve of the same chain, whose peak lies on it (within 1e-3 in frequency at the
    peak's amplitude, 1.26: the damping shifts the peak by O(zeta^2), zeta ~ 0.004)."""
    import matplotlib
    matplotlib.use("Agg")
    import dtdyn as dd
    chain = dd.Chain([1.0, 1.0], [1.0, 1.0], [0.004, 0.004])
    cubic = [Cubic(1, k3=0.5)]
    bb = backbone(chain, elements=cubic, amplitudes=(0.01, 1.5), harmonics=7, outputs=[1],
                  reference=1)
    assert bb.reference == 1 and bb.outputs.tolist() == [1] and bb.mode == 0
    assert np.allclose(bb.amplitude[[0, -1]], [0.01, 1.5], rtol=1e-12)
    assert abs(bb.harmonics[:, 0, 1].imag).max() < 1e-12           # the phase condition
    w_lin = np.sqrt((3 - np.sqrt(5)) / 2)                            # the chain's first mode
    assert bb.linear_frequency_hz == pytest.approx(w_lin / (2 * np.pi), rel=1e-12)
    frc = harmonic_balance(chain, elements=cubic, force_dofs=[1], force=[0.003],
                           freqs_hz=(0.08, 0.2), harmonics=7, outputs=[1],
                           convergence_points=0)
    i = int(np.argmax(frc.x_max[:, 0]))
    f_bb = np.interp(frc.x_max[i, 0], bb.x_max[:, 0], bb.frequency_hz)
    assert abs(frc.frequency_hz[i] / f_bb - 1) < 1e-3, (frc.frequency_hz[i], f_bb)
    ax = frc.plot(backbone=bb)
    assert len(ax.lines) == frc.omega.size   # the curve's segments and the backbone's line
    ax.figure.savefig(tmp_path / "frc.png")
    assert bb.plot(quantity="energy").get_yscale() == "log"
    with pytest.raises(ValueError, match="outputs"):
        harmonic_balance(chain, elements=cubic, force_dofs=[1], force=[0.01],
                         freqs_hz=(0.08, 0.09), harmonics=3, outputs=[0], stability=False,
                         convergence_points=0).plot(backbone=bb)


def _call(**kw):
    args = dict(elements=[Cubic(0, k3=K3)], amplitudes=(0.01, 1.0), harmonics=3)
    args.update(kw)
    return backbone(np.eye(2), K=np.array([[2.0, -1.0], [-1.0, 2.0]]), **args)


@pytest.mark.parametrize("kw, match", [
    (dict(amplitudes=None), "one of amplitudes"),
    (dict(energies=(1.0, 2.0)), "one of amplitudes"),
    (dict(amplitudes=(1.0, 0.1)), "amplitudes must increase"),
    (dict(amplitudes=(0.0, 1.0)), "amplitudes"),
    (dict(amplitudes=None, energies=(1.0,)), "energies"),
    (dict(mode=2), "mode"),
    (dict(mode=-1), "mode"),
    (dict(harmonics=0), "harmonics"),
    (dict(elements=[]), "elements is empty"),
    (dict(elements=[BoucWen(0, stiffness=1.0, beta=1.0, gamma=1.0)]), "internal states"),
    (dict(reference=5), "reference"),
    (dict(step=1.0), "min_step <= step"),
    (dict(harmonics=2000), "at most"),
])
def test_bad_inputs_name_the_field(kw, match):
    with pytest.raises(ValueError, match=match):
        _call(**kw)


def test_missing_K_and_singular_K_are_named():
    with pytest.raises(ValueError, match="K is required"):
        backbone(np.eye(1), elements=[Cubic(0, k3=1.0)], amplitudes=(0.1, 1.0))
    with pytest.raises(ValueError, match="rigid-body"):
        backbone(np.eye(2), K=np.array([[1.0, -1.0], [-1.0, 1.0]]),
                 elements=[Cubic(0, k3=1.0)], amplitudes=(0.1, 1.0))
    with pytest.raises(TypeError, match="amplitude"):
        backbone(np.eye(1), K=np.eye(1), elements=[Cubic(0, k3=1.0)], amplitude=(0.1, 1.0))
