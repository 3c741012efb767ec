"""Two checks behind docs/nonlinear.md: the stability of each method against an element's
tangent stiffness, and the Bouc-Wen hysteresis loop against the solve_ivp reference.

1. Stability: x'' + 2 zeta x' + x = -k_t x (the element as a linear spring of tangent stiffness
   k_t), step h = 0.01: spectral radius of the closed-loop step map of each method (its LinearStep
   with g = k_t w) minus 1, against Omega_t = h sqrt(k_t), and theta = B0 k_t (what the C loop
   checks against THETA_LIMIT; modal_explicit, whose step has no B0: (Cw Bg) k_t).
2. Bouc-Wen: 1 kg on a 100 N/m spring and a Bouc-Wen element (k = 1e4 N/m, alpha = 0.1,
   beta = gamma = 50 1/m, n = 1), 0.5 N s/m damper, 50 N sine at 1 Hz, fs = 200 Hz, 5 s: error
   against the reference (DOP853 rtol 1e-12 restarted at every sample), dissipated energy, loop.

3. DT-TMM chains with nonlinear elements: run time per step of nonlinear_chain_response (two
   cubic springs) against the linear chain_response on the same chain, N = 1e3 .. 1e5 masses,
   measured in the same run: median [min, max] of 3 runs after a warm-up, BLAS pinned to one
   thread (dtdyn.app.pin_blas, threadpoolctl).

Writes docs/nonlinear_checks.md and docs/img/bouc_wen_loop.png.
Usage: python benchmarks/nonlinear_checks.py
"""
from __future__ import annotations

import functools
import pathlib

import numpy as np

from dtdyn.nonlinear import _response as NL
from dtdyn.nonlinear._elements import BoucWen
from dtdyn.nonlinear._reference import reference_response

ROOT = pathlib.Path(__file__).resolve().parent.parent
OMEGAS = (0.01, 0.1, 0.3, 0.5, 1.0, 2.0, 3.4, 3.6, 10.0)


def stability_rows(zeta):
    h, L = 0.01, np.array([[1.0]])
    M, K, C = np.eye(1), np.eye(1), np.array([[2 * zeta]])
    rows = []
    for method in ("modal_ramp", "modal_parabolic", "modal_quintic", "modal_explicit", "newmark",
                   "generalized_alpha"):
        st = NL.linear_step(method, M, C, K, h, np.array([0]), L, np.array([0]))
        B0 = -st.Dwg[0, 0]
        cells = []
        for Om in OMEGAS:
            kt = (Om / h) ** 2
            A = st.A + st.Bg @ (kt * st.Cw) / (1 + kt * B0)
            cells.append(np.abs(np.linalg.eigvals(A)).max() - 1)
        rows.append((method, -(st.Cw @ st.Bg)[0, 0] if method == "modal_explicit" else B0,
                     cells))
    return rows


def bouc_wen():
    M, K, C = np.array([[1.0]]), np.array([[100.0]]), np.array([[0.5]])
    fs, n = 200.0, 1000
    t = np.arange(n) / fs
    f = (50.0 * np.sin(2 * np.pi * t))[:, None]
    els = [BoucWen(0, stiffness=1e4, alpha=0.1, beta=50.0, gamma=50.0)]
    ref = reference_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els)

    def g_of(r):  # the element force from the equation of motion
        return f[:, 0] - M[0, 0] * r.a[:, 0] - C[0, 0] * r.v[:, 0] - K[0, 0] * r.x[:, 0]

    out = []
    for method in ("modal_ramp", "modal_parabolic", "modal_explicit", "newmark"):
        for S in (1, 2, 4, 8):
            r = NL.nonlinear_mck_response(M, C, K, f, 1 / fs, force_dofs=[0], elements=els,
                                      scheme=method, substeps=S)
            err = np.abs(r.x - ref.x).max() / np.abs(ref.x).max()
            out.append((method, S, err, np.trapezoid(g_of(r), r.x[:, 0]), r))
    return ref, np.trapezoid(g_of(ref), ref.x[:, 0]), out, g_of


def chain_scaling():
    from dtdyn import chain_response
    from dtdyn.app import measure
    from dtdyn.nonlinear._elements import Cubic
    from dtdyn.nonlinear._chain import nonlinear_chain_response
    rows = []
    n_steps = 100
    f = (np.random.default_rng(1).standard_normal(n_steps + 1) * 100.0)[:, None]
    for n in (1_000, 10_000, 100_000):
        m, k, c = np.ones(n), np.full(n, 1e4), np.full(n, 1.0)
        els = [Cubic(0, k3=2e7), Cubic(n - 3, n - 2, k3=2e7)]
        times = []
        for run in (functools.partial(chain_response, m, k, c, f, 1e-3, force_dofs=[n - 1],
                                      outputs=[n - 1], form="acceleration"),
                    functools.partial(nonlinear_chain_response, m, k, c, f, 0.001,
                                      force_dofs=[n - 1], elements=els, outputs=[n - 1],
                                      form="acceleration")):
            times.append(measure(run, 3)[1].scaled(1 / n_steps))
        rows.append((n, *times))
    return rows


def main():
    from dtdyn.app import pin_blas
    with pin_blas(1) as pin:
        _main(pin)


def _main(pin):
    lines = ["# Nonlinear checks", "", "Output of `python benchmarks/nonlinear_checks.py`.", "",
             "## Stability against an element's tangent stiffness", "",
             "x'' + 2 zeta x' + x = -k_t x, h = 0.01; entries: spectral radius - 1 of the step "
             "with the element (negative: decays).", ""]
    for zeta in (0.0, 0.02):
        lines += [f"zeta = {zeta}:", "",
                  "| method | B0 | " + " | ".join(f"Omega_t = {o:g}" for o in OMEGAS) + " |",
                  "|---|---|" + "---|" * len(OMEGAS)]
        for method, B0, cells in stability_rows(zeta):
            lines.append(f"| {method} | {B0:.3e} | " + " | ".join(f"{c:+.1e}" for c in cells)
                         + " |")
        lines.append("")
    lines += ["theta = B0 k_t = Omega_t^2 B0 / h^2 (modal_explicit's B0 column: Cw Bg, the "
              "weight of the newest element force on the next step's y); both backends stop "
              "with "
              "DtdynStepStabilityError above theta = "
              + ", ".join(f"{k:.3g} for {m}" for m, k in NL.THETA_LIMIT.items()) + ".", ""]
    ref, w_ref, runs, g_of = bouc_wen()
    lines += ["## Bouc-Wen hysteresis", "",
              f"Reference dissipated energy (integral of g dy over 5 cycles): {w_ref:.6g} J.", "",
              "| method | substeps | max error of x | dissipated energy error |",
              "|---|---|---|---|"]
    for method, S, err, w, _ in runs:
        lines.append(f"| {method} | {S} | {err:.2e} | {abs(w - w_ref) / w_ref:.2e} |")
    plot_loop(ref, [r for m, S, *_, r in runs if m == "modal_parabolic" and S == 2][0], g_of)
    lines += ["", "![Bouc-Wen loop](img/bouc_wen_loop.png)", "",
              "## DT-TMM chains with nonlinear elements", "",
              "Two cubic springs (k3 = 2e7) on a uniform chain, 100 steps, acceleration form; time "
              "per step, median [min, max] of 3 runs after a warm-up; " + pin.describe() + ":",
              "", "| masses | chain_response (linear) [ms] | nonlinear_chain_response "
              "[ms] | ratio (medians) |", "|---|---|---|---|"]
    for n, t_lin, t_nl in chain_scaling():
        lines.append(f"| {n} | {t_lin.format('ms', 3).removesuffix(' ms')} | "
                     f"{t_nl.format('ms', 3).removesuffix(' ms')} | {t_nl / t_lin:.1f} |")
    lines.append("")
    text = "\n".join(lines)
    print(text)
    (ROOT / "docs" / "nonlinear_checks.md").write_text(text)


def plot_loop(ref, r, g_of):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(ref.x[:, 0] * 1e3, g_of(ref), "k-", lw=2.5, alpha=0.35,
            label="solve_ivp DOP853 reference")
    ax.plot(r.x[:, 0] * 1e3, g_of(r), "C1-", lw=1, label="modal_parabolic, 2 sub-steps")
    ax.set_xlabel("y [mm]")
    ax.set_ylabel("element force g [N]")
    ax.set_title("Bouc-Wen element under a 1 Hz sine: hysteresis loop")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path = ROOT / "docs" / "img" / "bouc_wen_loop.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
