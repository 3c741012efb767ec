"""Harmonic balance on a cantilever with a cubic spring and a gap: the reduced receptance
against the banded one for 100 .. 10,000 elements, and the curve against long time-domain runs.

The model: a steel cantilever (E = 2.1e11 Pa, I = 8e-6 m^4, rho_A = 20 kg/m, L = 3 m) of N
Hermite elements, Rayleigh damping C = alpha M + beta K with 5 % of critical damping in its
first two modes (18.0 and 113 Hz), a cubic spring k3 = 7.5e8 N/m^3 from the tip to the
ground, a gap (clearance 1 mm, stiffness 1e5 N/m, both sides) at mid-span, a force
100 cos(omega t) N at the tip, swept from 5 to 150 Hz (a band holding the first two modes),
outputs: the tip and mid-span deflections. Hill's stability is off (its dense eigenproblem
is refused above 2 n (2 H + 1) = 6000).

1. The curve (H = 10 harmonics, n_time 128 samples per period, ``max_step=0.03`` for about
   200 points, ``convergence_points=0``) with ``receptance="reduced"`` and ``"banded"`` for
   N = 100, 300, 1,000, 2,000 (and 10,000 with ``--full``). Per run: the points, the setup
   (the run time of a two-point curve over the same band: the reduced receptance's modes and
   residual terms, built for the whole band, and two points' Newton), the time per point
   over the rest of the 200-point run (``info["run_time"]`` of one run after a warm-up; BLAS
   pinned to one thread), the Newton tolerance ``tol`` used (the smallest of 1e-10, 1e-9 ..
   1e-5 with which the continuation got through; the banded receptance's rounding, which varies from
   one frequency to the next, stops Newton below that), the reduced receptance's check
   (``info["receptance_check"]``: its modes, series terms and difference from the banded
   receptance at the top of the band, or why it fell back), and the peak tip amplitude.
2. Convergence in the harmonics at N = 300: ``harmonic_convergence`` (x_max with 2 H
   harmonics and twice the samples against H, at 10 points and the peak) for H = 10 and 20.
3. Three frequencies (15 and 18.5 Hz, the gap in contact near the first resonance, and 110 Hz
   near the second) at N = 1,000 (``--td-elements``): the harmonic balance at that frequency
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
Usage: python benchmarks/harmonic_balance_beam.py [--full] [--td-elements N]
(about 4 minutes; --full adds N = 10,000 to part 1)
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time
import warnings

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
                r = dd.harmonic_balance(b, tol=tol, **args)
        except dd.NewtonError as exc:
            err = str(exc).removeprefix("harmonic_balance: ")
            continue
        if r.info["stop"] == "end of the range" or "max_points" in kw:
            return r, tol, err
        err = f"stopped: {r.info['stop']} at {r.frequency_hz[-1]:.4g} Hz"
    return None, None, err


def check_text(info):
    c = info.get("receptance_check")
    if not c:
        return "-"
    if c.get("receptance") == "reduced":
        return (f"passed: {c['modes']} modes, {c['terms']} terms, {c['error']:.1e} at "
                f"{c['verified_to_hz']:.0f} Hz")
    return f"failed: {c.get('reason', '?')}"


def part1(sizes, lines):
    lines.append(f"1) the curve {BAND[0]:g} .. {BAND[1]:g} Hz, H = 10, max_step 0.03")
    lines.append(f"{'N':>6} {'receptance':>10} {'points':>6} {'tol':>6} {'setup s':>8} "
                 f"{'ms/point':>8} {'Newton/pt':>9} {'tip max mm':>10}  reduced check")
    per_point = {}
    for n in sizes:
        for rec in ("reduced", "banded"):
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
    return per_point


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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="also N = 10,000 in part 1")
    ap.add_argument("--td-elements", type=int, default=1000, help="N of part 3")
    ap.add_argument("--no-write", action="store_true", help="do not write the doc")
    args = ap.parse_args(argv)
    sizes = (100, 300, 1000, 2000) + ((10_000,) if args.full else ())
    lines = []
    with pin_blas(1) as pin:
        lines.append(pin.describe())
        curve(20, "reduced", freqs_hz=(5.0, 6.0))              # warm-up: imports, CasADi
        t0 = time.perf_counter()
        part1(sizes, lines)
        part2(lines)
        part3(args.td_elements, lines)
        lines.append(f"\ntotal {time.perf_counter() - t0:.0f} s")
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        DOC.write_text(EXPLANATION.format(output=text, flag=" --full" if args.full else ""))
        print(f"wrote {DOC}", file=sys.stderr)


EXPLANATION = """\
# Harmonic balance on a beam: reduced and banded receptances, and the time domain

`python benchmarks/harmonic_balance_beam.py` (its docstring has the model and what each column
is): a cantilever with a cubic spring at the tip and a gap at mid-span, the frequency response
curve over its first two modes by `harmonic_balance` with `receptance="reduced"` and
`"banded"`, and three of its points against long `nonlinear_beam_response` runs.

What the output shows. The reduced receptance (modes below a cut-off and the residual series,
checked against the banded receptance at the top of the band) is a smooth function of the
frequency: Newton converges to the default `tol=1e-10` and the time per point does not grow
with N while its check passes. The banded receptance (LAPACK's banded LU at every harmonic and
evaluation) carries the rounding of a solve with the beam's stiffness matrix, about eps N^3.5
relative (docs/beam_conditioning.md), and that rounding changes from one frequency to the
next: the continuation's Newton stalls below a tolerance that grows with N, and from about
1,000 elements no tolerance gets the curve through the band. From 2,000 elements the reduced
receptance's own check fails for the same reason (ARPACK's modes come from the same
ill-conditioned factors, and the banded receptance it is checked against is no better), it
falls back to the banded one and fails with it. The curve of a 10,000-element beam is
therefore out of reach of both receptances as they are; a beam of the elements its band needs
(docs/beam_conditioning.md: 6 to 10 per wavelength of the highest harmonic's mode) gives the
same curve. Part 3 is the check of the curve against the time domain on the largest model
where the reduced receptance passes its check.

Output of `python benchmarks/harmonic_balance_beam.py{flag}` (2-core shared machine; every
number from this run):

```
{output}
```
"""


if __name__ == "__main__":
    main()
