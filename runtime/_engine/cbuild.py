"""Compile generated C sources on first use and load them with :mod:`ctypes`.

Shared libraries are cached per user (``$DTDYN_CACHE``, else
``$XDG_CACHE_HOME/dtdyn``, else ``~/.cache/dtdyn``) under a key that covers the
source text, the compiler and its flags, so a source is compiled once per
machine and reused afterwards. Concurrent processes are serialised with a file
lock and the library is moved into place atomically.

A cached library is loaded only when it is complete: its size and hash match the sidecar its
build wrote, its ELF headers put every segment and section inside the file (a library cut short
would be mapped past its end, and the first touch of the missing pages kills the process with
SIGBUS), and, once loaded and before any call, it exports the entry points its source defines and
the stamp of its own cache key (a library swapped with another, sidecar and all, is caught
there). A library that fails is removed and rebuilt once; if the rebuilt one fails too,
:class:`DtdynCacheError` is raised.

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
import struct
import subprocess
import sys
import sysconfig
import time
import tempfile
import threading
from pathlib import Path
from dtdyn._engine.errors import DtdynCacheError, DtdynFallbackWarning
from dtdyn._engine.public import warn

try:  # POSIX only; without it the C backend is reported as unavailable.
    import fcntl
except ImportError:  # pragma: no cover - non-POSIX platforms
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "CFLAGS",
    "LIBS",
    "DtdynCacheError",
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


#: ELF constants (System V gABI): e_ident fields, ET_DYN, PT_LOAD, SHT_NOBITS, PN_XNUM
_ELFCLASS = {1: 32, 2: 64}
_ELFDATA = {1: "little", 2: "big"}
_ET_DYN, _PT_LOAD, _SHT_NOBITS, _PN_XNUM = 3, 1, 8, 0xFFFF
#: per class: (header layout after e_ident, program header layout, section header layout);
#: the program header's fields are read by name below, as the two classes order them differently
_ELF_LAYOUT = {
    32: ("HHIIIIIHHHHHH", "IIIIIIII", "IIIIIIIIII"),
    64: ("HHIQQQIHHHHHH", "IIQQQQQQ", "IIQQQQIIQQ"),
}
_PH_FIELDS = {
    32: ("type", "offset", "vaddr", "paddr", "filesz", "memsz", "flags", "align"),
    64: ("type", "flags", "offset", "vaddr", "paddr", "filesz", "memsz", "align"),
}


def _elf_problem(path: str | os.PathLike[str]) -> str | None:  # noqa: C901 (one check a field)
    """What makes ``path`` not a complete ELF shared library for this process, or ``None``.

    The loader maps each PT_LOAD segment's file range ``[p_offset, p_offset + p_filesz)``; a range
    past the end of the file is mapped anyway and the first read of it kills the process with
    SIGBUS, so every segment, the program and section header tables and every section with file
    contents must lie inside the file. The file must also be a shared object (``ET_DYN``) of this
    process's word size and byte order (ELF32 or big-endian files are parsed and refused, as
    dlopen would refuse them). Pure Python (:mod:`struct`), reading only the headers.

    On macOS libraries are Mach-O, not ELF: the check is skipped there (dtdyn is developed and
    tested on Linux; the sidecar's size and hash still guard the file).
    """
    if sys.platform == "darwin":  # Mach-O: no ELF headers to read (see the docstring)
        return None
    try:
        with open(path, "rb") as fh:
            return _ElfReader(fh).problem()
    except (OSError, struct.error) as exc:
        return f"cannot be read ({type(exc).__name__}: {exc})"


class _ElfReader:
    """The checks of :func:`_elf_problem` on an open file; each returns a problem or None."""

    def __init__(self, fh):
        self.fh = fh
        self.size = os.fstat(fh.fileno()).st_size

    def read(self, offset: int, n: int) -> bytes:
        self.fh.seek(offset)
        return self.fh.read(n)

    def table(self, offset: int, count: int, entsize: int, what: str) -> str | None:
        if offset + count * entsize > self.size:
            return (f"is cut short: its {what} table ends at byte {offset + count * entsize}, "
                    f"the file has {self.size} bytes")
        return None

    def problem(self) -> str | None:
        size, ident = self.size, self.read(0, 16)
        if len(ident) < 16 or ident[:4] != b"\x7fELF":
            return f"is not an ELF file ({size} bytes, starts {ident[:4]!r})"
        bits, order = _ELFCLASS.get(ident[4]), _ELFDATA.get(ident[5])
        if bits is None or order is None or ident[6] != 1:
            return f"has an unknown ELF class, byte order or version ({ident[4:7].hex()})"
        host = 8 * struct.calcsize("P")
        if bits != host or order != sys.byteorder:
            return (f"is a {bits}-bit {order}-endian ELF file; this Python is {host}-bit "
                    f"{sys.byteorder}-endian")
        end = "<" if order == "little" else ">"
        eh_fmt, self.ph_fmt, self.sh_fmt = (end + f for f in _ELF_LAYOUT[bits])
        self.fields = _PH_FIELDS[bits]
        head = self.read(16, struct.calcsize(eh_fmt))
        if len(head) < struct.calcsize(eh_fmt):
            return f"ends inside its ELF header ({size} bytes)"
        (e_type, _machine, _version, _entry, phoff, shoff, _flags, _ehsize, phentsize,
         phnum, shentsize, shnum, _shstrndx) = struct.unpack(eh_fmt, head)
        if e_type != _ET_DYN:
            return f"is not a shared library (ELF e_type {e_type}, expected {_ET_DYN})"
        sections: list[tuple] = []
        if shoff:
            bad = self.sections(shoff, shnum, shentsize, sections)
            if bad:
                return bad
            if phnum == _PN_XNUM:  # the real count is in section 0's sh_info
                phnum = sections[0][7]
        return self.segments(phoff, phnum, phentsize) or self.section_extents(sections)

    def sections(self, shoff: int, shnum: int, shentsize: int, out: list) -> str | None:
        """The section header table inside the file (section 0 holds the real count when it
        overflows e_shnum); ``out`` receives the headers."""
        sh_size = struct.calcsize(self.sh_fmt)
        if shentsize != sh_size:
            return f"has section headers of {shentsize} bytes, expected {sh_size}"
        bad = self.table(shoff, max(shnum, 1), sh_size, "section header")
        if bad:
            return bad
        shnum = shnum or struct.unpack(self.sh_fmt, self.read(shoff, sh_size))[5]
        bad = self.table(shoff, shnum, sh_size, "section header")
        if bad:
            return bad
        data = self.read(shoff, shnum * sh_size)
        out.extend(struct.unpack_from(self.sh_fmt, data, i * sh_size) for i in range(shnum))
        return None

    def segments(self, phoff: int, phnum: int, phentsize: int) -> str | None:
        """The program header table and every segment's file range inside the file."""
        ph_size = struct.calcsize(self.ph_fmt)
        if phentsize != ph_size or phnum == 0:
            return f"has no usable program headers ({phnum} of {phentsize} bytes)"
        bad = self.table(phoff, phnum, ph_size, "program header")
        if bad:
            return bad
        data = self.read(phoff, phnum * ph_size)
        loads = 0
        for i in range(phnum):
            ph = dict(zip(self.fields, struct.unpack_from(self.ph_fmt, data, i * ph_size)))
            loads += ph["type"] == _PT_LOAD
            if ph["filesz"] and ph["offset"] + ph["filesz"] > self.size:
                return (f"is cut short: segment {i} (type {ph['type']:#x}) ends at byte "
                        f"{ph['offset'] + ph['filesz']}, the file has {self.size} bytes")
            if ph["type"] == _PT_LOAD and ph["filesz"] > ph["memsz"]:
                return f"has a PT_LOAD segment {i} larger in the file than in memory"
        return None if loads else "has no PT_LOAD segment"

    def section_extents(self, sections) -> str | None:
        """Every section with file contents (not SHT_NOBITS) inside the file."""
        for i, sh in enumerate(sections):
            sh_type, sh_offset, sh_bytes = sh[1], sh[4], sh[5]
            if sh_type != _SHT_NOBITS and sh_bytes and sh_offset + sh_bytes > self.size:
                return (f"is cut short: section {i} ends at byte {sh_offset + sh_bytes}, "
                        f"the file has {self.size} bytes")
        return None


def _sidecar_problem(so_path: Path) -> str | None:
    """What is wrong with the library against the size and hash its build wrote next to it."""
    sidecar = so_path.with_name(so_path.name + ".sha256")
    try:
        if sidecar.read_text().strip() != _digest(so_path):
            return "does not match the size and hash its build recorded"
    except OSError as exc:
        return f"or its sidecar cannot be read ({type(exc).__name__})"
    return None


def _file_problem(so_path: Path) -> str | None:
    """Why the cached library must not be handed to the loader, or ``None``: its sidecar (size
    and hash) and its ELF headers (every segment inside the file)."""
    return _sidecar_problem(so_path) or _elf_problem(so_path)


def _verified(so_path: Path) -> bool:
    """True when the library matches the size and hash its build wrote next to it and its ELF
    headers describe a complete file: a cache file cut short, emptied, overwritten or swapped is
    never handed to the loader (a truncated ELF file crashes the process with SIGBUS, even when
    its sidecar was rewritten to match; checking it first, in this process, prevents that)."""
    return _file_problem(so_path) is None


def _identity(path: Path) -> tuple[int, int, int, int] | None:
    """The file's (device, inode, size, mtime): tells a file rejected earlier from a new one."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


#: the words a function definition's return type may be made of; a macro (upper case) or an
#: attribute before the name may make it static or hidden, so such a definition promises nothing
_TYPE_WORD = re.compile(r"[a-z_][a-z0-9_]*|\*")
_NOT_EXPORTED = {"static", "inline", "__inline", "__inline__", "extern", "typedef", "struct",
                 "union", "enum", "return", "if", "while", "for", "switch", "do", "else"}
_DEFINITION = re.compile(r"(?:^|(?<=[;}]))\s*([A-Za-z_][\w\s*]*?)\s*\b([A-Za-z_]\w*)\s*"
                         r"\(([^(){};]*)\)\s*\{\}")
_TOKENS = re.compile(r"/\*.*?\*/|//[^\n]*|\"(?:\\.|[^\"\\\n])*\"|'(?:\\.|[^'\\\n])*'", re.S)
_DIRECTIVE = re.compile(r"^[ \t]*#(?:[^\n]*\\\n)*[^\n]*", re.M)


def entry_points(source: str) -> tuple[str, ...]:
    """The functions a C translation unit defines with external linkage, as far as can be told
    without a preprocessor: file-scope definitions ``type name(params) { ... }`` whose return
    type is plain lower-case words and ``*`` and neither they nor the name is a macro (no
    ``static``, ``inline``, ``#define``d word or upper-case word that may hide one). Comments,
    string literals and preprocessor lines are removed first; function bodies are skipped by
    brace depth. Conservative: a definition it cannot read is left out, never guessed.

    Parameters
    ----------
    source : str
        A complete C99 translation unit.

    Returns
    -------
    tuple of str
        The names, sorted.

    Examples
    --------
    >>> entry_points("static int f(void) { return 0; }\\nint g(int a) { return a; }\\n")
    ('g',)
    """
    text = _TOKENS.sub(lambda m: " " if m.group(0)[0] == "/" else '""', source)
    macros = set(re.findall(r"^[ \t]*#[ \t]*define[ \t]+([A-Za-z_]\w*)", text, re.M))
    text = _DIRECTIVE.sub("", text)
    flat, depth, last = [], 0, 0  # the file-scope text, every {...} body replaced by {}
    for match in re.finditer(r"[{}]", text):
        if match.group(0) == "{":
            if depth == 0:
                flat.append(text[last:match.start()] + "{")
            depth += 1
        else:
            depth -= 1
            if depth == 0:
                flat.append("}")
                last = match.end()
            elif depth < 0:  # unbalanced: read nothing rather than guess
                return ()
    flat.append(text[last:] if depth == 0 else "")
    names = set()
    for match in _DEFINITION.finditer("".join(flat)):
        prefix = match.group(1).replace("*", " * ").split()
        if prefix and not _NOT_EXPORTED.intersection(prefix) and all(
                _TYPE_WORD.fullmatch(word) and word not in macros
                for word in [*prefix, match.group(2)]):
            names.add(match.group(2))
    return tuple(sorted(names))


def _stamp(key: str) -> tuple[str, str]:
    """The symbol every library carries for its cache key, and its C definition."""
    name = f"dtdyn_cache_key_{key[:32]}"
    return name, f'\n/* dtdyn cache key stamp */\nconst char {name}[] = "{key}";\n'


def _export_problem(lib: ctypes.CDLL, key: str, names: tuple[str, ...]) -> str | None:
    """What the loaded library lacks of what its key promises (looked up, never called): the
    key stamp with the full key as its value, and every entry point of its source."""
    stamp, _ = _stamp(key)
    try:
        value = (ctypes.c_char * (len(key) + 1)).in_dll(lib, stamp).value.decode("ascii")
    except (AttributeError, ValueError, UnicodeDecodeError):
        return f"lacks the stamp {stamp} of its cache key (a library built from another source)"
    if value != key:
        return f"carries the stamp of another cache key ({value[:16]}...)"
    missing = [name for name in names if not hasattr(lib, name)]
    if missing:
        return f"does not export {', '.join(missing)}"
    return None


def _dlclose(lib: ctypes.CDLL) -> None:
    """Unload a rejected library, so that loading the rebuilt file at the same path maps the new
    file (the loader would otherwise hand back the library already open under that name)."""
    try:
        import _ctypes

        _ctypes.dlclose(lib._handle)
    except (ImportError, AttributeError, OSError):  # pragma: no cover - no dlclose here
        pass


def _discard(so_path: Path) -> None:
    for path in (so_path, so_path.with_name(so_path.name + ".sha256")):
        _unlink(path)


def _compile(source: str, argv: tuple[str, ...], folder: Path, stem: str,
             rejected: tuple | None = None) -> Path:
    """``folder/stem.so``, verified: reused when its sidecar and ELF headers check, else
    (re)built by this process under an exclusive lock (a racing process waits and reuses it).
    ``rejected``: the :func:`_identity` of a file the caller found bad after loading it; the
    file is removed and rebuilt only if it is still that one (a racing process may have
    replaced it already), so two processes that both reject it build it once.

    A build counts only when the compiler exits 0 and leaves a complete shared object (its
    ELF headers check); then the sidecar ``stem.so.sha256`` (size and hash) is written
    atomically and the library renamed into place. Anything else is never cached.

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
        # built by another process while we waited (and not the file the caller rejected)
        if so_path.exists() and _verified(so_path) and (
                rejected is None or _identity(so_path) != rejected):
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
            if not magic if sys.platform == "darwin" else magic != b"\x7fELF":
                raise _Unavailable(f"{argv[0]!r} exited 0 but produced no shared library "
                                   f"({os.path.getsize(tmp)} bytes); nothing was cached")
            bad = _elf_problem(tmp)
            if bad:
                raise _Unavailable(f"{argv[0]!r} exited 0 but the library it wrote {bad}; "
                                   "nothing was cached")
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


def _load_checked(source: str, name: str, key: str, argv: tuple[str, ...]) -> ctypes.CDLL:
    """Load ``name-<key>.so`` from the cache, building it if missing, such that no file that is
    not a complete library reaches the loader and no library lacking what its key promises is
    returned; a bad file is removed and rebuilt once (under the build lock, see
    :func:`_compile`), a second failure raises :class:`DtdynCacheError`."""
    folder = cache_dir()
    stem = f"{name}-{key[:16]}"
    so_path = folder / f"{stem}.so"
    compiled = source + _stamp(key)[1]
    names = entry_points(source)
    rejected, problem = None, None
    for attempt in range(2):
        if attempt == 0 and so_path.exists() and _verified(so_path):
            path = so_path  # the common case: checked without the lock, the file is never
        else:               # rewritten in place (builds are renamed over it)
            path = _compile(compiled, argv, folder, stem, rejected)
        identity = _identity(path)
        try:
            lib = ctypes.CDLL(str(path))
        except OSError as exc:  # checked yet not loadable
            problem = f"was refused by the loader ({exc})"
        else:
            problem = _export_problem(lib, key, names)
            if problem is None:
                return lib
            _dlclose(lib)
        rejected = identity
    raise DtdynCacheError(
        f"the cached C library {so_path} {problem}, again after it was removed and rebuilt; "
        f"something rewrites the cache folder {folder} or the compiler {argv[0]!r} does not "
        "build a complete library (set DTDYN_CACHE to another folder, or DTDYN_NO_C=1 to use "
        "the NumPy implementation)")


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
    DtdynCacheError
        If the cached library fails its checks (sidecar, ELF headers, key stamp and entry
        points, see the module docstring) again after it was removed and rebuilt once.
    """
    if not isinstance(name, str) or _NAME_RE.fullmatch(name) is None:
        raise ValueError(
            f"invalid library name {name!r}: must match ^[A-Za-z_][A-Za-z0-9_]*$"
        )
    if not isinstance(source, str):
        raise TypeError(f"source must be str, not {type(source).__name__}")
    source = expand_includes(source)
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
            lib = _load_checked(source, name, key, argv)
        except DtdynCacheError:
            raise
        except _Unavailable as exc:
            reason = str(exc)
        except (OSError, RuntimeError) as exc:  # cache not writable, no home, dlopen error
            reason = f"{type(exc).__name__}: {exc}"
        _memo[memo_key] = lib
    if lib is None:
        _warn_once(reason or "unknown error")
    return lib


#: where ``#include "x.h"`` of a source is found: the generated headers (c_api.h), then the
#: hand-written C (dtdyn/_engine/csrc)
INCLUDE_PACKAGES = ("dtdyn.generated", "dtdyn._engine")
_INCLUDE_RE = re.compile(r'(?m)^[ \t]*#include "([A-Za-z0-9_]+\.h)"[^\n]*\n?')


def include_dirs() -> list:
    """The folders `expand_includes` reads (generated/, then _engine/csrc/), for a compiler's -I."""
    from importlib import resources

    return [resources.files("dtdyn.generated"), resources.files("dtdyn._engine") / "csrc"]


def expand_includes(source: str, _depth: int = 0) -> str:
    """``source`` with each ``#include "x.h"`` of a header dtdyn ships (`include_dirs`) replaced by
    its text, recursively (as the preprocessor reads it: each header's own guard keeps a second
    copy out), so the compile needs no include path and the cache key covers the included code.
    Other includes (``<math.h>``) are left as they are."""
    if _depth > 16:
        raise RuntimeError("#include nesting deeper than 16 in dtdyn's C sources (a cycle?)")
    folders = include_dirs()

    def text(match):
        for folder in folders:
            path = folder.joinpath(match.group(1))
            if path.is_file():
                body = expand_includes(path.read_text(), _depth + 1)
                return body if body.endswith("\n") else body + "\n"
        return match.group(0)

    return _INCLUDE_RE.sub(text, source)


def generated_source(filename: str) -> str:
    """A generated C source (dtdyn.generated) as one translation unit (`expand_includes`)."""
    from importlib import resources

    return expand_includes(resources.files("dtdyn.generated").joinpath(filename).read_text())


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
