"""Run by test_sanitizers.py in a subprocess with libasan and libubsan preloaded: the chain, shaft,
beam (block chain), mck, nonlinear (mck, its modal path, chain, beam and shaft, these three also
with the kept-LU Newton) loops and the modal filters (per mode and as sections), compiled with
-fsanitize=address,undefined, on tiny problems.
With the argument ``overflow``: the chain kernel told its work is longer than it is (the check at
entry passes), which ASan must report."""
import sys
import warnings

import numpy as np
from dtdyn._engine import cbuild
SANITIZE = ("-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer")
cbuild.CFLAGS = tuple(f for f in cbuild.CFLAGS if f != "-O3") + ("-O1", "-g", *SANITIZE)
cbuild.LIBS = cbuild.LIBS + SANITIZE[:1]
warnings.simplefilter("ignore")
warnings.simplefilter("error", cbuild.DtdynFallbackWarning)  # C or nothing
import dtdyn  # noqa: E402
from dtdyn._engine import kernels  # noqa: E402

if sys.argv[1:] == ["overflow"]:
    fn = kernels.c_chain_function("newmark")
    N = 300
    work = np.zeros(kernels.WORK_ROWS["stable"] * N - 1)  # one double short, malloc'ed
    m, hist, force = np.ones(N), np.zeros((3, N)), np.ones((3, 1))
    loaded, params = np.array([N - 1], dtype=np.int64), np.array([0.25, 0.5])
    fn(0, 0, N, 2, m.ctypes.data, m.ctypes.data, m.ctypes.data, None, None, 1e-3,
       params.ctypes.data, 1, loaded.ctypes.data, force.ctypes.data, hist.ctypes.data, 0, None,
       None, None, None, work.ctypes.data, work.size + 1, None, None, 1)
    print("not caught")
    sys.exit(0)
rng = np.random.default_rng(0)
N = 9
m, k, c = 1 + rng.random(N), 1e4 * (1 + rng.random(N)), 0.5 + rng.random(N)
f = rng.standard_normal((41, 2))
for sweep in ("stable", "plain"):
    for form in ("displacement", "acceleration"):
        dtdyn.chain_response(m, k, c, f, 1e-3, force_dofs=[0, 8], sweep=sweep, form=form,
                             scheme="hht", alpha=-0.1)
dtdyn.shaft_response(dtdyn.Shaft(np.ones(5), 1e4 * np.ones(5), 0.1 * np.ones(5)), f[:, 0], 1e-3,
                     force_dofs=[4])
dtdyn.beam_response(dtdyn.Beam(E=2e11, I=1e-8, rho_A=1.0, length=1.0, elements=4), f[:, 0],
                    1e-4, force_dofs=[7])
M, C, K = dtdyn.chain_matrices(m, k, c)
dtdyn.mck_response(M, C, K, f, 1e-3, force_dofs=[0, 8])
cubic = [dtdyn.Cubic(0, k3=1e8)]
dtdyn.nonlinear_mck_response(M, C, K, 50 * f, 1e-3, force_dofs=[0, 8], elements=cubic,
                             scheme="newmark")
dtdyn.nonlinear_chain_response(m, k, c, 50 * f, 1e-3, force_dofs=[0, 8], elements=cubic)
# nl_stations: a beam (block chain step in the library) and a tree (its sweep by pointer)
dtdyn.nonlinear_beam_response(dtdyn.Beam(E=2e11, I=1e-8, rho_A=1.0, length=1.0, elements=4),
                              20 * f[:, 0], 1e-4, force_dofs=[7],
                              elements=[dtdyn.Cubic(7, k3=1e12), dtdyn.Gap(3, gap=0.0,
                                                                           stiffness=1e3)])
dtdyn.nonlinear_shaft_response(dtdyn.Shaft(np.ones(5), 1e4 * np.ones(5), 0.1 * np.ones(5),
                                           branches=[dtdyn.Branch(2, [0.5], [5e3], ratio=2.0)]),
                               50 * f[:, 0], 1e-3, force_dofs=[4],
                               elements=[dtdyn.Cubic(1, 5, k3=1e8)], substeps=2)
# the kept-LU Newton (newton_kept): a chain with 8 Bouc-Wen elements (24 unknowns, from
# LU_KEPT_MIN on), then the beam and the shaft with it from 1 unknown on
from dtdyn.nonlinear import _chain as nl_chain  # noqa: E402
assert nl_chain.LU_KEPT_MIN <= 24
hysteretic = [dtdyn.BoucWen(i, i - 1 if i else None, stiffness=5e3, beta=50.0, gamma=50.0)
              for i in range(8)]
kept = dtdyn.nonlinear_chain_response(m, k, c, 50 * f, 1e-3, force_dofs=[0, 8],
                                      elements=hysteretic)
assert kept.info["newton_iterations"]["factorizations"] >= 1
nl_chain.LU_KEPT_MIN = 1
kept = dtdyn.nonlinear_beam_response(dtdyn.Beam(E=2e11, I=1e-8, rho_A=1.0, length=1.0,
                                                elements=4),
                                     20 * f[:, 0], 1e-4, force_dofs=[7],
                                     elements=[dtdyn.Cubic(7, k3=1e12), dtdyn.Cubic(5, k3=1e12),
                                               dtdyn.Gap(3, gap=0.0, stiffness=1e3)])
assert kept.info["newton_iterations"]["factorizations"] >= 1
kept = dtdyn.nonlinear_shaft_response(dtdyn.Shaft(np.ones(5), 1e4 * np.ones(5), 0.1 * np.ones(5)),
                                      50 * f[:, 0], 1e-3, force_dofs=[4],
                                      elements=[dtdyn.Cubic(i, i + 1, k3=1e8) for i in range(4)])
assert kept.info["newton_iterations"]["factorizations"] >= 1
nl_chain.LU_KEPT_MIN = 24
for scheme in ("modal_quintic", "modal_explicit"):  # nl_loop's modal path and its estimate
    dtdyn.nonlinear_mck_response(M, C, K, 50 * f, 1e-3, force_dofs=[0, 8], elements=cubic,
                                 scheme=scheme)
for n in (3, 6, 13):  # the modal filters: chunks of 4, 8 and 16 states; 13 outputs: axpy
    Md, Cd, Kd = dtdyn.chain_matrices(1 + rng.random(n), 1e4 * (1 + rng.random(n)),
                                      0.5 + rng.random(n), sparse=False)
    for algorithm in ("modes", "sections"):
        dtdyn.modal_filter_response(Md, Cd, Kd, f, 1e-3, force_dofs=[0, n - 1],
                                    outputs=list(range(n)), algorithm=algorithm)
print("ok")
