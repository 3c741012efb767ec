"""dtdyn against OpenSees on a 5-storey shear building under a ground acceleration record.

The peer is OpenSees (openseespy), not a dependency of dtdyn or of its tests. On Debian or
Ubuntu it needs two system libraries first::

    apt-get install libblas3 liblapack3
    pip install openseespy

The building is the one of tests/behaviour/test_ground_motion.py and the README: floor masses
2e5 kg, storey stiffnesses 3e8 N/m (the top one 2e8 N/m), with Rayleigh damping
C = a0 M + a1 K of 5 % in modes 1 and 3, the same C in both programs. In OpenSees: a 1-D model
(ndm 1, ndf 1), node 0 fixed, nodes 1..5 with the floor masses, one zeroLength element per
storey with an Elastic uniaxial material (``-doRayleigh 1``, or the element adds no
stiffness-proportional damping), ``rayleigh(a0, a1, 0, 0)``, the record as a ``Path`` time
series (``-dt``) in a ``UniformExcitation`` pattern, Newmark (gamma 1/2, beta 1/4),
``algorithm Linear``. dtdyn: ``mck_response(M, C, K, None, dt, scheme="average_acceleration",
ground_acceleration=ag)``.

1. Accuracy. Both load the structure with -M r a_g(t_k) and report displacements relative to
   the support; the script prints max |x_dtdyn - x_OpenSees| / max |x| (target 1e-10: the same
   scheme at the same dt differs by rounding only) and compares dtdyn's absolute acceleration
   ``a_abs`` with OpenSees' nodal acceleration (relative under UniformExcitation) plus a_g.
   OpenSees advances its clock by adding dt, and its Path series is read at that clock: with
   dt = 0.01 s (not a binary fraction) the clock drifts from k dt by rounding and the series
   is read between samples, so the two differ by more than rounding on long records; the
   column "x, clock" gives dtdyn the record read at that clock (`clock_samples`) and shows the
   runs then agree to rounding. With dt = 1/128 s the clock is exact; the target is checked
   there, and the script exits with status 1 when it is missed.
2. Speed, same run: OpenSees ``analyze(n_steps, dt)`` in one call with a Node recorder writing
   the displacement of every floor at every step (the fastest of the systems tried below,
   ``Linear -factorOnce``, a binary recorder file), against ``mck_response`` (generated C loop)
   storing x of every DOF; after a warm-up, the median [min, max] of repeats, BLAS pinned to
   one thread in this process (dtdyn.app.pin_blas, threadpoolctl). Only the analysis is timed
   in OpenSees (not the model building nor reading the file back); dtdyn's time is the whole
   call (checks, factorization, loop, result).

    python benchmarks/opensees_peer.py [n_steps ...]     (default: 20000 200000)
"""
import functools
import os
import sys
import tempfile
import time

import numpy as np

import dtdyn as dd
from dtdyn.app import Timing, measure, pin_blas

MASS, STIFF = [2e5] * 5, [3e8] * 4 + [2e8]
#: OpenSees equation solvers tried for speed (all exact for this symmetric positive definite
#: effective stiffness); the fastest one's median is the peer's time
SYSTEMS = ("BandSPD", "ProfileSPD", "BandGeneral", "FullGeneral")


def building():
    """(M, C, K, a0, a1): the shear building with 5 % Rayleigh damping in modes 1 and 3."""
    M, _, K = dd.chain_matrices(MASS, STIFF, [0.0] * 5, sparse=False)
    w = dd.mck_modes(M, None, K).omega
    a0, a1 = np.linalg.solve([[1 / (2 * w[0]), w[0] / 2], [1 / (2 * w[2]), w[2] / 2]],
                             [0.05, 0.05])
    return M, a0 * M + a1 * K, K, a0, a1


def record(n_steps, dt, seed=3):
    """A ground acceleration, m/s^2: smoothed white noise, ramped in over 2 s."""
    t = np.arange(n_steps + 1) * dt
    rng = np.random.default_rng(seed)
    ag = np.convolve(rng.standard_normal(t.size), np.ones(8) / 8, mode="same") * 3.0
    return ag * np.minimum(1.0, t / 2.0)


def opensees(ops, ag, dt, a0, a1, *, system="BandSPD", factor_once=True, binary=True,
             accel=False):
    """Run the OpenSees model; (elapsed s of analyze, x (n_steps, 5), a (n_steps, 5) or None)
    at t_1 .. t_n (the recorder writes after each step)."""
    ops.wipe()
    ops.model("basic", "-ndm", 1, "-ndf", 1)
    ops.node(0, 0.0)
    ops.fix(0, 1)
    for i in range(1, 6):
        ops.node(i, 0.0)
        ops.mass(i, MASS[i - 1])
        ops.uniaxialMaterial("Elastic", i, STIFF[i - 1])
        ops.element("zeroLength", i, i - 1, i, "-mat", i, "-dir", 1, "-doRayleigh", 1)
    ops.rayleigh(a0, a1, 0.0, 0.0)
    # -useLast: at t_n = n dt the series is read at its last sample (without it OpenSees reads
    # the interval past the end, which it takes as 0, on the last step)
    ops.timeSeries("Path", 1, "-dt", dt, "-values", *ag.tolist(), "-useLast")
    ops.pattern("UniformExcitation", 1, 1, "-accel", 1)
    ops.constraints("Plain")
    ops.numberer("Plain")
    ops.system(system)
    ops.integrator("Newmark", 0.5, 0.25)
    ops.algorithm(*(("Linear", "-factorOnce") if factor_once else ("Linear",)))
    ops.analysis("Transient")
    folder = tempfile.mkdtemp()
    files = {q: os.path.join(folder, f"{q}.out") for q in (("disp", "accel") if accel
                                                            else ("disp",))}
    fmt = ("-binary",) if binary else ("-file",)
    for q, path in files.items():
        extra = () if binary else ("-precision", 17)
        ops.recorder("Node", *fmt, path, *extra, "-node", 1, 2, 3, 4, 5, "-dof", 1, q)
    n_steps = ag.size - 1
    start = time.perf_counter()
    status = ops.analyze(n_steps, dt)
    elapsed = time.perf_counter() - start
    ops.wipe()   # closes the recorders
    if status != 0:
        raise RuntimeError(f"OpenSees analyze returned {status}")
    out = {}
    for q, path in files.items():
        if binary:   # each row: 5 doubles, then a newline byte
            rows = np.fromfile(path, dtype=np.uint8).reshape(n_steps, 5 * 8 + 1)
            out[q] = np.ascontiguousarray(rows[:, :40]).view(float)
        else:
            out[q] = np.loadtxt(path).reshape(-1, 5)
        os.remove(path)
    os.rmdir(folder)
    return elapsed, out["disp"], out.get("accel")


def dtdyn_run(M, C, K, ag, dt, quantities=("x",)):
    return dd.mck_response(M, C, K, None, dt, scheme="average_acceleration",
                           ground_acceleration=ag, quantities=quantities, backend="c")


def clock_samples(ag, dt):
    """The record as OpenSees reads it: at its clock t_k = t_{k-1} + dt (added step by step),
    linear between samples as its Path series interpolates, the last sample held."""
    t = np.cumsum(np.full(ag.size - 1, dt))      # sequential sums, as the analysis adds dt
    x = t / dt
    i = np.minimum(np.floor(x).astype(int), ag.size - 2)
    return np.r_[ag[0], ag[i] + (ag[i + 1] - ag[i]) * (x - i)]


def accuracy(ops, M, C, K, a0, a1, n_steps, dt):
    """(max |dx| / max |x|, max |a_abs - (a_OS + a_g)| / max |a_abs|, and max |dx| / max |x|
    when dtdyn is given the record as read at OpenSees' clock)."""
    ag = record(n_steps, dt)
    _, x_os, a_os = opensees(ops, ag, dt, a0, a1, binary=False, factor_once=False,
                             system="FullGeneral", accel=True)
    r = dtdyn_run(M, C, K, ag, dt, quantities=("x", "a"))
    ex = np.abs(r.x[1:] - x_os).max() / np.abs(r.x).max()
    ea = np.abs(r.a_abs[1:] - (a_os + ag[1:, None])).max() / np.abs(r.a_abs).max()
    clock = dtdyn_run(M, C, K, clock_samples(ag, dt), dt)
    return ex, ea, np.abs(clock.x[1:] - x_os).max() / np.abs(r.x).max()


def median_time(fn, repeats):
    """Timing (median, spread) of ``repeats`` calls after a warm-up."""
    return measure(fn, repeats)[1]


def main(steps=(20_000, 200_000)):
    try:
        import openseespy.opensees as ops
    except ImportError as exc:   # the peer is optional: say how to get it
        sys.exit(f"openseespy is not importable ({exc}): apt-get install libblas3 liblapack3; "
                 "pip install openseespy")
    M, C, K, a0, a1 = building()
    w = dd.mck_modes(M, None, K).omega
    print(f"5-storey shear building, f1 = {w[0] / 2 / np.pi:.3f} Hz, Rayleigh C = a0 M + a1 K "
          f"(a0 = {a0:.6g} 1/s, a1 = {a1:.6g} s: 5 % in modes 1 and 3); Newmark gamma 1/2, "
          "beta 1/4")
    print("\n1. accuracy: max|x_dtdyn - x_OpenSees| / max|x|, and max|a_abs - (a_OpenSees + a_g)| "
          "/ max|a_abs|")
    print("   and x again with dtdyn given the record read at OpenSees' clock (t += dt)")
    print(f"{'dt [s]':>10s} {'steps':>8s} {'x':>9s} {'a_abs':>9s} {'x, clock':>9s}  "
          "target 1e-10 (dt = 1/128 s)")
    missed = False
    for dt in (1 / 128, 0.01):
        for n in steps:
            ex, ea, ec = accuracy(ops, M, C, K, a0, a1, n, dt)
            gated = dt == 1 / 128
            ok = max(ex, ea) <= 1e-10
            missed |= gated and not ok
            note = ("met" if ok else "MISSED") if gated else "OpenSees' clock drifts from k dt"
            print(f"{dt:10.7g} {n:8d} {ex:9.1e} {ea:9.1e} {ec:9.1e}  {note}")

    print("\n2. speed, same run: displacement of every floor stored at every step; median "
          "[min, max] of repeats after a warm-up")
    dt = 1 / 128
    print(f"{'steps':>8s} {'dtdyn C [ms]':>24s} {'OpenSees [ms]':>24s} {'system':>12s} "
          f"{'ratio':>7s}")
    for n in steps:
        ag = record(n, dt)
        repeats = 5 if n <= 50_000 else 3
        t_dd = median_time(functools.partial(dtdyn_run, M, C, K, ag, dt), repeats)
        t_os = {s: Timing([opensees(ops, ag, dt, a0, a1, system=s)[0]
                           for _ in range(repeats)]) for s in SYSTEMS}
        best = min(t_os, key=t_os.get)
        print(f"{n:8d} {t_dd.format('ms').removesuffix(' ms'):>24s} "
              f"{t_os[best].format('ms').removesuffix(' ms'):>24s} {best:>12s} "
              f"{t_os[best] / t_dd:6.1f}x")
    print("OpenSees: one analyze(n_steps, dt) call, algorithm Linear -factorOnce, a binary Node "
          "recorder of disp; systems tried: " + ", ".join(SYSTEMS))
    print(f"dtdyn {dd.__version__}, openseespy {_version('openseespy')}, numpy {np.__version__}")
    if missed:
        print("accuracy target 1e-10 missed at dt = 1/128 s", file=sys.stderr)
        sys.exit(1)


def _version(name):
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version(name)
    except PackageNotFoundError:
        return "?"


if __name__ == "__main__":
    with pin_blas(1) as pin:
        print(pin.describe())
        main(tuple(int(float(a)) for a in sys.argv[1:]) or (20_000, 200_000))
