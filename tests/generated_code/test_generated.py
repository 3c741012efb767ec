"""Tier 2: the generated code (dtdyn.generated) against hand formulas at random points.

- every scheme's ``coefficients(form, dt, *params)`` against the maps built here from the
  reference's formulas (shared/reference.md section 4), at random dt and random admissible
  parameters;
- the generated C chain kernel against the generated NumPy sweep (chain_response backend "c" vs
  "numpy"), every scheme, both forms, both sweeps;
- the generated Laplace-domain element matrices against reference section 2.

Meaning of the coefficient names (dtdyn.derive.kernels, dtdyn.derive.dttmm): with u the primary
unknown (u = xe - x0, the increment, in the displacement form; u = ae in the acceleration form)
and h the history,
    xe = p u + q.h,   ve = r u + s.h,   ae = alpha_u u + b.h,
    x1 = x1_u u + x1.h,   v1 = v1_u u + v1.h,   a1 = a1_u u + a1.h,
and the equilibrium is enforced with the force w0 F_n + w1 F_{n+1}. A coefficient named with an
increment, q_dx0 or q_dxm1, multiplies x0 - xm1 or xm1 - xm2; `plain` expands it here.
"""
from __future__ import annotations

import importlib
import math
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

import dtdyn.generated as G
from dtdyn.generated import tmm as gtmm
from dtdyn._engine import kernels
from dtdyn import DtdynAccuracyWarning, chain_response

RTOL = 1e-13
N_DRAWS = 25


# ----------------------------------------------------------------- affine maps, typed by hand
class Aff(dict):
    """An affine map as {basis name: (coefficient, magnitude)}: u (the primary unknown) and
    history names. The magnitude is the sum of the absolute values of everything added into the
    coefficient, so a coefficient that cancels to (nearly) zero is compared at the scale of its
    terms: |generated - hand| <= RTOL * magnitude (magnitude >= |coefficient|)."""

    def __add__(self, other):
        if not isinstance(other, Aff):
            raise TypeError("add Aff to Aff only")
        out = Aff(self)
        for key, (val, mag) in other.items():
            v0, m0 = out.get(key, (0.0, 0.0))
            out[key] = (v0 + val, m0 + mag)
        return out

    __radd__ = __add__

    def __sub__(self, other):
        return self + (-1.0) * other

    def __mul__(self, a):
        return Aff({key: (a * val, abs(a) * mag) for key, (val, mag) in self.items()})

    __rmul__ = __mul__

    def __neg__(self):
        return (-1.0) * self

    def __truediv__(self, a):
        return self * (1.0 / a)


def e(name):
    return Aff({name: (1.0, 1.0)})


U = e("u")
X0, V0, A0, XM1, XM2, VM1, VM2 = (e(n) for n in ("x0", "v0", "a0", "xm1", "xm2", "vm1", "vm2"))
XE_DISPLACEMENT = U + X0  # the displacement form's unknown is the increment u = xe - x0


def newmark_hand(dt, b, g):
    """Reference sec. 4: A = 1/(beta dt^2), B = -A (x0 + dt v0 + (1/2 - beta) dt^2 a0),
    D = gamma/(beta dt), E = v0 + dt ((1 - gamma) a0 + gamma B) (B, E as maps of the history)."""
    A = 1.0 / (b * dt**2)
    B = -A * (X0 + dt * V0 + (0.5 - b) * dt**2 * A0)
    D = g / (b * dt)
    E = V0 + dt * ((1.0 - g) * A0 + g * B)
    return A, B, D, E


def alpha_family(form, dt, b, g, af, am):
    """Newmark kinematics, equilibrium at xe = (1-af) x1 + af x0 (v alike), ae = (1-am) a1 + am a0.

    Returns (xe, ve, ae, x1, v1, a1) as affine maps of u and the history.
    """
    if form == "displacement":
        A, B, D, E = newmark_hand(dt, b, g)
        x1 = (XE_DISPLACEMENT - af * X0) / (1.0 - af)
        a1 = A * x1 + B
        v1 = D * x1 + E
    else:
        a1 = (U - am * A0) / (1.0 - am)
        x1 = X0 + dt * V0 + dt**2 * ((0.5 - b) * A0 + b * a1)
        v1 = V0 + dt * ((1.0 - g) * A0 + g * a1)
    xe = (1.0 - af) * x1 + af * X0
    ve = (1.0 - af) * v1 + af * V0
    ae = (1.0 - am) * a1 + am * A0
    return xe, ve, ae, x1, v1, a1, (af, 1.0 - af)


def wilson(form, dt, theta):
    td = theta * dt
    A = 6.0 / td**2
    B = -A * (X0 + td * V0 + td**2 / 3.0 * A0)
    D = 3.0 / td
    E = V0 + td / 2.0 * (A0 + B)
    if form == "displacement":
        xe = XE_DISPLACEMENT
        ae, ve = A * xe + B, D * xe + E
    else:
        ae = U
        xe = X0 + td * V0 + td**2 / 6.0 * (ae + 2.0 * A0)
        ve = V0 + td / 2.0 * (A0 + ae)
    a1 = A0 + (ae - A0) / theta
    v1 = V0 + dt / 2.0 * (A0 + a1)
    x1 = X0 + dt * V0 + dt**2 / 6.0 * (a1 + 2.0 * A0)
    return xe, ve, ae, x1, v1, a1, (1.0 - theta, theta)


def multistep(form, A, B, D, E):
    """x1 = xe, v1 = ve = D x1 + E, a1 = ae = A x1 + B (u = x1 - x0, or u = a1 with
    x1 = (u - B)/A)."""
    x1 = XE_DISPLACEMENT if form == "displacement" else (U - B) / A
    v1 = D * x1 + E
    a1 = A * x1 + B
    return x1, v1, a1, x1, v1, a1, (0.0, 1.0)


def houbolt(form, dt):
    A = 2.0 / dt**2
    B = -(5.0 * X0 - 4.0 * XM1 + XM2) / dt**2
    D = 11.0 / (6.0 * dt)
    E = -(18.0 * X0 - 9.0 * XM1 + 2.0 * XM2) / (6.0 * dt)
    return multistep(form, A, B, D, E)


def park(form, dt):
    """v1 = (10 x1 - 15 x0 + 6 xm1 - xm2)/(6 dt), a1 = (10 v1 - 15 v0 + 6 vm1 - vm2)/(6 dt)."""
    A = 100.0 / (36.0 * dt**2)
    D = 10.0 / (6.0 * dt)
    E = (-15.0 * X0 + 6.0 * XM1 - XM2) / (6.0 * dt)
    B = (10.0 * E + (-15.0 * V0 + 6.0 * VM1 - VM2)) / (6.0 * dt)
    return multistep(form, A, B, D, E)


def hand_maps(name, form, dt, params):
    """(xe, ve, ae, x1, v1, a1, (w0, w1)) of scheme ``name`` from the formulas above."""
    presets = {"average_acceleration": (0.25, 0.5), "linear_acceleration": (1 / 6, 0.5),
               "fox_goodwin": (1 / 12, 0.5), "newmark_1_8": (0.125, 0.5), "fox_euler": (0.5, 1.0),
               "central_difference": (0.0, 0.5)}
    if name in presets:
        return alpha_family(form, dt, *presets[name], 0.0, 0.0)
    if name == "newmark":
        return alpha_family(form, dt, params["beta"], params["gamma"], 0.0, 0.0)
    if name == "hht":
        a = params["alpha"]
        return alpha_family(form, dt, (1 - a) ** 2 / 4, (1 - 2 * a) / 2, -a, 0.0)
    if name == "generalized_alpha":
        rho = params["rho_inf"]
        am, af = (2 * rho - 1) / (rho + 1), rho / (rho + 1)
        return alpha_family(form, dt, (1 - am + af) ** 2 / 4, 0.5 - am + af, af, am)
    if name == "bossak":  # Wood, Bossak & Zienkiewicz: alpha_f = 0, beta, gamma from alpha_m
        am = params["alpha_m"]
        return alpha_family(form, dt, (1 - am) ** 2 / 4, 0.5 - am, 0.0, am)
    if name == "wilson":
        return wilson(form, dt, params["theta"])
    if name == "houbolt":
        return houbolt(form, dt)
    if name == "park":
        return park(form, dt)
    raise KeyError(name)


def expected_coefficients(name, form, dt, params, history):
    """{coefficient name: (value, magnitude)} from the hand maps."""
    xe, ve, ae, x1, v1, a1, (w0, w1) = hand_maps(name, form, dt, params)
    zero = (0.0, 0.0)
    out = {"w0": (w0, abs(w0)), "w1": (w1, abs(w1)), "p": xe.get("u", zero),
           "r": ve.get("u", zero), "alpha_u": ae.get("u", zero)}
    for prefix, mp in (("q", xe), ("s", ve), ("b", ae)):
        assert set(mp) <= {"u", *history}
        out.update({f"{prefix}_{h}": mp.get(h, zero) for h in history})
    for prefix, mp in (("x1", x1), ("v1", v1), ("a1", a1)):
        out.update({f"{prefix}_{h}": mp.get(h, zero) for h in ("u", *history)})
    return out


def plain(got):
    """Coefficients with the increments expanded: c_dx0 (x0 - xm1) + c_dxm1 (xm1 - xm2)."""
    out = {}
    for key, val in got.items():
        prefix, _, name = key.rpartition("_")
        if name in ("dx0", "dxm1", "dv0", "dvm1"):
            newer = name[1:]
            older = newer[0] + ("m1" if newer.endswith("0") else "m2")
            out[f"{prefix}_{newer}"] = out.get(f"{prefix}_{newer}", 0.0) + val
            out[f"{prefix}_{older}"] = out.get(f"{prefix}_{older}", 0.0) - val
        else:
            out[key] = out.get(key, 0.0) + val
    return out


def check_coefficients(got, want, what):
    got = plain(got)
    assert set(got) <= set(want), sorted(set(got) - set(want))
    for key in sorted(want):
        val, mag = want[key]
        g = got.get(key, 0.0)  # the generated dict omits coefficients that are zero
        assert abs(g - val) <= RTOL * mag, (f"{what} {key}: generated {g!r}, hand {val!r} "
                                            f"(scale {mag!r})")


def random_params(name, rng):
    if name == "newmark":
        return {"beta": 10 ** rng.uniform(-3, 0), "gamma": rng.uniform(0.5, 1.0)}
    if name == "wilson":
        return {"theta": rng.uniform(1.0, 2.0)}
    if name == "hht":
        return {"alpha": rng.uniform(-1 / 3, 0.0)}
    if name == "generalized_alpha":
        return {"rho_inf": rng.uniform(0.0, 1.0)}
    if name == "bossak":
        return {"alpha_m": rng.uniform(-0.5, 0.0)}
    return {}


def module(name):
    return importlib.import_module(f"dtdyn.generated.scheme_{name}")


CASES = [(n, f) for n in G.SCHEMES for f in module(n).FORMS]


def test_generated_scheme_list():
    from dtdyn.derive.integrators import SCHEMES

    assert set(G.SCHEMES) == set(SCHEMES)
    assert module("central_difference").FORMS == ("acceleration",)
    assert module("central_difference").EXPLICIT is True
    for n in G.SCHEMES:
        if n != "central_difference":
            assert set(module(n).FORMS) == {"displacement", "acceleration"}, n


@pytest.mark.parametrize("name,form", CASES)
def test_coefficients_match_hand_formulas(name, form):
    mod = module(name)
    rng = np.random.default_rng(sum(map(ord, name + form)))
    assert set(random_params(name, rng)) == set(mod.PARAMS)
    for draw in range(N_DRAWS):
        dt = 10 ** rng.uniform(-5, -1)
        params = random_params(name, rng)
        if draw == 0 and mod.PARAMS:  # the defaults too
            params = dict(mod.DEFAULTS)
        got = mod.coefficients(form, dt, *(params[p] for p in mod.PARAMS))
        want = expected_coefficients(name, form, dt, params, mod.HISTORY)
        check_coefficients(got, want, f"{name} {form} dt={dt!r} params={params}")


@pytest.mark.parametrize("name", ["newmark", "wilson", "hht", "generalized_alpha"])
def test_coefficients_at_parameter_edges(name):
    edges = {"newmark": [{"beta": 0.25, "gamma": 0.5}, {"beta": 0.5, "gamma": 1.0}],
             "wilson": [{"theta": 1.0}, {"theta": (1 + math.sqrt(3)) / 2}],
             "hht": [{"alpha": 0.0}, {"alpha": -1 / 3}],
             "generalized_alpha": [{"rho_inf": 0.0}, {"rho_inf": 1.0}]}[name]
    mod = module(name)
    for params in edges:
        for form in mod.FORMS:
            for dt in (1e-5, 1e-3, 1e-1):
                got = mod.coefficients(form, dt, *(params[p] for p in mod.PARAMS))
                want = expected_coefficients(name, form, dt, params, mod.HISTORY)
                check_coefficients(got, want, f"{name} {form} dt={dt!r} params={params}")


def test_presets_equal_general_newmark():
    nm = module("newmark")
    for name, (b, g) in {"average_acceleration": (0.25, 0.5), "fox_euler": (0.5, 1.0),
                         "linear_acceleration": (1 / 6, 0.5), "fox_goodwin": (1 / 12, 0.5),
                         "newmark_1_8": (0.125, 0.5)}.items():
        for form in ("displacement", "acceleration"):
            got = module(name).coefficients(form, 3e-3)
            ref = nm.coefficients(form, 3e-3, b, g)
            assert set(got) <= set(ref)
            for key in ref:  # the preset omits what is exactly zero for its beta, gamma
                assert_allclose(got.get(key, 0.0), ref[key], rtol=RTOL, atol=0,
                                err_msg=f"{name} {key}")


def test_hht_and_generalized_alpha_limits_equal_average_acceleration():
    avg = module("average_acceleration")
    for form in ("displacement", "acceleration"):
        ref = avg.coefficients(form, 2e-3)
        for got in (module("hht").coefficients(form, 2e-3, 0.0),
                    module("generalized_alpha").coefficients(form, 2e-3, 1.0)):
            for key in ("p", "r", "alpha_u"):
                assert_allclose(got[key], ref[key], rtol=RTOL, atol=0)
        hht = module("hht").coefficients(form, 2e-3, 0.0)
        assert set(ref) <= set(hht)
        for key in hht:
            assert_allclose(hht[key], ref.get(key, 0.0), rtol=RTOL, atol=0, err_msg=key)


# ----------------------------------------------------------------- C kernel vs NumPy sweep
def c_available():
    return all(kernels.c_chain_function(n) is not None for n in G.SCHEMES)


def stable_params(name, rng):
    """Random parameters in the unconditionally stable range of each scheme."""
    if name == "newmark":
        g = rng.uniform(0.5, 0.7)
        return {"gamma": g, "beta": (g + 0.5) ** 2 / 4 + rng.uniform(0.0, 0.1)}
    if name == "wilson":
        return {"theta": rng.uniform(1.37, 2.0)}
    if name == "hht":
        return {"alpha": rng.uniform(-1 / 3, 0.0)}
    if name == "generalized_alpha":
        return {"rho_inf": rng.uniform(0.0, 1.0)}
    if name == "bossak":
        return {"alpha_m": rng.uniform(-0.5, 0.0)}
    return {}


def random_chain(n, rng, k_scale, c_scale):
    m = rng.uniform(0.5, 2.0, n)
    k = k_scale * rng.uniform(0.5, 1.5, n)
    c = c_scale * rng.uniform(0.5, 1.5, n)  # > 0 everywhere: central difference needs it
    return m, k, c


def compare_backends(name, form, sweep, n_mass, dt, k_scale, c_scale, seed, n_steps=200):
    rng = np.random.default_rng(seed)
    m, k, c = random_chain(n_mass, rng, k_scale, c_scale)
    loaded = np.sort(rng.choice(n_mass, 3, replace=False))
    force = rng.standard_normal((n_steps + 1, 3))
    params = stable_params(name, rng)
    kw = dict(force_dofs=loaded, scheme=name, form=form, sweep=sweep, **params)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DtdynAccuracyWarning)  # the chains are well conditioned
        rc = chain_response(m, k, c, force, dt, backend="c", **kw)
        rn = chain_response(m, k, c, force, dt, backend="numpy", **kw)
    assert rc.info["backend"] == "c" and rn.info["backend"] == "numpy"
    for q in ("x", "v", "a"):
        xc, xn = getattr(rc, q), getattr(rn, q)
        assert xc.shape == xn.shape == (n_steps + 1, n_mass)
        scale = np.max(np.abs(xn))
        assert np.isfinite(scale) and scale > 0.0
        assert_allclose(xc, xn, rtol=0, atol=1e-12 * scale, err_msg=f"{name} {form} {sweep} {q}")


@pytest.mark.skipif(not c_available(), reason="no C compiler: the C kernels are not built")
@pytest.mark.parametrize("name,form", CASES)
def test_c_kernel_matches_numpy_stable(name, form):
    compare_backends(name, form, "stable", 30, 2e-3, 5e3, 2.0, sum(map(ord, name + form)))


@pytest.mark.skipif(not c_available(), reason="no C compiler: the C kernels are not built")
@pytest.mark.parametrize("name,form", CASES)
def test_c_kernel_matches_numpy_plain(name, form):
    # The plain sweep is only as accurate as its transfer-matrix product allows (entries grow
    # like (1 + m alpha/kappa)^N): the two backends can agree to 1e-12 only where the plain
    # sweep itself is that accurate. Heavy damping makes kappa = k p + c r >~ m alpha, so the
    # product stays small; omega_max dt ~ 1.6 < 2 keeps central difference stable.
    compare_backends(name, form, "plain", 5, 1e-2, 2e3, 1e3, 7 + sum(map(ord, name + form)))


# ----------------------------------------------------------------- Laplace-domain elements
def test_tmm_element_matrices():
    rng = np.random.default_rng(3)
    for _ in range(50):
        s = complex(rng.normal(0, 100), rng.normal(0, 1000))
        k, c, m, F = rng.uniform(0.1, 1e4), rng.uniform(0, 100), rng.uniform(0.1, 10), rng.normal()
        assert_allclose(gtmm.spring_damper(k, c, s),
                        np.array([[1, 1 / (k + c * s), 0], [0, 1, 0], [0, 0, 1]]), rtol=RTOL)
        assert_allclose(gtmm.mass(m, s), np.array([[1, 0, 0], [m * s**2, 1, 0], [0, 0, 1]]),
                        rtol=RTOL)
        assert_allclose(gtmm.force(F), np.array([[1, 0, 0], [0, 1, -F], [0, 0, 1]]), rtol=RTOL)


def test_tmm_two_dof_product_matches_closed_form():
    """The generated elements, multiplied as in reference sec. 2, give x1/F and x2/F."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        s = complex(rng.normal(0, 10), rng.normal(0, 100))
        m1, m2 = rng.uniform(0.5, 5, 2)
        k1, k2 = rng.uniform(10, 1e3, 2)
        c1, c2 = rng.uniform(0.1, 10, 2)
        F = 1.0
        S1 = gtmm.force(F) @ gtmm.mass(m1, s) @ gtmm.spring_damper(k1, c1, s)
        S2 = gtmm.force(0.0) @ gtmm.mass(m2, s) @ gtmm.spring_damper(k2, c2, s)
        Usys = S2 @ S1
        f_base = -Usys[1, 2] / Usys[1, 1]
        z0 = np.array([0.0, f_base, 1.0])
        x1, x2 = (S1 @ z0)[0], (Usys @ z0)[0]
        P = (m1 * m2 * s**4 + (c2 * m1 + c2 * m2 + c1 * m2) * s**3
             + (k2 * m2 + k1 * m2 + k2 * m1 + c1 * c2) * s**2 + (k2 * c1 + k1 * c2) * s + k1 * k2)
        assert_allclose(x1 / F, (m2 * s**2 + c2 * s + k2) / P, rtol=1e-10)
        assert_allclose(x2 / F, (c2 * s + k2) / P, rtol=1e-10)


@pytest.mark.parametrize("name", [n for n, f in CASES if f == "displacement"])
def test_displacement_form_reads_displacements_as_increments(name):
    """The velocity and acceleration maps of the displacement form never multiply a stored
    displacement (size |x|, times 1/dt or 1/dt^2), only increments x0 - xm1, ... or the
    unknown u = xe - x0 (dtdyn.derive.dttmm): that is what keeps the form accurate as dt -> 0."""
    mod = module(name)
    got = mod.coefficients("displacement", 1e-3, *(mod.DEFAULTS[p] for p in mod.PARAMS))
    absolute = [k for k in got if k.split("_")[0] in ("s", "b", "v1", "a1")
                and k.split("_", 1)[1] in ("x0", "xm1", "xm2")]
    assert not absolute, absolute
