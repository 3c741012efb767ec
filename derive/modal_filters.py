"""Modal digital filters (Ahlin, Josefsson & Magnevall): step, impulse and ramp invariant.

One first-order modal term y' = s y + R x has the exact solution

    y((n+1)T) = e^{sT} y(nT) + R * integral_0^T e^{s(T-u)} x(nT + u) du,

and the way x is rebuilt between samples defines the filter:

- step invariant (x held at x_n):                 y_{n+1} = e^{sT} y_n + c0 x_n
- impulse invariant (x = T sum x_n delta(t - nT)):  y_{n+1} = e^{sT} y_n + c1 x_{n+1}
- ramp invariant (x linear between samples):      y_{n+1} = e^{sT} y_n + c0 x_n + c1 x_{n+1}

SymPy evaluates the integral for each hold and writes the coefficients with z = sT through
phi1(z) = (e^z - 1)/z and phi2(z) = (e^z - 1 - z)/z^2, which the kernels evaluate without the
cancellation of the closed forms when |z| is small (high sampling rate). A conjugate pair of terms
folds into one real second-order section

    (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2),  a1 = -2 e^{sigma T} cos(omega T),
                                                       a2 = e^{2 sigma T},

and a real pole (overdamped mode) into a first-order section.

The per-mode form keeps the complex recursion instead (`increment_form`): one state per mode and
residue factor, updated as eta <- eta + (d eta + c0 p_n + c1 p_{n+1}) with d = e^{sT} - 1 =
z phi1(z). Storing d (to ~ eps |d|, i.e. the pole to ~ eps |sT|) instead of
a1 = -2 e^{sigma T} cos(omega T) (whose rounding moves the pole angle omega T by ~ eps / (omega T))
makes the phase error of a lightly damped mode after n samples ~ n eps |sT| instead of
~ n eps / (omega T).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import sympy as sp

s = sp.Symbol("s")
T = sp.Symbol("T", positive=True)
u = sp.Symbol("u", positive=True)
R = sp.Symbol("R")
z = sp.Symbol("z")
x0, x1 = sp.symbols("x_n x_n1")

INVARIANTS = ("step", "impulse", "ramp")


def phi1(zz):
    return (sp.exp(zz) - 1) / zz


def phi2(zz):
    return (sp.exp(zz) - 1 - zz) / zz**2


@dataclass(frozen=True)
class Invariant:
    """y_{n+1} = e^{sT} y_n + c0 x_n + c1 x_{n+1}; c0, c1 as closed forms in s, T, R and as
    R T (k1 phi1(z) + k2 phi2(z) + k0) with z = sT (``phi`` = (k0, k1, k2) for c0 and c1)."""

    name: str
    c0: sp.Expr
    c1: sp.Expr
    phi: tuple


def _input_between_samples(name):
    if name == "step":
        return x0
    if name == "ramp":
        return x0 + (x1 - x0) * u / T
    raise ValueError(name)


@cache
def derive_invariant(name: str) -> Invariant:
    """Evaluate the convolution integral for one hold and identify its phi-function form."""
    if name == "impulse":
        # x(t) = T sum_k x_k delta(t - kT): on (nT, (n+1)T] only the sample at u = T counts
        forced = R * T * x1
    else:
        integrand = R * sp.exp(s * (T - u)) * _input_between_samples(name)
        forced = sp.integrate(sp.expand(integrand), (u, 0, T), conds="none")
    forced = sp.expand(forced)
    c0 = sp.simplify(forced.coeff(x0))
    c1 = sp.simplify(forced.coeff(x1))
    assert sp.simplify(forced - c0 * x0 - c1 * x1) == 0
    phi = tuple(_phi_form(c, name) for c in (c0, c1))
    return Invariant(name, c0, c1, phi)


def _phi_form(c, name):
    """(k0, k1, k2) with c = R T (k0 + k1 phi1(sT) + k2 phi2(sT)), found and checked
    symbolically."""
    k0, k1, k2 = sp.symbols("k0 k1 k2")
    target = R * T * (k0 + k1 * phi1(s * T) + k2 * phi2(s * T))
    for cand in ((0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (0, 1, -1)):
        trial = target.subs(dict(zip((k0, k1, k2), cand)))
        if sp.simplify(sp.expand(trial - c)) == 0:
            return cand
    raise ValueError(f"{name}: coefficient {c} is not a small combination of phi1, phi2")


# --- folding a conjugate pair into a real second-order section --------------------------------
pr, pi, c0r, c0i, c1r, c1i = sp.symbols("p_re p_im c0_re c0_im c1_re c1_im", real=True)


@cache
def fold_pair():
    """Real SOS of  (c1 + c0 z^-1)/(1 - p z^-1) + conjugate  for
    y_n = p y_{n-1} + c1 x_n + c0 x_{n-1}.

    Returns {b0, b1, b2, a1, a2} in p = p_re + j p_im, c0, c1 (real and imaginary parts).
    """
    p = pr + sp.I * pi
    c0 = c0r + sp.I * c0i
    c1 = c1r + sp.I * c1i
    w = sp.Symbol("w")  # w = z^-1
    num = sp.expand((c1 + c0 * w) * (1 - sp.conjugate(p) * w)
                    + (sp.conjugate(c1) + sp.conjugate(c0) * w) * (1 - p * w))
    den = sp.expand((1 - p * w) * (1 - sp.conjugate(p) * w))
    out = {f"b{k}": sp.simplify(sp.re(num.coeff(w, k))) for k in range(3)}
    out.update({f"a{k}": sp.simplify(sp.re(den.coeff(w, k))) for k in (1, 2)})
    for k in range(3):
        assert sp.simplify(sp.im(num.coeff(w, k))) == 0
    return out


def phi_series(order: int = 18):
    """Taylor coefficients of phi1 and phi2 about 0 (for |z| small), from SymPy's series."""
    out = []
    for f in (phi1, phi2):
        ser = sp.series(f(z), z, 0, order).removeO()
        out.append([sp.Rational(ser.coeff(z, k)) for k in range(order)])
    return out


# --- the per-mode recursion in increment form -------------------------------------------------
e_re, e_im, d_re, d_im = sp.symbols("e_re e_im d_re d_im", real=True)
g0r, g0i, g1r, g1i = sp.symbols("g0_re g0_im g1_re g1_im", real=True)
xa, xb = sp.symbols("x_a x_b", real=True)  # input sample before (x_n) and after (x_{n+1})


@cache
def increment_form():
    """Real increments of eta_{n+1} = e^{sT} eta_n + g0 x_n + g1 x_{n+1} with e^{sT} = 1 + d.

    eta = e_re + j e_im, d = d_re + j d_im, g0 = c0 v, g1 = c1 v (c0, c1 of `derive_invariant` with
    unit residue, v the input factor of the residue R = u v). Returns {"e_re": ..., "e_im": ...},
    the increments eta_{n+1} - eta_n, after checking them against the complex recursion and
    d = z phi1(z) = e^z - 1 symbolically. One input column; several inputs add their terms.
    """
    eta = e_re + sp.I * e_im
    d = d_re + sp.I * d_im
    nxt = (1 + d) * eta + (g0r + sp.I * g0i) * xa + (g1r + sp.I * g1i) * xb
    inc = {"e_re": d_re * e_re - d_im * e_im + g0r * xa + g1r * xb,
           "e_im": d_re * e_im + d_im * e_re + g0i * xa + g1i * xb}
    assert sp.expand(sp.re(nxt) - e_re - inc["e_re"]) == 0
    assert sp.expand(sp.im(nxt) - e_im - inc["e_im"]) == 0
    assert sp.simplify(z * phi1(z) - (sp.exp(z) - 1)) == 0
    return inc
