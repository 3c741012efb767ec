"""Support motion (ground_acceleration, influence) on every time-history entry point.

Truths: scipy.signal.lsim (the matrix exponential, exact for a load linear between samples) of
the first-order form loaded by -M r a_g; the same run with the effective force written out by
hand; a_abs = a + r a_g."""
import numpy as np
import pytest
import scipy.signal

import dtdyn as dd

MASS, STIFF, DAMP = [2e5] * 5, [3e8] * 4 + [2e8], [4e5] * 5   # a 5-storey shear building
DT = 0.01


@pytest.fixture(scope="module")
def building():
    M, C, K = dd.chain_matrices(MASS, STIFF, DAMP, sparse=False)
    t = np.arange(1501) * DT
    rng = np.random.default_rng(3)
    ag = np.convolve(rng.standard_normal(t.size), np.ones(8) / 8, mode="same") * 3.0  # m/s^2
    ag *= np.minimum(1.0, t / 2.0) * np.exp(-0.2 * t)
    return M, C, K, t, ag


def _lsim(M, C, K, t, ag):
    A, B = dd.first_order_form(M, C, K)
    n = M.shape[0]
    Bg = B @ (M @ np.ones(n))[:, None]            # input -a_g through M r
    sys = scipy.signal.StateSpace(A, Bg, np.eye(2 * n), np.zeros((2 * n, 1)))
    _, y, _ = scipy.signal.lsim(sys, -ag, t, interp=True)
    return y[:, :n]


def test_exact_modal_filters_and_state_space_equal_the_matrix_exponential(building):
    M, C, K, t, ag = building
    ref = _lsim(M, C, K, t, ag)
    scale = np.abs(ref).max()
    ex = dd.exact_response(M, C, K, None, DT, ground_acceleration=ag)
    mf = dd.modal_filter_response(M, C, K, None, DT, ground_acceleration=ag)
    ss = dd.state_space_response(dd.discretize(M, C, K, DT, hold="foh"), None,
                                 ground_acceleration=ag)
    for r in (ex, mf, ss):
        assert np.abs(r.x - ref).max() <= 1e-12 * scale
    with pytest.raises(ValueError, match="needs the structure's mass matrix"):
        model = dd.discretize(M, C, K, DT, hold="foh")
        dd.state_space_response(dd.DiscreteModel(*model, DT, quantities=("x", "v"), n_dof=5),
                                None, ground_acceleration=ag)
    for r in (ex, mf):   # absolute acceleration = relative + ground
        np.testing.assert_allclose(r.a_abs, r.a + ag[:, None], rtol=0, atol=1e-12 * np.abs(
            r.a_abs).max())
        assert r.info["ground"]["directions"] == 1


@pytest.mark.parametrize("run", ["mck", "chain", "nonlinear", "nonlinear_chain"])
def test_schemes_equal_the_hand_written_effective_force(building, run):
    """The same scheme with f = -M r a_g given as a force gives the same numbers (the ground
    record is a load like any other), and the chain's moving base equals the matrices'."""
    M, C, K, t, ag = building
    f = -np.outer(ag, np.diag(M))
    dofs = list(range(5))
    cubic = [dd.Cubic(0, k3=1e12)]
    calls = {
        "mck": lambda **kw: dd.simulate_mck(M, C, K, dt=DT, scheme="average_acceleration", **kw),
        "chain": lambda **kw: dd.simulate_chain(MASS, STIFF, DAMP, dt=DT,
                                                scheme="average_acceleration", **kw),
        "nonlinear": lambda **kw: dd.nonlinear_response(M, C, K, dt=DT, elements=cubic,
                                                        scheme="newmark", **kw),
        "nonlinear_chain": lambda **kw: dd.nonlinear_chain_response(
            MASS, STIFF, DAMP, dt=DT, elements=cubic, scheme="newmark", **kw),
    }
    g = calls[run](force=None, ground_acceleration=ag)
    h = calls[run](force=f, force_dofs=dofs)
    np.testing.assert_allclose(g.x, h.x, rtol=0, atol=1e-12 * np.abs(h.x).max())
    np.testing.assert_allclose(g.a_abs, g.a + ag[:, None], rtol=0,
                               atol=1e-12 * np.abs(g.a_abs).max())
    if run == "chain":
        ref = dd.simulate_mck(M, C, K, None, DT, ground_acceleration=ag,
                              scheme="average_acceleration")
        np.testing.assert_allclose(g.x, ref.x, rtol=0, atol=1e-12 * np.abs(ref.x).max())


def test_force_and_two_directions(building):
    """A force on the roof plus two ground directions through an influence matrix: the
    effective load is f - M r a_g, and a_abs adds r a_g per DOF."""
    M, C, K, t, ag = building
    r = np.c_[np.ones(5), np.linspace(0.2, 1.0, 5)]          # a second, rotational direction
    a2 = np.c_[ag, 0.5 * ag[::-1]]
    f = np.sin(t)[:, None] * 1e5
    g = dd.exact_response(M, C, K, f, DT, force_dofs=[4], ground_acceleration=a2, influence=r)
    load = -a2 @ (M @ r).T
    load[:, 4] += f[:, 0]
    h = dd.exact_response(M, C, K, load, DT)
    np.testing.assert_allclose(g.x, h.x, rtol=0, atol=1e-13 * np.abs(h.x).max())
    np.testing.assert_allclose(g.a_abs, g.a + a2 @ r.T, rtol=0, atol=1e-12 * np.abs(g.a_abs).max())


def test_a_abs_is_saved_and_loaded(building, tmp_path):
    M, C, K, t, ag = building
    r = dd.simulate_mck(M, C, K, None, DT, ground_acceleration=ag, quantities=("x", "a"))
    for suffix in (".npz", ".csv"):
        back = dd.load_result(r.save(tmp_path / f"r{suffix}"))
        np.testing.assert_allclose(back.a_abs, r.a_abs, rtol=1e-15 if suffix == ".npz" else 1e-9)


@pytest.mark.parametrize("kw, match", [
    ({"influence": np.ones(5)}, "influence is given without ground_acceleration"),
    ({"force": None}, "force is None"),
    ({"force": None, "ground_acceleration": np.ones(10)}, None),
    ({"ground_acceleration": np.ones(7)}, "ground_acceleration has 7 samples and force 11"),
    ({"ground_acceleration": np.ones((11, 2))}, "give the influence matrix"),
    ({"ground_acceleration": np.ones(11), "influence": np.ones(3)}, r"influence has shape \(3,\)"),
    ({"ground_acceleration": np.r_[np.ones(10), np.nan]}, r"ground_acceleration\[10, 0\] = nan"),
])
def test_bad_input(building, kw, match):
    M, C, K, _, _ = building
    args = dict(force=np.ones(11), force_dofs=[4])
    args.update(kw)
    if match is None:   # the support motion alone: its own length sets the record
        assert dd.simulate_mck(M, C, K, args.pop("force"), DT, **args).x.shape == (10, 5)
        return
    with pytest.raises(ValueError, match=match):
        dd.simulate_mck(M, C, K, args.pop("force"), DT, **args)


def test_acceleration_from_displacement_and_velocity_records():
    """The acceleration linear between samples whose motion passes through the given record:
    integrated back exactly (piecewise-linear a) it returns the displacement (from rest) or the
    velocity at every sample to round-off; against the exact second derivative of a smooth
    record the error is the spline's O(dt^2) (1e-3 here, (omega dt)^2 / 12 = 1.4e-3)."""
    dt, w = 0.01, 2 * np.pi * 1.3
    t = np.arange(501) * dt
    u = (1 - np.cos(w * t)) * np.exp(-0.2 * t)
    a = dd.ground_acceleration_from(dt, displacement=u)
    d, v = np.zeros_like(u), 0.0
    for k in range(u.size - 1):
        d[k + 1] = d[k] + dt * v + dt * dt * (2 * a[k] + a[k + 1]) / 6
        v += dt * (a[k] + a[k + 1]) / 2
    assert np.abs(d - u).max() <= 1e-12 * np.abs(u).max()
    vel = w * np.sin(w * t)
    a2 = dd.ground_acceleration_from(dt, velocity=vel)
    back = np.r_[vel[0], vel[0] + np.cumsum(dt * (a2[:-1] + a2[1:]) / 2)]
    assert np.abs(back - vel).max() <= 1e-12 * np.abs(vel).max()
    assert np.abs(a2 - w * w * np.cos(w * t)).max() <= 1e-3 * w * w
    with pytest.raises(ValueError, match="exactly one"):
        dd.ground_acceleration_from(dt, displacement=u, velocity=vel)
    with pytest.raises(ValueError, match="dt"):
        dd.ground_acceleration_from(0.0, velocity=vel)
