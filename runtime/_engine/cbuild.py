"""Compile generated C sources on first use and load them with :mod:`ctypes`.

Shared libraries are cached per user (``$DTDYN_CACHE``, else
``$XDG_CACHE_HOME/dtdyn``, else ``~/.cache/dtdyn``) under a key that covers the
source text, the compiler and its flags, so a source is compiled once per
machine and reused afterwards. Concurrent processes are serialised with a file
lock and the library is moved into place atomically.

When no compiler is available, compilation fails, or ``DTDYN_NO_C=1`` is set,
:func:`load_library` returns ``None`` and warns once per process with
:class:`DtdynFallbackWarning`; callers then use their NumPy implementation.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import re
import shlex
import shutil
import subprocess
import sysconfig
import time
import tempfile
import threading
from pathlib import Path
from dtdyn._engine.errors import DtdynFallbackWarning
from dtdyn._engine.public import warn

try:  # POSIX only; without it the C backend is reported as unavailable.
    import fcntl
except ImportError:  # pragma: no cover - non-POSIX platforms
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "CFLAGS",
    "LIBS",
    "DtdynFallbackWarning",
    "c_available",
    "cache_dir",
    "load_library",
    "reset_for_tests",
]

#: Compiler flags. ``-ffp-contract=off`` and ``-fno-fast-math`` keep the
#: floating-point results reproducible against NumPy to rounding (no FMA
#: contraction, no reassociation).
CFLAGS: tuple[str, ...] = (
    "-O3",
    "-march=native",
    "-ffp-contract=off",
    "-fno-fast-math",
    "-shared",
    "-fPIC",
    "-std=c99",
)
#: Libraries linked after the source file.
LIBS: tuple[str, ...] = ("-lm", "-pthread")

_CANDIDATES = ("cc", "gcc", "clang")
_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_ERROR_LINES = 8
_COMPILE_TIMEOUT = 600.0
_VERSION_TIMEOUT = 30.0

_lock = threading.RLock()
_memo: dict[tuple[str, str], ctypes.CDLL | None] = {}
_compilers: dict[tuple[str | None, str | None], tuple[tuple[str, ...], str]] = {}
_warned = False


class _Unavailable(Exception):
    """Internal: the C backend cannot be used; the message says why."""


def _disabled() -> bool:
    return os.environ.get("DTDYN_NO_C", "").strip().lower() not in ("", "0", "false", "no", "off")


def cache_dir() -> Path:
    """Return the cache folder, creating it if missing.

    Returns
    -------
    pathlib.Path
        ``$DTDYN_CACHE`` if set, else ``$XDG_CACHE_HOME/dtdyn`` if set, else
        ``~/.cache/dtdyn``.
    """
    explicit = os.environ.get("DTDYN_CACHE")
    if explicit:
        path = Path(explicit).expanduser()
    else:
        xdg = os.environ.get("XDG_CACHE_HOME")
        base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
        path = base / "dtdyn"
    path.mkdir(parents=True, exist_ok=True)
    return path


def _compiler() -> tuple[tuple[str, ...], str]:
    """Return ``(argv, first line of --version)`` of the C compiler to use.

    Raises
    ------
    _Unavailable
        If no compiler is found or it cannot be run.
    """
    cc_env = os.environ.get("CC") or None
    memo_key = (cc_env, os.environ.get("PATH"))
    with _lock:
        if memo_key in _compilers:
            return _compilers[memo_key]
        if cc_env is not None:
            argv = shlex.split(cc_env)
            if not argv:
                raise _Unavailable(f"$CC={cc_env!r} is not a command")
            exe = shutil.which(argv[0])
            if exe is None:
                raise _Unavailable(f"C compiler {argv[0]!r} (from $CC) not found")
            argv[0] = exe
        else:
            exe = next((p for p in map(shutil.which, _CANDIDATES) if p), None)
            if exe is None:
                raise _Unavailable(
                    f"no C compiler found (tried {', '.join(_CANDIDATES)}; set $CC to choose one)"
                )
            argv = [exe]
        try:
            proc = subprocess.run(
                [*argv, "--version"],
                capture_output=True,
                text=True,
                timeout=_VERSION_TIMEOUT,
                check=False,
            )
        except (OSError, subprocess.SubprocessError) as exc:
            raise _Unavailable(f"C compiler {argv[0]!r} cannot be run: {exc}") from exc
        lines = (proc.stdout or proc.stderr or "").strip().splitlines()
        info = (tuple(argv), lines[0].strip() if lines else "")
        _compilers[memo_key] = info
        return info


def _cpu_id() -> str:
    """The CPU model and flags: -march=native code must not be reused on another processor."""
    try:
        text = Path("/proc/cpuinfo").read_text(errors="replace")
    except OSError:
        return platform.processor() or platform.machine()
    keep = [ln for ln in text.splitlines() if ln.startswith(("model name", "flags", "Features"))]
    return "\n".join(sorted(set(keep)))


def _key(source: str, argv: tuple[str, ...], version: str) -> str:
    h = hashlib.sha256()
    for part in (source, shlex.join(argv), shlex.join(CFLAGS + LIBS), version,
                 sysconfig.get_platform(), _cpu_id()):
        data = part.encode("utf-8", "surrogatepass")
        h.update(len(data).to_bytes(8, "little"))
        h.update(data)
    return h.hexdigest()


def _write_atomic(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=path.suffix, dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        _unlink(tmp)
        raise


def _unlink(path: str | os.PathLike[str]) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


def _digest(path: Path) -> str:
    """``"<size> <sha256>"`` of a file (the sidecar's content)."""
    data = path.read_bytes()
    return f"{len(data)} {hashlib.sha256(data).hexdigest()}"


def _verified(so_path: Path) -> bool:
    """True when the library matches the size and hash its build wrote next to it: a cache file
    cut short, emptied, overwritten or swapped is never handed to the loader (a truncated ELF
    file can crash dlopen; checking it first, in this process, makes that impossible)."""
    sidecar = so_path.with_name(so_path.name + ".sha256")
    try:
        return sidecar.read_text().strip() == _digest(so_path)
    except OSError:
        return False


def _discard(so_path: Path) -> None:
    for path in (so_path, so_path.with_name(so_path.name + ".sha256")):
        _unlink(path)


def _compile(source: str, argv: tuple[str, ...], folder: Path, stem: str) -> Path:
    """``folder/stem.so``, verified: reused when its sidecar matches, else (re)built by this
    process under an exclusive lock (a racing process waits and reuses it).

    A build counts only when the compiler exits 0 and leaves a non-empty shared object (ELF
    header); then the sidecar ``stem.so.sha256`` (size and hash) is written atomically and
    the library renamed into place. Anything else is never cached.

    Raises
    ------
    _Unavailable
        If compilation fails; the message holds the first lines of the compiler error.
    """
    so_path = folder / f"{stem}.so"
    if fcntl is None:  # pragma: no cover - non-POSIX platforms
        raise _Unavailable("file locking (fcntl) is not available on this platform")
    lock_fd = os.open(folder / f"{stem}.so.lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(lock_fd, fcntl.LOCK_EX)
        if so_path.exists() and _verified(so_path):  # built by another process while we waited
            return so_path
        _discard(so_path)  # stale, damaged or foreign: rebuilt below
        c_path = folder / f"{stem}.c"
        _write_atomic(c_path, source)
        fd, tmp = tempfile.mkstemp(prefix=f"{stem}.", suffix=".so", dir=folder)
        os.close(fd)
        try:
            cmd = [*argv, *CFLAGS, "-o", tmp, str(c_path), *LIBS]
            try:
                proc = subprocess.run(
                    cmd,
                    capture_output=True,
                    text=True,
                    timeout=_COMPILE_TIMEOUT,
                    check=False,
                )
            except (OSError, subprocess.SubprocessError) as exc:
                raise _Unavailable(f"running {argv[0]!r} failed: {exc}") from exc
            if proc.returncode != 0:
                out = (proc.stderr or proc.stdout or "").strip().splitlines()
                head = "\n".join(out[:_ERROR_LINES]) or "(no output)"
                raise _Unavailable(
                    f"compiling {c_path} failed (exit code {proc.returncode}):\n{head}"
                )
            with open(tmp, "rb") as fh:
                magic = fh.read(4)
            if magic != b"\x7fELF":
                raise _Unavailable(f"{argv[0]!r} exited 0 but produced no shared library "
                                   f"({os.path.getsize(tmp)} bytes); nothing was cached")
            _write_atomic(so_path.with_name(so_path.name + ".sha256"), _digest(Path(tmp)))
            os.replace(tmp, so_path)
        finally:
            _unlink(tmp)
        return so_path
    finally:
        os.close(lock_fd)  # releases the flock


def _warn_once(reason: str) -> None:
    global _warned
    with _lock:
        if _warned:
            return
        _warned = True
    warn(
        f"dtdyn C backend unavailable, using the NumPy implementation instead. Reason: {reason}",
        DtdynFallbackWarning,
    )


def load_library(source: str, name: str) -> ctypes.CDLL | None:
    """Compile ``source`` on first use (cached on disk) and load it.

    Parameters
    ----------
    source : str
        Complete C99 translation unit.
    name : str
        Short identifier used in the cache file name; must match
        ``^[A-Za-z_][A-Za-z0-9_]*$``.

    Returns
    -------
    ctypes.CDLL or None
        The loaded library, memoised per process by ``(name, key)``. ``None``
        if the C backend is unavailable (``DTDYN_NO_C=1``, no compiler, or the
        compilation failed); the first such event in a process emits one
        :class:`DtdynFallbackWarning`.

    Raises
    ------
    ValueError
        If ``name`` is not a valid identifier.
    TypeError
        If ``source`` is not a string.
    """
    if not isinstance(name, str) or _NAME_RE.fullmatch(name) is None:
        raise ValueError(
            f"invalid library name {name!r}: must match ^[A-Za-z_][A-Za-z0-9_]*$"
        )
    if not isinstance(source, str):
        raise TypeError(f"source must be str, not {type(source).__name__}")
    if _disabled():
        _warn_once("disabled by DTDYN_NO_C")
        return None
    try:
        argv, version = _compiler()
    except _Unavailable as exc:
        _warn_once(str(exc))
        return None
    key = _key(source, argv, version)
    memo_key = (name, key)
    reason = None
    with _lock:
        if memo_key in _memo:
            return _memo[memo_key]
        lib = None
        try:
            folder = cache_dir()
            stem = f"{name}-{key[:16]}"
            so_path = folder / f"{stem}.so"
            if not (so_path.exists() and _verified(so_path)):
                so_path = _compile(source, argv, folder, stem)
            try:
                lib = ctypes.CDLL(str(so_path))
            except OSError:  # verified yet not loadable: rebuild once
                _discard(so_path)
                lib = ctypes.CDLL(str(_compile(source, argv, folder, stem)))
        except _Unavailable as exc:
            reason = str(exc)
        except (OSError, RuntimeError) as exc:  # cache not writable, no home, dlopen error
            reason = f"{type(exc).__name__}: {exc}"
        _memo[memo_key] = lib
    if lib is None:
        _warn_once(reason or "unknown error")
    return lib


def generated_source(filename: str) -> str:
    """A generated C source as one translation unit: its ``#include "x.h"`` lines of files that
    dtdyn.generated ships (chain_loop.h) are replaced by their text, so the compile needs no
    include path and the cache key covers the included code."""
    from importlib import resources

    folder = resources.files("dtdyn.generated")
    out = []
    for line in folder.joinpath(filename).read_text().splitlines(keepends=True):
        match = re.fullmatch(r'#include "([A-Za-z0-9_]+\.h)"\s*', line)
        out.append(folder.joinpath(match.group(1)).read_text() if match else line)
    return "".join(out)


def bind(lib, kernel: str, symbol: str | None = None):
    """The function ``symbol`` (default ``kernel``) of a loaded library with its argtypes and
    restype from the generated signature table (the same spec as its C declaration)."""
    from dtdyn.generated.c_api import SIGNATURES

    restype, argtypes = SIGNATURES[kernel]
    fn = getattr(lib, symbol or kernel)
    fn.restype = getattr(ctypes, restype)
    fn.argtypes = [getattr(ctypes, a) for a in argtypes]
    return fn


#: below this much work (samples x the loop's multiply-adds per sample, ~0.3-1 ns each) a call
#: runs in the calling thread: it ends within some 50 ms, well before a Ctrl-C needs the worker
#: thread, which costs tens of microseconds to start and, on P4's 1.7 ms nonlinear loop, another
#: 0.1 ms of caches warmed on the other core
INTERRUPTIBLE_WORK = 1 << 26


def interruptible(lib, call, work: float, timing: list | None = None):
    """``call()`` (one ctypes call into ``lib``, whose loop polls the flag of dtdyn_set_stop)
    such that Ctrl-C stops it within a second: in the main thread and for ``work`` above
    INTERRUPTIBLE_WORK, the call runs in a worker thread while this thread waits; on
    KeyboardInterrupt the flag is set, the loop returns at its next check and the interrupt is
    raised again. Returns what ``call()`` returns; ``timing``: a list that receives the call's
    own duration in seconds (the kernel's run time, without the worker thread's start)."""
    if timing is not None:
        untimed = call

        def call():
            t0 = time.perf_counter()
            try:
                return untimed()
            finally:
                timing.append(time.perf_counter() - t0)
    if work < INTERRUPTIBLE_WORK or threading.current_thread() is not threading.main_thread():
        return call()
    stop = bind(lib, "dtdyn_set_stop")
    stop(0)
    box, done = {}, threading.Event()

    def run():
        try:
            box["rc"] = call()
        except BaseException as exc:  # re-raised in the caller's thread
            box["exc"] = exc
        finally:
            done.set()

    # an Event, not Thread.join: an interrupted join marks a running thread as stopped
    # (CPython 3.11), and the arrays the loop writes must outlive it
    threading.Thread(target=run, name="dtdyn-kernel", daemon=True).start()
    try:
        while not done.wait(0.05):
            pass
    except KeyboardInterrupt:
        stop(1)
        while not done.is_set():  # the loop returns at its next check; a second Ctrl-C waits too
            try:
                done.wait(0.05)
            except KeyboardInterrupt:
                pass
        stop(0)  # a flag left set would stop the next call of this library at its first check
        raise
    if "exc" in box:
        raise box["exc"]
    return box["rc"]


def c_available() -> bool:
    """Tell whether the C backend can be tried.

    Returns
    -------
    bool
        ``False`` if ``DTDYN_NO_C`` is set or no C compiler is found, else
        ``True``. Does not compile anything and never warns; a later
        compilation may still fail, in which case :func:`load_library`
        returns ``None``.
    """
    if _disabled() or fcntl is None:
        return False
    try:
        _compiler()
    except _Unavailable:
        return False
    return True


def reset_for_tests() -> None:
    """Forget loaded libraries, resolved compilers and the warned-once flag."""
    global _warned
    with _lock:
        _memo.clear()
        _compilers.clear()
        _warned = False
