"""Load the generated DT-TMM chain kernels: C when a compiler exists, else the NumPy sweep."""
from __future__ import annotations


import numpy as np

from dtdyn.generated import c_api, dttmm_sweep

from dtdyn._engine import cbuild
from dtdyn._engine.errors import DtdynKernelError  # noqa: F401 (re-exported: its old home)
from dtdyn._engine.schemes import SchemeInfo, get_scheme
from dtdyn._engine.stepping import history_from_states

# the kernels' codes and work rows (doubles per mass) from the one spec, dtdyn.derive.c_api
FORM_CODE = {"displacement": c_api.FORM_DISPLACEMENT, "acceleration": c_api.FORM_ACCELERATION}
SWEEP_CODE = {"stable": c_api.SWEEP_STABLE, "plain": c_api.SWEEP_PLAIN}
WORK_ROWS = {"stable": c_api.CHAIN_ROWS_STABLE, "plain": c_api.CHAIN_ROWS_PLAIN}


class PlainSweepError:
    """The plain sweep's running error estimate, shared by the steppers of one run.

    The kernels carry two error histories, E_s and E_r (rows as the scheme's history H; E has
    shape H.shape + (2,): pairs, as the C kernels read them), through the exact zero-force step
    and add each step's rounding error to their unknowns (dtdyn.derive.dttmm derives it);
    ``err = [max_n e_n, max |x|, steps so far]``. A multistep
    scheme's start-up runs single average-acceleration steps first: the error states (x, v, a of
    both histories) after those steps are kept, and the main scheme's E (with its lags) is built
    from them as stepping.integrate builds H from the states.
    """

    def __init__(self, n_mass: int):
        zero = np.zeros(n_mass)
        self.states = [((zero,) * 3, (zero,) * 3)]  # (E_s, E_r) states after the steps so far
        self.names = None
        self.E = None
        self.err = np.zeros(3)

    def history(self, names) -> np.ndarray:
        """E for a scheme with history rows ``names`` (rebuilt when the scheme changes)."""
        if names != self.names:
            lags = max(int(nm[2:]) if nm[1:] != "0" else 0 for nm in names)
            states = [self.states[0]] * max(lags + 1 - len(self.states), 0) + self.states
            self.E = np.ascontiguousarray(np.stack(
                [history_from_states(names, [st[part] for st in states]) for part in (0, 1)],
                axis=-1))
            self.names = names
        return self.E

    def record(self, n_steps: int) -> None:
        """Keep the error states after a single step (the start-up's steps are single calls)."""
        if n_steps == 1:
            self.states.append(tuple(
                tuple(self.E[self.names.index(q + "0"), :, part].copy() for q in "xva")
                for part in (0, 1)))
            del self.states[:-8]

    @property
    def estimate(self) -> float:
        """e / (max |x| - e): relative to max |x_true| >= max |x| - e; inf when e >= max |x|."""
        e, xmax = float(self.err[0]), float(self.err[1])
        if e == 0.0:
            return 0.0
        return e / (xmax - e) if xmax > e else float("inf")


_FUNCTIONS: dict = {}


def c_scheme_function(kind: str, scheme):
    """The ctypes function dtdyn_<kind>_<scheme> (``kind`` "chain" or "shaft"; ``scheme`` a
    name, a scheme file's FileScheme or a SchemeInfo, a composite scheme's stage too), or None
    when C is unavailable. Bound once per kernel and process."""
    info = scheme if isinstance(scheme, SchemeInfo) else get_scheme(scheme)
    key = (kind, info.key)
    if key not in _FUNCTIONS:
        lib = cbuild.load_library(info.c_source(kind), f"{kind}_{info.key}")
        _FUNCTIONS[key] = None if lib is None else cbuild.bind(
            lib, f"dtdyn_{kind}", f"dtdyn_{kind}_{info.name}")
    return _FUNCTIONS[key]


def c_chain_function(scheme):
    """The ctypes function dtdyn_chain_<scheme> (`c_scheme_function`), or None."""
    return c_scheme_function("chain", scheme)


def _p(a):
    return None if a is None else a.ctypes.data


def ground_elements(chain):
    """(kg, cg) of a chain for the kernels: (None, None) when it has no spring or damper to the
    ground, so that they skip those terms (NULL pointers in C)."""
    kg, cg = chain[3], chain[4]
    return (kg, cg) if kg.any() or cg.any() else (None, None)


def params_array(scheme) -> np.ndarray:
    """The scheme's parameters in the order its C kernel reads them (one 0.0 when none)."""
    return np.array([scheme.params[p] for p in scheme.module.PARAMS] or [0.0])


def chain_advance(backend, scheme, coeffs, form, sweep, chain, dt, loaded, out_idx,
                  tracker: PlainSweepError | None = None, threads: int = 1):
    """An ``advance(force_rows, H, xo, vo, ao) -> error estimate of the run so far`` for
    stepping.integrate. ``chain``: the checked (m, k, c, kg, cg) arrays (linear.chain.Chain).
    The plain sweep needs the run's ``tracker`` (0.0 for the stable one); ``threads`` = 2 runs
    the C stable sweep on two threads (the chain split in two parts)."""
    if sweep == "plain" and tracker is None:
        raise ValueError("the plain sweep needs a PlainSweepError tracker")
    plain = sweep == "plain"
    m, k, c = chain[:3]
    kg, cg = ground_elements(chain)
    fn = c_chain_function(scheme) if backend == "c" else None
    if fn is None:
        def advance(force, H, xo, vo, ao):
            E = tracker.history(scheme.history) if plain else None
            dttmm_sweep.run_chain(coeffs, scheme.history, sweep, m, k, c, kg, cg, loaded, force, H,
                                  out_idx, xo, vo, ao, E, tracker.err if plain else None)
            if plain:
                tracker.record(force.shape[0] - 1)
            return tracker.estimate if plain else 0.0
        return advance
    N = m.size
    params = params_array(scheme)
    loaded64 = np.ascontiguousarray(loaded, dtype=np.int64)
    out64 = np.ascontiguousarray(out_idx, dtype=np.int64)
    work = np.empty(WORK_ROWS[sweep] * N)
    # the stable sweep on one thread keeps its Riccati factors in work between calls (same
    # chain, dt, scheme and form): later calls skip them (SWEEP_REUSE; the same numbers)
    code = [SWEEP_CODE[sweep]]
    reusable = sweep == "stable" and threads == 1

    def advance(force, H, xo, vo, ao):
        force = np.ascontiguousarray(force)
        assert H.flags.c_contiguous and H.dtype == np.float64
        for arr in (xo, vo, ao):
            assert arr is None or arr.flags.c_contiguous
        E = tracker.history(scheme.history) if plain else None
        rc = fn(FORM_CODE[form], code[0], N, force.shape[0] - 1, m.ctypes.data,
                k.ctypes.data, c.ctypes.data, _p(kg), _p(cg), dt, params.ctypes.data, loaded64.size,
                loaded64.ctypes.data, force.ctypes.data, H.ctypes.data, out64.size,
                out64.ctypes.data, _p(xo), _p(vo), _p(ao), work.ctypes.data, work.size, _p(E),
                _p(tracker.err) if plain else None, threads)
        if rc != c_api.OK:
            raise DtdynKernelError(f"dtdyn_chain_{scheme.name}", rc, f"form {form!r}, sweep "
                                   f"{sweep!r}, N = {N}, n_work = {work.size}")
        if reusable:
            code[0] = c_api.SWEEP_REUSE
        if plain:
            tracker.record(force.shape[0] - 1)
        return tracker.estimate if plain else 0.0
    return advance
