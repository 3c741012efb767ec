"""The C kernels flush subnormal numbers to zero while they run and restore the caller's mode.

The oracle is scipy.signal.lfilter (gradual underflow): it agrees with the C filter bank to
rounding where its value is far from underflow, no C value is subnormal (|y| < 2.2e-308), and
the two differ by amounts near the underflow threshold only: a flushed recursion can settle
into a limit cycle just above it (here 1.8e-307 and 1.3e-305) instead of decaying through the
subnormals to 0. The speed this buys is measured by benchmarks/subnormals.py, not here.
"""
import numpy as np
import pytest
from scipy.signal import lfilter

import dtdyn as dd
from dtdyn.modal._filters import run_bank

TINY = np.finfo(float).tiny  # 2.2e-308, the smallest normal double
SUBNORMAL = np.float64(5e-324)


def _normal_or_zero(y):
    return np.all((y == 0.0) | (np.abs(y) >= TINY))


def _mode_restored():
    """Subnormals still exist in this thread: no flush-to-zero or denormals-are-zero left on."""
    return SUBNORMAL * np.float64(1.0) == SUBNORMAL and SUBNORMAL / np.float64(2.0) == 0.0 \
        and np.float64(3e-308) / np.float64(4.0) > 0.0


@pytest.mark.parametrize("a1, a2, n", [(-1.8, 0.81, 2000),   # a double pole at 0.9
                                     (-2 * 0.9999 * np.cos(0.01), 0.9999**2, 200_000)])
def test_filter_bank_flushes_subnormals_in_the_calling_thread_and_restores_its_mode(a1, a2, n):
    """An impulse of 1e-300 decays through the subnormal range (the second filter: a mode of
    2e-4 damping ratio, sampled at 628 points per cycle, whose flushed limit cycle is larger)."""
    sos = np.array([[1.0, 0.0, 0.0, a1, a2]])
    x = np.zeros((n, 1))
    x[0, 0] = 1e-300
    assert _mode_restored()
    y = run_bank(sos, [0], [0], [[0.0]], x, 1)[:, 0]   # small: runs in this thread
    assert _mode_restored()
    ref = lfilter([1.0, 0.0, 0.0], [1.0, a1, a2], x[:, 0])
    sub = (ref != 0.0) & (np.abs(ref) < TINY)
    assert sub.sum() > 10                       # the oracle passes through subnormals ...
    assert _normal_or_zero(y)                   # ... the C bank never holds one
    assert np.max(np.abs(y - ref)) < 1e-300
    far = np.abs(ref) >= 1e-290                 # away from the flush: rounding differences
    np.testing.assert_allclose(y[far], ref[far], rtol=1e-12, atol=0.0)


def test_chain_from_rest_has_no_subnormal_state():
    """A wave entering a chain at rest: the far masses' displacements underflow to 0 without
    passing through subnormal values; the near ones equal the NumPy backend's to rounding."""
    N, steps = 200, 400
    m, k, c = np.ones(N), np.full(N, 1e4), np.ones(N)
    F = np.ones((steps + 1, 1))
    kw = dict(force_dofs=[N - 1], quantities=("x",))
    xc = dd.chain_response(m, k, c, F, 1e-4, backend="c", **kw).x
    xn = dd.chain_response(m, k, c, F, 1e-4, backend="numpy", **kw).x
    assert _mode_restored()
    assert ((xn != 0.0) & (np.abs(xn) < TINY)).any()   # NumPy's gradual underflow
    assert _normal_or_zero(xc)
    scale = np.max(np.abs(xn))
    np.testing.assert_allclose(xc, xn, rtol=0.0, atol=1e-12 * scale)
