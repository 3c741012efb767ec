"""Input checks shared by every entry point: each error names the field and the value."""
from __future__ import annotations

import os

import numpy as np


def positive_scalar(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):  # OverflowError: an int beyond float range
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not np.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return v


def frequencies(name: str, omega) -> np.ndarray:
    """A non-empty 1-D array of finite frequencies >= 0 (rad/s), else ValueError naming it."""
    w = np.atleast_1d(real_array(name, omega, "an array of frequencies (rad/s)"))
    if w.ndim != 1 or w.size == 0 or not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError(f"{name} = {omega!r}: must be a non-empty 1-D array of finite "
                         "frequencies >= 0 (rad/s)")
    return w


def flag(name: str, value) -> bool:
    """True or False (not 0, 1 or a string), else ValueError naming it."""
    if not isinstance(value, bool):
        raise ValueError(f"{name} = {value!r}: must be True or False")
    return value


def step_count(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def vector(name: str, values, *, positive: bool = False, nonnegative: bool = False,
           length: int | None = None) -> np.ndarray:
    """A finite 1-D float array; ``positive``/``nonnegative`` check every entry."""
    arr = real_array(name, values, "a sequence of numbers")
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D sequence, got shape {arr.shape}")
    if length is not None and arr.size != length:
        raise ValueError(f"{name} has length {arr.size}, expected {length}")
    bad = ~np.isfinite(arr)
    if positive:
        bad |= arr <= 0.0
    if nonnegative:
        bad |= arr < 0.0
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        need = "> 0" if positive else (">= 0" if nonnegative else "finite")
        raise ValueError(f"{name}[{i}] = {float(arr[i])!r}: every entry must be finite and {need}")
    return arr


def dof_indices(name: str, values, n_dof: int, default_all: bool = True,
                names: tuple | None = None) -> np.ndarray:
    """0-based, unique, in-range DOF indices (all DOFs when ``values`` is None); with ``names``
    (a model's ``dof_names``) an entry may also be a DOF's name."""
    if values is None:
        if not default_all:
            raise ValueError(f"{name} is required")
        return np.arange(n_dof, dtype=np.int64)
    if names is not None:
        vals = [values] if isinstance(values, (str, int, np.integer)) else list(values)
        for v in vals:
            if isinstance(v, str) and v not in names:
                shown = ", ".join(names[:8]) + (" ..." if len(names) > 8 else "")
                raise ValueError(f"{name}: no DOF named {v!r} (the DOFs are {shown})")
        values = [names.index(v) if isinstance(v, str) else v for v in vals]
    idx = np.atleast_1d(np.asarray(values))
    if idx.ndim != 1 or idx.size == 0 or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"{name} must be a non-empty sequence of integer DOF indices, got "
                         f"{values!r}")
    if idx.min() < 0 or idx.max() >= n_dof:
        raise ValueError(f"{name} = {idx.tolist()} has an index outside 0..{n_dof - 1}")
    if np.unique(idx).size != idx.size:
        raise ValueError(f"{name} = {idx.tolist()} repeats an index")
    return idx.astype(np.int64)


def time_history(force, dt, force_dofs, n_dof: int, min_samples: int = 2):
    """The checked inputs every time-history entry point shares (the vocabulary of the README).

    Returns ``(force, dt, force_dofs)``: ``force`` of shape (n_steps + 1, len(force_dofs)),
    samples at t_k = k dt, finite, C-contiguous (a 1-D array is one column); ``dt`` > 0;
    ``force_dofs`` 0-based DOF indices, all DOFs when None.
    """
    dt = positive_scalar("dt", dt)
    force_dofs = dof_indices("force_dofs", force_dofs, n_dof)
    f = force_record(force, force_dofs.size)
    if f.shape[0] < min_samples:
        raise ValueError(f"force has {f.shape[0]} sample(s); a time history needs at least "
                         f"{min_samples} (t_0 .. t_n, n_steps = len(force) - 1)")
    return f, dt, force_dofs


def initial_conditions(x0, v0, n_dof: int):
    """Initial displacement and velocity of every DOF (zeros when None), checked finite."""
    x = np.zeros(n_dof) if x0 is None else vector("x0", x0, length=n_dof)
    v = np.zeros(n_dof) if v0 is None else vector("v0", v0, length=n_dof)
    return x, v


def force_record(force, n_inputs: int, what: str = "force_dofs") -> np.ndarray:
    """Force samples of shape (n_samples, n_inputs), n_samples >= 1, finite, float, C-contiguous
    (a 1-D array is one column when n_inputs is 1); ``what`` names the DOF list in errors."""
    f = real_array("force", force, "a record of force samples")
    if f.ndim == 1 and n_inputs == 1:
        f = f[:, None]
    if f.ndim != 2 or f.shape[1] != n_inputs or f.shape[0] < 1:
        raise ValueError(f"force has shape {np.shape(force)}, expected (n_samples, len({what})) "
                         f"= (n_samples, {n_inputs}) with n_samples >= 1")
    bad = ~np.isfinite(f)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ValueError(f"force[{i}, {j}] = {float(f[i, j])!r} (sample {i}, column {j}) is not "
                         "finite")
    return np.ascontiguousarray(f)


def force_samples(force, n_steps: int, loaded: np.ndarray) -> np.ndarray:
    """Force samples at t_0 .. t_n, shape (n_steps + 1, len(loaded)) (scenes)."""
    f = force_record(force, loaded.size)
    if f.shape[0] != n_steps + 1:
        raise ValueError(f"force has {f.shape[0]} samples, expected n_steps + 1 = {n_steps + 1}")
    return f


def available_memory() -> int | None:
    """Bytes this process may still allocate: MemAvailable of /proc/meminfo, capped by the
    address-space limit (RLIMIT_AS) less what the process maps now; None where unknown."""
    avail = None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        import resource  # POSIX only

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            with open("/proc/self/statm") as fh:
                mapped = int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
            room = max(0, soft - mapped)
            avail = room if avail is None else min(avail, room)
    except (ImportError, OSError, ValueError):
        pass
    return avail


def memory(what: str, need: int, advice: str) -> int:
    """The one up-front size check: refuse, before anything is allocated, work that needs
    ``need`` bytes when fewer are available (`available_memory`), with a MemoryError that
    names ``what`` (the input and its size), the bytes needed and available, and ``advice``
    (what to do instead). Returns ``need``."""
    need = int(need)
    avail = available_memory()
    if avail is not None and need > avail:
        raise MemoryError(f"{what} need {_bytes(need)}, more than the {_bytes(avail)} "
                          f"available; {advice}")
    return need


def output_size(what: str, n_samples: int, n_columns: int, itemsize: int = 8) -> int:
    """Refuse, before anything is allocated, a result of n_samples x n_columns values that does
    not fit in the memory available (MemoryError naming ``what``, the shape and the size)."""
    return memory(f"{what}: {int(n_samples):,} samples x {int(n_columns):,} values",
                  int(n_samples) * int(n_columns) * itemsize,
                  "ask for fewer outputs or quantities, or a shorter record")


#: what to use instead of a dense conversion of a large sparse model
SPARSE_PATHS = ("mck_response (implicit schemes on sparse M, C, K: a sparse LU), "
                "mck_modes(M, None, K, count=...) (the lowest modes by a sparse eigensolver), "
                "or chain_response for a chain")


def dense_conversion(name: str, A, what: str | None = None, copies: int = 1) -> None:
    """Refuse, before ``A.toarray()``, a dense copy of a scipy.sparse matrix ``A`` (named
    ``name``) that does not fit in the memory available: n x n x 8 bytes times ``copies`` (the
    dense matrices the caller builds from it). The message names the entry point (``what``,
    default the public function being called), the shape, the size and the sparse paths to
    use instead (`SPARSE_PATHS`)."""
    if not hasattr(A, "shape") or len(A.shape) != 2:
        return
    from dtdyn._engine.public import current_call

    what = what or current_call() or "a dense conversion"
    rows, cols = (int(n) for n in A.shape)
    memory(f"{what}: {name} is a sparse {rows:,} x {cols:,} matrix; as dense matrices "
           f"({copies} of this size) they would",
           copies * rows * cols * 8,
           f"{what} works on dense matrices: for a sparse model use {SPARSE_PATHS}")


def real_array(name: str, value, what: str = "an array of numbers") -> np.ndarray:
    """``value`` as a float ndarray; a file name (str or path) or complex values are a
    ValueError naming ``name`` (numpy would say "could not convert string to float", or drop
    the imaginary part with only a ComplexWarning)."""
    if isinstance(value, (str, bytes, os.PathLike)):
        if "record" in what or "samples" in what:  # a record given by its file name
            raise ValueError(f"{name} = {value!r} is a file name, not {what}: read the file "
                             f"first, e.g. {name}=dd.load_record({str(value)!r}) (a .csv, .txt "
                             "or .npy record), and pass the array")
        raise ValueError(f"{name} must be {what}, got the string {value!r}")
    try:
        listed = isinstance(value, (list, tuple)) and np.iscomplexobj(np.asarray(value))
    except (TypeError, ValueError):  # ragged nesting: float conversion below names it
        listed = False
    if np.iscomplexobj(value) or listed:
        arr = np.atleast_1d(np.asarray(value))
        where = np.argwhere(arr.imag != 0)
        first = (f" ({name}[{', '.join(str(int(i)) for i in where[0])}] = "
                 f"{complex(arr[tuple(where[0])])!r})") if where.size else ""
        raise ValueError(f"{name} is complex (dtype {arr.dtype}){first}: dtdyn takes real "
                         f"values; pass {name}.real explicitly if the imaginary part is to be "
                         "dropped")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:  # OverflowError: int beyond float
        raise ValueError(f"{name} must be {what}, got {type(value).__name__}: {exc}") from None


def matrix_rows(name: str, value) -> None:
    """A matrix given as nested lists or tuples whose rows differ in length (numpy would say
    "inhomogeneous shape"): a ValueError naming ``name``, the first row whose length differs
    from row 0's and both lengths. Anything else passes unchanged."""
    if not isinstance(value, (list, tuple)) or not value:
        return
    lengths = [len(row) if isinstance(row, (list, tuple, np.ndarray)) else None
               for row in value]
    if all(n is None for n in lengths):
        return  # a flat sequence: the shape check names it
    for i, n in enumerate(lengths):
        if n != lengths[0]:
            got, first = ("a number" if k is None else f"{k} entr{'y' if k == 1 else 'ies'}"
                          for k in (n, lengths[0]))
            raise ValueError(f"{name} must be a square matrix (every row as long as the "
                             f"number of rows, {len(value)}); row {i} has {got}, row 0 has "
                             f"{first}")


def _bytes(n: float) -> str:
    units = ("B", "KiB", "MiB", "GiB", "TiB", "PiB")
    k = 0
    while n >= 1024 and k < len(units) - 1:
        n, k = n / 1024, k + 1
    return f"{n:.3g} {units[k]}"


def finite_response(what: str, dt: float, *records) -> None:
    """FloatingPointError naming the first step (row) at which any of ``records`` (arrays of
    shape (n_steps + 1, ...) or None) is not finite: a result never carries inf or NaN."""
    first = None
    for rec in records:
        if rec is None:
            continue
        bad = np.flatnonzero(~np.isfinite(rec.reshape(rec.shape[0], -1)).all(axis=1))
        if bad.size and (first is None or bad[0] < first):
            first = int(bad[0])
    if first is not None:
        raise FloatingPointError(f"{what}: the response is not finite from step {first} "
                                 f"(t = {first * dt:.6g} s): the model grows without bound "
                                 f"(an unstable pole), or the inputs or dt = {dt:.6g} s make it "
                                 "overflow")
