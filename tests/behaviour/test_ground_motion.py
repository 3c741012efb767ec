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
        "mck": lambda **kw: dd.mck_response(M, C, K, dt=DT, scheme="average_acceleration", **kw),
        "chain": lambda **kw: dd.chain_response(MASS, STIFF, DAMP, dt=DT,
                                                scheme="average_acceleration", **kw),
        "nonlinear": lambda **kw: dd.nonlinear_mck_response(M, C, K, dt=DT, elements=cubic,
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
        ref = dd.mck_response(M, C, K, None, DT, ground_acceleration=ag,
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


def test_a_abs_and_x_abs_are_saved_and_loaded(building, tmp_path):
    M, C, K, t, ag = building
    u = np.cumsum(np.cumsum(ag)) * DT ** 2     # a displacement record: x_abs is stored too
    r = dd.mck_response(M, C, K, None, DT, ground_displacement=u, quantities=("x", "a"))
    for suffix in (".npz", ".csv"):
        back = dd.load_result(r.save(tmp_path / f"r{suffix}"))
        for q in ("a_abs", "x_abs"):   # csv: 17 significant digits read back bitwise
            np.testing.assert_array_equal(getattr(back, q), getattr(r, q))
        assert back.x_abs is not None and back.v is None


@pytest.mark.parametrize("kw, match", [
    ({"influence": np.ones(5)}, "influence is given without a ground record"),
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
        assert dd.mck_response(M, C, K, args.pop("force"), DT, **args).x.shape == (10, 5)
        return
    with pytest.raises(ValueError, match=match):
        dd.mck_response(M, C, K, args.pop("force"), DT, **args)


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


RUNS = {   # every time-history entry point on the building, keywords passed through
    "mck_response": lambda M, C, K, **kw: dd.mck_response(M, C, K, None, DT, **kw),
    "chain_response": lambda M, C, K, **kw: dd.chain_response(MASS, STIFF, DAMP, None, DT, **kw),
    "exact_response": lambda M, C, K, **kw: dd.exact_response(M, C, K, None, DT, **kw),
    "state_space_response": lambda M, C, K, **kw: dd.state_space_response(
        dd.discretize(M, C, K, DT, hold="foh"), None, **kw),
    "modal_filter_response": lambda M, C, K, **kw: dd.modal_filter_response(M, C, K, None, DT,
                                                                            **kw),
    "nonlinear_mck_response": lambda M, C, K, **kw: dd.nonlinear_mck_response(
        M, C, K, None, DT, elements=[dd.Cubic(0, k3=1e12)], scheme="newmark", **kw),
    "nonlinear_chain_response": lambda M, C, K, **kw: dd.nonlinear_chain_response(
        MASS, STIFF, DAMP, None, DT, elements=[dd.Cubic(0, k3=1e12)], scheme="newmark", **kw),
}


def _smooth_records(t):
    """A ground displacement from rest (zero slope at t_0) and a velocity record, m and m/s."""
    w = 2 * np.pi * 1.3
    u = 0.02 * (1 - np.cos(w * t)) * np.exp(-0.3 * t)
    v = 0.02 * w * np.sin(w * t) * np.exp(-0.5 * t)
    return u, v


@pytest.mark.parametrize("run", sorted(RUNS))
def test_displacement_and_velocity_records_equal_their_acceleration(building, run):
    """ground_displacement / ground_velocity give the run of ground_acceleration_from's record
    (the same conversion, so the same numbers to round-off), and a displacement record adds
    x_abs = x + r u_g with u_g the record's own samples."""
    M, C, K, t, _ = building
    u, v = _smooth_records(t[:401])
    for quantity, record in (("displacement", u), ("velocity", v)):
        ag = dd.ground_acceleration_from(DT, **{quantity: record})
        ref = RUNS[run](M, C, K, ground_acceleration=ag)
        got = RUNS[run](M, C, K, **{f"ground_{quantity}": record})
        scale = np.abs(ref.x).max()
        np.testing.assert_allclose(got.x, ref.x, rtol=0, atol=1e-12 * scale)
        if ref.a is not None:   # the "foh" model outputs x, v only
            np.testing.assert_allclose(got.a_abs, ref.a_abs, rtol=0,
                                       atol=1e-12 * np.abs(ref.a_abs).max())
        assert got.info["ground"]["quantity"] == quantity and ref.x_abs is None
        if quantity == "displacement":
            np.testing.assert_array_equal(got.x_abs, got.x + u[:, None])
        else:
            assert got.x_abs is None


def test_two_directions_convert_column_by_column(building):
    """A (n, 2) displacement record with an influence matrix: each direction is converted on
    its own, and x_abs adds r u_g per DOF."""
    M, C, K, t, _ = building
    u, _ = _smooth_records(t[:401])
    u2 = np.c_[u, 0.5 * u[::-1] - 0.5 * u[-1]]
    r = np.c_[np.ones(5), np.linspace(0.2, 1.0, 5)]
    a2 = np.c_[dd.ground_acceleration_from(DT, displacement=u2[:, 0]),
               dd.ground_acceleration_from(DT, displacement=u2[:, 1])]
    got = dd.exact_response(M, C, K, None, DT, ground_displacement=u2, influence=r)
    ref = dd.exact_response(M, C, K, None, DT, ground_acceleration=a2, influence=r)
    np.testing.assert_allclose(got.x, ref.x, rtol=0, atol=1e-12 * np.abs(ref.x).max())
    np.testing.assert_allclose(got.x_abs, got.x + u2 @ r.T, rtol=0, atol=1e-15)


def test_absolute_displacement_equals_solve_ivp_in_absolute_coordinates():
    """The building under a ground displacement u_g(t) = U (1 - cos w t), in absolute
    coordinates M u'' + C (u' - r u_g') + K (u - r u_g) = 0 from rest, by solve_ivp (DOP853,
    rtol 1e-12): dtdyn's x_abs = x + r u_g (exact_response, so the only error is the ground
    motion's) equals it

    - to solve_ivp's own error when solve_ivp is driven by the same piecewise cubic ground
      displacement (the cubic spline, zero slope at t_0, zero curvature at the end, whose
      curvature is the acceleration record): 1e-9, ten times the 1e-10 solve_ivp reaches here;
    - to the spline's interpolation error when driven by the analytic u_g: that error is at most
      (5/384) dt^4 max|u''''| (the end conditions are right for this u_g: u_g'(0) = 0 and
      u_g''(T) = 0 with w T = 4.5 pi), and is O(dt^4): halving dt divides it by 16 (14 .. 18
      allowed). It is 0.43 of that bound here, on relative x_abs."""
    import scipy.integrate
    import scipy.interpolate

    M, C, K = dd.chain_matrices(MASS, STIFF, DAMP, sparse=False)
    U, w, T = 0.05, 2 * np.pi * 1.125, 2.0
    Minv, Cr, Kr = np.linalg.inv(M), C.sum(axis=1), K.sum(axis=1)   # r = ones

    def absolute(ug, vg, t):
        def rhs(s, y):
            return np.r_[y[5:], Minv @ (Cr * vg(s) + Kr * ug(s) - C @ y[5:] - K @ y[:5])]
        sol = scipy.integrate.solve_ivp(rhs, (0.0, T), np.zeros(10), method="DOP853", t_eval=t,
                                        rtol=1e-12, atol=1e-15)
        return sol.y[:5].T

    errors = []
    for dt in (0.01, 0.005):
        t = np.arange(round(T / dt) + 1) * dt
        ug = U * (1 - np.cos(w * t))
        got = dd.exact_response(M, C, K, None, dt, ground_displacement=ug, quantities=("x",))
        ref = absolute(lambda s: U * (1 - np.cos(w * s)), lambda s: U * w * np.sin(w * s), t)
        scale = np.abs(ref).max()
        errors.append(np.abs(got.x_abs - ref).max() / scale)
        assert errors[-1] <= 5 / 384 * dt ** 4 * U * w ** 4 / scale
        if dt == 0.01:
            spline = scipy.interpolate.CubicSpline(t, ug, bc_type=((1, 0.0), (2, 0.0)))
            same = absolute(spline, spline.derivative(), t)
            assert np.abs(got.x_abs - same).max() <= 1e-9 * scale
    assert 14 <= errors[0] / errors[1] <= 18


@pytest.mark.parametrize("kw, match", [
    ({"ground_acceleration": np.ones(11), "ground_displacement": np.ones(11)},
     "ground_acceleration and ground_displacement are both given"),
    ({"ground_velocity": np.ones(11), "ground_displacement": np.ones(11)},
     "ground_velocity and ground_displacement are both given"),
    ({"ground_displacement": np.ones(7)}, "ground_displacement has 7 samples and force 11"),
    ({"ground_velocity": np.r_[np.ones(10), np.inf]}, r"ground_velocity\[10, 0\] = inf"),
    ({"ground_displacement": np.ones((11, 2))}, "ground_displacement has 2 directions"),
    ({"ground_displacement": np.ones(11), "influence": np.ones(3)},
     "one column per direction of ground_displacement"),
])
def test_bad_ground_records(building, kw, match):
    M, C, K, _, _ = building
    with pytest.raises(ValueError, match=match):
        dd.mck_response(M, C, K, np.ones(11), DT, force_dofs=[4], **kw)
    with pytest.raises(ValueError, match="ground_displacement has shape"):   # spline needs 3
        dd.exact_response(M, C, K, None, DT, ground_displacement=np.ones(2))
