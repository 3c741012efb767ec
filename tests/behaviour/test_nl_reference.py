"""The nonlinear reference (runtime/nl_reference.py) against independent truths.

Linear limit: the matrix exponential (exact_response). Nonlinear: a second solver (Radau), the
same force function sampled twice as finely, Bouc-Wen's closed-form loading branch and the energy
balance of its hysteresis loop.
"""

import numpy as np
import pytest

from dtdyn.nonlinear import _reference as nl_reference
from dtdyn.nonlinear._elements import BoucWen, Cubic
from dtdyn.linear._exact import exact_response
from dtdyn.nonlinear._reference import check_reference, reference_response
from problems import p4, rel_error


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """Every test writes its cache files into its own folder."""
    monkeypatch.setenv("DTDYN_CACHE", str(tmp_path / "cache"))


def _args(P, elements=None):
    return dict(M=P["M"], C=P["C"], K=P["K"], force=P["force"], dt=P["dt"],
                force_dofs=P["force_dofs"],
                elements=P["elements"] if elements is None else elements)


# ---------------------------------------------------------------------------------------------
# (a) linear limit: the matrix exponential with the same first-order hold

@pytest.mark.parametrize("elements", [(), [Cubic(0, None, k3=0.0), Cubic(1, 2, k3=0.0)]],
                         ids=["no elements", "cubic k3=0"])
def test_linear_limit_equals_matrix_exponential(elements):
    n = 2000
    P = p4(n)
    ref = reference_response(**_args(P, elements), cache=False)
    ex = exact_response(P["M"], P["C"], P["K"], P["force"], P["dt"],
                        force_dofs=P["force_dofs"])
    assert ref.x.shape == (n, 4)
    np.testing.assert_allclose(ref.t, ex.t, rtol=0, atol=1e-12)
    for q in "xva":
        assert rel_error(getattr(ref, q), getattr(ex, q)) < 1e-10, q


# ---------------------------------------------------------------------------------------------
# (b) P4, the cubic chain

def test_p4_dop853_and_radau_agree():
    P = p4(300)
    assert check_reference(**_args(P), n_samples=300) < 1e-9


def test_p4_same_force_sampled_twice_as_finely():
    """The piecewise-linear force with its midpoints inserted is the same function of time; the
    run restarts twice as often (and at a tighter rtol) and must land on the same samples."""
    n = 1000
    P = p4(n)
    f = P["force"][:, 0]
    f2 = np.interp(np.arange(2 * n - 1) / 2.0, np.arange(n), f)[:, None]
    a = reference_response(**_args(P), cache=False)
    b = reference_response(**{**_args(P), "force": f2, "dt": P["dt"] / 2}, rtol=1e-13, cache=False)
    for q in "xva":
        assert rel_error(getattr(a, q), getattr(b, q)[::2]) < 1e-10, q


def test_p4_cubic_forces_matter():
    """Peak cubic over peak linear force of the two springs: 0.72 and 0.51 over these 5000
    samples, 1.33 and 0.85 over all 100,000 (dtdyn.app._problems.p4)."""
    P = p4(5000)
    x = reference_response(**_args(P), cache=False).x
    y = np.stack([x[:, 0], x[:, 1] - x[:, 2]], axis=1)       # the two cubic springs
    ratio = np.max(np.abs(P["k3"] * y ** 3), axis=0) / np.max(np.abs(P["k"] * y), axis=0)
    np.testing.assert_allclose(ratio, [0.718, 0.514], rtol=1e-2)


def test_outputs_and_n_samples():
    P = p4(400)
    full = reference_response(**_args(P), cache=False)
    part = reference_response(**_args(P), outputs=[3, 0], n_samples=250, cache=False)
    assert part.x.shape == part.v.shape == part.a.shape == (250, 2)
    np.testing.assert_array_equal(part.outputs, [3, 0])
    np.testing.assert_allclose(part.t, np.arange(250) / 1000.0)
    np.testing.assert_array_equal(part.x, full.x[:250, [3, 0]])   # a prefix of the full run
    assert np.all(full.x[0] == 0) and np.all(full.v[0] == 0)


# ---------------------------------------------------------------------------------------------
# (c) Bouc-Wen hysteresis

def _bouc_wen_case():
    fs, n = 1000.0, 1001                                      # two cycles of a 2 Hz force
    t = np.arange(n) / fs
    force = (150.0 * np.sin(2 * np.pi * 2.0 * t))[:, None]
    el = BoucWen(0, None, stiffness=1e4, alpha=0.1, A=1.0, beta=50.0, gamma=50.0, n=1.0)
    # damping 40 N s/m (20 % at the initial stiffness) settles the loop within the first cycle
    return dict(force=force, dt=1 / fs, M=[[1.0]], C=[[40.0]], K=[[0.0]], force_dofs=[0],
                elements=[el]), t, el


def test_bouc_wen_loop():
    P, t, el = _bouc_wen_case()
    r = reference_response(**_args(P), cache=False)
    y, v, a = r.x[:, 0], r.v[:, 0], r.a[:, 0]
    z = r.info["internal"][:, 0]
    g = el.alpha * el.stiffness * y + (1 - el.alpha) * el.stiffness * z

    # first loading branch (y' >= 0, z >= 0, n = 1): dz/dy = A - (beta + gamma) z, so
    # z = A / (beta + gamma) * (1 - exp(-(beta + gamma) y))
    k1 = int(np.argmax(v < 0))
    assert k1 > 50
    bg = el.beta + el.gamma
    z_branch = el.A / bg * (1 - np.exp(-bg * y[:k1]))
    assert np.max(np.abs(z[:k1] - z_branch)) < 1e-9 * np.max(z_branch)
    assert z.max() < el.A / bg                                 # bounded by the ultimate z

    # the second cycle is a closed loop enclosing a positive area: the dissipated energy
    cyc = slice(500, 1001)
    span = np.ptp(y[cyc])
    assert abs(y[1000] - y[500]) < 1e-3 * span
    dissipated = np.trapezoid(g[cyc], y[cyc])                  # closed integral of g dy
    assert dissipated > 0.05 * np.ptp(g[cyc]) * span

    # energy balance over the cycle: work in = kinetic change + viscous + hysteretic
    work = np.trapezoid(P["force"][cyc, 0] * v[cyc], t[cyc])
    viscous = np.trapezoid(40.0 * v[cyc] ** 2, t[cyc])
    kinetic = 0.5 * (v[1000] ** 2 - v[500] ** 2)
    assert abs(work - (kinetic + viscous + dissipated)) < 1e-3 * work
    # and the equation of motion holds at the samples
    np.testing.assert_allclose(a + 40.0 * v + g, P["force"][:, 0], rtol=0, atol=1e-9 * 150)


def test_bouc_wen_dop853_and_radau_agree():
    P, _, _ = _bouc_wen_case()
    assert check_reference(**_args(P), n_samples=1001) < 1e-8


# ---------------------------------------------------------------------------------------------
# (d) the disk cache

def _cache_files():
    return sorted(nl_reference.reference_cache_dir().iterdir())


def test_cache_reuses_identical_arrays():
    P = p4(1000)
    first = reference_response(**_args(P))
    files = _cache_files()
    assert not first.info["cached"] and len(files) == 1 and files[0].suffix == ".npz"
    second = reference_response(**_args(P))
    assert second.info["cached"] and second.info["n_rhs"] == 0  # read, not integrated again
    for q in "xva":
        np.testing.assert_array_equal(getattr(first, q), getattr(second, q))
    # another output selection reads the same file; another k3 or ODE solver does not
    assert reference_response(**_args(P), outputs=[1]).info["cached"]
    other = reference_response(**_args(P, [Cubic(0, None, k3=1e7), Cubic(1, 2, k3=2e7)]))
    assert not other.info["cached"]
    assert len(_cache_files()) == 2


@pytest.mark.parametrize("damage", ["garbage", "truncated"])
def test_corrupt_cache_file_is_not_read(damage):
    P = p4(200)
    good = reference_response(**_args(P))
    path = nl_reference.reference_cache_dir() / good.info["cache_file"].split("/")[-1]
    data = path.read_bytes()
    path.write_bytes(b"not a zip file" if damage == "garbage" else data[: len(data) // 2])
    again = reference_response(**_args(P))
    assert not again.info["cached"]
    np.testing.assert_array_equal(again.x, good.x)
    assert reference_response(**_args(P)).info["cached"]        # rewritten whole


def test_interrupted_write_leaves_no_file(monkeypatch):
    P = p4(200)

    def crash(fh, **arrays):
        fh.write(b"PK\x03\x04 partial")
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(nl_reference.np, "savez", crash)
        with pytest.raises(KeyboardInterrupt):
            reference_response(**_args(P))
    assert _cache_files() == []                                # neither the file nor a temp
    assert not reference_response(**_args(P)).info["cached"]


# ---------------------------------------------------------------------------------------------
# (e) bad inputs

def _bad(**change):
    P = p4(20)
    P.update(change)
    return P


@pytest.mark.parametrize("change, match", [
    (dict(dt=0.0), "dt"),
    (dict(dt=-1e-3), "dt"),
    (dict(force=np.full((20, 1), np.nan)), r"force\[0, 0\]"),
    (dict(force=np.zeros((20, 2))), "force has shape"),
    (dict(force=np.zeros((2, 20, 1))), "force has shape"),
    (dict(force_dofs=[4]), "force_dofs"),
    (dict(force_dofs=None), "force has shape"),
    (dict(M=np.diag([1.0, 1.0, 1.0, 0.0])), "nonsingular mass matrix"),
    (dict(K=np.eye(3)), "K has shape"),
    (dict(elements=[Cubic(0, 4, k3=1.0)]), "outside the model's DOFs"),
    (dict(elements=["cubic"]), "not a dtdyn element"),
])
def test_bad_inputs(change, match):
    P = _bad(**change)
    with pytest.raises(ValueError, match=match):
        reference_response(**_args(P), cache=False)


@pytest.mark.parametrize("kw, match", [
    (dict(ode_solver="RK45"), "ode_solver"),
    (dict(rtol=0.0), "rtol"),
    (dict(atol=-1.0), "atol"),
    (dict(atol=[1e-12] * 3), "atol"),
    (dict(n_samples=21), "n_samples"),
    (dict(n_samples=0), "n_samples"),
    (dict(outputs=[7]), "outputs"),
])
def test_bad_options(kw, match):
    P = p4(20)
    with pytest.raises(ValueError, match=match):
        reference_response(**_args(P), cache=False, **kw)
