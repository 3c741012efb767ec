"""Load the generated DT-TMM chain kernels: C when a compiler exists, else the NumPy sweep."""
from __future__ import annotations

import ctypes
from functools import lru_cache
from importlib import resources

import numpy as np

from dtdyn.generated import dttmm_sweep

from . import cbuild

FORM_CODE = {"displacement": 0, "acceleration": 1}
SWEEP_CODE = {"stable": 0, "plain": 1}
WORK_ROWS = 12  # doubles per mass the C kernel needs as scratch


@lru_cache(maxsize=None)
def c_chain_function(scheme: str):
    """The ctypes function dtdyn_chain_<scheme>, or None when C is unavailable."""
    source = resources.files("dtdyn.generated").joinpath(f"chain_{scheme}.c").read_text()
    lib = cbuild.load_library(source, f"chain_{scheme}")
    if lib is None:
        return None
    fn = getattr(lib, f"dtdyn_chain_{scheme}")
    ptr, lng = ctypes.c_void_p, ctypes.c_long
    fn.argtypes = [ctypes.c_int, ctypes.c_int, lng, lng, ptr, ptr, ptr, ctypes.c_double, ptr, lng,
                   ptr, ptr, ptr, lng, ptr, ptr, ptr, ptr, ptr, ptr]
    fn.restype = ctypes.c_int
    return fn


def _p(a):
    return None if a is None else a.ctypes.data


def chain_advance(backend, scheme, coeffs, form, sweep, m, k, c, dt, loaded, out_idx):
    """An ``advance(force_rows, H, xo, vo, ao) -> error estimate`` for stepping.integrate."""
    fn = c_chain_function(scheme.name) if backend == "c" else None
    if fn is None:
        def advance(force, H, xo, vo, ao):
            return dttmm_sweep.run_chain(coeffs, scheme.history, sweep, m, k, c, loaded, force, H,
                                         out_idx, xo, vo, ao)
        return advance
    N = m.size
    params = np.array([scheme.params[p] for p in scheme.module.PARAMS] or [0.0])
    loaded64 = np.ascontiguousarray(loaded, dtype=np.int64)
    out64 = np.ascontiguousarray(out_idx, dtype=np.int64)
    work = np.empty(WORK_ROWS * N)
    err = np.zeros(1)

    def advance(force, H, xo, vo, ao):
        force = np.ascontiguousarray(force)
        assert H.flags.c_contiguous and H.dtype == np.float64
        for arr in (xo, vo, ao):
            assert arr is None or arr.flags.c_contiguous
        err[0] = 0.0
        rc = fn(FORM_CODE[form], SWEEP_CODE[sweep], N, force.shape[0] - 1, m.ctypes.data,
                k.ctypes.data, c.ctypes.data, dt, params.ctypes.data, loaded64.size,
                loaded64.ctypes.data, force.ctypes.data, H.ctypes.data, out64.size,
                out64.ctypes.data, _p(xo), _p(vo), _p(ao), work.ctypes.data, err.ctypes.data)
        if rc != 0:
            raise RuntimeError(f"C kernel chain_{scheme.name} returned {rc} for form {form!r}")
        return float(err[0])
    return advance
