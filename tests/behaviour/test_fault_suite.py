"""The fault suite: hostile and mistaken inputs, one row each, with the named error (or the
correct result) each must give. Never a crash, a bare traceback from deep inside, a silent
non-finite or unstable result, or a half-written file.

Rows are grouped: shapes, types, ranges, physics, expressions, scenes, names that could reach C
source, output paths; then cache faults, signals and memory, which need a process of their own.
"""
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.app import main

M2, C2, K2 = dd.chain_matrices([1.0, 1.0], [1e4, 1e4], [1.0, 1.0])
F = np.ones(101)
DT = 1e-3
CUBIC = [dd.Cubic(0, k3=1e6)]


def mck(**kw):
    args = dict(M=M2, C=C2, K=K2, force=F, dt=DT, force_dofs=[1])
    args.update(kw)
    return lambda: dd.mck_response(args.pop("M"), args.pop("C"), args.pop("K"), args.pop("force"),
                                   args.pop("dt"), **args)


def chain(**kw):
    args = dict(mass=[1.0, 1.0], stiffness=[1e4, 1e4], damping=[1.0, 1.0], force=F, dt=DT,
                force_dofs=[1])
    args.update(kw)
    return lambda: dd.chain_response(args.pop("mass"), args.pop("stiffness"),
                                     args.pop("damping"), args.pop("force"), args.pop("dt"),
                                     **args)


def nonlinear(**kw):
    args = dict(M=M2, C=C2, K=K2, force=F, dt=DT, force_dofs=[1], elements=CUBIC)
    args.update(kw)
    return lambda: dd.nonlinear_mck_response(args.pop("M"), args.pop("C"), args.pop("K"),
                                         args.pop("force"), args.pop("dt"), **args)


def law(expression):
    return lambda: dd.Law(0, expression=expression)


def _neg(M):
    M = M.copy()
    M[1, 1] = -1.0
    return M


UNSTABLE_A = dd.DiscreteModel(np.array([[1.5]]), np.ones((1, 1)), np.eye(1), np.zeros((1, 1)), 0.1)

#: (id, thunk, exception type, message pattern)
CASES = [
    # --- shapes ---------------------------------------------------------------------------
    ("force-columns", mck(force=np.ones((101, 3))), ValueError, r"force has shape \(101, 3\)"),
    ("force-3d", mck(force=np.ones((10, 1, 1))), ValueError, "force has shape"),
    ("force-one-sample", mck(force=np.ones(1)), ValueError, "at least 2"),
    ("M-not-square", mck(M=np.ones((2, 3))), ValueError, "M must be a non-empty square"),
    ("C-wrong-size", mck(C=np.eye(3)), ValueError, r"C has shape \(3, 3\), expected \(2, 2\)"),
    ("M-empty", mck(M=np.zeros((0, 0))), ValueError, "M must be a non-empty square"),
    ("outputs-out-of-range", mck(outputs=[5]), ValueError, "outputs .* outside 0..1"),
    ("force-dofs-repeated", mck(force=np.ones((101, 2)), force_dofs=[1, 1]), ValueError,
     "repeats an index"),
    ("chain-length-mismatch", chain(stiffness=[1e4]), ValueError, "stiffness"),
    ("x0-length", mck(x0=[0.0, 0.0, 0.0]), ValueError, "x0 has length 3, expected 2"),
    ("state-space-B-rows", lambda: dd.DiscreteModel(np.eye(2), np.ones((3, 1)), np.eye(2),
                                                    np.zeros((2, 1)), 0.1), ValueError,
     "B has 3 rows"),
    ("nonlinear-element-outside", nonlinear(elements=[dd.Cubic(9, k3=1.0)]), ValueError,
     r"elements\[0\].*outside"),
    # --- types ----------------------------------------------------------------------------
    ("dt-string", mck(dt="fast"), ValueError, "dt must be a number, got 'fast'"),
    ("dt-none", mck(dt=None), ValueError, "dt must be a number, got None"),
    ("force-strings", mck(force=np.array(["a"] * 101)), ValueError, "could not convert|force"),
    ("M-objects", mck(M=[[object(), 0], [0, 1]]), ValueError, "M must be a real numeric matrix"),
    ("substeps-float", nonlinear(substeps=2.5), ValueError, "substeps must be an integer"),
    ("quantities-unknown", mck(quantities=("x", "jerk")), ValueError, "quantities must be"),
    ("element-not-element", nonlinear(elements=["cubic"]), ValueError, "not a dtdyn element"),
    # --- ranges ---------------------------------------------------------------------------
    ("dt-zero", mck(dt=0.0), ValueError, "dt must be finite and > 0, got 0.0"),
    ("dt-negative", chain(dt=-1e-3), ValueError, "dt must be finite and > 0"),
    ("dt-nan", mck(dt=float("nan")), ValueError, "dt must be finite and > 0, got nan"),
    ("dt-inf", chain(dt=float("inf")), ValueError, "dt must be finite and > 0, got inf"),
    ("substeps-zero", nonlinear(substeps=0), ValueError, "substeps must be an integer >= 1"),
    ("tol-negative", nonlinear(tol=-1.0), ValueError, "tol must be finite and > 0"),
    ("max-iter-zero", nonlinear(max_iter=0), ValueError, "max_iter must be an integer >= 1"),
    ("srs-damping-negative",
     lambda: dd.shock_response_spectrum(F, DT, [10.0], damping_ratio=-0.1), ValueError,
     "damping_ratio"),
    ("srs-freq-negative", lambda: dd.shock_response_spectrum(F, DT, [-10.0]), ValueError,
     r"freqs_hz\[0\] = -10.0"),
    ("force-nan", mck(force=np.r_[np.ones(50), np.nan, np.ones(50)]), ValueError,
     r"force\[50, 0\] = nan"),
    ("force-inf-chain", chain(force=np.r_[np.ones(50), np.inf, np.ones(50)]), ValueError,
     r"force\[50, 0\] = inf"),
    ("scheme-parameter-out-of-range", mck(scheme="newmark", beta=-1.0), ValueError, "beta"),
    ("scheme-unknown", mck(scheme="runge_kutta_17"), ValueError, "unknown scheme"),
    # --- physics --------------------------------------------------------------------------
    ("chain-negative-mass", chain(mass=[1.0, -1.0]), ValueError, r"mass\[1\] = -1.0"),
    ("mck-negative-mass", mck(M=_neg(M2)), ValueError, r"M\[1, 1\] = -1.0: negative mass at DOF 1"),
    ("M-not-symmetric", mck(M=np.array([[1.0, 0.5], [0.0, 1.0]])), ValueError,
     "M is not symmetric"),
    ("M-indefinite", mck(M=np.array([[1.0, 2.0], [2.0, 1.0]])), ValueError,
     "M is not positive semi-definite: its smallest eigenvalue is -1"),
    ("K-inf", mck(K=np.array([[np.inf, 0], [0, 1.0]])), ValueError, r"K\[0, 0\] = inf"),
    ("central-difference-unstable", chain(scheme="central_difference", form="acceleration",
                                          dt=0.05), dd.DtdynUnstableError,
     r"Omega = omega dt = .* > 2"),
    ("mck-unstable", mck(scheme="central_difference", dt=0.05), dd.DtdynUnstableError,
     "use dt <"),
    ("discrete-model-growing", lambda: UNSTABLE_A.simulate(np.ones(11)),
     dd.DtdynUnstableError, "spectral radius of A is 1.5"),
    ("exact-unstable-pole-overflows", lambda: dd.exact_response([[1.0]], [[0.0]], [[-1e4]],
                                                                np.ones(100001), 1e-2),
     FloatingPointError, r"exact_response: the response is not finite from step \d+"),
    ("modal-unstable-pole", lambda: dd.modal_filter_response([[1.0]], [[0.0]], [[-1e4]],
                                                             np.ones(11), 1e-2),
     ValueError, "unstable pole"),
    ("exact-singular-M", lambda: dd.exact_response(np.zeros((2, 2)), np.zeros((2, 2)), K2,
                                                   np.ones((11, 2)), 1e-2), dd.SingularMassError,
     r"C at the massless DOFs \[0, 1\] is singular"),
    ("nonlinear-modal-beyond-limit", nonlinear(scheme="modal_ramp", dt=1e-2,
                                               elements=[dd.Cubic(0, k3=1e14)],
                                               force=np.ones(50) * 1e3),
     (dd.DtdynStepStabilityError, dd.NewtonError), "step"),
    ("newton-diverges", nonlinear(scheme="newmark", force=np.r_[0.0, np.full(49, 1e9)],
                                  elements=[dd.Cubic(0, k3=1e14)], max_iter=3),
     dd.NewtonError, r"Newton did not converge at step \d+"),
    # --- expressions ----------------------------------------------------------------------
    ("expr-tower", law("9**9**9*x"), ValueError, "exponent"),
    ("expr-huge-constant", law("1e308*10*x"), ValueError, "not a finite float"),
    ("expr-fullwidth", law("ｘ**3"), ValueError, "ASCII"),
    ("expr-import", law("__import__('os').system('true')"), ValueError,
     "only the listed functions may be called"),
    ("expr-lambda", law("(lambda: x)()"), ValueError, "only the listed functions"),
    ("expr-attribute", law("x.real"), ValueError, "attribute access is not allowed"),
    ("expr-unknown-name", law("x + y_unknown"), ValueError, "y_unknown"),
    ("expr-empty", law(""), ValueError, "Law.expression is empty"),
    ("expr-subscript", law("x[0]"), ValueError, "indexing is not allowed"),
    ("expr-string", law("'x'"), ValueError, "a string is not allowed"),
]


def _ids(cases):
    return [c[0] for c in cases]


@pytest.mark.parametrize("case", CASES, ids=_ids(CASES))
def test_fault(case):
    _, thunk, exc, pattern = case
    with np.errstate(over="ignore", invalid="ignore"):
        with pytest.raises(exc, match=pattern):
            thunk()


# --- scenes: each refused by `dtdyn simulate` with one line, exit 2, nothing written ---------

GOOD = {
    "model": 'mass = [1.0, 1.0]\nstiffness = [1e4, 1e4]\ndamping = [1.0, 1.0]',
    "load": 'dof = 1\nkind = "step"',
    "scheme": 'name = "average_acceleration"',
    "time": 'dt = 1e-3\nduration = 0.1',
}


def _scene(**change):
    parts = dict(GOOD, **change)
    return "\n".join(f"[[{k}]]\n{v}" if k == "load" else f"[{k}]\n{v}"
                     for k, v in parts.items() if v is not None)


SCENES = [
    ("no-time", _scene(time=None), "time"),
    ("steps-not-integer", _scene(time="dt = 3e-3\nduration = 0.1"), "duration"),
    ("unknown-key", _scene(scheme='name = "average_acceleration"\nspeed = "max"'), "speed"),
    ("negative-mass", _scene(model="mass = [1.0, -1.0]\nstiffness = [1e4, 1e4]"), "mass"),
    ("1e15-steps", _scene(time="dt = 1e-12\nduration = 1e3"), "need .* available"),
    ("load-file-missing", _scene(load='dof = 1\nkind = "file"\npath = "nope.csv"'), "nope.csv"),
    ("unknown-scheme", _scene(scheme='name = "euler_forward_17"'), "euler_forward_17"),
    ("dof-out-of-range", _scene(load='dof = 7\nkind = "step"'), "7"),
    ("not-toml", "mass = [1.0,\n", "TOML|toml|line"),
    ("dt-negative", _scene(time="dt = -1e-3\nduration = 0.1"), "dt"),
]


@pytest.mark.parametrize("case", SCENES, ids=_ids(SCENES))
def test_bad_scene(case, tmp_path, capsys):
    _, text, pattern = case
    path = tmp_path / "bad.toml"
    path.write_text(text)
    out = tmp_path / "r.npz"
    assert main(["simulate", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("dtdyn simulate: error: "), err
    assert __import__("re").search(pattern, err), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


# --- output paths (names that could reach C source: tests/generated_code/test_cbuild.py) -----

@pytest.mark.parametrize("target", ["dir", "missing/r.npz", "r.exe"])
def test_bad_output_path_is_refused_before_the_run(target, tmp_path, capsys):
    (tmp_path / "dir").mkdir()
    assert main(["simulate", "--out", str(tmp_path / target), "--no-check"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error:" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir"]


def test_srs_column_on_a_single_column_record(tmp_path):
    path = tmp_path / "a.npy"
    np.save(path, np.ones(100))
    with pytest.raises(ValueError, match="single column"):
        dd.load_record(path, column=5)


# --- cache faults, signals and memory: a process each -----------------------------------------

def _python(code, env=None, timeout=300):
    full = dict(os.environ, **(env or {}))
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, env=full, timeout=timeout)


RUN_MODAL = """
import numpy as np, dtdyn as dd
M, C, K = dd.chain_matrices([1.0, 1.0], [1e4, 1e4], [1.0, 1.0])
r = dd.modal_filter_response(M, C, K, np.ones(1001), 1e-3, force_dofs=[1])
e = dd.exact_response(M, C, K, np.ones(1001), 1e-3, force_dofs=[1])
print(r.info["backend"], float(np.abs(r.x - e.x).max() / np.abs(e.x).max()))
"""


@pytest.mark.slow
def test_truncated_cached_kernel_is_rebuilt(tmp_path):
    """A cached .so cut in half used to crash every later run (SIGBUS): now it is rebuilt and
    the answer is right (ramp-invariant filters are exact for a step: round-off)."""
    env = {"DTDYN_CACHE": str(tmp_path)}
    first = _python(RUN_MODAL, env)
    assert first.returncode == 0, first.stderr
    libs = list(tmp_path.rglob("*.so"))
    assert libs
    for so in libs:
        data = so.read_bytes()
        so.write_bytes(data[:len(data) // 2])
    second = _python(RUN_MODAL, env)
    assert second.returncode == 0, second.stderr
    backend, err = second.stdout.split()
    assert backend == "c" and float(err) < 1e-10


LONG_RUN = """
import sys, time, numpy as np, dtdyn as dd
import signal
signal.signal(signal.SIGINT, signal.default_int_handler)  # ignored in a shell's background job
M, C, K = dd.chain_matrices([1.0] * 4, [1e3] * 4, [0.1] * 4)
f = np.sin(np.arange({n}) * 7e-3)
run = lambda f: dd.nonlinear_mck_response(M, C, K, f, 1e-3, force_dofs=[3], outputs=[0],
                                      elements=[dd.Cubic(0, k3=1e5)], scheme="newmark",
                                      substeps=8, quantities=("x",))
run(f[:100])
print("start", flush=True)
t = time.time()
try:
    run(f)
    print("finished", flush=True)
except KeyboardInterrupt:
    print("interrupted %.3f" % (time.time() - t), flush=True)
"""


@pytest.mark.slow
def test_ctrl_c_stops_a_long_c_loop_within_a_second():
    """A 2e7-sample nonlinear record (tens of seconds in one C call): SIGINT one second in
    raises KeyboardInterrupt well within a second, and the process exits cleanly."""
    p = subprocess.Popen([sys.executable, "-c", LONG_RUN.format(n=int(2e7))],
                         stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "start"
    time.sleep(1.0)
    t = time.perf_counter()
    p.send_signal(signal.SIGINT)
    out, _ = p.communicate(timeout=60)
    waited = time.perf_counter() - t
    assert p.returncode == 0 and out.startswith("interrupted"), out
    assert waited < 1.0, waited


#: each backend once over 1e6 samples of a 4-DOF model (P4-like), under an address-space limit
#: of what the process maps after its warm-up plus LIMIT_MB: the run's own allocations (its
#: outputs are 1e6 x 1 x 8 B = 8 MB) must fit; the CasADi backend needed 1.4 GB before it ran
#: in chunks
LIMIT_MB = 300
MEMORY_RUN = """
import resource, numpy as np, dtdyn as dd
M, C, K = dd.chain_matrices([1.0] * 4, [1e3] * 4, [0.1] * 4)
n = 1_000_000
f = np.sin(np.arange(n) * 7e-3)
kw = dict(force_dofs=[3], outputs=[0], quantities=("x",))
runs = {{
    "chain-c": lambda f: dd.chain_response([1.0] * 4, [1e3] * 4, [0.1] * 4, f, 1e-3, **kw),
    "mck-c": lambda f: dd.mck_response(M, C, K, f, 1e-3, **kw),
    "state-space-c": lambda f: dd.state_space_response(dd.newmark_ss(M, C, K, 1e-3), f, **kw),
    "modal-filters-c": lambda f: dd.modal_filter_response(M, C, K, f, 1e-3, **kw),
    "nonlinear-c": lambda f: dd.nonlinear_mck_response(M, C, K, f, 1e-3, elements=[dd.Cubic(0,
                             k3=1e5)], scheme="modal_parabolic", backend="c", **kw),
    "nonlinear-casadi": lambda f: dd.nonlinear_mck_response(M, C, K, f, 1e-3, elements=[dd.Cubic(0,
                                  k3=1e5)], scheme="modal_parabolic", backend="casadi", **kw),
}}
run = runs["{backend}"]
run(f[:5000])  # compile, cache, warm up
with open("/proc/self/statm") as fh:
    mapped = int(fh.read().split()[0]) * resource.getpagesize()
resource.setrlimit(resource.RLIMIT_AS, (mapped + {limit} * 2**20, resource.RLIM_INFINITY))
r = run(f)
print(r.x.shape[0], np.isfinite(r.x).all(),
      resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024)
"""


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["chain-c", "mck-c", "state-space-c", "modal-filters-c",
                                     "nonlinear-c", "nonlinear-casadi"])
def test_a_million_samples_fit_in_bounded_memory(backend):
    done = _python(MEMORY_RUN.format(backend=backend, limit=LIMIT_MB), timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    n, finite, peak_mb = done.stdout.split()
    assert n == "1000000" and finite == "True"
    assert int(peak_mb) < 2 * LIMIT_MB, peak_mb


def test_srs_of_an_impossible_size_is_refused_before_allocating(tmp_path, capsys):
    """A wrong --dt (1 s for a record sampled at 10 kHz) asked for 359 GiB and died with a
    MemoryError traceback: now one line naming the size, exit 2."""
    path = tmp_path / "a.npy"
    np.save(path, np.sin(np.arange(100_000) * 1e-2))
    assert main(["srs", str(path), "--dt", "1", "--freqs", "10", "1e4", "5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "upsampled" in err and "available" in err, err
