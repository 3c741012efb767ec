"""Torsional shafts, gears and trees (issue #14, torsion).

Independent truths: the matrices are assembled here by hand from each element's energy (a gear
as the constraint phi_side = -phi_parent / n, T^T k_e T per shaft), not by shaft_matrices; the
frequencies are scipy.linalg.eigh of that (M, K); the time histories are mck_response on it
(same scheme, same dt); a continuous shaft's frequencies are the closed form (2j - 1) pi c / (2 L)
(clamped-free) and the roots of the clamped shaft with a tip disk, found here by a fine scan.
"""
import math
import time

import numpy as np
import pytest
import scipy.linalg as sla

import dtdyn as dd

SCHEMES = ["newmark", "hht", "generalized_alpha", "wilson", "houbolt", "fox_goodwin"]


def hand_matrices(dofs, disks, shafts, grounds):
    """M, C, K (dense) from disks {name: J}, shafts [(parent or None, child, k, c, ratio or None)]
    and grounds {name: (kg, cg)}: each shaft stores 1/2 k (phi_child - g phi_parent)^2 with
    g = -1/ratio across a gear (phi on the gear's driven side), 1 without."""
    n = len(dofs)
    ix = {d: i for i, d in enumerate(dofs)}
    M, C, K = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    for d, J in disks.items():
        M[ix[d], ix[d]] += J
    for parent, child, k, c, ratio in shafts:
        g = 1.0 if ratio is None else -1.0 / ratio
        if parent is None:
            T = np.zeros((1, n))
            T[0, ix[child]] = 1.0
            ke = np.array([[1.0]])
        else:
            T = np.zeros((2, n))
            T[0, ix[parent]] = g
            T[1, ix[child]] = 1.0
            ke = np.array([[1.0, -1.0], [-1.0, 1.0]])
        K += T.T @ (k * ke) @ T
        C += T.T @ (c * ke) @ T
    for d, (kg, cg) in grounds.items():
        K[ix[d], ix[d]] += kg
        C[ix[d], ix[d]] += cg
    return M, C, K


def five_disk():
    J = [1.0, 2.0, 1.5, 0.7, 1.2]
    k = [1e4, 2e4, 1.5e4, 3e4, 2e4]
    c = [1.0, 2.0, 0.5, 1.0, 0.3]
    s = dd.Shaft(J, k, c, left="clamped")
    dofs = [f"main.{i}" for i in range(5)]
    shafts = [(None, "main.0", k[0], c[0], None)] + [
        (f"main.{i - 1}", f"main.{i}", k[i], c[i], None) for i in range(1, 5)]
    return s, hand_matrices(dofs, dict(zip(dofs, J)), shafts, {}), dofs


def geared():
    """Motor - shaft - pinion | gear n = 3 | shaft - disk - shaft - disk - shaft to a wall."""
    s = dd.Shaft([0.8, 0.2], [5e3, 2e4], [0.5, 0.5], left="elastic",
                 branches=[dd.Branch(1, [0.6, 1.1], [8e3, 6e3], [0.4, 0.2], ratio=3.0,
                                     right="clamped", right_stiffness=4e3, right_damping=0.1,
                                     name="out")])
    dofs = ["main.0", "main.1", "out.0", "out.1"]
    disks = dict(zip(dofs, [0.8, 0.2, 0.6, 1.1]))
    shafts = [(None, "main.0", 5e3, 0.5, None), ("main.0", "main.1", 2e4, 0.5, None),
              ("main.1", "out.0", 8e3, 0.4, 3.0), ("out.0", "out.1", 6e3, 0.2, None)]
    return s, hand_matrices(dofs, disks, shafts, {"out.1": (4e3, 0.1)}), dofs


def branched():
    """One gear (on disk 1 of the main line) driving two branches, one of them branching again
    directly, with ground springs and dampers; free left end (a motor on bearings)."""
    s = dd.Shaft([1.0, 0.3, 0.9], [0.0, 1.2e4, 9e3], [0.0, 0.8, 0.3], left="free",
                 ground_stiffness=[2e3, 0.0, 0.0], ground_damping=[0.5, 0.0, 0.0],
                 branches=[
                     dd.Branch(1, [0.5, 0.4, 0.7], [6e3, 5e3, 7e3], [0.2, 0.2, 0.1], ratio=2.0,
                               name="left", ground_stiffness=[0.0, 1e3, 0.0],
                               branches=[dd.Branch(2, [0.25], [3e3], [0.05], name="leaf")]),
                     dd.Branch(1, [0.6, 0.45], [4e3, 8e3], [0.3, 0.1], ratio=-3.5, name="right",
                               right="clamped", right_stiffness=2e3)])
    dofs = ["main.0", "main.1", "main.2", "left.0", "left.1", "left.2", "leaf.0", "right.0",
            "right.1"]
    disks = dict(zip(dofs, [1.0, 0.3, 0.9, 0.5, 0.4, 0.7, 0.25, 0.6, 0.45]))
    shafts = [("main.0", "main.1", 1.2e4, 0.8, None), ("main.1", "main.2", 9e3, 0.3, None),
              ("main.1", "left.0", 6e3, 0.2, 2.0), ("left.0", "left.1", 5e3, 0.2, None),
              ("left.1", "left.2", 7e3, 0.1, None), ("left.2", "leaf.0", 3e3, 0.05, None),
              ("main.1", "right.0", 4e3, 0.3, -3.5), ("right.0", "right.1", 8e3, 0.1, None)]
    grounds = {"main.0": (2e3, 0.5), "left.1": (1e3, 0.0), "right.1": (2e3, 0.0)}
    return s, hand_matrices(dofs, disks, shafts, grounds), dofs


SYSTEMS = {"five_disk": five_disk, "geared": geared, "branched": branched}


@pytest.mark.parametrize("name", SYSTEMS)
def test_matrices_equal_hand_assembly(name):
    s, (M, C, K), dofs = SYSTEMS[name]()
    Ms, Cs, Ks = dd.shaft_matrices(s)
    names = s.dof_names
    assert list(names) == dofs
    for a, b in ((Ms, M), (Cs, C), (Ks, K)):
        np.testing.assert_allclose(a.toarray(), b, rtol=0, atol=1e-12 * np.abs(b).max())


@pytest.mark.parametrize("name", SYSTEMS)
def test_frequencies_equal_eigh(name):
    s, (M, _, K), _ = SYSTEMS[name]()
    ref = np.sqrt(sla.eigh(K, M, eigvals_only=True))
    w = dd.shaft_frequencies(s)
    assert w.size == ref.size
    assert np.abs(w - ref).max() <= 1e-10 * ref.max()
    np.testing.assert_allclose(dd.shaft_frequencies(s, count=3), w[:3], rtol=0, atol=0)
    below = dd.shaft_frequencies(s, below=0.5 * (ref[2] + ref[3]))
    np.testing.assert_array_equal(below, w[:3])


@pytest.mark.parametrize("name", SYSTEMS)
@pytest.mark.parametrize("form", ["displacement", "acceleration"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_time_history_equals_assembled(name, form, scheme):
    s, (M, C, K), dofs = SYSTEMS[name]()
    dt, n = 2e-3, 400
    t = dt * np.arange(n + 1)
    force = np.c_[np.where(t > 0.05, 10.0, 0.0), 3.0 * np.sin(40.0 * t)]
    fd = [len(dofs) - 1, 1]
    x0 = 1e-3 * np.arange(len(dofs))
    r = dd.shaft_response(s, force, dt, force_dofs=[dofs[i] for i in fd], scheme=scheme,
                          form=form, x0=x0)
    ref = dd.mck_response(M, C, K, force, dt, force_dofs=fd, scheme=scheme, x0=x0)
    for q in "xva":
        a, b = getattr(r, q), getattr(ref, q)
        assert np.abs(a - b).max() <= 1e-9 * np.abs(b).max(), q


@pytest.mark.parametrize("form", ["displacement", "acceleration"])
def test_numpy_backend_equals_c(form):
    s, (M, C, K), dofs = branched()
    force = np.ones(301)
    rc = dd.shaft_response(s, force, 1e-3, force_dofs=["leaf.0"], form=form, scheme="hht")
    rn = dd.shaft_response(s, force, 1e-3, force_dofs=["leaf.0"], form=form, scheme="hht",
                           backend="numpy")
    assert rn.info["backend"] == "numpy"
    assert np.abs(rc.x - rn.x).max() <= 1e-12 * np.abs(rc.x).max()


def test_explicit_central_difference():
    s, (M, C, K), dofs = five_disk()
    dt = 1e-4
    f = np.ones(501)
    r = dd.shaft_response(s, f, dt, force_dofs=[4], scheme="central_difference",
                          form="acceleration")
    ref = dd.mck_response(M, C, K, f, dt, force_dofs=[4], scheme="central_difference")
    assert np.abs(r.x - ref.x).max() <= 1e-9 * np.abs(ref.x).max()


def test_continuous_clamped_free_closed_form():
    L, G, Jp, rho = 2.0, 8e10, 1e-6, 7800.0
    seg = dd.ContinuousShaft(L, G, Jp, rho, elements=40)
    s = dd.Shaft([0.0], [seg], left="clamped")
    c = math.sqrt(G * Jp / (rho * Jp))
    ref = (2 * np.arange(1, 9) - 1) * math.pi * c / (2 * L)
    w = dd.shaft_frequencies(s, count=8)
    assert np.abs(w / ref - 1).max() <= 1e-12
    w2 = dd.shaft_frequencies(s, below=ref[4] * (1 + 1e-9))
    assert w2.size == 5 and np.abs(w2 / ref[:5] - 1).max() <= 1e-12
    # the lumped segments (time domain) converge to it at second order
    lumped = dd.shaft_frequencies(s, count=2, exact=False)
    assert 0 < 1 - lumped[0] / ref[0] < 1e-3


def test_continuous_with_tip_disk_no_root_missed():
    """Clamped shaft with a tip disk J_d: z beta tan(beta) = J_d omega^2... written
    z beta cot(beta) = J_d omega^2 (z = G J_p / L, omega = beta c / L); roots by a fine scan."""
    L, G, Jp, rho, Jd = 1.5, 8e10, 2e-6, 7800.0, 0.02
    s = dd.Shaft([Jd], [dd.ContinuousShaft(L, G, Jp, rho)])
    z, c = G * Jp / L, math.sqrt(G / rho)
    w = dd.shaft_frequencies(s, count=6)

    def f(beta):  # sin-weighted, continuous: z beta cos - J_d (beta c / L)^2 sin
        return z * beta * np.cos(beta) - Jd * (beta * c / L) ** 2 * np.sin(beta)
    beta = np.linspace(1e-6, w[-1] * L / c * 1.0001, 2_000_001)
    fv = f(beta)
    roots = beta[:-1][np.sign(fv[:-1]) != np.sign(fv[1:])]
    roots = roots[np.abs(np.sin(roots)) > 1e-3]  # (sin beta = 0 is not a root of the original)
    assert roots.size == 6
    assert np.abs(w * L / c - roots).max() <= 2 * (beta[1] - beta[0])  # the scan's grid
    from scipy.optimize import brentq
    exact = np.array([brentq(f, r - 1e-5, r + 1e-5) for r in roots])
    assert np.abs(w * L / c / exact - 1).max() <= 1e-10


def test_continuous_between_disks_matches_fine_lumping():
    seg = dd.ContinuousShaft(1.0, 8e10, 1e-6, 7800.0, elements=400)
    s = dd.Shaft([1.0, 0.5], [1e4, seg],
                 branches=[dd.Branch(1, [0.3], [2e4], ratio=3.0, name="g")])
    exact = dd.shaft_frequencies(s, count=5)
    lumped = dd.shaft_frequencies(s, count=5, exact=False)
    coarse = dd.Shaft([1.0, 0.5], [1e4, dd.ContinuousShaft(1.0, 8e10, 1e-6, 7800.0, elements=200)],
                      branches=[dd.Branch(1, [0.3], [2e4], ratio=3.0, name="g")])
    err2, err1 = (np.abs(w / exact - 1) for w in (lumped, dd.shaft_frequencies(coarse, count=5,
                                                                                 exact=False)))
    assert np.all((err1[2:] / err2[2:] > 3.9) & (err1[2:] / err2[2:] < 4.1))  # second order
    M, C, K = dd.shaft_matrices(s)
    ref = np.sqrt(sla.eigh(K.toarray(), M.toarray(), eigvals_only=True)[:5])
    assert np.abs(lumped - ref).max() <= 1e-10 * ref.max()


def _big_tree(N):
    """A main line of N / 2 disks and a branch through a gear at its middle (N / 2 disks)."""
    h = N // 2
    rng = np.random.default_rng(1)
    br = dd.Branch(h // 2, rng.uniform(0.5, 1.5, N - h), rng.uniform(5e3, 2e4, N - h),
                   np.full(N - h, 0.1), ratio=1.5, name="b")
    return dd.Shaft(rng.uniform(0.5, 1.5, h), rng.uniform(5e3, 2e4, h), np.full(h, 0.1),
                    branches=[br])


def test_ten_thousand_station_tree_equals_sparse_newmark_and_scales_linearly():
    s = _big_tree(10_000)
    M, C, K = dd.shaft_matrices(s)
    f = np.ones(201)
    out = [0, 4_999, 9_999]
    r = dd.shaft_response(s, f, 1e-3, force_dofs=[9_999], outputs=out)
    ref = dd.mck_response(M, C, K, f, 1e-3, force_dofs=[9_999], outputs=out)
    assert np.abs(r.x - ref.x).max() <= 1e-9 * np.abs(ref.x).max()
    # O(N) per step: 10x the stations costs about 10x (not 100x), best of three
    times = {}
    for n in (1_000, 10_000):
        sh = _big_tree(n)
        best = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            dd.shaft_response(sh, np.ones(501), 1e-3, force_dofs=[n - 1], outputs=[0])
            best = min(best, time.perf_counter() - t0)
        times[n] = best
    assert times[10_000] / times[1_000] < 30


@pytest.mark.parametrize("kwargs, match", [
    (dict(inertia=[1.0, -2.0], stiffness=[1.0, 1.0]), r"inertia\[1\] = -2.0"),
    (dict(inertia=[1.0, 2.0], stiffness=[1.0, "x"]), r"stiffness\[1\] = 'x'"),
    (dict(inertia=[1.0, 2.0], stiffness=[1.0, 0.0]), r"stiffness\[1\] = damping\[1\] = 0"),
    (dict(inertia=[1.0, 2.0], stiffness=[5.0, 1.0], left="free"), r"stiffness\[0\] = 5.0"),
    (dict(inertia=[1.0], stiffness=[1.0], left="pinned"), r"left = 'pinned'"),
    (dict(inertia=[1.0], stiffness=[1.0], right="clamped"), r"right = 'clamped' needs"),
    (dict(inertia=[1.0], stiffness=[1.0], branches=[dd.Branch(3, [1.0], [1.0], name="b")]),
     r"branch 'b' at = 3"),
    (dict(inertia=[1.0], stiffness=[1.0], branches=[dd.Branch(0, [1.0], [-1.0], name="b")]),
     r"branch 'b' stiffness\[0\] = -1.0"),
    (dict(inertia=[0.0], stiffness=[1.0]), r"disk 'main.0' has inertia 0"),
])
def test_bad_input_names_field_and_value(kwargs, match):
    with pytest.raises(ValueError, match=match):
        dd.Shaft(**kwargs)


def test_bad_gear_and_segment_and_dofs():
    with pytest.raises(ValueError, match=r"ratio = 0.0"):
        dd.Branch(0, [1.0], [1.0], ratio=0.0)
    with pytest.raises(ValueError, match=r"ContinuousShaft G = -1.0"):
        dd.ContinuousShaft(1.0, -1.0, 1.0, 1.0)
    s = dd.Shaft([1.0, 1.0], [1.0, 1.0])
    with pytest.raises(ValueError, match=r"no DOF named 'main.7'"):
        dd.shaft_response(s, np.ones(3), 0.01, force_dofs=["main.7"])
    with pytest.raises(ValueError, match=r"count = 0"):
        dd.shaft_frequencies(s, count=0)
    seg = dd.Shaft([0.0], [dd.ContinuousShaft(1.0, 1.0, 1.0, 1.0)])
    with pytest.raises(ValueError, match=r"count or below is required"):
        dd.shaft_frequencies(seg)


def test_support_motion_of_a_geared_tree():
    """Supports turning with an angular acceleration record: the relative response equals the
    assembled model loaded by -M r a_g, with r written by hand (1 on the main line, -1/n on a
    line behind a gear of ratio n, -1/n * 1/m two gears deep), and a_abs = a + r a_g."""
    inner = dd.Branch(0, [0.2], [3e3], ratio=-1.5, name="c")
    gear = dd.Branch(1, [0.5, 0.4], [6e3, 5e3], [0.2, 0.2], ratio=2.0, name="a",
                     branches=[inner])
    s = dd.Shaft([1.0, 0.3, 0.9], [1e4, 1.2e4, 9e3], [0.5, 0.8, 0.3], branches=[gear])
    r_hand = {"main": 1.0, "a": -1 / 2.0, "c": (-1 / 2.0) * (-1 / -1.5)}
    r = np.array([r_hand[name.split(".")[0]] for name in s.dof_names])
    dt = 1e-3
    t = np.arange(1001) * dt
    ag = 40.0 * np.sin(2 * np.pi * 7.0 * t)
    res = dd.shaft_response(s, None, dt, ground_acceleration=ag, scheme="hht", alpha=-0.1)
    M, C, K = dd.shaft_matrices(s)
    ref = dd.mck_response(M, C, K, -np.outer(ag, M @ r), dt, scheme="hht", alpha=-0.1)
    for q in "xva":
        assert np.abs(getattr(res, q) - getattr(ref, q)).max() \
            <= 1e-9 * np.abs(getattr(ref, q)).max(), q
    np.testing.assert_allclose(res.a_abs, res.a + np.outer(ag, r), rtol=0, atol=1e-12)
    # a rigid turn deforms no shaft or gear: K r vanishes but at the wall's disk (its shaft to
    # the wall is fixed in the relative coordinates)
    assert np.abs((K @ r)[1:]).max() <= 1e-12 * abs(K).max()


@pytest.mark.parametrize("form", ["displacement", "acceleration"])
@pytest.mark.parametrize("grounded", [False, True])
@pytest.mark.parametrize("many", [0, 1])
def test_blocked_tree_loop_at_block_edges(form, grounded, many):
    """The C tree loop works in blocks of 256 stations and takes two plain line stations a
    round: branches hanging at block edges (stations 255 and 256), a geared branch at the last
    disk of the main line (its parent is station n - 1, but through a gear), a branch of a
    branch without a gear and an odd number of stations: equal to mck_response."""
    rng = np.random.default_rng(7)

    def line(n):
        return rng.uniform(0.5, 1.5, n), rng.uniform(5e3, 2e4, n), rng.uniform(0.05, 0.2, n)

    extra = dict(ground_stiffness=rng.uniform(0.0, 1e3, 301)) if grounded else {}
    sub = dd.Branch(10, *line(17), name="sub")
    s = dd.Shaft(*line(301), **extra, branches=[
        dd.Branch(255, *line(120), ratio=2.0, name="b255", branches=[sub]),
        dd.Branch(256, *line(33), name="b256"),
        dd.Branch(300, *line(64), ratio=-1.5, name="tail")])
    M, C, K = dd.shaft_matrices(s)
    n = M.shape[0]
    # loads on a few stations (the loop then skips the force row and redoes them): plain ones,
    # the root and a branch's first station; and on every fifth station (the force row read)
    fd = [[n - 1, 150, 0, s.dof("b255.0")], list(range(0, n, 5))][many]
    f = np.sin(np.outer(np.arange(301) * 0.1, np.arange(1, len(fd) + 1)))
    r = dd.shaft_response(s, f, 1e-3, force_dofs=fd, form=form, scheme="hht")
    ref = dd.mck_response(M, C, K, f, 1e-3, force_dofs=fd, scheme="hht")
    for q in "xva":
        a, b = getattr(r, q), getattr(ref, q)
        assert np.abs(a - b).max() <= 1e-9 * np.abs(b).max(), q
