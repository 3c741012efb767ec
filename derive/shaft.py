"""Torsional shafts with disks, gears and branches (trees): station matrices and sweeps.

State z = [phi, T, 1]: the rotation and the internal torque (twisting the shaft positively when
the right end turns ahead of the left). Elements, Laplace domain (s):

    disk (inertia J, spring k_g and damper c_g to the ground):
        T_R = T_L + (J s^2 + k_g + c_g s) phi
    shaft spring-damper (k_t, c_t):                             phi_R = phi_L + T / (k_t + c_t s)
    gear mesh, ratio n (side 2 turns n times slower, backwards): phi_2 = -phi_1 / n,  T_2 = -n T_1
    continuous uniform shaft (G, J_p, rho, length L):           z_R = exp(A L) z_L,
        A = [[0, 1/(G J_p)], [rho J_p s^2, 0]]  (T = G J_p phi',  rho J_p phi_tt = T')

In time the disk and the shaft are the chain's mass and spring-damper with x -> phi, f -> T,
m -> J (dtdyn.derive.dttmm: x = p u + q, v = r u + s, a = alpha u + b at every disk), so the
torsional station matrix *is* dttmm.station_step(); `torsional_station()` rebuilds it from the
torsional laws and checks that. A continuous shaft is cut into lumped segments in time.

Riccati relation: T = S phi + R on the left of every station (S once per run, R every step).
Through any element with matrix E ([phi, T, 1]) it transforms as

    S_L = (S_R E11 - E21) / (E22 - S_R E12),   R_L = (S_R E13 + R_R - E23) / (E22 - S_R E12),

which for the gear gives S_L = S_R / n^2 and R_L = -R_R / n (`gear_riccati`): the branch on the
far side of a gear is seen through its ratio squared, its load through the ratio. A junction (a
disk with several shafts leaving it on the right) balances the torques of all of them, so the
relations of its branches add: S_R = sum_c S_c, R_R = sum_c R_c (`junction`), each branch's
pair first carried through its gear. The unknown goes forward the same way: u_2 = -u_1 / n (the
gear's E11), and the history terms q, s of a disk seen across a gear scale alike (they are
rotations and velocities). One backward pass (leaves to root) carries S (once) and R (each
step), one forward pass u: O(N) per step for any tree.

Frequencies (Wittrick-Williams): with s = i omega the undamped stations are real. Written with
an element's dynamic stiffness [[a, b], [b, a]] (T at both ends against phi at both ends; a
spring: a = k_t, b = -k_t; a continuous shaft: a = (G J_p / L) beta cot beta,
b = -(G J_p / L) beta / sin beta, beta = omega L sqrt(rho / G), derived from exp(A L) by
`dynamic_stiffness`), eliminating disk by disk from the leaves gives the pivots

    D = a + k_g - omega^2 J - S_R,    S_L = -(a - b^2 / D)   (times gear factors into the parent)

which are the same recursion as the time-domain S with mu = k_g - omega^2 J, kappa = a. The
number of natural frequencies below omega is the number of negative pivots plus J_0, the
number of clamped-clamped frequencies of the continuous segments below omega
(floor(beta / pi) each; `clamped_clamped_count`).
"""
from __future__ import annotations

import sympy as sp

from . import dttmm

s = sp.Symbol("s")
omega = sp.Symbol("omega", positive=True)
J, kt, ct = sp.symbols("J k_t c_t", positive=True)
kg, cg = dttmm.kg, dttmm.cg
n = sp.Symbol("n", nonzero=True)  # gear ratio
G, Jp, rho, L = sp.symbols("G J_p rho L", positive=True)
x = sp.Symbol("x")
S_R, R_R = dttmm.S_R, dttmm.R_R
a, b = sp.symbols("a b")  # an element's dynamic stiffness entries


# --- Laplace domain ---------------------------------------------------------------------------

def disk():
    """Point matrix of a disk with its ground spring and damper: T_R = T_L + (J s^2 + k_g +
    c_g s) phi."""
    return sp.Matrix([[1, 0, 0], [J * s**2 + kg + cg * s, 1, 0], [0, 0, 1]])


def shaft_spring():
    """Field matrix of a massless shaft (spring k_t parallel to damper c_t)."""
    return sp.Matrix([[1, 1 / (kt + ct * s), 0], [0, 1, 0], [0, 0, 1]])


def gear():
    """Point matrix of a gear mesh of ratio n: phi_2 = -phi_1 / n, T_2 = -n T_1 (power
    T_1 phi_1' = T_2 phi_2' passes unchanged)."""
    return sp.Matrix([[-1 / n, 0, 0], [0, -n, 0], [0, 0, 1]])


def continuous_generator():
    """A of z' = A z for the uniform shaft: phi' = T / (G J_p), T' = rho J_p s^2 phi."""
    return sp.Matrix([[0, 1 / (G * Jp)], [rho * Jp * s**2, 0]])


def continuous_field():
    """exp(A L), the exact field matrix of a uniform continuous shaft ([phi, T])."""
    E = (continuous_generator() * L).exp()
    E = E.applyfunc(lambda e: sp.simplify(e.rewrite(sp.cosh)))
    # check: dE/dL = A E and E(0) = I
    assert sp.simplify(E.diff(L) - continuous_generator() * E) == sp.zeros(2, 2)
    assert sp.simplify(E.subs(L, 0)) == sp.eye(2)
    return E


def dynamic_stiffness(E):
    """(a, b) of the 2x2 field matrix E of a symmetric element: [T_L, T_R] = [[a, b], [b, a]]
    [phi_L, phi_R] up to the sign of T_L (T_L = -(a phi_L + b phi_R) is the torque on the
    element's left end): from phi_R = E11 phi_L + E12 T, T = (phi_R - E11 phi_L) / E12."""
    return sp.simplify(E[0, 0] / E[0, 1]), sp.simplify(-1 / E[0, 1])


def continuous_stiffness():
    """The continuous shaft's (a, b) at s = i omega, real: beta = omega L sqrt(rho / G)."""
    E = continuous_field()
    beta = sp.Symbol("beta", positive=True)
    out = []
    for e in dynamic_stiffness(E):
        e = sp.simplify(e.subs(s, sp.I * omega).rewrite(sp.exp))
        e = sp.simplify(sp.simplify(e.rewrite(sp.cos)).subs(omega, beta / (L * sp.sqrt(rho / G))))
        out.append(sp.simplify(e))
    a_c, b_c = out
    # the oracle in the module docstring
    assert sp.simplify(a_c - G * Jp / L * beta * sp.cos(beta) / sp.sin(beta)) == 0
    assert sp.simplify(b_c + G * Jp / L * beta / sp.sin(beta)) == 0
    return beta, a_c, b_c


def clamped_clamped_count():
    """J_0 of one continuous segment: its clamped-clamped frequencies (sin beta = 0, beta =
    j pi) below beta: floor(beta / pi)."""
    beta = sp.Symbol("beta", positive=True)
    return beta, sp.floor(beta / sp.pi)


# --- Riccati transforms -----------------------------------------------------------------------

def riccati(E):
    """(S_L, R_L) from T_R = S_R phi_R + R_R through the element matrix E ([phi, T, 1])."""
    den = E[1, 1] - S_R * E[0, 1]
    return (sp.simplify((S_R * E[0, 0] - E[1, 0]) / den),
            sp.simplify((S_R * E[0, 2] + R_R - E[1, 2]) / den))


def gear_riccati():
    """The gear's factors: u_2 = g_u u_1 (and q, s alike), S_1 = g_S S_2, R_1 = g_R R_2."""
    Gm = gear()
    S_L, R_L = riccati(Gm)
    g_u = Gm[0, 0]
    g_S = sp.simplify(S_L / S_R)
    g_R = sp.simplify(R_L / R_R)
    assert sp.simplify(S_L - g_S * S_R) == 0 and sp.simplify(R_L - g_R * R_R) == 0
    assert sp.simplify(g_S - g_u**2) == 0 and sp.simplify(g_R - g_u) == 0
    return {"u": g_u, "S": g_S, "R": g_R}


def junction(n_branches: int = 2):
    """The relation on the left of a disk that has n_branches shafts leaving it: its torque
    balance T_L = sum_c T_c - (disk terms) with T_c = S_c phi + R_c gives S_R = sum S_c,
    R_R = sum R_c before the disk (checked against the disk's point matrix with one S_R)."""
    Sc = sp.symbols(f"S_1:{n_branches + 1}")
    Rc = sp.symbols(f"R_1:{n_branches + 1}")
    phi = sp.Symbol("phi")
    mu_ = J * s**2 + kg + cg * s
    T_L = sum(Si * phi + Ri for Si, Ri in zip(Sc, Rc)) - mu_ * phi
    S_one, R_one = riccati(disk())
    summed = S_one.subs(S_R, sum(Sc)) * phi + R_one.subs(R_R, sum(Rc))
    assert sp.simplify(T_L - summed) == 0
    return sum(Sc), sum(Rc)


def torsional_station():
    """The DT-TMM station (shaft then disk then torque) from the torsional laws, equal to the
    chain's dttmm.station_step() (J in the place of m)."""
    T = sp.Symbol("T")
    u_p, u = sp.symbols("u_p u")
    p, r, q_n, q_p, s_n, s_p, alpha, b_n, F = (dttmm.p, dttmm.r, dttmm.q_n, dttmm.q_p,
                                               dttmm.s_n, dttmm.s_p, dttmm.alpha, dttmm.b_n,
                                               dttmm.F_n)
    # shaft: T = k_t (phi_n - phi_{n-1}) + c_t (phi_n' - phi_{n-1}'), phi = p u + q, phi' = r u + s
    u_sol = sp.solve(sp.Eq(T, kt * ((p * u + q_n) - (p * u_p + q_p))
                           + ct * ((r * u + s_n) - (r * u_p + s_p))), u)[0]
    # disk: J phi'' + k_g phi + c_g phi' = T_R - T_L + F
    T_R = T + J * (alpha * u + b_n) + kg * (p * u + q_n) + cg * (r * u + s_n) - F
    T_R = sp.expand(T_R.subs(u, u_sol))
    Tm = sp.Matrix([[sp.diff(u_sol, u_p), sp.diff(u_sol, T), u_sol.subs({u_p: 0, T: 0})],
                    [sp.diff(T_R, u_p), sp.diff(T_R, T), T_R.subs({u_p: 0, T: 0})],
                    [0, 0, 1]])
    chain = dttmm.station_step().subs({dttmm.kappa: dttmm.KAPPA, dttmm.Delta: dttmm.DELTA,
                                       dttmm.mu: dttmm.MU, dttmm.beta: dttmm.BETA})
    chain = chain.subs({dttmm.k: kt, dttmm.c: ct, dttmm.m: J})
    assert sp.simplify(Tm - chain) == sp.zeros(3, 3)
    return Tm


def frequency_pivot():
    """(D, S_L) of the Wittrick-Williams elimination in the dynamic-stiffness entries (a, b),
    derived from the Riccati transform through the element's field matrix (a, b) and the
    undamped disk (mu = k_g - omega^2 J): D = a + mu - S_R, S_L = -(a - b^2 / D)."""
    lam = sp.Symbol("lam")
    E = sp.Matrix([[-a / b, -1 / b, 0], [b - a**2 / b, -a / b, 0], [0, 0, 1]])  # field from (a, b)
    assert [sp.simplify(e) for e in dynamic_stiffness(E)] == [a, b]
    mu_ = kg - lam * J
    S_disk = S_R - mu_  # the disk's point matrix (s^2 = -lam): S_L = S_R - mu
    den = E[1, 1] - S_disk * E[0, 1]  # the transform's divisor, = D / b... written as a pivot
    S_L = sp.simplify((S_disk * E[0, 0] - E[1, 0]) / den)
    D = sp.expand(a + mu_ - S_R)
    assert sp.simplify(S_L - (-(a - b**2 / D))) == 0
    # the lumped spring (a = k, b = -k) gives the time-domain recursion with kappa = k
    chain_S = dttmm.derive_sweeps().S_expr.subs({dttmm.kappa: kt, dttmm.mu: mu_})
    assert sp.simplify(S_L.subs({a: kt, b: -kt}) - chain_S) == 0
    # S_L in the pivot D (the guarded divisor) and in s = D - a = k_g - lam J - S_R, what the
    # node adds to its connection: S_L = -(a s + (a - b)(a + b)) / D. For a lumped spring
    # (b = -a, so the product is exactly 0) this is -a s / (a + s), the series springs of
    # chain_frequencies, where -a + b^2 / D would cancel to about eps a absolute (a stiff
    # spring next to soft ones: 1.8e-7 relative on mode 1)
    Dsym = sp.Symbol("D")
    s_node = kg - lam * J - S_R
    S_in_D = -(a * s_node + (a - b) * (a + b)) / Dsym
    assert sp.simplify(S_in_D.subs(Dsym, D) - S_L) == 0
    return lam, D, S_in_D


# --- emission ---------------------------------------------------------------------------------

def _np(e):
    """NumPy text (np.tan, np.floor) of an expression with transcendental functions."""
    from sympy.printing.numpy import NumPyPrinter
    return NumPyPrinter({"fully_qualified_modules": False}).doprint(e)


def numpy_context() -> dict:
    """What generated/shaft.py and generated/shaft.md print."""
    from . import emit, printing
    sw = dttmm.derive_sweeps()
    gr = gear_riccati()
    ratio = sp.Symbol("ratio")
    beta, a_c, b_c = continuous_stiffness()
    _, j0 = clamped_clamped_count()
    lam, D, S_D = frequency_pivot()
    torsional_station()
    junction(2)
    Ec = continuous_field()
    scalar = lambda e: printing.py(sp.sympify(e).xreplace(emit.SCALAR))  # noqa: E731
    py = lambda e, names=emit.PY_ARRAY: printing.py(sp.sympify(e).xreplace(names))  # noqa: E731
    return {
        "gear_u": printing.py(gr["u"].subs(n, ratio)),
        "gear_S": printing.py(gr["S"].subs(n, ratio)),
        "gear_R": printing.py(gr["R"].subs(n, ratio)),
        "cont_a": _np(sp.simplify(a_c * L / (G * Jp)) * sp.Symbol("z")),
        "cont_b": _np(sp.simplify(b_c * L / (G * Jp)) * sp.Symbol("z")),
        "cont_beta": _np(sp.sqrt(rho / G) * L),
        "j0": _np(j0),
        "pivot": printing.py(D.xreplace({kg: sp.Symbol("kg[n]"), J: sp.Symbol("J[n]"),
                                          a: sp.Symbol("a[n]")})),
        "S_L_pivot": printing.py(S_D.xreplace({a: sp.Symbol("a[n]"), b: sp.Symbol("b[n]"),
                                               kg: sp.Symbol("kg[n]"), J: sp.Symbol("J[n]")})),
        "S_py": scalar(sw.S_expr), "g_py": scalar(sw.g), "a_py": scalar(sw.a_fwd),
        "den_py": scalar(sw.den), "S_doc": py(sw.S_expr), "g_doc": py(sw.g),
        "a_doc": py(sw.a_fwd), "den_doc": py(sw.den),
        "h_py": py(sw.h_num), "bf_py": py(sw.b_num),
        "latex": {
            "disk": sp.latex(disk()), "spring": sp.latex(shaft_spring()),
            "gear": sp.latex(gear()), "A": sp.latex(continuous_generator()),
            "field": sp.latex(Ec), "a": sp.latex(a_c), "b": sp.latex(b_c),
            "beta": sp.latex(sp.Eq(beta, omega * L * sp.sqrt(rho / G))),
            "j0": sp.latex(j0),
            "gear_S": sp.latex(gr["S"]), "gear_R": sp.latex(gr["R"]), "gear_u": sp.latex(gr["u"]),
            "station": sp.latex(torsional_station().applyfunc(sp.factor)),
            "S": sp.latex(sw.S_expr), "g": sp.latex(sw.g), "h": sp.latex(sw.h),
            "a_fwd": sp.latex(sw.a_fwd), "b_fwd": sp.latex(sw.b_fwd),
            "D": sp.latex(D), "S_L_pivot": sp.latex(S_D),
        },
    }


def c_context(scheme_ctx: dict, chain_macros: dict) -> dict:
    """The per-scheme C file of the tree loop: the chain's derived macros (the torsional
    station is the chain's) without the plain sweep."""
    forms = []
    for f in chain_macros["forms"]:
        forms.append({"form": f["form"], "constants": f["constants"], "g": f["g"], "S": f["S"],
                      "den": f["den"], "hD": f["hD"],
                      "q": f["q"], "s": f["s"], "b": f["b"],
                      "update_lines": ["const double x1 = " + f["x1"] + ";",
                                 "const double v1 = " + f["v1"] + ";",
                                 "const double a1 = " + f["a1"] + ";"] + scheme_ctx["shift"]})
    history = [f"double *{h} = hist + {i} * N;" for i, h in enumerate(scheme_ctx["history"])]
    return {"forms": forms, "history_lines": history, "name": scheme_ctx["name"],
            "title": scheme_ctx["title"], "history": scheme_ctx["history"]}


def render(render_fn, scheme_context, chain_macros, schemes) -> None:
    """Emit generated/shaft.py, shaft.md and shaft_<scheme>.c through ``render_fn`` (emit's
    render(template, dest, source, **ctx))."""
    ctx = {**numpy_context(), **receptance_context()}
    render_fn("numpy/shaft.py.jinja", "shaft.py", "dtdyn.derive.shaft", **ctx)
    render_fn("markdown/shaft.md.jinja", "shaft.md", "dtdyn.derive.shaft", **ctx["latex"],
              **ctx["latex_s"])
    for name in schemes:
        sc = scheme_context(name)
        cc = c_context(sc, chain_macros(sc))
        render_fn("c/shaft.c.jinja", f"shaft_{name}.c",
                  f"dtdyn.derive.shaft with dtdyn.derive.integrators.SCHEMES[{name!r}]", **cc)


# --- frequency responses and mode shapes: the tree's solve in the Laplace domain -------------

tau = sp.Symbol("tau", nonnegative=True)  # a continuous shaft's damping time c_t L / (G J_p)
gamma = sp.Symbol("gamma")


def continuous_stiffness_laplace():
    """(a, b) of a continuous shaft at any s, with its damping as a Kelvin-Voigt modulus
    G (1 + tau s), tau = c_t L / (G J_p) (each of the time domain's lumped segments has
    c / k = tau, so both models share it): with z = G J_p / L and
    gamma = s L sqrt(rho / (G (1 + tau s))),

        a = z (1 + tau s) gamma / tanh(gamma),    b = -z (1 + tau s) gamma / sinh(gamma),

    derived from exp(A L) by `dynamic_stiffness` with G -> G (1 + tau s), checked at s = i omega
    against the undamped (a, b) of `continuous_stiffness`."""
    E = continuous_field()
    z = sp.Symbol("z", positive=True)
    kv = 1 + tau * s
    g_of_s = s * L * sp.sqrt(rho / G) / sp.sqrt(kv)
    a_t = z * kv * gamma / sp.tanh(gamma)
    b_t = -z * kv * gamma / sp.sinh(gamma)
    a_d, b_d = dynamic_stiffness(E)
    # tau of the lumped segments: c / k = (c_t E) / (G J_p E / L), whatever E
    ct, nE = sp.symbols("c_t E", positive=True)
    assert sp.simplify((ct * nE) / (G * Jp * nE / L) - ct * L / (G * Jp)) == 0
    # G -> G (1 + tau s) in the field matrix, then the closed forms at gamma(s)
    import random
    rng = random.Random(14)
    for _ in range(4):
        vals = {G: rng.uniform(1, 3), Jp: rng.uniform(1, 3), rho: rng.uniform(1, 3),
                L: rng.uniform(0.5, 2), tau: rng.uniform(0, 0.3),
                s: complex(rng.uniform(-0.3, 0.1), rng.uniform(0.2, 3))}
        Gs = vals[G] * (1 + vals[tau] * vals[s])
        ref = [complex(e.subs(G, sp.Symbol("Gc")).subs({**vals, sp.Symbol("Gc"): Gs}).evalf(30))
               for e in (a_d, b_d)]
        gv = complex(g_of_s.subs(vals).evalf(30))
        zv = vals[G] * vals[Jp] / vals[L]
        got = [complex(e.subs({z: zv, tau: vals[tau], s: vals[s], gamma: gv}).evalf(30))
               for e in (a_t, b_t)]
        assert all(abs(x - y) <= 1e-12 * max(1.0, abs(x)) for x, y in zip(ref, got)), (ref, got)
    # undamped, s = i omega: gamma = i beta and the real (a, b) of the frequency count
    beta_c, a_c, b_c = continuous_stiffness()
    at_iw = [e.subs({tau: 0, gamma: sp.I * beta_c}) for e in (a_t, b_t)]
    assert sp.simplify((at_iw[0] - a_c.subs(G * Jp / L, z)).rewrite(sp.exp)) == 0
    assert sp.simplify((at_iw[1] - b_c.subs(G * Jp / L, z)).rewrite(sp.exp)) == 0
    return z, g_of_s, a_t, b_t


def receptance_sweep():
    """The tree's dynamic-stiffness system Z(s) phi = F solved from the leaves, for one node n
    with its connection (a, b) to the parent through the gear factor g_u = g (phi on the
    parent's side of the connection: g phi_p) and its own terms mu = J s^2 + c_g s + k_g.

    With S_R the sum of its children's S_L (each times g_S = g^2) and y the node's load plus its
    children's condensed loads (each times g_R = g), the node's row is D phi_n + b g phi_p = y,

        D = mu + a - S_R,    S_L = -(a - b^2 / D),    y_parent += g R_L,  R_L = -b y / D,
        phi_n = (y - b g phi_p) / D                    (forward, root to leaves),

    derived here by eliminating phi_n from the two-node system (checked: the parent's row then
    carries g^2 (a - b^2 / D) phi_p and the load -g b y / D). Undamped at s^2 = -lam it is the
    pivot of the Wittrick-Williams count (`frequency_pivot`)."""
    D, y, phi_p, phi_n, g = sp.symbols("D y phi_p phi_n g")
    mu_s = J * s**2 + cg * s + kg
    row = sp.Eq(D * phi_n + b * g * phi_p, y)
    fwd = sp.solve(row, phi_n)[0]
    # the connection's torque on the parent, carried through the gear: g (b phi_n + a g phi_p)
    on_parent = sp.expand(g * (b * fwd + a * g * phi_p))
    stiff = sp.simplify(on_parent.coeff(phi_p))
    load = sp.simplify(on_parent - stiff * phi_p)
    S_L = -(a - b**2 / D)
    R_L = -b * y / D
    gr = gear_riccati()
    gsym = sp.Symbol("ratio")
    assert sp.simplify(stiff - (-S_L) * g**2) == 0
    assert sp.simplify(-load - g * R_L) == 0
    assert sp.simplify(gr["S"] - gr["u"]**2) == 0 and sp.simplify(gr["R"] - gr["u"]) == 0
    pivot = mu_s + a - S_R
    lam = sp.Symbol("lam")
    _, D_ww, _ = frequency_pivot()
    assert sp.simplify(pivot.subs({s**2: -lam, cg: 0}).subs(s, 0) - D_ww) == 0
    del gsym
    return {"mu": mu_s, "pivot": pivot, "S_L": S_L, "R_L": R_L,
            "forward": fwd.subs(g, sp.Symbol("g"))}


def receptance_context() -> dict:
    """The expressions generated/shaft.py's `continuous_stiffness_s` and `tree_solve` print."""
    from . import printing
    z, g_of_s, a_t, b_t = continuous_stiffness_laplace()
    sw = receptance_sweep()
    arr = {J: sp.Symbol("J"), kg: sp.Symbol("kg"), cg: sp.Symbol("cg"), a: sp.Symbol("a[n]"),
           b: sp.Symbol("b[n]")}
    Dn, yn, gn, pp = sp.symbols("D[n] y[n] gu[n] phi_p")
    D_, y_, g_, ph_ = sp.symbols("D y g phi_p")
    c_seg = sp.Symbol("c_t", nonnegative=True)
    a_k, b_k = dynamic_stiffness(shaft_spring()[:2, :2])  # the shaft spring-damper's (a, b)
    return {
        "spring_a_s": printing.py(a_k.xreplace({kt: sp.Symbol("k"), ct: sp.Symbol("c")})),
        "spring_b_s": printing.py(b_k.xreplace({kt: sp.Symbol("k"), ct: sp.Symbol("c")})),
        "mu_s_node": printing.py(sw["mu"].xreplace({J: sp.Symbol("J"), kg: sp.Symbol("kg"),
                                                    cg: sp.Symbol("cg")})),
        "cont_gamma_s": _np(g_of_s), "cont_tau": printing.py(c_seg * L / (G * Jp)),
        "cont_a_s": _np(a_t), "cont_b_s": _np(b_t),
        "mu_s": printing.py(sw["mu"].xreplace(arr)),
        "pivot_s": printing.py(sw["pivot"].xreplace({**arr, sp.Symbol("mu"): sp.Symbol("mu")})
                               .subs(sw["mu"].xreplace(arr), sp.Symbol("mu[n]"))),
        "S_L_s": printing.py(sw["S_L"].xreplace({**arr, D_: Dn})),
        "R_L_s": printing.py(sw["R_L"].xreplace({**arr, D_: Dn, y_: yn})),
        "forward_s": printing.py(sw["forward"].xreplace({**arr, D_: Dn, y_: yn, g_: gn,
                                                         ph_: pp})),
        "latex_s": {"a_s": sp.latex(a_t), "b_s": sp.latex(b_t),
                    "gamma_s": sp.latex(sp.Eq(gamma, g_of_s)), "pivot_s": sp.latex(sw["pivot"]),
                    "S_L_s": sp.latex(sw["S_L"]), "R_L_s": sp.latex(sw["R_L"]),
                    "forward_s": sp.latex(sw["forward"])},
    }
