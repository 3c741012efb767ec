"""Figures and checks of the vector-state transfer matrices (beams, shafts, trees).

1. A 200-element cantilever (E = 2.1e11 Pa, I = 8e-6 m^4, rho A = 20 kg/m, L = 3 m): the first
   four mode shapes from `beam_modes` (the block Riccati sweep at the Wittrick-Williams roots)
   against the closed-form Euler-Bernoulli shapes
   phi(x) = cosh bx - cos bx - s (sinh bx - sin bx), s = (cosh bL + cos bL) / (sinh bL + sin bL),
   and the relative error of the first five frequencies against (beta L)^2 sqrt(EI/(rho A L^4)).
   -> docs/img/beam_modes.png
2. The branched torsional system (a motor line, one gear n = 2 driving a line that branches
   again, a second gear n = -3.5 to a clamped line): |receptance| at the far disk of each
   branch for a torque at the motor, from `shaft_frequency_response` (the tree's Laplace-domain
   sweep), the direct solve of (K + i w C - w^2 M) at a few frequencies, and the natural
   frequencies of `shaft_frequencies`. -> docs/img/shaft_tree_frf.png
3. The residuals of `beam_modes`' shapes (200 elements) and, for an undamped 40-element beam
   between and next to its resonances, the error of the unpivoted block sweep and of the pivoted
   banded LU against a dense solve, in units of eps cond(Z) |u|.

Usage: python benchmarks/vector_state_figures.py [--no-plot]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import dtdyn as dd

IMG = Path(__file__).resolve().parent.parent / "docs" / "img"
E, I, RHO_A, LENGTH = 2.1e11, 8.0e-6, 20.0, 3.0
BETA_L = np.array([1.875104068711961, 4.694091132974175, 7.854757438237613,
                   10.99554073487547, 14.13716839104647])


def _axes():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt.subplots(figsize=(7, 3.6))


def _save(fig, ax, xlabel, ylabel, title, name):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(IMG / name, dpi=110)
    print(f"   figure: {IMG / name}")


def cantilever_shape(bl, x):
    b = bl / LENGTH
    s = (np.cosh(bl) + np.cos(bl)) / (np.sinh(bl) + np.sin(bl))
    return np.cosh(b * x) - np.cos(b * x) - s * (np.sinh(b * x) - np.sin(b * x))


def beam_part(plot):
    beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=LENGTH, elements=200, left="clamped",
                   right="free")
    m = dd.beam_modes(beam, count=5)
    exact = BETA_L ** 2 * np.sqrt(E * I / (RHO_A * LENGTH ** 4))
    print("1) 200-element cantilever, beam_modes against the closed form")
    print("   mode  omega [rad/s]   relative error   shape error (max |w|, scaled)")
    w_rows = [i for i, n in enumerate(m.dof_names) if n.startswith("w")]
    x = np.linspace(0.0, LENGTH, 201)[1:]  # node positions of the w DOFs (clamped node removed)
    shape_err = []
    for r in range(5):
        w = m.shapes[w_rows, r]
        ref = cantilever_shape(BETA_L[r], x)
        ref = ref * (w @ ref) / (ref @ ref)  # the same scale and sign
        shape_err.append(np.abs(w - ref).max() / np.abs(ref).max())
        print(f"   {r + 1:4d}  {m.omega[r]:13.4f}   {abs(m.omega[r] - exact[r]) / exact[r]:14.1e}"
              f"   {shape_err[-1]:10.1e}")
    if plot:
        fig, ax = _axes()
        xf = np.linspace(0.0, LENGTH, 400)
        for r in range(4):
            w = m.shapes[w_rows, r]
            scale = np.abs(w).max()
            ref = cantilever_shape(BETA_L[r], xf)
            ref = ref / np.abs(ref).max() * np.sign(ref[-1] * w[-1])
            ax.plot(xf, ref, color="0.7", lw=3)
            ax.plot(x[::8], w[::8] / scale, "o", ms=3, label=f"mode {r + 1}, "
                    f"{m.omega[r] / (2 * np.pi):.1f} Hz")
        _save(fig, ax, "x [m]", "w (scaled)",
              "Cantilever: beam_modes (dots) and the closed form (grey)", "beam_modes.png")
    return max(shape_err)


def branched():
    return dd.Shaft([1.0, 0.3, 0.9], [0.0, 1.2e4, 9e3], [0.0, 0.8, 0.3], left="free",
                    ground_stiffness=[2e3, 0.0, 0.0], ground_damping=[0.5, 0.0, 0.0],
                    branches=[
                        dd.Branch(1, [0.5, 0.4, 0.7], [6e3, 5e3, 7e3], [0.2, 0.2, 0.1],
                                  ratio=2.0, name="left", ground_stiffness=[0.0, 1e3, 0.0],
                                  branches=[dd.Branch(2, [0.25], [3e3], [0.05], name="leaf")]),
                        dd.Branch(1, [0.6, 0.45], [4e3, 8e3], [0.3, 0.1], ratio=-3.5,
                                  name="right", right="clamped", right_stiffness=2e3)])


def shaft_part(plot):
    s = branched()
    M, C, K = (A.toarray() for A in dd.shaft_matrices(s))
    names = list(s.dof_names)
    w = np.linspace(1.0, 600.0, 3000)
    outs = ["leaf.0", "right.1", "main.2"]
    H = {o: dd.shaft_frequency_response(s, w, "main.0", o) for o in outs}
    check = np.array([10.0, 55.0, 130.0, 260.0, 480.0])
    worst = 0.0
    for x in check:
        col = np.linalg.solve(K + 1j * x * C - x * x * M, np.eye(len(names))[0])
        for o in outs:
            h = dd.shaft_frequency_response(s, [x], "main.0", o)[0]
            worst = max(worst, abs(h - col[names.index(o)]) / np.abs(col).max())
    wn = dd.shaft_frequencies(s)
    print("\n2) branched geared tree, shaft_frequency_response against the direct solve")
    print(f"   largest relative difference at {check.size} frequencies: {worst:.1e}")
    print("   natural frequencies [rad/s]: " + ", ".join(f"{v:.2f}" for v in wn))
    if plot:
        fig, ax = _axes()
        for o in outs:
            ax.semilogy(w, np.abs(H[o]), lw=1.2, label=f"{o} / torque at main.0")
        for v in wn[wn < w[-1]]:
            ax.axvline(v, color="0.8", lw=0.8, zorder=0)
        _save(fig, ax, "omega [rad/s]", "|receptance| [rad/(N m)]",
              "Branched geared shaft: tree sweep (lines), natural frequencies (grey)",
              "shaft_tree_frf.png")
    return worst


def solver_part():
    """The residuals of beam_modes' shapes, and the unpivoted sweep against the pivoted banded
    LU inside the spectrum of an undamped beam (both against a dense solve)."""
    from dtdyn._engine import linalg
    from dtdyn.linear import _beam_frequency as bf

    eps = np.finfo(float).eps
    print("\n3) residuals and pivoting (200 elements: shapes; 40 elements: receptances)")
    for left, right in (("clamped", "free"), ("pinned", "pinned")):
        beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=LENGTH, elements=200, left=left,
                       right=right)
        M, _, K = (A.toarray() for A in dd.beam_matrices(beam))
        m = dd.beam_modes(beam, count=8)
        res = [np.linalg.norm(K @ p - (p @ K @ p) * (M @ p)) / (np.linalg.norm(K, 2)
               * np.linalg.norm(p)) / eps for p in m.shapes.T]
        print(f"   {left}-{right}: beam_modes residual ||K phi - rho M phi|| <= "
              f"{max(res):.2f} eps ||K|| ||phi|| (8 modes)")
        beam = dd.Beam(E=E, I=I, rho_A=RHO_A, length=LENGTH, elements=40, left=left,
                       right=right)
        M, _, K = (A.toarray() for A in dd.beam_matrices(beam))
        Mg, _, Kg = beam.global_matrices()
        (DK, EK, _), (DM, EM, _) = (linalg.node_blocks(A) for A in (Kg, Mg))
        wn = dd.beam_frequencies(beam, count=10)
        w = np.r_[0.5 * (wn[:-1] + wn[1:]), wn[:5] * (1 + 1e-6)]
        s2 = (w * w)[:, None, None, None]
        D, Eb = DK - s2 * DM, EK - s2 * EM
        n, nodes, held = beam.n_dof, beam.elements + 1, bf._held(beam)
        worst = dict.fromkeys(("unpivoted sweep", "pivoted banded LU"), 0.0)
        for i_f in (n - 1, beam.dof("w20"), beam.dof("psi30")):
            f = np.zeros((w.size, 2 * nodes))
            f[:, beam.free[i_f]] = 1.0
            for name, solve in zip(worst, (bf.block_sweep, bf.banded_solve)):
                u = solve(D, Eb, held, f.reshape(w.size, nodes, 2))
                u = u.reshape(w.size, -1)[:, beam.free]
                for j, x in enumerate(w):
                    Z = K - x * x * M
                    col = np.linalg.solve(Z, np.eye(n)[i_f])
                    worst[name] = max(worst[name], np.abs(u[j] - col).max()
                                      / (eps * np.linalg.cond(Z) * np.abs(col).max()))
        print(f"   {left}-{right}, undamped, between and next to its first 10 resonances: "
              + ", ".join(f"{k} {v:.2f}" for k, v in worst.items()) + " eps cond(Z) |u|")


def main(plot=True):
    IMG.mkdir(parents=True, exist_ok=True)
    beam_part(plot)
    shaft_part(plot)
    solver_part()


if __name__ == "__main__":
    main(plot="--no-plot" not in sys.argv)
