"""One spec for every C/Python contract of the kernels, written once here and emitted into both
sides: the signatures, as the C prototypes of generated/c_api.h (every source includes it, so the
compiler checks each definition against it) and as the ctypes bindings of generated/c_api.py (so
the runtime never types argtypes by hand); the codes, work-array row counts and offsets
(`CONSTANTS`), as ``#define DTDYN_<name>`` in c_api.h and as ``<name>`` in c_api.py. A kernel
with a work array receives its length (``n_work``) and returns ``DTDYN_ERR_WORK`` before
touching it when it is too short. Where the length is a count of rows, the count is a constant
here (the runtime allocates ``<ROWS> * N``); where it is a formula of the problem's sizes (the
modal filters, the nonlinear loops), the kernel's source defines a size function in `KERNELS`
(``dtdyn_modal_filters_work``, ``dtdyn_nl_work``, ``dtdyn_nl_chain_work``,
``dtdyn_nl_stations_work``) that the runtime calls to allocate and the kernel calls to check, so
the formula is written once."""
from __future__ import annotations

import re

#: kernel -> (return type, parameters as C text); ``dtdyn_chain`` stands for every
#: ``dtdyn_chain_<scheme>`` (one per scheme, the same signature)
KERNELS = {
    "dtdyn_chain": ("int", (
        "int form", "int sweep", "long N", "long n_steps", "const double *m", "const double *k",
        "const double *c", "const double *kg", "const double *cg", "double dt",
        "const double *params", "long n_loaded",
        "const long *loaded", "const double *force", "double *hist", "long n_out",
        "const long *out_idx", "double *xo", "double *vo", "double *ao", "double *work",
        "long n_work", "double *ehist", "double *err", "int threads")),
    # every dtdyn_shaft_<scheme> (derive/shaft.py): the DT-TMM loop of a torsional tree
    "dtdyn_shaft": ("int", (
        "int form", "int sweep", "long N", "long n_steps", "const long *parent",
        "const double *gu", "const double *gS", "const double *gR", "const double *m",
        "const double *k", "const double *c", "const double *kg", "const double *cg", "double dt",
        "const double *params", "long n_loaded", "const long *loaded", "const double *force",
        "double *hist", "long n_out", "const long *out_idx", "double *xo", "double *vo",
        "double *ao", "double *work", "long n_work")),
    "dtdyn_ss_states": ("int", (
        "long ns", "long n_steps", "const double *restrict At", "const double *restrict w",
        "double *restrict X")),
    "dtdyn_filter_bank": ("int", (
        "long n", "long n_in", "long n_out", "long n_sec", "const double *restrict sos",
        "const long *restrict in_col", "const long *restrict out_col",
        "const double *restrict xt", "double *restrict yt", "double *restrict state")),
    "dtdyn_set_stop": ("int", ("int value",)),  # csrc/stop.h, in every library with a long loop
    "dtdyn_mck_loop": ("int", (
        "int solver", "long n", "long n_hist", "long n_steps", "long n_loaded",
        "const long *restrict loaded",
        "const double *restrict force", "const long *const *idx", "const double *const *val",
        "const double *restrict L", "const double *restrict c_u", "double w0", "double w1",
        "long n_shift",
        "const long *restrict shift", "const long *restrict rows", "double *restrict H",
        "long n_out", "const long *restrict out_idx", "double *restrict xo",
        "double *restrict vo", "double *restrict ao", "double *restrict work", "long n_work")),
    # csrc/block_chain.h: 2 x 2 node-block chains (beam_response)
    "dtdyn_block_chain_factor": ("int", (
        "long N", "const double *restrict A", "double *restrict fac")),
    "dtdyn_block_chain_solve": ("int", (
        "long N", "const double *restrict fac", "double *restrict b")),
    "dtdyn_block_chain_loop": ("int", (
        "long N", "long n_hist", "long n_steps", "long n_loaded", "const long *restrict loaded",
        "const double *restrict force", "const double *const *mats",
        "const double *restrict L", "const double *restrict c_u", "double w0", "double w1",
        "long n_shift", "const long *restrict shift", "const long *restrict rows",
        "double *restrict H", "long n_out", "const long *restrict out_idx",
        "double *restrict xo", "double *restrict vo", "double *restrict ao",
        "double *restrict work", "long n_work")),
    "dtdyn_sturm_counts": ("int", (
        "long N", "const double *restrict k", "const double *restrict kg",
        "const double *restrict m", "double pivmin", "long n_lam", "const double *restrict lam",
        "long *restrict counts")),
    "dtdyn_sturm_laguerre": ("int", (
        "long N", "const double *restrict k", "const double *restrict kg",
        "const double *restrict m", "double pivmin", "long n_lam", "const double *restrict lam",
        "long *restrict counts", "double *restrict G", "double *restrict H")),
    # csrc/fma_peak.h: the multiply-add peak that `dtdyn bench` measures the loops against
    "dtdyn_fma_peak": ("double", ("long rounds",)),
    # csrc/rainflow.h: rainflow counting (ASTM E1049-85), reversals then the stack count
    "dtdyn_turning_points": ("long", ("long n", "const double *restrict x", "long *restrict tp")),
    "dtdyn_rainflow": ("long", (
        "long n_tp", "const double *restrict x", "long *restrict tp", "long *restrict start",
        "long *restrict end", "double *restrict count", "long *restrict residue_size")),
    "dtdyn_modal_filters_lanes": ("int", ("long m",)),
    "dtdyn_modal_filters_work": ("long", ("long m", "long n_out")),
    "dtdyn_modal_filters": ("int", (
        "long n", "long m", "long n_in", "long n_out", "int im_out",
        "const double *restrict coef", "const double *restrict wt", "const double *restrict x",
        "double *restrict e", "double *restrict y", "double *restrict work", "long n_work")),
    "dtdyn_nl_run": ("int", (
        "const long *dims", "const double *const *mats", "const double *restrict force",
        "double *restrict x", "double *restrict u", "double *restrict g",
        "double *restrict rate", "double *restrict out", "double tol", "double theta_limit",
        "double *stats", "long *fail", "double *restrict work", "long n_work",
        "nl_int *restrict iwork", "long n_iwork")),
    # csrc/nl_loop.h: the doubles dtdyn_nl_run's work needs for these dims (CasADi's work, then
    # the embedded estimate's block)
    "dtdyn_nl_work": ("long", ("const long *dims",)),
    # the elements' residual, Jacobian and forces: CasADi's code generation, appended to
    # nl_loop.c and nl_chain.c at run time (CasADi's calling convention)
    "nl_residual": ("int", ("const double **arg", "double **res", "nl_int *iw", "double *w",
                            "int mem")),
    # ... and the sizes of its work arrays (the kernels check n_work and n_iwork against them)
    "nl_residual_work": ("int", ("nl_int *sz_arg", "nl_int *sz_res", "nl_int *sz_iw",
                                 "nl_int *sz_w")),
    "dtdyn_nl_chain": ("int", (
        "const long *dims", "chain_fn sweep", "const long *const *idx",
        "const double *const *mats", "double *restrict H", "double *restrict u",
        "double *restrict g", "double *restrict rate", "double *const *out", "double h",
        "double tol", "double *stats", "long *fail", "double *restrict work", "long n_work",
        "nl_int *restrict iwork", "long n_iwork")),
    # csrc/nl_chain.h: the doubles dtdyn_nl_chain's work needs for these dims
    "dtdyn_nl_chain_work": ("long", ("const long *dims",)),
    # csrc/nl_stations.h: beams (block chain step) and shafts (the tree sweep through
    # ``sweep``, NULL for a beam) with nonlinear elements, the whole record
    "dtdyn_nl_stations": ("int", (
        "const long *dims", "shaft_fn sweep", "const long *const *idx",
        "const double *const *mats", "double *restrict H", "double *restrict u",
        "double *restrict g", "double *restrict rate", "double *const *out", "double h",
        "double tol", "double *stats", "long *fail", "double *restrict work", "long n_work",
        "nl_int *restrict iwork", "long n_iwork")),
    # ... and the doubles its work needs for these dims
    "dtdyn_nl_stations_work": ("long", ("const long *dims",)),
}

#: the contract's numbers: name -> (value, meaning); ``#define DTDYN_<name> <value>`` in
#: generated/c_api.h, ``<name> = <value>`` in generated/c_api.py. Rows are rows of N doubles of a
#: kernel's work array (N: masses or disks); `check_layout` checks how they fit together.
CONSTANTS = {
    # what the kernels return
    "OK": (0, "success"),
    "ERR_FORM": (-1, "the scheme has no such form (an explicit scheme's displacement form)"),
    "ERR_WORK": (-2, "the work array is shorter than the kernel needs (nothing was written)"),
    "STOPPED": (5, "stopped by dtdyn_set_stop(1) (stop.h: Ctrl-C)"),
    # the chain and shaft kernels' form and sweep codes
    "FORM_DISPLACEMENT": (0, "the displacement form"),
    "FORM_ACCELERATION": (1, "the acceleration form"),
    "SWEEP_STABLE": (0, "the stable (Riccati) sweep"),
    "SWEEP_PLAIN": (1, "the plain sweep with its rounding-error estimate"),
    "SWEEP_REUSE": (2, "the stable sweep reusing the Riccati factors a previous call left in work"),
    # dtdyn_chain_<scheme>'s work (chain_loop.h)
    "CHAIN_ROWS_STABLE": (12, "rows of the stable sweep: Fe, q, s, b, Delta, S_R, g, h, R, u, "
                              "P_u, den"),
    "CHAIN_ROW_DEN": (11, "row of den, the stable sweep's last"),
    "CHAIN_ROW_PAIRS": (12, "first row of the plain sweep's error pairs (eu, eb, eDelta, eR: "
                            "2 rows each)"),
    "CHAIN_ROW_PLAIN": (20, "first row of the plain sweep's station entries (one row each)"),
    "CHAIN_ROWS_PLAIN": (30, "rows of the plain sweep"),
    # dtdyn_shaft_<scheme>'s work (shaft_loop.h)
    "SHAFT_ROWS": (15, "rows of the torsional tree loop"),
    # dtdyn_mck_loop's work (mck_loop.h): rows of n doubles (n: DOFs)
    "MCK_ROW_Q": (0, "row of q, the displacements' history terms"),
    "MCK_ROW_S": (1, "row of s, the velocities' history terms"),
    "MCK_ROW_RHS": (2, "row of the right side, solved in place for u"),
    "MCK_ROW_UPDATE": (3, "first of the 3 rows of x1, v1, a1"),
    "MCK_ROW_Z": (6, "row of the sparse solve's intermediate z"),
    "MCK_ROW_B": (7, "row of b, the accelerations' history terms"),
    "MCK_ROWS": (8, "rows of the mck loop"),
    # dtdyn_block_chain_loop's work (block_chain.h): rows of P doubles (P: the node stride,
    # N + 1 rounded up to BLOCK_CHAIN_ALIGN), each after a gap whose last double is z[-1] = 0
    "BLOCK_CHAIN_ROWS": (2, "rows of the block chain loop: z, components 0 and 1"),
    "BLOCK_CHAIN_GAP": (8, "doubles before each row (64 bytes: the rows stay aligned)"),
    "BLOCK_CHAIN_ALIGN": (8, "the node stride P of every per-node row: N + 1 rounded up to a "
                             "multiple of this many doubles (64 bytes: the rows stay aligned)"),
    "BLOCK_CHAIN_REFINE_ROWS": (10, "rows of P doubles the refined step needs after the "
                                   "step's own (u, r, x_e hi and lo, ...: block_chain.h)"),
    # dtdyn_nl_stations' model (its dims[0], nl_stations.h)
    "NL_STATIONS_BEAM": (0, "a beam: the block chain step (block_chain.h)"),
    "NL_STATIONS_SHAFT": (1, "a shaft or tree: the tree sweep dtdyn_shaft_<scheme>"),
    # the Newton solve of dtdyn_nl_chain and dtdyn_nl_stations (their dims[15], dims[16];
    # newton.h)
    "NEWTON_PLAIN": (0, "plain Newton: an LU of the Jacobian at every iteration (newton_solve)"),
    "NEWTON_KEPT_LU": (1, "the LU factors kept while the iteration contracts (newton_kept), "
                          "their nu^2 + nu doubles in work"),
    # dtdyn_modal_filters' work (modal_filters.h): 2 m (MODAL_BLOCK + n_out) doubles
    "MODAL_BLOCK": (256, "samples per block of the modal filters (the states' rows of a block "
                         "are kept in work: 2 m MODAL_BLOCK doubles, then 2 m n_out weights)"),
}

#: the C types the signatures name besides int, long and double (generated/c_api.h)
TYPEDEFS = ("typedef long long int nl_int; /* CasADi's integer (casadi_int) */",)


def constant(name: str) -> int:
    """The value of a `CONSTANTS` entry."""
    return CONSTANTS[name][0]


def check_layout(plain_rows: int = 0) -> None:
    """Raise ValueError when the chain's or the mck loop's work rows in `CONSTANTS` overlap or
    do not fit ``plain_rows`` station-entry rows (the most any scheme's plain sweep uses)."""
    c = constant
    need = {"CHAIN_ROW_DEN": c("CHAIN_ROWS_STABLE") - 1,
            "CHAIN_ROW_PAIRS": c("CHAIN_ROWS_STABLE"),
            "CHAIN_ROW_PLAIN": c("CHAIN_ROW_PAIRS") + 8}
    # the mck loop's rows in order, each one row long but the update (x1, v1, a1)
    mck = [("MCK_ROW_Q", 1), ("MCK_ROW_S", 1), ("MCK_ROW_RHS", 1), ("MCK_ROW_UPDATE", 3),
           ("MCK_ROW_Z", 1), ("MCK_ROW_B", 1), ("MCK_ROWS", 0)]
    for (name, _), (prev, length) in zip(mck[1:], mck):
        need[name] = c(prev) + length
    # the block chain reads z[-1] before each row and keeps its rows 64-byte aligned
    if c("BLOCK_CHAIN_ROWS") < 2 or c("BLOCK_CHAIN_GAP") < 1 or c("BLOCK_CHAIN_GAP") % 8:
        raise ValueError("c_api.CONSTANTS: BLOCK_CHAIN_ROWS must be at least 2 and "
                         "BLOCK_CHAIN_GAP a positive multiple of 8 doubles, not "
                         f"{c('BLOCK_CHAIN_ROWS')} and {c('BLOCK_CHAIN_GAP')}")
    if c("BLOCK_CHAIN_ALIGN") < 1 or c("BLOCK_CHAIN_ALIGN") % 8:
        raise ValueError("c_api.CONSTANTS: BLOCK_CHAIN_ALIGN must be a positive multiple of 8 "
                         f"doubles (64 bytes), not {c('BLOCK_CHAIN_ALIGN')}")
    for name, value in need.items():
        if c(name) != value:
            raise ValueError(f"c_api.CONSTANTS[{name!r}] = {c(name)}, expected {value}")
    if c("CHAIN_ROW_PLAIN") + plain_rows > c("CHAIN_ROWS_PLAIN"):
        raise ValueError(f"c_api.CONSTANTS['CHAIN_ROWS_PLAIN'] = {c('CHAIN_ROWS_PLAIN')} is "
                         f"too small for {plain_rows} station-entry rows from row "
                         f"{c('CHAIN_ROW_PLAIN')}")


#: the hand-written C (dtdyn/_engine/csrc/, runtime/_engine/csrc in the repository) that each
#: generated source of `SOURCES` consists of, besides c_api.h and its entry points
BODIES = {"ss_response.c": "ss_response.h", "filter_bank.c": "filter_bank.h",
          "sturm.c": "sturm.h", "fma_peak.c": "fma_peak.h", "mck_loop.c": "mck_loop.h",
          "block_chain.c": "block_chain.h", "nl_loop.c": "nl_loop.h", "nl_chain.c": "nl_chain.h",
          "nl_stations.c": "nl_stations.h", "rainflow.c": "rainflow.h"}

#: the kernels each generated source defines
SOURCES = {
    "ss_response.c": ("dtdyn_ss_states",),
    "filter_bank.c": ("dtdyn_set_stop", "dtdyn_filter_bank"),
    "sturm.c": ("dtdyn_sturm_counts", "dtdyn_sturm_laguerre"),
    "rainflow.c": ("dtdyn_turning_points", "dtdyn_rainflow"),
    "fma_peak.c": ("dtdyn_fma_peak",),
    "mck_loop.c": ("dtdyn_set_stop", "dtdyn_mck_loop"),
    "block_chain.c": ("dtdyn_set_stop", "dtdyn_block_chain_factor", "dtdyn_block_chain_solve",
                      "dtdyn_block_chain_loop"),
    "modal_states.c": ("dtdyn_set_stop", "dtdyn_modal_filters_lanes", "dtdyn_modal_filters_work",
                       "dtdyn_modal_filters"),
    "nl_loop.c": ("dtdyn_set_stop", "nl_residual", "dtdyn_nl_work", "dtdyn_nl_run"),
    "nl_chain.c": ("dtdyn_set_stop", "nl_residual", "dtdyn_nl_chain_work", "dtdyn_nl_chain"),
    "nl_stations.c": ("dtdyn_set_stop", "dtdyn_block_chain_factor", "dtdyn_block_chain_solve",
                      "nl_residual", "dtdyn_nl_stations_work", "dtdyn_nl_stations"),
}

#: kernel -> the loop it runs with subnormals flushed to zero (csrc/flush_subnormals.h): the
#: generated entry point wraps the source's ``DTDYN_LOOP int <loop>(<same parameters>)``
FLUSHED = {"dtdyn_ss_states": "ss_states_run", "dtdyn_filter_bank": "filter_bank_run",
           "dtdyn_mck_loop": "mck_loop_run", "dtdyn_block_chain_loop": "block_chain_loop_run",
           "dtdyn_modal_filters": "modal_filters_run", "dtdyn_nl_run": "nl_loop_run",
           "dtdyn_nl_chain": "nl_chain_run", "dtdyn_nl_stations": "nl_stations_run"}

_SCALARS = {"int": "c_int", "long": "c_long", "double": "c_double"}


def prototype(kernel: str, name: str | None = None) -> str:
    """The C declaration of ``kernel`` (under ``name``, for the per-scheme chain kernels)."""
    restype, params = KERNELS[kernel]
    return f"{restype} {name or kernel}({', '.join(params)});"


def pointer_typedef(alias: str, kernel: str) -> str:
    """``typedef <restype> (*alias)(<parameters>);``: a pointer to ``kernel``'s signature."""
    restype, params = KERNELS[kernel]
    return f"typedef {restype} (*{alias})({', '.join(params)});"


def header(schemes: list[str], shaft_schemes: list[str]) -> dict:
    """What generated/c_api.h holds: ``typedefs``, ``defines`` (name, value, meaning) and
    ``prototypes`` (every kernel; ``dtdyn_chain`` and ``dtdyn_shaft`` once per scheme)."""
    protos = []
    for kernel in KERNELS:
        if kernel == "dtdyn_chain":
            protos += [prototype(kernel, f"dtdyn_chain_{s}") for s in schemes]
        elif kernel == "dtdyn_shaft":
            protos += [prototype(kernel, f"dtdyn_shaft_{s}") for s in shaft_schemes]
        else:
            protos.append(prototype(kernel))
    return {"typedefs": [*TYPEDEFS, pointer_typedef("chain_fn", "dtdyn_chain"),
                         pointer_typedef("shaft_fn", "dtdyn_shaft")],
            "defines": [(f"DTDYN_{n}", v, doc) for n, (v, doc) in CONSTANTS.items()],
            "prototypes": protos}


def _wrapped(head: str, items: list[str], tail: str, width: int = 100) -> list[str]:
    """``head item, item, ... tail`` in lines of at most ``width``, aligned after ``head``."""
    lines, line = [], head
    for i, item in enumerate(items):
        piece = item + (", " if i < len(items) - 1 else tail)
        if len(line) + len(piece.rstrip()) > width and line != head:
            lines.append(line.rstrip())
            line = " " * len(head)
        line += piece
    return lines + [line]


def flushed_entries(source: str) -> str:
    """The entry points of ``source``'s kernels in `FLUSHED`: each calls its loop with
    subnormals flushed to zero and the caller's mode restored."""
    out = []
    for kernel in (k for k in SOURCES[source] if k in FLUSHED):
        restype, params = KERNELS[kernel]
        names = [re.findall(r"[A-Za-z_]\w*", p)[-1] for p in params]
        out += ["", f"/* {FLUSHED[kernel]} with subnormals flushed to zero (flush_subnormals.h) */"]
        out += _wrapped(f"{restype} {kernel}(", list(params), ")")
        out += ["{", "    const unsigned long long mode = dtdyn_flush_on();"]
        out += _wrapped(f"    const {restype} rc = {FLUSHED[kernel]}(", names, ");")
        out += ["    dtdyn_flush_off(mode);", "    return rc;", "}"]
    return "\n".join(out)


def _ctype(param: str) -> str:
    """ctypes name of a C parameter: pointers (and the function pointers chain_fn, shaft_fn) are
    addresses."""
    if "*" in param or param.split()[0] in ("chain_fn", "shaft_fn"):
        return "c_void_p"
    return _SCALARS[param.split()[-2]]


def bindings() -> dict:
    """kernel -> (restype, argtypes) as ctypes names."""
    return {k: (_SCALARS[r], tuple(_ctype(p) for p in params if p != "void"))
            for k, (r, params) in KERNELS.items()}
