"""Peak memory of each time-history backend over a long record (#12's bound).

Every backend runs a 4-DOF chain model (P4-like: unit masses, k = 1e3 N/m, c = 0.1 N s/m;
the nonlinear runs add a cubic spring of 1e5 N/m^3 at DOF 0) for N samples, each in a fresh
process: the peak resident set size (ru_maxrss) after the run, the same after a warm-up of
5,000 samples (imports, compiled kernels), and their difference. The result is the
displacement of DOF 0 only (N x 8 bytes).

    python benchmarks/memory.py [N ...]     (default 1e6; 1e7 adds the CasADi backend's figure)
"""
import subprocess
import sys

RUN = """
import resource, numpy as np, dtdyn as dd
M, C, K = dd.chain_matrices([1.0] * 4, [1e3] * 4, [0.1] * 4)
f = np.sin(np.arange({n}) * 7e-3)
kw = dict(force_dofs=[3], outputs=[0], quantities=("x",))
cubic = [dd.Cubic(0, k3=1e5)]
runs = {{
    "chain (C)": lambda f: dd.chain_response([1.0] * 4, [1e3] * 4, [0.1] * 4, f, 1e-3, **kw),
    "mck_response (C)": lambda f: dd.mck_response(M, C, K, f, 1e-3, **kw),
    "mck_response (NumPy)": lambda f: dd.mck_response(M, C, K, f, 1e-3, backend="numpy", **kw),
    "state space (C)": lambda f: dd.state_space_response(dd.newmark_ss(M, C, K, 1e-3), f, **kw),
    "modal filters (C)": lambda f: dd.modal_filter_response(M, C, K, f, 1e-3, **kw),
    "nonlinear (C)": lambda f: dd.nonlinear_mck_response(M, C, K, f, 1e-3, elements=cubic,
                                                     scheme="modal_parabolic", **kw),
    "nonlinear (CasADi)": lambda f: dd.nonlinear_mck_response(M, C, K, f, 1e-3, elements=cubic,
                                                          scheme="modal_parabolic",
                                                          backend="casadi", **kw),
}}
run = runs[{name!r}]
run(f[:5000])
warm = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
r = run(f)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(f"{{warm:.0f}} {{peak:.0f}} {{r.info.get('run_time', float('nan')):.3f}}")
"""

NAMES = ["chain (C)", "mck_response (C)", "mck_response (NumPy)", "state space (C)",
         "modal filters (C)", "nonlinear (C)", "nonlinear (CasADi)"]


def main(sizes):
    print(f"{'backend':24s} {'samples':>10s} {'warm MB':>8s} {'peak MB':>8s} {'run MB':>7s} "
          f"{'run s':>7s}")
    for n in sizes:
        names = NAMES if n <= 1_000_000 else ["nonlinear (C)", "nonlinear (CasADi)"]
        for name in names:
            out = subprocess.run([sys.executable, "-c", RUN.format(n=n, name=name)],
                                 capture_output=True, text=True, check=True).stdout.split()
            warm, peak, t = float(out[0]), float(out[1]), float(out[2])
            print(f"{name:24s} {n:10.0e} {warm:8.0f} {peak:8.0f} {peak - warm:7.0f} {t:7.2f}")


if __name__ == "__main__":
    main([int(float(a)) for a in sys.argv[1:]] or [1_000_000])
