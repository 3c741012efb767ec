"""Harmonic balance on a cantilever with a cubic spring and a gap: the reduced receptance
against the banded one for 100 .. 10,000 elements, and the curve against long time-domain runs.

The model: a steel cantilever (E = 2.1e11 Pa, I = 8e-6 m^4, rho_A = 20 kg/m, L = 3 m) of N
Hermite elements, Rayleigh damping C = alpha M + beta K with 5 % of critical damping in its
first two modes (18.0 and 113 Hz), a cubic spring k3 = 7.5e8 N/m^3 from the tip to the
ground, a gap (clearance 1 mm, stiffness 1e5 N/m, both sides) at mid-span, a force
100 cos(omega t) N at the tip, swept from 5 to 150 Hz (a band holding the first two modes),
outputs: the tip and mid-span deflections. Hill's stability is off (its dense eigenproblem
is refused above 2 n (2 H + 1) = 6000).

0. The linear beam's tip receptance at 1e-3, 15, 18, 60, 110 and 1875 Hz against the closed
   form of the continuous cantilever with Rayleigh damping (mpmath, 40 digits; the
   discretization error of 1,000 elements is below 1e-9 there), for N = 1,000, 2,000 (and
   10,000 with ``--full``), with the damping of the model (alpha + beta) and with beta alone
   (alpha = 0): by LAPACK's banded LU alone ("banded LU"), by the banded receptance of
   `harmonic_balance` (the same LU refined with residuals in twice the working precision;
   the size of its last correction under the row) and by the reduced receptance (its modes
   refined), both built as `harmonic_balance` builds them for a Beam (alpha M and beta K
   kept apart: C v = alpha M v + beta K v, the modes' damping alpha + beta k_r). Below: the
   first two frequencies by ARPACK and refined against ``beam_frequencies``, and the first
   mode's damping, the reduced receptance's and that of the assembled C (phi^T C phi, C phi
   summed exactly), against alpha + beta w_1^2 (w_1 from ``beam_frequencies``).
1. The curve (H = 10 harmonics, n_time 128 samples per period, ``max_step=0.03`` for about
   200 points, ``convergence_points=0``) with ``receptance="reduced"``, ``"banded"`` and
   "plain LU" (LAPACK's banded LU unrefined: what ``"auto"`` ran on a Beam before it chose
   the reduced receptance for Rayleigh-damped models of 50 DOFs and more) for N = 100, 300,
   1,000, 2,000 (and 10,000 with ``--full``, the reduced receptance only); then the receptance
   ``"auto"`` runs at each N.
   Per run: the points, the setup
   (the run time of a two-point curve over the same band: the reduced receptance's modes and
   residual terms, built for the whole band, and two points' Newton), the time per point
   over the rest of the 200-point run (``info["run_time"]`` of one run after a warm-up; BLAS
   pinned to one thread), the Newton tolerance ``tol`` used (the smallest of 1e-10, 1e-9 ..
   1e-5 with which the continuation got through; the banded receptance's rounding, which varies from
   one frequency to the next, stops Newton below that), the reduced receptance's check
   (``info["receptance_check"]``: its modes, series terms and difference from the banded
   receptance at the top of the band, or why it fell back), and the peak tip amplitude.
   Under the table (with --full): the reduced receptance's cost per point and per Newton
   iteration at N = 1,000 and 10,000, measured interleaved (`cost_ratio`: the curve at each
   N in turn, 5 rounds; per point its run time less its setup, timed apart, over its points).
2. Convergence in the harmonics at N = 300: ``harmonic_convergence`` (x_max with 2 H
   harmonics and twice the samples against H, at 10 points and the peak) for H = 10 and 20.
3. Three frequencies (15 and 18.5 Hz, the gap in contact near the first resonance, and 110 Hz
   near the second) at N = 1,000 (and 10,000 with ``--full``; ``--td-elements``): the
   harmonic balance at that frequency
   (H = 20 and 40, reduced; H = 20, banded; each with the first tol of the list above that
   gets through) against ``nonlinear_beam_response``
   (Newmark's average acceleration, the C loop) from rest for 3 s, the force ramped in over
   0.5 s by a half cosine, dt = T / P for P = 512 and 1024 steps per period. The steady
   amplitude: the largest |x| over the last period, from its samples' Fourier series
   evaluated 16x finer; "transient": its change from the period before; "dt error": the
   difference between P = 512 and 1024 over 3 (the error of the P = 1024 run for a
   second-order method); "Richardson": x(1024) + (x(1024) - x(512)) / 3. Relative
   differences of the harmonic balance from Richardson's value.

The script writes docs/harmonic_balance_beam.md with its output.
Usage: python benchmarks/harmonic_balance_beam.py [--full] [--td-elements N ...]
(about 5 minutes; --full adds N = 10,000 to parts 0, 1 and 3, about 10 minutes more)
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time
import warnings

import mpmath
import numpy as np

import dtdyn as dd
from dtdyn.app import pin_blas

E, I, RHO_A, L = 2.1e11, 8e-6, 20.0, 3.0  # noqa: E741
BETA_L = (1.8751040687119611, 4.6940911329741746)
ZETA = 0.05
K3, GAP, K_GAP, FORCE = 7.5e8, 1e-3, 1e5, 100.0
BAND = (5.0, 150.0)
TOLS = (1e-10, 1e-9, 1e-8, 1e-7, 1e-6, 1e-5)
TD_FREQS = (15.0, 18.5, 110.0)
TD_DURATION, TD_RAMP, TD_STEPS = 3.0, 0.5, (512, 1024)
#: part 1 runs the banded receptance up to this N
BANDED_MAX_N = 2000
#: part 0's frequencies (Hz)
P0_FREQS = (1e-3, 15.0, 18.0, 60.0, 110.0, 1875.0)
DOC = pathlib.Path(__file__).resolve().parent.parent / "docs" / "harmonic_balance_beam.md"


def beam(n):
    """The cantilever of n elements with 5 % Rayleigh damping in modes 1 and 2."""
    w1, w2 = (b ** 2 * np.sqrt(E * I / (RHO_A * L ** 4)) for b in BETA_L)
    beta = 2 * ZETA / (w1 + w2)
    return dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n, rayleigh=(beta * w1 * w2, beta))


def problem(n):
    """(beam, keyword arguments of harmonic_balance without the receptance and tol)."""
    b = beam(n)
    tip, mid = b.dof(f"w{n}"), b.dof(f"w{n // 2}")
    elements = [dd.Cubic(tip, k3=K3), dd.Gap(mid, gap=GAP, stiffness=K_GAP)]
    return b, dict(elements=elements, force_dofs=[tip], force=[FORCE], outputs=[tip, mid],
                   stability=False, max_step=0.03)


def curve(n, receptance, harmonics=10, freqs_hz=BAND, **kw):
    """The first tol in TOLS with which the run gets through (to the end of the range, or to
    ``max_points`` when given): (result, tol, the last failure)."""
    b, args = problem(n)
    args.update(harmonics=harmonics, freqs_hz=freqs_hz, receptance=receptance,
                convergence_points=0)
    args.update(kw)
    err = None
    for tol in TOLS:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                r = plain_lu(b, tol, args) if receptance == "plain LU" else \
                    dd.harmonic_balance(b, tol=tol, **args)
        except dd.NewtonError as exc:
            err = str(exc).removeprefix("harmonic_balance: ")
            continue
        if r.info["stop"] == "end of the range" or "max_points" in kw:
            return r, tol, err
        err = f"stopped: {r.info['stop']} at {r.frequency_hz[-1]:.4g} Hz"
    return None, None, err


def plain_lu(b, tol, args):
    """harmonic_balance with LAPACK's banded LU unrefined: what receptance="auto" ran on a Beam
    before it chose the reduced receptance for Rayleigh-damped models of 50 DOFs and more."""
    from dtdyn.nonlinear import _harmonic_balance as hb
    keep = hb.REDUCED_AUTO_MIN_DOFS
    hb.REDUCED_AUTO_MIN_DOFS = 1 << 62
    try:
        return dd.harmonic_balance(b, tol=tol, **{**args, "receptance": "auto"})
    finally:
        hb.REDUCED_AUTO_MIN_DOFS = keep


def check_text(info):
    c = info.get("receptance_check")
    if not c:
        return "-"
    if c.get("receptance") == "reduced":
        return (f"passed: {c['modes']} modes, {c['terms']} terms, {c['error']:.1e} at "
                f"{c['verified_to_hz']:.0f} Hz")
    return f"failed: {c.get('reason', '?')}"


def exact_tip_receptance(omega, alpha, beta):
    """The tip receptance of the continuous clamped-free beam with Rayleigh damping (EI (1 + i
    omega beta), rho_A (omega^2 - i omega alpha)) at omega (rad/s), in 40-digit arithmetic:
    H = (sin x cosh x - cos x sinh x) / (EI* b^3 (1 + cos x cosh x)), x = b L,
    b^4 = rho_A (omega^2 - i omega alpha) / EI*."""
    with mpmath.workdps(40):
        om = mpmath.mpf(omega)
        ei = mpmath.mpf(E) * I * (1 + 1j * om * beta)
        b = (mpmath.mpf(RHO_A) * (om ** 2 - 1j * om * alpha) / ei) ** 0.25
        x = b * L
        num = mpmath.sin(x) * mpmath.cosh(x) - mpmath.cos(x) * mpmath.sinh(x)
        return complex(num / (ei * b ** 3 * (1 + mpmath.cos(x) * mpmath.cosh(x))))


def part0(sizes, lines):
    """The tip receptance of the linear beam against the continuous beam's closed form."""
    import scipy.linalg as sla
    import scipy.sparse.linalg as spla

    from dtdyn.nonlinear._elements import element_matrix
    from dtdyn.nonlinear._harmonic_balance import _bandwidth, _BandedReceptance
    from dtdyn.nonlinear._receptance import (ReducedReceptance, exact_product,
                                             rayleigh_coefficients, rayleigh_parts)
    lines.append("0) the tip receptance |H / H_exact - 1| of the linear beam against the "
                 "continuous beam's closed form (mpmath)")
    lines.append(f"{'N':>6} {'damping':>9} {'receptance':>16} "
                 + " ".join(f"{f:>8g}Hz" for f in P0_FREQS))
    for n in sizes:
        ref = beam(n)
        for name, (alpha, beta) in (("alpha+beta", ref.rayleigh), ("beta only",
                                                                   (0.0, ref.rayleigh[1]))):
            first = len(lines)
            b = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n, rayleigh=(alpha, beta))
            M, C, K = dd.beam_matrices(b)
            tip = b.dof(f"w{n}")
            Lm = element_matrix([dd.Cubic(tip, k3=1.0)], M.shape[0])
            B = np.zeros((M.shape[0], 1))
            B[tip] = 1.0
            out = np.array([tip])
            # as harmonic_balance builds them for a Beam: alpha M and beta K kept apart
            parts = rayleigh_parts(b, M, C, K)
            exact = _BandedReceptance(M, C, K, Lm, out, B, _bandwidth(M, C, K), refine=True,
                                      parts=parts)
            t0 = time.perf_counter()
            rec = ReducedReceptance(exact, M, C, K, Lm, out, B, rayleigh_coefficients(M, C, K),
                                    w_max=2 * np.pi * 10 * BAND[1], parts=parts)
            t_setup = time.perf_counter() - t0
            w = 2 * np.pi * np.array(P0_FREQS)
            h = np.array([exact_tip_receptance(wk, alpha, beta) for wk in w])
            bM, bC, bK = exact.bands
            plain = np.array([sla.solve_banded((3, 3), bK - wk * wk * bM + 1j * wk * bC,
                                               B[:, 0].astype(complex))[tip] for wk in w])
            refined, corr = [], []
            for wk in w:
                refined.append(exact(np.array([wk]))[0][0, 0, 0])
                corr.append(exact.last_correction)
            reduced = rec(w)[0][:, 0, 0]
            rows = (("banded LU", plain), ("banded refined", np.array(refined)),
                    ("reduced", reduced))
            for label, v in rows:
                lines.append(f"{n:>6} {name:>9} {label:>16} "
                             + " ".join(f"{abs(x / y - 1):>10.1e}" for x, y in zip(v, h)))
            lines.append(f"{'':>33}" + " ".join(f"{c:>10.0e}" for c in corr)
                         + "  <- the refinement's last correction (relative)")
            if rec.name != "reduced":
                lines.append(f"{'':>8}reduced fell back: {rec.check.get('reason')}")
            else:
                k = rec.k
                m = k.size
                lu = spla.splu(rec.K)
                op = spla.LinearOperator(K.shape, matvec=lu.solve, dtype=float)
                k0 = spla.eigsh(rec.K, m, M=rec.M, sigma=0.0, OPinv=op,
                                return_eigenvectors=False)
                ww = dd.beam_frequencies(b, count=2) ** 2
                lines.append(f"{'':>8}reduced: {rec.check['modes']} modes, setup "
                             f"{t_setup:.2f} s; f1, f2 against beam_frequencies: ARPACK "
                             f"{abs(np.sqrt(np.sort(k0)[0] / ww[0]) - 1):.1e}, "
                             f"{abs(np.sqrt(np.sort(k0)[1] / ww[1]) - 1):.1e}; refined "
                             f"{abs(np.sqrt(k[0] / ww[0]) - 1):.1e}, "
                             f"{abs(np.sqrt(k[1] / ww[1]) - 1):.1e}")
                lines.append(f"{'':>8}mode 1's damping / (alpha + beta w_1^2) - 1, w_1 from "
                             f"beam_frequencies: the reduced receptance's "
                             f"{rec.modal_damping[0] / (alpha + beta * ww[0]) - 1:.1e}; the "
                             f"assembled C's, phi^T C phi (C phi exactly) "
                             f"{modal_damping_error(rec, exact_product, alpha, beta, ww[0]):.1e}")
            print("\n".join(lines[first:]), flush=True)
    lines.append("")


def modal_damping_error(rec, exact_product, alpha, beta, k1):
    """phi_1^T C phi_1 / (alpha + beta k1) - 1 for the reduced receptance's first mode (C phi
    exactly), the first mode's damping in the assembled C against the Rayleigh damping."""
    phi = rec.modes[:, :1]
    hi, lo = exact_product(rec.cd, phi)
    return float(phi[:, 0] @ (hi + lo)[:, 0]) / (alpha + beta * k1) - 1


def part1(sizes, lines):
    lines.append(f"1) the curve {BAND[0]:g} .. {BAND[1]:g} Hz, H = 10, max_step 0.03")
    lines.append(f"{'N':>6} {'receptance':>10} {'points':>6} {'tol':>6} {'setup s':>8} "
                 f"{'ms/point':>8} {'Newton/pt':>9} {'tip max mm':>10}  reduced check")
    per_point = {}
    for n in sizes:
        for rec in ("reduced", "banded", "plain LU"):
            if rec != "reduced" and n > BANDED_MAX_N:
                lines.append(f"{n:>6} {rec:>10}  not run: its LU does not converge near the "
                             f"first resonance at this N (part 0)")
                print(lines[-1], flush=True)
                continue
            t0 = time.perf_counter()
            first, tol, err = curve(n, rec, max_points=2)
            wall = time.perf_counter() - t0
            t_first = first.info["run_time"] if first is not None else wall
            if first is None:
                lines.append(f"{n:>6} {rec:>10} {'-':>6} {'-':>6} {t_first:>8.2f} {'-':>8} "
                             f"{'-':>9} {'-':>10}  no tol in {TOLS[0]:g} .. {TOLS[-1]:g} got "
                             f"through "
                             f"the first point: {err}")
                print(lines[-1], flush=True)
                continue
            t0 = time.perf_counter()
            r, tol, err = curve(n, rec)
            wall = time.perf_counter() - t0
            if r is None:
                lines.append(f"{n:>6} {rec:>10} {'-':>6} {'-':>6} {t_first:>8.2f} {'-':>8} "
                             f"{'-':>9} {'-':>10}  no tol in {TOLS[0]:g} .. {TOLS[-1]:g} got "
                             f"through "
                             f"the band ({wall:.0f} s); the last: {err}")
                print(lines[-1], flush=True)
                continue
            pts = r.omega.size
            ms = 1e3 * (r.info["run_time"] - t_first) / (pts - 2)
            per_point[(n, r.info["receptance"], rec)] = ms
            lines.append(f"{n:>6} {rec:>10} {pts:>6} {tol:>6.0e} {t_first:>8.2f} {ms:>8.2f} "
                         f"{r.info['newton_iterations'] / pts:>9.2f} "
                         f"{1e3 * r.x_max[:, 0].max():>10.5f}  "
                         + (check_text(r.info) if rec == "reduced" else ""))
            print(lines[-1], flush=True)
    used = []
    for n in sizes:
        r, _, _ = curve(n, "auto", max_points=2)
        used.append(f"N = {n}: {r.info['receptance'] if r is not None else '-'}")
    lines.append("receptance='auto' runs (2-point curves): " + ", ".join(used))
    print(lines[-1], flush=True)
    if (1000, "reduced", "reduced") in per_point and (10_000, "reduced", "reduced") in per_point:
        lines.extend(cost_ratio())
        print("\n".join(lines[-3:]), flush=True)
    return per_point


def cost_ratio(sizes=(1000, 10_000), repeats=5):
    """The reduced receptance's cost per point at two N, interleaved (`interleaved`: each
    round runs the curve at every N in turn, so that the machine's drift reaches all alike):
    per point, ``info["run_time"]`` less the setup (the run's `_prepare`: the model's matrices,
    the receptance's modes and residual terms, timed by a wrapper) over the points; the median
    over the rounds [min, max]."""
    from dtdyn.app import interleaved
    from dtdyn.nonlinear import _harmonic_balance as hb
    prepare, setup = hb._prepare, []

    def timed(*args, **kw):
        t0 = time.perf_counter()
        out = prepare(*args, **kw)
        setup.append(time.perf_counter() - t0)
        return out

    fns = {}
    for n in sizes:
        tol = curve(n, "reduced")[1]

        def run(n=n, tol=tol):
            b, args = problem(n)
            args.update(harmonics=10, freqs_hz=BAND, receptance="reduced",
                        convergence_points=0)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                r = dd.harmonic_balance(b, tol=tol, **args)
            return r, setup[-1]
        fns[n] = run
    hb._prepare = timed
    try:
        t = interleaved(fns, repeats, key=lambda out: (out[0].info["run_time"] - out[1])
                        / out[0].omega.size)
        found = {n: fn() for n, fn in fns.items()}
    finally:
        hb._prepare = prepare
    out = []
    for n in sizes:
        r, prep = found[n]
        pts = r.omega.size
        out.append(f"   N = {n:>6}: {pts} points, {r.info['newton_iterations'] / pts:.2f} Newton "
                   f"iterations per point, {1e3 * t[n].median:.2f} ms per point "
                   f"[{1e3 * t[n].min:.2f}, {1e3 * t[n].max:.2f}] "
                   f"({1e3 * t[n].median * pts / r.info['newton_iterations']:.3f} ms per "
                   f"iteration), setup {prep:.2f} s, whole run {r.info['run_time']:.2f} s "
                   f"(medians of {repeats})")
    a, b = sizes
    nw = {n: found[n][0].info["newton_iterations"] / found[n][0].omega.size for n in sizes}
    out.append(f"reduced, N = {b:,} / N = {a:,}: cost per point {t[b].median / t[a].median:.2f}"
               f", per Newton iteration {(t[b].median / nw[b]) / (t[a].median / nw[a]):.2f}")
    return out


def part2(lines, n=300):
    lines.append(f"\n2) convergence in the harmonics, N = {n}: max over 10 points and the peak "
                 "of |x_max(2H) - x_max(H)| / max x_max(2H)")
    for h in (10, 20):
        b, args = problem(n)
        args.update(harmonics=h, freqs_hz=BAND, receptance="reduced", convergence_points=10)
        r = dd.harmonic_balance(b, tol=1e-10, **args)
        lines.append(f"   H = {h:2d} (n_time {r.info['n_time']}): "
                     f"{r.info['harmonic_convergence']:.1e}")
        print(lines[-1], flush=True)


def steady_amplitude(x, steps):
    """max |x| over the last period (``steps`` samples) by its Fourier series on a 16x finer
    grid, and the same for the period before."""
    out = []
    for end in (x.shape[0], x.shape[0] - steps):
        seg = x[end - steps:end]
        spec = np.fft.rfft(seg, axis=0)
        fine = np.fft.irfft(spec, n=16 * steps, axis=0) * 16
        out.append(np.abs(fine).max(axis=0))
    return out


def time_domain(n, f, steps):
    b, args = problem(n)
    dt = 1.0 / f / steps
    count = int(round(TD_DURATION * f)) * steps
    t = np.arange(count + 1) * dt
    ramp = np.where(t < TD_RAMP, 0.5 * (1 - np.cos(np.pi * t / TD_RAMP)), 1.0)
    t0 = time.perf_counter()
    r = dd.nonlinear_beam_response(b, FORCE * ramp * np.cos(2 * np.pi * f * t), dt,
                                   force_dofs=args["force_dofs"], elements=args["elements"],
                                   outputs=args["outputs"], quantities=("x",),
                                   scheme="average_acceleration")
    last, before = steady_amplitude(r.x[1:], steps)
    return last, before, time.perf_counter() - t0, count


def part3(n, lines):
    lines.append(f"\n3) N = {n}: harmonic balance (H = 20) at three frequencies against "
                 f"nonlinear_beam_response, {TD_DURATION:g} s from rest, average acceleration")
    lines.append(f"{'f Hz':>6} {'output':>6} {'TD P=512':>13} {'TD P=1024':>13} {'transient':>9} "
                 f"{'dt error':>9} {'Richardson':>13} {'HB reduced':>13} {'diff':>8} "
                 f"{'HB banded':>13} {'diff':>8} {'H=40 diff':>9}")
    worst = 0.0
    for f in TD_FREQS:
        td = [time_domain(n, f, p) for p in TD_STEPS]
        (x1, _, t1, c1), (x2, x2b, t2, c2) = td
        rich = x2 + (x2 - x1) / 3
        hb = {}
        for rec, h in (("reduced", 20), ("banded", 20), ("reduced", 40)):
            if rec == "banded" and n > BANDED_MAX_N:
                hb[(rec, h)] = (np.full(2, np.nan), np.nan, "not run")
                continue
            # the band from f to its end (the first point, at f): the reduced receptance is
            # built and checked for the band as in part 1
            r, tol, err = curve(n, rec, harmonics=h, freqs_hz=(f, BAND[1]), max_points=2)
            hb[(rec, h)] = (r.x_max[0] if r is not None else np.full(2, np.nan), tol,
                            r.info["receptance"] if r is not None else "-")
        for o, name in enumerate(("tip", "mid")):
            xr, xb, x40 = hb[("reduced", 20)][0][o], hb[("banded", 20)][0][o], \
                hb[("reduced", 40)][0][o]
            d_r, d_b = xr / rich[o] - 1, xb / rich[o] - 1
            worst = max(worst, abs(d_r))
            lines.append(f"{f:>6g} {name:>6} {x1[o]:>13.8e} {x2[o]:>13.8e} "
                         f"{abs(x2[o] / x2b[o] - 1):>9.1e} {abs(x2[o] - x1[o]) / 3 / x2[o]:>9.1e} "
                         f"{rich[o]:>13.8e} {xr:>13.8e} {d_r:>8.1e} {xb:>13.8e} {d_b:>8.1e} "
                         f"{abs(x40 / xr - 1):>9.1e}")
            print(lines[-1], flush=True)
        lines.append(f"{'':>6} time domain: {c1} and {c2} steps, {t1:.1f} s and {t2:.1f} s; "
                     f"tol reduced {hb[('reduced', 20)][1]:g} (used: {hb[('reduced', 20)][2]}),"
                     f" banded {hb[('banded', 20)][1]:g}")
    lines.append(f"largest |HB reduced / Richardson - 1|: {worst:.1e}")


def part4(sizes, lines, duration=4.0, dts=(2e-4, 1e-4)):
    """The time domain's rounding: a tip force ramped to FORCE (0.5 s) and held, the tip
    deflection at the end against the static solution k x + k3 x^3 = FORCE, k = 3 EI / L^3
    (Hermite elements are nodally exact for a static load; the gap at mid-span stays open)."""
    k = 3 * E * I / L ** 3
    roots = np.roots([K3, 0.0, k, -FORCE])
    x_static = float(roots[np.abs(roots.imag) < 1e-12].real.max())
    lines.append(f"\n4) the time domain's rounding: the tip force ramped to {FORCE:g} N over "
                 f"{TD_RAMP:g} s and held for {duration:g} s in all, average acceleration; the "
                 f"tip deflection at the end (and its mean over the last 0.5 s) against the "
                 f"static solution {x_static:.10e} m; the model's damping (alpha+beta), and at "
                 f"the largest N alpha M alone and beta K alone")
    lines.append(f"   (beta only: {2 * duration:g} s, its first mode being damped 3.6 times "
                 "less; refine: the step's refinement, 'auto' (the corrections per step at "
                 "most: 0 when off), and refine=False at the largest N)")
    cases = [(n, "alpha+beta", dt, "auto") for n in sizes for dt in dts]
    cases += [(max(sizes), "alpha+beta", dts[-1], False)]
    cases += [(max(sizes), name, dts[-1], "auto") for name in ("alpha only", "beta only")]
    for n, name, dt, refine in cases:
        b, args = problem(n)
        alpha, beta = b.rayleigh
        if name != "alpha+beta":
            b = dd.Beam(E=E, I=I, rho_A=RHO_A, length=L, elements=n,
                        rayleigh=(alpha, 0.0) if name == "alpha only" else (0.0, beta))
        end = 2 * duration if name == "beta only" else duration
        t = np.arange(int(round(end / dt)) + 1) * dt
        ramp = np.where(t < TD_RAMP, 0.5 * (1 - np.cos(np.pi * t / TD_RAMP)), 1.0)
        t0 = time.perf_counter()
        r = dd.nonlinear_beam_response(b, FORCE * ramp, dt, force_dofs=args["force_dofs"],
                                       elements=args["elements"], outputs=args["outputs"],
                                       quantities=("x",), scheme="average_acceleration",
                                       refine=refine)
        x = r.x[:, 0]
        tail = x[-int(round(0.5 / dt)):]
        lines.append(f"   N = {n:>6}, {name:>10}, dt = {dt:g}, refine {str(refine):>5} "
                     f"({r.info['refinements']} at most): end "
                     f"{x[-1] / x_static - 1:>9.1e}, mean "
                     f"{tail.mean() / x_static - 1:>9.1e}, spread over the last 0.5 s "
                     f"{(tail.max() - tail.min()) / x_static:.1e} "
                     f"({time.perf_counter() - t0:.1f} s)")
        print(lines[-1], flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="also N = 10,000 in part 1")
    ap.add_argument("--td-elements", type=int, nargs="+", default=None,
                    help="N of part 3 (default 1000; with --full 1000 and 10000)")
    ap.add_argument("--no-write", action="store_true", help="do not write the doc")
    args = ap.parse_args(argv)
    sizes = (100, 300, 1000, 2000) + ((10_000,) if args.full else ())
    lines = []
    with pin_blas(1) as pin:
        lines.append(pin.describe())
        curve(20, "reduced", freqs_hz=(5.0, 6.0))              # warm-up: imports, CasADi
        t0 = time.perf_counter()
        part0((1000, 2000) + ((10_000,) if args.full else ()), lines)
        part1(sizes, lines)
        part2(lines)
        td = args.td_elements or ((1000, 10_000) if args.full else (1000,))
        for n in td:
            part3(n, lines)
        part4(td, lines)
        lines.append(f"\ntotal {time.perf_counter() - t0:.0f} s")
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        DOC.write_text(EXPLANATION.format(output=text, flag=" --full" if args.full else ""))
        print(f"wrote {DOC}", file=sys.stderr)


EXPLANATION = """\
# Harmonic balance on a beam: reduced and banded receptances, and the time domain

`python benchmarks/harmonic_balance_beam.py` (its docstring has the model and what each column
is): a cantilever with a cubic spring at the tip and a gap at mid-span, its linear receptance
against the continuous beam's closed form, the frequency response curve over its first two
modes by `harmonic_balance` with `receptance="reduced"` and `"banded"`, and three of its
points against long `nonlinear_beam_response` runs.

What the output shows.

Part 0, the linear receptance. A Hermite beam of N elements has cond(K) ~ N^4, and LAPACK's
banded LU loses about eps N^3.5 of a solve (docs/beam_conditioning.md), more in complex
arithmetic near a resonance ("banded LU": 2.7e-3 at 18 Hz for N = 1,000, all digits at 10,000).
The banded receptance of `harmonic_balance` refines every solve with the residual summed in
twice the working precision: where the LU keeps some digits the refinement converges (its last
correction near 1e-16) and the receptance is that of the matrices to rounding. At N = 10,000
the LU's error is 0.2 to 1 up to 110 Hz, and below 60 Hz the refinement cannot start from it
(its corrections stay at 2e-2 .. 0.5): no banded solve in double precision gives the receptance
of a 10,000-element beam near its first mode. The reduced receptance gets it from the modes:
ARPACK's (shift-invert with SuperLU's factors of K) are off by 3.8e-3 in f1 at N = 10,000, and
after residual correction with a banded LU of K - k_r M per mode they equal `beam_frequencies`
to 2e-15; the residual series solves with K, refined. It passes its check against the refined
banded receptance at the top of the band (where the refinement converges) at every N, and with
beta-only damping it equals the continuous beam to 6e-6 at 10,000 elements (at 18 Hz: the
model's own error in f1, docs/beam_conditioning.md, times the peak's amplification), 3e-7 or
less elsewhere in the band.

With the model's damping, alpha M + beta K, a second loss appears, in the matrices
themselves: `beam_matrices` sums C = alpha M + beta K entry by entry in double precision, and
at large N an entry of alpha M (of order rho_A h) falls below the rounding of beta K's (of
order beta EI / h^3): the first mode's damping phi^T C phi in the assembled C is 40 % below
alpha + beta w_1^2 at N = 10,000 (1e-4 at 2,000, 7e-6 at 1,000). `harmonic_balance` takes a
Beam's Rayleigh coefficients from the model instead of from its C: the reduced receptance
damps each kept mode by alpha + beta k_r (equal to alpha + beta w_1^2 from
`beam_frequencies` to rounding, the line under each reduced row), and the refined banded and
the reduced receptances form C v as alpha M v + beta K v (K v exactly); the rows above are
built as `harmonic_balance` builds them. With the model's damping the reduced receptance then
equals the continuous beam at N = 10,000 as closely as with beta alone (before, with the
assembled C: 0.67 off at 18 Hz), and the refined banded one at N = 1,000 to the model's own
rounding. Only the plain banded LU ("banded LU") still solves with the assembled C.

Part 1, the curve. The reduced receptance's cost per point does not grow with N: the
10,000-element curve is the 1,000-element one (the same points, Newton iterations per point
and peak), and its time per point and per Newton iteration, measured interleaved under the
table, is the same; only its setup (the modes, refined, and the residual terms: O(N)) grows.
The refined banded receptance gets through the band at `tol=1e-10` for every N where it is
run, at a cost per point that grows with N (exact residual products with K at every solve):
it is the reference, not the fast path.

Part 3, the time domain. The harmonic balance equals the extrapolated time domain to about
1e-5, the time domain's own dt error, at N = 1,000 and at N = 10,000. At 10,000 elements this
needs the time steps' refinement (`refine="auto"` refines from 2,000 elements on): a
double-precision step carries the eps N^3.5 rounding of part 0 at every step (its solves and
its products with K), and without refinement the amplitude changes by about 1e-3 from one
period to the next after 3 s and P = 512 and 1024 steps per period differ by percents. The
refined step corrects its solve with the step equation's residual formed element by element
(each element's deformation from x + beta v in double-double, so no element stiffness
multiplies a rounded displacement, and C v as alpha M v + beta K v, never an assembled C);
docs/beam_conditioning.md has the equations and the cost (about 3x a plain step).

Part 4, the time domain's rounding. A static tip load, ramped in and held: with the refined
steps the deflection at the end equals the static solution to about 1e-9 at N = 10,000 with
the model's damping and with alpha M alone; with beta K alone (mode 1 then has about 1.4 % of
critical damping, run for 8 s) what is left is the physical transient, the same at
N = 1,000. The row with `refine=False` shows the plain step's rounding at N = 10,000.

Output of `python benchmarks/harmonic_balance_beam.py{flag}` (2-core shared machine; every
number from this run):

```
{output}
```
"""


if __name__ == "__main__":
    main()
