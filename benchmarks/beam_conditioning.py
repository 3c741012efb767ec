"""How the accuracy of an assembled Hermite beam falls with its element count.

A steel cantilever (E = 2.1e11 Pa, I = 8e-6 m^4, rho_A = 20 kg/m, L = 3 m, clamped-free) of N
Hermite cubic elements, N = 100, 1,000, 10,000 (and 100,000 with ``--full``). Printed per N,
each as a relative error against a closed form of the continuous beam:

- the static tip deflection under a unit tip force, against L^3 / (3 EI) (Hermite elements are
  nodally exact for a static beam, so the discretization adds nothing): by LAPACK's banded LU
  (scipy.linalg.solve_banded) of K from ``dd.beam_matrices``; the same after three steps of
  iterative refinement with the residual b - K x summed in long double (np.longdouble);
- the tip receptance from ``dd.beam_frequency_response`` at 1e-3 Hz, against the exact
  receptance of the continuous cantilever (mpmath, 40 digits)
  H = (sin x cosh x - cos x sinh x) / (EI beta^3 (1 + cos x cosh x)), x = beta L,
  beta^4 = rho_A omega^2 / (EI) (its limit x -> 0 is L^3 / (3 EI); its poles are the roots
  of 1 + cos x cosh x = 0, the cantilever's frequency equation);
- the lowest natural frequency by ARPACK (scipy.sparse.linalg.eigsh, shift-invert about 0
  with SuperLU's factors of K) and by ``dd.beam_frequencies`` (the Wittrick-Williams count),
  against 1.8751040687119611^2 sqrt(EI / (rho_A L^4));
- eps N^3.5 for comparison (eps = 2.2e-16).

Then, for N = 100 (and 1,000), the relative error of the first 40 frequencies by
``dd.beam_frequencies`` against the roots of cos x + 1 / cosh x = 0 (brentq), against the
elements per wavelength 2 pi N / (beta_r L): the discretization error, which sets how many
elements a frequency band needs.

Then the time domain (``dd.beam_response``, average acceleration, dt = 1e-4 s): a unit tip
force ramped in over 0.1 s (half cosine) and held to 0.6 s, the first mode critically damped by
alpha M alone or by beta K alone; the end deflection against L^3 / (3 EI) with
``refine=False`` and ``refine=True`` and the time per step of each (the best of three runs of
one solver), for N = 250 .. 10,000. And the refinement's convergence: the harmonic-balance
benchmark's 10,000-element cantilever (5 % Rayleigh damping in modes 1 and 2) under a tip force
at 18.5 Hz, 2,000 steps, with 0 .. 3 corrections per step and the default rule, each against 3.

The script writes docs/beam_conditioning.md (its output and the explanation).
Usage: python benchmarks/beam_conditioning.py [--full]   (about 2 minutes; --full 1 more)
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

import mpmath
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps
import scipy.sparse.linalg as spla
from scipy.optimize import brentq

import dtdyn as dd

E, I, RHO_A, L = 2.1e11, 8e-6, 20.0, 3.0  # noqa: E741
BETA1_L = 1.8751040687119611
EPS = float(np.finfo(float).eps)
F_LOW = 1e-3                                       # Hz, the receptance's frequency
DOC = pathlib.Path(__file__).resolve().parent.parent / "docs" / "beam_conditioning.md"
TD_RAMP, TD_DURATION, TD_DT = 0.1, 0.6, 1e-4      # the time-domain table's load and step


def exact_tip_receptance(omega):
    """The tip receptance (m/N) of the continuous clamped-free Euler-Bernoulli beam at omega
    (rad/s), evaluated in 40-digit arithmetic (the numerator cancels to x^3 at small x)."""
    with mpmath.workdps(40):
        beta = (mpmath.mpf(RHO_A) * mpmath.mpf(omega) ** 2 / (mpmath.mpf(E) * I)) ** 0.25
        x = beta * L
        num = mpmath.sin(x) * mpmath.cosh(x) - mpmath.cos(x) * mpmath.sinh(x)
        den = mpmath.mpf(E) * I * beta ** 3 * (1 + mpmath.cos(x) * mpmath.cosh(x))
        return float(num / den)


def cantilever_roots(count):
    """beta_r L, r = 1 .. count: the roots of 1 + cos x cosh x = 0, as cos x + 1 / cosh x = 0."""
    f = lambda x: np.cos(x) + 1.0 / np.cosh(x)  # noqa: E731
    return np.array([brentq(f, (r - 1) * np.pi + 1e-9 if r > 1 else 1.0, r * np.pi,
                            xtol=1e-15, rtol=4 * EPS) for r in range(1, count + 1)])


def banded(K, width=3):
    """K in LAPACK's banded storage (rows of diagonals, ``width`` above and below)."""
    Kc = K.tocoo()
    ab = np.zeros((2 * width + 1, K.shape[0]))
    np.add.at(ab, (width + Kc.row - Kc.col, Kc.col), Kc.data)
    return ab


def static_tip(beam, n):
    """(banded LU, after 3 refinements with the residual in long double) tip deflection."""
    _, _, K = dd.beam_matrices(beam)
    tip = beam.dof(f"w{n}")
    b = np.zeros(K.shape[0])
    b[tip] = 1.0
    ab = banded(K)
    x0 = sla.solve_banded((3, 3), ab, b)
    Kc = K.tocoo()
    data = Kc.data.astype(np.longdouble)
    x = x0.copy()
    for _ in range(3):
        r = b.astype(np.longdouble)
        np.subtract.at(r, Kc.row, data * x.astype(np.longdouble)[Kc.col])
        x = x + sla.solve_banded((3, 3), ab, r.astype(float))
    return x0[tip], x[tip]


def arpack_lowest(beam):
    """The lowest frequency (rad/s) by eigsh shift-invert about 0 (SuperLU's factors of K)."""
    M, _, K = dd.beam_matrices(beam)
    lu = spla.splu(sps.csc_matrix(K))
    op = spla.LinearOperator(K.shape, matvec=lu.solve, dtype=float)
    vals = spla.eigsh(K, 1, M=M, sigma=0.0, OPinv=op, return_eigenvectors=False)
    return float(np.sqrt(vals.min()))


def conditioning_table(sizes):
    lines = []
    w_static = L ** 3 / (3 * E * I)
    w_low = 2 * np.pi * F_LOW
    h_low = exact_tip_receptance(w_low)
    w1 = BETA1_L ** 2 * np.sqrt(E * I / (RHO_A * L ** 4))
    lines.append(f"static tip deflection L^3/(3EI) = {w_static:.10e} m/N; exact receptance at "
                 f"{F_LOW:g} Hz = {h_low:.10e} m/N (ratio - 1 = {h_low / w_static - 1:.2e}); "
                 f"f1 = {w1 / 2 / np.pi:.10f} Hz")
    lines.append("relative errors against the continuous beam's closed forms")
    head = (f"{'N':>7} {'banded LU':>10} {'LU+refine':>10} {'frf 1e-3Hz':>10} "
            f"{'eigsh f1':>10} {'WW f1':>10} {'eps N^3.5':>10} {'time':>6}")
    lines.append(head)
    rows = []
    for n in sizes:
        t0 = time.perf_counter()
        beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n)
        tip = f"w{n}"
        lu, refined = static_tip(beam, n)
        frf = dd.beam_frequency_response(beam, [w_low], tip, tip)[0]
        arp = arpack_lowest(beam)
        ww = dd.beam_frequencies(beam, count=1)[0]
        row = (lu / w_static - 1, refined / w_static - 1, abs(frf) / h_low - 1, arp / w1 - 1,
               ww / w1 - 1, EPS * n ** 3.5)
        rows.append((n, row))
        lines.append(f"{n:>7} " + " ".join(f"{v:>10.1e}" for v in row)
                     + f" {time.perf_counter() - t0:>5.1f}s")
    return lines, rows


def discretization_table(sizes, count=40):
    lines = ["first frequencies by beam_frequencies against the roots of 1 + cos x cosh x = 0:",
             "relative error per mode, elements per wavelength 2 pi N / (beta_r L)"]
    roots = cantilever_roots(count)
    modes = [1, 2, 3, 5, 10, 15, 20, 25, 30, 40]
    out = {}
    for n in sizes:
        beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n)
        w = dd.beam_frequencies(beam, count=count)
        ref = roots ** 2 * np.sqrt(E * I / (RHO_A * L ** 4))
        err = w / ref - 1
        per_wave = 2 * np.pi * n / roots
        lines.append(f"N = {n}")
        lines.append(f"{'mode':>6} " + " ".join(f"{r:>8d}" for r in modes))
        lines.append(f"{'el/wave':>6} " + " ".join(f"{per_wave[r - 1]:>8.1f}" for r in modes))
        lines.append(f"{'error':>6} " + " ".join(f"{err[r - 1]:>8.1e}" for r in modes))
        out[n] = (per_wave, err)
    per_wave, err = out[sizes[0]]
    sel = slice(9, count)                     # modes 10 .. count: past rounding, 5 .. 21 per wave
    c = np.exp(np.mean(np.log(np.abs(err[sel])) + 4 * np.log(per_wave[sel])))
    spread = np.abs(np.log(np.abs(err[sel]) * per_wave[sel] ** 4 / c)).max()
    lines.append(f"fit over modes 10 .. {count} of N = {sizes[0]}: error = {c:.2f} / (elements per "
                 f"wavelength)^4, within a factor {np.exp(spread):.2f}")
    return lines, out, c


EXPLANATION = """\
# Accuracy of an assembled beam against its element count

A beam of N Hermite cubic elements has nodal displacements and rotations as unknowns. An
element's stiffness is of order EI / h^3 = N^3 EI / L^3, while the lowest modes bend each
element by little more than a rigid motion: their stiffness, EI / L^3 for the whole beam, is
the small difference of element terms about N^3 times larger, and cond(K) grows as N^4.
`beam_frequencies`, which counts with the element deformations as unknowns and finishes each
root with compensated residuals (docs/beam.md), loses little of it (column "WW f1" below). A
solve with K loses much more. Each pivot's rounding is a perturbation of about eps times the
element stiffness, random in sign from element to element; against the near-rigid motion of
the low modes, N of them add up to a relative error of about eps N^3 sqrt(N) = eps N^3.5. The
static tip deflection by LAPACK's banded LU, the low-frequency receptance of
`beam_frequency_response` (a banded LU of K - w^2 M + i w C) and the lowest frequency by
ARPACK's shift-invert (SuperLU's factors of K) below lose their digits as eps N^3.5
predicts. Iterative refinement with the residual in long double (64-bit mantissa) recovers
them while eps_long_double N^3.5 stays small (to 10,000 elements), not beyond: the matrices
hold the answer, the double-precision solve loses it.

What to do: give a beam the elements its frequency band needs and no more. The second table
is the discretization error of the frequencies against the elements per wavelength of each
mode, about {c:.2f} / n_w^4 for n_w elements per wavelength: 6 per wavelength of the highest
mode of interest give {e6:.0e}, 10 give {e10:.0e}. The rounding above (about eps N^3.5 on
what a displacement solve returns) then sets the useful range of N: past a few thousand
elements it is larger than any discretization error a band of low modes needs. Near a
resonance the receptance's error is the frequency's error times about 1 / (2 zeta) (zeta the
modal damping). `harmonic_balance` refines its banded solves with residuals in twice the
working precision and its modes by residual correction ([harmonic balance on
beams](harmonic_balance_beam.md)).

The time histories (`beam_response`, `simulate_beam`, `nonlinear_beam_response`: the block
Riccati step) refine every step's solve from {n_min:,} elements on (`refine="auto"`; `True` and
`False` force it). The step keeps its factors of the effective matrix A = alpha M + r C + p K
as they are and corrects u by A^-1 r, r the residual of the step's equation
F - K x - C v - M a at the step's x, v, a, taken element by element: x + beta v in
double-double (exact products by fma, Knuth's TwoSum; Dekker's product in NumPy), each
element's deformation y = x_i - T x_(i+1) (the left node against the right node's rigid
extension) from it, rounded once, and its end forces F^-1 y and -T^T F^-1 y (K_e =
[I, -T]^T F^-1 [I, -T]) in double, the inertia M (a + alpha v) and the nodes' springs, dampers
and masses in double. No product of an element stiffness with a displacement is rounded, rigid
motions give y = 0 exactly, and C v is alpha M v + beta K v (never an assembled C, whose
alpha M part is lost at 10,000 elements). Long double would not do: a 64-bit mantissa leaves
eps_ld N^3.5 (1e-5 at 10,000 elements), and it is double on MSVC and aarch64; double-double
leaves the state's own rounding, a harmless perturbation of a stable system. The corrections
contract by a factor of about eps times the element stiffness's share of A against the low
modes' (the last table: each correction shrinks the difference from three corrections by
{c1:.0f} and {c2:.0f} times for this cantilever at dt = 1e-4; less when beta K dominates A); the
step stops when the next correction is predicted below {tol:g} of the displacements, at most
{cmax}. What a step leaves adds up over the slowest mode's
decay, which is why the tolerance is far below the accuracy wanted. A refined step costs
{r_lo:.1f} to {r_hi:.1f} times a plain one (the table: each correction is a residual and a
solve, two or three corrections a step, more where beta K dominates A). The threshold: below
{n_min:,} elements the plain step's rounding of a static deflection stays below about 1e-6
(the table), well below a time step's own error in common use (about 1e-5 at 1,024 steps per
period in part 3 of [harmonic balance on beams](harmonic_balance_beam.md)), so "auto" keeps
the plain step there, and its results bitwise; at 5,000 elements the rounding reaches 1e-5 to
1e-4, at 10,000 1e-3, and with beta K alone the plain step is unstable there.

Output of `python benchmarks/beam_conditioning.py{flag}` (2-core shared machine; every number
from this run):

```
{output}
```
"""


def static_by_time_domain(beam, tip, refine, dt=TD_DT, duration=TD_DURATION):
    """The tip deflection at the end of a unit tip force ramped in over TD_RAMP s (half cosine)
    and held, by ``dd.beam_response`` (average acceleration) with ``refine``, and the seconds
    per step of its run (the best of three, the solver made once)."""
    t = np.arange(int(round(duration / dt)) + 1) * dt
    f = np.where(t < TD_RAMP, 0.5 * (1 - np.cos(np.pi * t / TD_RAMP)), 1.0)
    solver = beam.solver(dt, scheme="average_acceleration", outputs=[tip], quantities=("x",),
                         refine=refine)
    best, r = np.inf, None
    for _ in range(3):
        t0 = time.perf_counter()
        r = solver.run(f, force_dofs=[tip])
        best = min(best, time.perf_counter() - t0)
    return float(r.x[-1, 0]), best / (t.size - 1)


def time_domain_table(sizes):
    """The static tip deflection by the time domain, refined and not (module docstring)."""
    w_static = L ** 3 / (3 * E * I)
    w1 = BETA1_L ** 2 * np.sqrt(E * I / (RHO_A * L ** 4))
    lines = [f"time domain: a unit tip force ramped in over {TD_RAMP:g} s and held to "
             f"{TD_DURATION:g} s, dt = {TD_DT:g} s, average acceleration (beam_response); the "
             "tip deflection at the end against L^3/(3EI), refine=False and True; mode 1 "
             "critically damped by alpha M alone (alpha = 2 w1) or by beta K alone (beta = "
             "2 / w1); us per step (best of 3)",
             f"{'N':>7} {'damping':>8} {'plain':>10} {'refined':>10} {'eps N^3.5':>10} "
             f"{'us/step':>8} {'refined':>8} {'ratio':>6}"]
    rows = []
    for n in sizes:
        for name, rayleigh in (("alpha", (2 * w1, 0.0)), ("beta", (0.0, 2 / w1))):
            beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n, rayleigh=rayleigh)
            tip = beam.dof(f"w{n}")
            (x0, t0), (x1, t1) = (static_by_time_domain(beam, tip, ref) for ref in (False, True))
            row = (x0 / w_static - 1, x1 / w_static - 1, EPS * n ** 3.5)
            rows.append((n, name, row, t0, t1))
            lines.append(f"{n:>7} {name:>8} " + " ".join(f"{v:>10.1e}" for v in row)
                         + f" {t0 * 1e6:>8.1f} {t1 * 1e6:>8.1f} {t1 / t0:>6.2f}")
            print(lines[-1], flush=True)
    return lines, rows


def corrections_table(n=10_000, steps=2000, dt=1e-4):
    """How fast the refinement converges: one beam_response of the harmonic-balance benchmark's
    cantilever (alpha + beta, 5 % in modes 1 and 2) under a tip force at 18.5 Hz with 0, 1, 2
    and 3 corrections per step; the largest difference of each from 3 corrections, relative to
    the largest |x|."""
    import dtdyn.linear._beam as beam_mod

    w1, w2 = (b ** 2 * np.sqrt(E * I / (RHO_A * L ** 4)) for b in (BETA1_L, 4.6940911329741746))
    beta = 2 * 0.05 / (w1 + w2)
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n, rayleigh=(beta * w1 * w2, beta))
    tip = beam.dof(f"w{n}")
    f = 100.0 * np.sin(2 * np.pi * 18.5 * dt * np.arange(steps + 1))
    xs = {}
    saved = beam_mod.REFINE_CORRECTIONS, beam_mod.REFINE_TOL
    try:
        for c in (0, 1, 2, 3, "auto"):  # a fixed count (tol 0), and the default rule
            beam_mod.REFINE_CORRECTIONS, beam_mod.REFINE_TOL = (saved if c == "auto"
                                                                else (max(c, 1), 0.0))
            xs[c] = dd.beam_response(beam, f, dt, force_dofs=[tip], outputs=[tip],
                                     scheme="average_acceleration", quantities=("x",),
                                     refine=c != 0).x[:, 0]
    finally:
        beam_mod.REFINE_CORRECTIONS, beam_mod.REFINE_TOL = saved
    scale = np.abs(xs[3]).max()
    diffs = [float(np.abs(xs[c] - xs[3]).max() / scale) for c in (0, 1, 2, "auto")]
    return [f"corrections per step at N = {n:,} ({steps} steps of {dt:g} s, a tip force at "
            "18.5 Hz, 5 % Rayleigh damping): max |x_c - x_3| / max |x_3| for c = 0, 1, 2 "
            "corrections and the default rule: " + ", ".join(f"{d:.1e}" for d in diffs)], diffs


def main(argv=None):
    from dtdyn.linear._beam import REFINE_CORRECTIONS, REFINE_MIN_ELEMENTS, REFINE_TOL

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="also N = 100,000")
    ap.add_argument("--no-write", action="store_true", help="do not write the doc")
    args = ap.parse_args(argv)
    sizes = (100, 1_000, 10_000) + ((100_000,) if args.full else ())
    lines, _ = conditioning_table(sizes)
    more, _, c = discretization_table((100, 1_000))
    lines += [""] + more
    td, rows = time_domain_table((250, 500, 1_000, 2_000, 5_000, 10_000))
    conv, diffs = corrections_table()
    lines += [""] + td + [""] + conv
    text = "\n".join(lines)
    print(text)
    ratios = [t1 / t0 for *_, t0, t1 in rows]
    if not args.no_write:
        DOC.write_text(EXPLANATION.format(output=text, flag=" --full" if args.full else "",
                                            c=c, e6=c / 6 ** 4, e10=c / 10 ** 4,
                                            r_lo=min(ratios), r_hi=max(ratios),
                                            n_min=REFINE_MIN_ELEMENTS, tol=REFINE_TOL,
                                            cmax=REFINE_CORRECTIONS, c1=diffs[0] / diffs[1],
                                            c2=diffs[1] / diffs[2]))
        print(f"\nwrote {DOC}", file=sys.stderr)


if __name__ == "__main__":
    main()
