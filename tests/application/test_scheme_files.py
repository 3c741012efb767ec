"""A user's scheme file: derived, checked and compiled for every entry point.

The oracle is a hand-written generalized-alpha recursion (Chung & Hulbert 1993) with alpha_f = 0,
which is Bossak-alpha (Wood, Bossak & Zienkiewicz 1980): the recursion below is typed from the
paper, not derived. Every entry point solves the same linear equations per step; the tolerance
1e-10 (relative to max |x|) covers rounding over 300 steps of a 30-DOF chain (condition of the
effective matrices ~1e3: a few 1e-13 measured) and nothing of the method's own error, which both
sides share.
"""
import os
import pickle
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import dtdyn as dd

BOSSAK = textwrap.dedent('''
    name = "my_bossak"
    title = "Wood-Bossak-Zienkiewicz alpha"
    reference = "Wood, Bossak & Zienkiewicz (1980), IJNME 15"
    relations = [
      "x1 = x0 + dt*v0 + dt**2*((1/2 - beta)*a0 + beta*a1)",
      "v1 = v0 + dt*((1 - gamma)*a0 + gamma*a1)",
      "xe = x1", "ve = v1",
      "ae = (1 - alpha_m)*a1 + alpha_m*a0",
    ]
    force_weights = ["0", "1"]          # Fe = w0 F_n + w1 F_{n+1}

    [parameters.alpha_m]
    default = -0.1
    range = [-0.5, 0.0]

    [substitutions]
    beta = "(1 - alpha_m)**2/4"
    gamma = "1/2 - alpha_m"
    ''')


@pytest.fixture(scope="module")
def scheme_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("schemes") / "my_bossak.toml"
    path.write_text(BOSSAK)
    return path


@pytest.fixture(scope="module")
def scheme(scheme_path):
    return dd.load_scheme(scheme_path, rebuild=True)    # derived here, not read from a cache


def galpha_step(M, C, K, dt, am, af, x, v, a, F0, F1):
    """One step of Chung & Hulbert's generalized-alpha, typed from the paper (eqs. 2-4):
    M a_{n+1-am} + C v_{n+1-af} + K x_{n+1-af} = F_{n+1-af}, Newmark's update with
    gamma = 1/2 - am + af, beta = (1 - am + af)^2 / 4."""
    gamma, beta = 0.5 - am + af, (1 - am + af) ** 2 / 4
    xp = x + dt * v + dt**2 * (0.5 - beta) * a
    vp = v + dt * (1 - gamma) * a
    # x1 = xp + beta dt^2 a1, v1 = vp + gamma dt a1
    lhs = (1 - am) * M + (1 - af) * gamma * dt * C + (1 - af) * beta * dt**2 * K
    rhs = ((1 - af) * F1 + af * F0 - am * (M @ a) - C @ ((1 - af) * vp + af * v)
           - K @ ((1 - af) * xp + af * x))
    a1 = np.linalg.solve(lhs, rhs)
    return xp + beta * dt**2 * a1, vp + gamma * dt * a1, a1


def galpha(M, C, K, F, dt, am, af=0.0):
    n = M.shape[0]
    x, v = np.zeros(n), np.zeros(n)
    a = np.linalg.solve(M, F[0])
    X = [x]
    for i in range(len(F) - 1):
        x, v, a = galpha_step(M, C, K, dt, am, af, x, v, a, F[i], F[i + 1])
        X.append(x)
    return np.array(X)


def dense(a):
    return np.asarray(a.todense()) if hasattr(a, "todense") else np.asarray(a)


def rel(x, ref):
    return float(np.abs(x - ref).max() / np.abs(ref).max())


@pytest.fixture(scope="module")
def chain30():
    rng = np.random.default_rng(30)
    N = 30
    m, k, c = rng.uniform(1, 2, N), rng.uniform(1e3, 2e3, N), rng.uniform(0.1, 1.0, N)
    f = np.zeros((301, N))
    f[:, -1] = np.sin(7.0 * 0.01 * np.arange(301))
    f[:, 10] = rng.standard_normal(301)
    return m, k, c, f


def test_issue_file_through_every_linear_entry_point(scheme, chain30):
    m, k, c, f = chain30
    dt, fd = 0.01, list(range(m.size))
    M, C, K = (dense(a) for a in dd.chain_matrices(m, k, c))
    ref = galpha(M, C, K, f, dt, -0.1)
    runs = {
        "mck c": dd.mck_response(M, C, K, f, dt, force_dofs=fd, scheme=scheme),
        "mck numpy": dd.mck_response(M, C, K, f, dt, force_dofs=fd, scheme=scheme,
                                     backend="numpy"),
        "chain displacement": dd.chain_response(m, k, c, f, dt, force_dofs=fd, scheme=scheme),
        "chain acceleration": dd.chain_response(m, k, c, f, dt, force_dofs=fd, scheme=scheme,
                                                form="acceleration"),
    }
    shaft = dd.Shaft(m, k, c, left="clamped")            # the same chain, torsional
    assert np.allclose(dense(dd.shaft_matrices(shaft)[2]), K)
    for form in ("displacement", "acceleration"):
        runs[f"shaft {form}"] = dd.shaft_response(shaft, f, dt, force_dofs=list(shaft.dof_names),
                                                  scheme=scheme, form=form)
    for name, r in runs.items():
        assert rel(r.x, ref) < 1e-10, name
        assert r.info["scheme"] == "my_bossak"


def test_issue_file_through_the_beam(scheme):
    beam = dd.Beam(E=2e11, I=1e-6, rho_A=10.0, length=2.0, elements=10)
    M, C, K = (dense(a) for a in dd.beam_matrices(beam))
    n, dt = M.shape[0], 1e-4
    f = np.zeros((301, n))
    f[:, -2] = np.sin(30.0 * dt * np.arange(301))
    ref = galpha(M, C, K, f, dt, -0.1)
    for form in ("displacement", "acceleration"):
        r = dd.beam_response(beam, f, dt, force_dofs=list(range(n)), scheme=scheme, form=form)
        assert rel(r.x, ref) < 1e-10, form


def test_parameters_as_keywords_checked_against_the_file(scheme, chain30):
    m, k, c, f = chain30
    M, C, K = (dense(a) for a in dd.chain_matrices(m, k, c))
    r = dd.chain_response(m, k, c, f, 0.01, force_dofs=list(range(m.size)), scheme=scheme,
                          alpha_m=-0.3)
    assert rel(r.x, galpha(M, C, K, f, 0.01, -0.3)) < 1e-10
    with pytest.raises(ValueError, match=r"alpha_m = 0.3 is outside \[-0.5, 0\]"):
        dd.chain_response(m, k, c, f, 0.01, force_dofs=[0], scheme=scheme, alpha_m=0.3)
    with pytest.raises(TypeError, match="did you mean 'alpha_m'"):
        dd.chain_response(m, k, c, f, 0.01, force_dofs=[0], scheme=scheme, alpha_n=-0.2)


@pytest.mark.parametrize("Omega", [0.05, 0.7, 3.0, 40.0])
@pytest.mark.parametrize("zeta", [0.0, 0.1])
def test_amplification_matrix_equals_the_hand_built_one(scheme, Omega, zeta):
    """A column by column from the hand-written step on x'' + 2 zeta w x' + w^2 x = 0 with w = 1,
    dt = Omega, on the scaled history (x, dt v, dt^2 a)."""
    dt, am = Omega, -0.1
    M, C, K = np.eye(1), np.array([[2 * zeta]]), np.eye(1)
    scale = np.array([1.0, dt, dt**2])
    A_hand = np.empty((3, 3))
    for j in range(3):
        y = np.zeros(3)
        y[j] = 1.0
        h = y / scale
        new = galpha_step(M, C, K, dt, am, 0.0, h[:1], h[1:2], h[2:], np.zeros(1), np.zeros(1))
        A_hand[:, j] = np.concatenate(new) * scale
    A = scheme.module("stability").amplification(scheme.name, np.array([Omega]), zeta, [am])[0]
    assert np.abs(A - A_hand).max() < 1e-12 * max(1.0, np.abs(A_hand).max())
    rho = dd.stability(scheme, [Omega], zeta).spectral_radius[0]
    assert abs(rho - np.abs(np.linalg.eigvals(A_hand)).max()) < 1e-12


def test_report_order_and_spectral_properties(scheme):
    rep = scheme.report()
    assert rep["order"] == 2 and rep["explicit"] is False
    assert rep["rho_inf"] == pytest.approx(0.9 / 1.1, abs=1e-9)   # (1 + am) / (1 - am)
    assert rep["critical_omega_dt"] == np.inf


@pytest.mark.parametrize("bad", [[0.0], [1.0, -2.0], [np.nan]])
def test_report_refuses_omega_dt_not_positive(scheme, bad):
    with pytest.raises(ValueError, match=r"omega_dt\[\d\] = .*finite and > 0"):
        scheme.report(omega_dt=bad)


def test_second_load_in_a_new_process_imports_no_sympy(scheme_path, scheme, chain30):
    code = textwrap.dedent(f"""
        import sys, numpy as np, dtdyn as dd
        s = dd.load_scheme({str(scheme_path)!r})
        r = dd.chain_response([1.0, 2.0], [1e3, 1e3], [1.0, 1.0], np.ones(11), 0.01,
                              force_dofs=[1], scheme=s)
        assert np.isfinite(r.x).all()
        print("sympy" in sys.modules, "jinja2" in sys.modules)
        """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ}, check=True).stdout.split()
    assert out == ["False", "False"]


def test_pickles_by_text(scheme):
    again = pickle.loads(pickle.dumps(scheme))
    assert again == scheme and again.folder == scheme.folder


def test_scene_scheme_file(tmp_path, scheme_path):
    (tmp_path / "mine.toml").write_text(BOSSAK)
    scene = dd.scene_from_dict({
        "model": {"mass": [1.0, 2.0], "stiffness": [1e3, 1e3]},
        "load": [{"dof": 1, "kind": "step", "amplitude": 1.0}],
        "scheme": {"file": "mine.toml", "alpha_m": -0.2},
        "time": {"dt": 0.01, "duration": 0.5}}, base_dir=tmp_path)
    r, _ = dd.run_scene(scene)
    direct = dd.chain_response([1.0, 2.0], [1e3, 1e3], [0.0, 0.0], np.ones(51), 0.01,
                               force_dofs=[1], scheme=dd.load_scheme(scheme_path), alpha_m=-0.2)
    assert np.array_equal(r.x, direct.x)
    with pytest.raises(ValueError, match="scheme.name .* and scheme.file"):
        dd.scene_from_dict({"model": {"mass": [1.0], "stiffness": [1.0]},
                            "scheme": {"file": "mine.toml", "name": "hht"}}, base_dir=tmp_path)


def _load(tmp_path, text, name="bad.toml"):
    path = tmp_path / name
    path.write_text(text)
    return dd.load_scheme(path)


def _relations(*rels, extra=""):
    return "name = \"bad\"\nrelations = [" + ", ".join(f'"{r}"' for r in rels) + "]\n" + extra


NEWMARK = ("x1 = x0 + dt*v0 + dt**2*(a0/4 + a1/4)", "v1 = v0 + dt*(a0 + a1)/2",
           "xe = x1", "ve = v1", "ae = a1")


@pytest.mark.parametrize("rels, message", [
    (NEWMARK[:4], r"the relations do not determine x1, v1, a1, xe, ve .* 5 needed"),
    (NEWMARK[:2] + ("xe = x1", "ve = v1", "ae = a1", "x1 = x0"),
     r"relations\[5\] = 'x1 = x0' contradicts|relations\[\d\] .* contradicts"),
    (NEWMARK[:4] + ("ae = a1 + y0",), r"relations\[4\] .*'y0'"),
    (NEWMARK[:4] + ("ae = a1.real",), r"relations\[4\] .*not allowed|relations\[4\]"),
    (NEWMARK[:4] + ("ae = __import__('os')",), r"relations\[4\]"),
    (NEWMARK[:4] + ("ae = a1*a1",), r"relations\[4\] = 'ae = a1\*a1' is not linear"),
    (NEWMARK[:4] + ("ae == a1",), r"relations\[4\] .* one equation"),
])
def test_bad_relations_refused_in_one_line(tmp_path, rels, message):
    with pytest.raises(ValueError, match=message) as exc:
        _load(tmp_path, _relations(*rels))
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("param", ["dt", "params", "N", "k0", "work", "double", "class", "x1"])
def test_parameter_names_that_reach_c_are_checked(tmp_path, param):
    rels = (f"x1 = x0 + dt*v0 + dt**2*((1/2 - {param}_)*a0 + {param}_*a1)".replace(
        f"{param}_", param),) + NEWMARK[1:]
    text = _relations(*rels, extra=f"[parameters.{param}]\ndefault = 0.25\n")
    with pytest.raises(ValueError, match=f"parameters.{param}"):
        _load(tmp_path, text)


def test_derived_order_and_claimed_order(tmp_path):
    first = ("x1 = x0 + dt*v0 + dt**2*((1/2 - bt)*a0 + bt*a1)",
             "v1 = v0 + dt*((1 - gm)*a0 + gm*a1)", "xe = x1", "ve = v1", "ae = a1")
    params = "[parameters.bt]\ndefault = 0.3025\n[parameters.gm]\ndefault = 0.6\n"
    s = _load(tmp_path, _relations(*first, extra=params))
    assert s.table["order"] == 1                                   # gamma != 1/2
    with pytest.raises(ValueError, match="order = 2 is claimed, but .* gives order 1"):
        _load(tmp_path, "order = 2\n" + _relations(*first, extra=params), "claimed.toml")


def test_explicit_file_scheme_has_the_acceleration_form_only(tmp_path):
    s = _load(tmp_path, _relations("x1 = x0 + dt*v0 + dt**2*a0/2", "v1 = v0 + dt*(a0 + a1)/2",
                                   "xe = x1", "ve = v1", "ae = a1"), "cd.toml")
    assert s.table["explicit"]
    m, k, c = [1.0, 1.0], [100.0, 100.0], [0.5, 0.5]
    ref = dd.chain_response(m, k, c, np.ones(51), 0.01, force_dofs=[1],
                            scheme="central_difference", form="acceleration")
    r = dd.chain_response(m, k, c, np.ones(51), 0.01, force_dofs=[1], scheme=s,
                          form="acceleration")
    assert rel(r.x, ref.x) < 1e-13
    # without a form: its only one, as for the built-in explicit scheme
    r = dd.chain_response(m, k, c, np.ones(51), 0.01, force_dofs=[1], scheme=s)
    assert r.info["form"] == "acceleration" and rel(r.x, ref.x) < 1e-13
    with pytest.raises(ValueError, match="explicit"):
        dd.chain_response(m, k, c, np.ones(51), 0.01, force_dofs=[1], scheme=s,
                          form="displacement")


def test_multistep_file_scheme_equals_the_built_in(tmp_path):
    s = _load(tmp_path, _relations("v1 = (11*x1 - 18*x0 + 9*xm1 - 2*xm2)/(6*dt)",
                                   "a1 = (2*x1 - 5*x0 + 4*xm1 - xm2)/dt**2",
                                   "xe = x1", "ve = v1", "ae = a1"), "houbolt2.toml")
    assert s.table["startup_steps"] == 2 and s.table["order"] == 2
    rng = np.random.default_rng(3)
    m, k, c = rng.uniform(1, 2, 8), rng.uniform(1e3, 2e3, 8), rng.uniform(0.1, 1, 8)
    f = rng.standard_normal((201, 8))
    for form in ("displacement", "acceleration"):
        a = dd.chain_response(m, k, c, f, 0.01, force_dofs=list(range(8)), scheme=s, form=form)
        b = dd.chain_response(m, k, c, f, 0.01, force_dofs=list(range(8)), scheme="houbolt",
                              form=form)
        assert rel(a.x, b.x) < 1e-13, form


def test_a_cache_folder_missing_a_file_is_rebuilt(tmp_path, scheme_path, scheme):
    victim = scheme.folder / "chain_my_bossak.c"
    text = victim.read_text()
    victim.unlink()
    try:
        again = dd.load_scheme(scheme_path)
        assert (again.folder / "chain_my_bossak.c").read_text() == text
    finally:
        if not victim.exists():
            victim.write_text(text)


# --- composite schemes: Bathe and rho_inf-Bathe, shipped as scheme files ----------------------

def bathe_oracle(M, C, K, F, dt):
    """Bathe's method (gamma = 1/2) typed from Bathe (2007): a trapezoidal sub-step of dt/2
    (load at its end, the mean of F_n and F_n+1), then v1 = (x - 4 x_g + 3 x1)/dt,
    a1 = (v - 4 v_g + 3 v1)/dt with equilibrium at t + dt."""
    n = M.shape[0]
    x, v = np.zeros(n), np.zeros(n)
    a = np.linalg.solve(M, F[0])
    X, h = [x], dt / 2
    for i in range(len(F) - 1):
        K1 = K + 2 / h * C + 4 / h**2 * M
        xg = np.linalg.solve(K1, 0.5 * (F[i] + F[i + 1]) + C @ (2 / h * x + v)
                             + M @ (4 / h**2 * x + 4 / h * v + a))
        vg = 2 / h * (xg - x) - v
        c1, c2, c3 = 1 / dt, -4 / dt, 3 / dt
        K2 = K + c3 * C + c3 * c3 * M
        x1 = np.linalg.solve(K2, F[i + 1] - C @ (c1 * x + c2 * xg)
                             - M @ (c1 * v + c2 * vg + c3 * (c1 * x + c2 * xg)))
        v1 = c1 * x + c2 * xg + c3 * x1
        a = c1 * v + c2 * vg + c3 * v1
        x, v = x1, v1
        X.append(x)
    return np.array(X)


@pytest.fixture(scope="module")
def bathe():
    return dd.load_scheme("bathe")


def test_bathe_through_every_linear_entry_point(bathe):
    rng = np.random.default_rng(5)
    N = 8
    m, k, c = rng.uniform(1, 2, N), rng.uniform(1e3, 2e3, N), rng.uniform(0.1, 1.0, N)
    M, C, K = (dense(a) for a in dd.chain_matrices(m, k, c))
    F = rng.standard_normal((201, N))
    ref = bathe_oracle(M, C, K, F, 0.01)
    fd = list(range(N))
    runs = {"mck c": dd.mck_response(M, C, K, F, 0.01, force_dofs=fd, scheme=bathe),
            "mck numpy": dd.mck_response(M, C, K, F, 0.01, force_dofs=fd, scheme=bathe,
                                         backend="numpy")}
    for form in ("displacement", "acceleration"):
        runs[f"chain {form}"] = dd.chain_response(m, k, c, F, 0.01, force_dofs=fd, scheme=bathe,
                                                  form=form)
    shaft = dd.Shaft(m, k, c, left="clamped")
    runs["shaft"] = dd.shaft_response(shaft, F, 0.01, force_dofs=list(shaft.dof_names),
                                      scheme=bathe)
    for name, r in runs.items():
        assert rel(r.x, ref) < 1e-10, name
    beam = dd.Beam(E=2e11, I=1e-6, rho_A=10.0, length=2.0, elements=6)
    Mb, Cb, Kb = (dense(a) for a in dd.beam_matrices(beam))
    fb = rng.standard_normal((101, Mb.shape[0]))
    r = dd.beam_response(beam, fb, 1e-4, force_dofs=list(range(Mb.shape[0])), scheme=bathe)
    assert rel(r.x, bathe_oracle(Mb, Cb, Kb, fb, 1e-4)) < 1e-10


def test_bathe_published_properties(bathe):
    """Second order, and rho -> 0 as Omega -> infinity at gamma = 1/2 (Bathe 2007)."""
    assert bathe.table["order"] == 2 and bathe.stages == ("bathe_s1", "bathe_s2")
    rho = dd.stability(bathe, [0.1, 1e8]).spectral_radius
    assert rho[0] > 0.9999 and rho[1] < 1e-6        # little damping where resolved, none kept
    assert dd.critical_omega_dt(bathe) == np.inf


@pytest.mark.parametrize("rho_inf", [0.0, 0.3, 0.6, 0.9])
@pytest.mark.parametrize("gamma", [0.3, 0.5, 0.7])
def test_rho_inf_bathe_reproduces_its_rho_inf(rho_inf, gamma):
    """Noh & Bathe (2019): the spectral radius at infinite frequency is rho_inf for every
    gamma, and the method is second order."""
    s = dd.load_scheme("rho_inf_bathe")
    assert s.table["order"] == 2
    rho = dd.stability(s, [1e9], rho_inf=rho_inf, gamma=gamma).spectral_radius[0]
    assert rho == pytest.approx(rho_inf, abs=1e-6)


def test_rho_inf_bathe_at_zero_is_bathe(bathe):
    rng = np.random.default_rng(6)
    M, K = np.diag(rng.uniform(1, 2, 4)), np.diag(rng.uniform(1e3, 2e3, 4))
    F = rng.standard_normal((101, 4))
    a = dd.mck_response(M, 0.01 * K, K, F, 0.01, force_dofs=[0, 1, 2, 3], scheme=bathe)
    b = dd.mck_response(M, 0.01 * K, K, F, 0.01, force_dofs=[0, 1, 2, 3],
                        scheme=dd.load_scheme("rho_inf_bathe"), rho_inf=0.0, gamma=0.5)
    assert rel(b.x, a.x) < 1e-12


def test_composite_refused_where_not_supported(bathe):
    M, K = np.eye(2), np.array([[2.0, -1.0], [-1.0, 1.0]])
    with pytest.raises(ValueError, match="composite of 2 sub-steps"):
        dd.discrete_state_space(M, 0.01 * K, K, 0.01, scheme=bathe)


def test_state_space_and_nonlinear_take_the_file_scheme(scheme):
    """The file and the built-in bossak derive to the same coefficients: the discrete models
    and the nonlinear one-step runs are equal, bitwise."""
    pytest.importorskip("casadi")
    M, K = np.diag([1.0, 2.0]), np.array([[2e3, -1e3], [-1e3, 1e3]])
    C = 0.001 * K
    a = dd.discrete_state_space(M, C, K, 0.01, scheme=scheme, alpha_m=-0.2)
    b = dd.discrete_state_space(M, C, K, 0.01, scheme="bossak", alpha_m=-0.2)
    assert np.array_equal(np.asarray(a.A), np.asarray(b.A))
    f = np.zeros((101, 2))
    f[:, 1] = 1.0
    runs = [dd.nonlinear_mck_response(M, C, K, f, 0.01, elements=[dd.Cubic(0, k3=1e6)],
                                      force_dofs=[0, 1], scheme=s) for s in (scheme, "bossak")]
    assert np.array_equal(runs[0].x, runs[1].x)


def test_run_batch_with_a_scene_scheme_file(tmp_path):
    pytest.importorskip("dask")
    (tmp_path / "mine.toml").write_text(BOSSAK)
    scene = tmp_path / "scene.toml"
    scene.write_text(textwrap.dedent("""
        [model]
        mass = [1.0, 2.0]
        stiffness = [1e3, 1e3]
        [[load]]
        dof = 1
        kind = "step"
        amplitude = 1.0
        [scheme]
        file = "mine.toml"
        alpha_m = -0.2
        [time]
        dt = 0.01
        duration = 0.2
        """))
    ds = dd.run_batch([str(scene), str(scene)], workers=1)
    direct = dd.chain_response([1.0, 2.0], [1e3, 1e3], [0.0, 0.0], np.ones(21), 0.01,
                               force_dofs=[1], scheme=dd.load_scheme(tmp_path / "mine.toml"),
                               alpha_m=-0.2)
    assert np.allclose(np.asarray(ds["x"]).reshape(2, 21, -1)[0], direct.x, rtol=0, atol=0)


def test_functions_of_the_allow_list_reach_the_generated_code(tmp_path):
    """sqrt in a substitution: the coefficient module and the amplification matrix evaluate
    it (NumPy's), and at sigma = 1/4 the scheme is average acceleration."""
    s = _load(tmp_path, _relations("x1 = x0 + dt*v0 + dt**2*((1/2 - beta)*a0 + beta*a1)",
                                   "v1 = v0 + dt*(a0 + a1)/2", "xe = x1", "ve = v1", "ae = a1",
                                   extra='[parameters.sigma]\ndefault = 0.25\nrange = [0.01, 1]\n'
                                         '[substitutions]\nbeta = "sqrt(sigma)/2"\n'), "fn.toml")
    m, k, c = [1.0, 1.0], [100.0, 100.0], [0.5, 0.5]
    a = dd.chain_response(m, k, c, np.ones(51), 0.01, force_dofs=[1], scheme=s)
    b = dd.chain_response(m, k, c, np.ones(51), 0.01, force_dofs=[1],
                          scheme="average_acceleration")
    assert rel(a.x, b.x) < 1e-14
    assert dd.stability(s, [1.0, 100.0]).spectral_radius == pytest.approx(1.0, abs=1e-12)


def test_review_findings_each_named(tmp_path):
    """A repeated relation is named redundant (not a contradiction); a power whose expansion
    would not end is refused at once; devices and folders are not read."""
    with pytest.raises(ValueError, match=r"relations\[5\] = 'xe = x1' is redundant"):
        _load(tmp_path, _relations(*NEWMARK, "xe = x1"))
    with pytest.raises(ValueError, match="degree above 64"):
        _load(tmp_path, _relations("x1 = x0 + dt*v0 + ((x0 + v0 + a0)**64)**8", *NEWMARK[1:]))
    for path in ("/dev/zero", str(tmp_path)):
        with pytest.raises(ValueError, match="not a regular file"):
            dd.load_scheme(path)


def test_multistep_file_in_the_nonlinear_solver_is_named(tmp_path):
    pytest.importorskip("casadi")
    s = _load(tmp_path, _relations("v1 = (11*x1 - 18*x0 + 9*xm1 - 2*xm2)/(6*dt)",
                                   "a1 = (2*x1 - 5*x0 + 4*xm1 - xm2)/dt**2",
                                   "xe = x1", "ve = v1", "ae = a1"), "h.toml")
    M, K = np.eye(2), np.array([[2e3, -1e3], [-1e3, 1e3]])
    with pytest.raises(ValueError, match="multistep"):
        dd.nonlinear_mck_response(M, 0.01 * K, K, np.ones((11, 2)), 0.01, force_dofs=[0, 1],
                                  elements=[dd.Cubic(0, k3=1.0)], scheme=s)


def test_accuracy_target_takes_the_derived_order(scheme):
    pytest.importorskip("casadi")
    M, K = np.eye(2), np.array([[2e3, -1e3], [-1e3, 1e3]])
    r = dd.nonlinear_mck_response(M, 0.01 * K, K, np.ones((201, 2)), 0.01, force_dofs=[0, 1],
                                  elements=[dd.Cubic(0, k3=1e3)], scheme=scheme, estimate=True)
    assert np.isfinite(r.info["error_estimate"])


def test_cli_runs_a_composite_scene_and_checks_a_shipped_scheme(tmp_path, capsys):
    from dtdyn.app._cli import main

    scene = tmp_path / "scene.toml"
    scene.write_text(textwrap.dedent("""
        [model]
        mass = [1.0, 2.0]
        stiffness = [1e3, 1e3]
        [[load]]
        dof = 1
        kind = "step"
        amplitude = 1.0
        [scheme]
        file = "BATHE"
        [time]
        dt = 0.01
        duration = 0.2
        """).replace("BATHE", str(dd.load_scheme("bathe").path)))
    assert main(["simulate", str(scene), "--no-check"]) == 0
    assert main(["scheme", "check", "bathe"]) == 0
    out = capsys.readouterr().out
    assert "order of accuracy: 2" in out and "gamma = 0.5 in [0.1, 0.9]" in out
