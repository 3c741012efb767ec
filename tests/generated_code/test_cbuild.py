"""Tests for dtdyn._engine.cbuild: compile-on-first-use C libraries."""
from __future__ import annotations

import ctypes
import multiprocessing
import os
import subprocess
import sys
import uuid
import warnings

import pytest

try:
    from dtdyn._engine import cbuild
except ImportError as exc:  # pragma: no cover - setup problem, not a test failure
    raise ImportError(
        "dtdyn is not importable; install it first: `pip install -e . --no-deps`"
    ) from exc

AXPY_SRC = """\
double axpy(double a, double x, double y) { return a * x + y; }
"""


def _axpy(lib: ctypes.CDLL):
    fn = lib.axpy
    fn.restype = ctypes.c_double
    fn.argtypes = [ctypes.c_double, ctypes.c_double, ctypes.c_double]
    return fn


@pytest.fixture(autouse=True)
def _isolated(tmp_path, monkeypatch):
    """Private empty cache per test, C enabled, fresh module state."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("DTDYN_CACHE", str(cache))
    monkeypatch.delenv("DTDYN_NO_C", raising=False)
    cbuild.reset_for_tests()
    yield cache
    cbuild.reset_for_tests()


needs_cc = pytest.mark.skipif(
    not cbuild.c_available(), reason="no C compiler (or DTDYN_NO_C set)"
)


def _fallback_warnings(record):
    return [w for w in record if issubclass(w.category, cbuild.DtdynFallbackWarning)]


@needs_cc
def test_compile_and_call(_isolated):
    lib = cbuild.load_library(AXPY_SRC, "axpy_test")
    assert lib is not None
    assert _axpy(lib)(2.0, 3.0, 0.5) == 6.5
    assert len(list(_isolated.glob("axpy_test-*.so"))) == 1
    assert len(list(_isolated.glob("axpy_test-*.c"))) == 1


@needs_cc
def test_cache_hit(_isolated):
    lib1 = cbuild.load_library(AXPY_SRC, "axpy_cache")
    assert lib1 is not None
    sos = list(_isolated.glob("*.so"))
    assert len(sos) == 1
    mtime = sos[0].stat().st_mtime_ns
    # same process: memoised object
    assert cbuild.load_library(AXPY_SRC, "axpy_cache") is lib1
    # fresh process state: found on disk, not rebuilt
    cbuild.reset_for_tests()
    lib2 = cbuild.load_library(AXPY_SRC, "axpy_cache")
    assert lib2 is not None
    assert lib2._name == lib1._name == str(sos[0])
    assert list(_isolated.glob("*.so")) == sos
    assert sos[0].stat().st_mtime_ns == mtime
    assert _axpy(lib2)(-1.0, 4.0, 1.0) == -3.0


def _race_child(env, source, barrier, queue):
    os.environ.update(env)
    from dtdyn._engine import cbuild as cb

    barrier.wait(timeout=60)
    lib = cb.load_library(source, "axpy_race")
    if lib is None:
        queue.put((None, None))
        return
    fn = lib.axpy
    fn.restype = ctypes.c_double
    fn.argtypes = [ctypes.c_double] * 3
    queue.put((lib._name, fn(3.0, 5.0, -1.0)))


@needs_cc
def test_two_processes_race(_isolated):
    source = f"/* {uuid.uuid4().hex} */\n" + AXPY_SRC
    env = {"DTDYN_CACHE": os.environ["DTDYN_CACHE"]}
    if "CC" in os.environ:
        env["CC"] = os.environ["CC"]
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(2)
    queue = ctx.Queue()
    procs = [
        ctx.Process(target=_race_child, args=(env, source, barrier, queue)) for _ in range(2)
    ]
    for p in procs:
        p.start()
    results = [queue.get(timeout=120) for _ in procs]
    for p in procs:
        p.join(timeout=60)
        assert p.exitcode == 0
    paths = {path for path, _ in results}
    assert None not in paths
    assert len(paths) == 1
    assert [value for _, value in results] == [14.0, 14.0]
    # exactly the library, its source and its lock file: no temporaries left
    names = sorted(p.name for p in _isolated.iterdir())
    (so,) = [n for n in names if n.endswith(".so")]
    stem = so[: -len(".so")]
    assert names == sorted([f"{stem}.so", f"{stem}.c", f"{stem}.so.lock", f"{stem}.so.sha256"])
    assert str(_isolated / so) in paths


def test_fallback_missing_compiler(monkeypatch):
    monkeypatch.setenv("CC", "/nonexistent/dtdyn-no-such-cc")
    assert cbuild.c_available() is False
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        assert cbuild.load_library(AXPY_SRC, "axpy_fb") is None
        assert cbuild.load_library(AXPY_SRC, "axpy_fb2") is None
    fb = _fallback_warnings(record)
    assert len(fb) == 1
    msg = str(fb[0].message)
    assert "dtdyn-no-such-cc" in msg and "NumPy" in msg
    assert fb[0].filename == __file__


def test_fallback_forced_by_env(monkeypatch):
    monkeypatch.setenv("DTDYN_NO_C", "1")
    assert cbuild.c_available() is False
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        assert cbuild.load_library(AXPY_SRC, "axpy_off") is None
        assert cbuild.load_library(AXPY_SRC, "axpy_off") is None
    assert len(_fallback_warnings(record)) == 1


@needs_cc
def test_fallback_compile_error(_isolated):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        assert cbuild.load_library("double broken( {\n", "broken") is None
        assert cbuild.load_library("double broken( {\n", "broken") is None
    fb = _fallback_warnings(record)
    assert len(fb) == 1
    assert "error" in str(fb[0].message).lower()
    assert not list(_isolated.glob("*.so"))


@pytest.mark.parametrize("bad", ["a;rm", "", "1abc", "a-b", "a b", "../x", "x\n"])
def test_rejects_bad_name(bad):
    with pytest.raises(ValueError, match="name"):
        cbuild.load_library(AXPY_SRC, bad)


@pytest.mark.parametrize("name", ["x; system(\"rm -rf /\")", "a b", "../../etc/passwd", "",
                                  "x\n#include <stdio.h>"])
def test_names_never_reach_c_unchecked(name):
    """(From the fault suite, tests/behaviour/test_fault_suite.py.)"""
    with pytest.raises(ValueError):
        cbuild.load_library("int f(void) { return 1; }", name)


# --- cache integrity: a damaged, emptied or swapped library is rebuilt, never loaded -------------

OTHER_SRC = "double other(double x) { return -x; }\n"


@needs_cc
@pytest.mark.parametrize("damage", ["truncated", "empty", "garbage", "swapped", "no sidecar"])
def test_damaged_cache_file_is_rebuilt(_isolated, damage):
    """The library is checked against the size and hash its build recorded before dlopen sees
    it (a truncated ELF file used to crash every later run with SIGBUS); a bad one is rebuilt
    once and gives the right answer."""
    # built by another process (a library mapped by this one must not be written to)
    code = ("from dtdyn._engine import cbuild; "
            f"assert cbuild.load_library({AXPY_SRC!r}, 'axpy_damage'); "
            f"assert cbuild.load_library({OTHER_SRC!r}, 'other_lib')")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300,
                   env=dict(os.environ, DTDYN_CACHE=str(_isolated)))
    (so,) = _isolated.glob("axpy_damage-*.so")
    (other_so,) = _isolated.glob("other_lib-*.so")
    data = so.read_bytes()
    if damage == "truncated":
        so.write_bytes(data[: len(data) // 2])
    elif damage == "empty":
        so.write_bytes(b"")
    elif damage == "garbage":
        so.write_bytes(b"\x7fELF" + os.urandom(2000))
    elif damage == "swapped":  # another valid library in its place
        so.write_bytes(other_so.read_bytes())
    else:
        so.with_name(so.name + ".sha256").unlink()
    cbuild.reset_for_tests()  # a new process: nothing memoised
    with warnings.catch_warnings():
        warnings.simplefilter("error", cbuild.DtdynFallbackWarning)
        lib = cbuild.load_library(AXPY_SRC, "axpy_damage")
    assert _axpy(lib)(2.0, 3.0, 0.5) == 6.5
    assert so.read_bytes() == data and cbuild._verified(so)


@needs_cc
def test_a_compiler_that_builds_nothing_is_not_cached(_isolated, monkeypatch):
    """CC=/bin/true exits 0 without writing a library: the NumPy fallback with one warning, and
    no cached file that would stop a later real compiler from building it."""
    monkeypatch.setenv("CC", "/bin/true")
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        assert cbuild.load_library(AXPY_SRC, "axpy_true") is None
    assert any("produced no shared library" in str(w.message) for w in _fallback_warnings(record))
    assert list(_isolated.glob("axpy_true-*.so")) == []
    monkeypatch.delenv("CC")
    cbuild.reset_for_tests()
    assert _axpy(cbuild.load_library(AXPY_SRC, "axpy_true"))(1.0, 1.0, 1.0) == 2.0


# --- a complete library or none: ELF extents, key stamp and entry points (issue 29) ---------------

def _build_in_child(cache, *pairs):
    """Build ``(source, name)`` libraries in another process (a library mapped by this one must
    not be rewritten under it)."""
    code = "from dtdyn._engine import cbuild\n" + "".join(
        f"assert cbuild.load_library({src!r}, {name!r})\n" for src, name in pairs)
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300,
                   env=dict(os.environ, DTDYN_CACHE=str(cache)))


#: run in a child process, so that a SIGBUS would fail the test instead of killing pytest: every
#: file handed to the loader is recorded (its size and hash), then each library is called
CHILD_LOAD = """
import ctypes, hashlib, json, os, sys, warnings
from dtdyn._engine import cbuild
loaded = []
real = cbuild.ctypes.CDLL
class Recording(real):
    def __init__(self, name, *args, **kwargs):
        data = open(name, "rb").read()
        loaded.append([os.path.basename(name), len(data), hashlib.sha256(data).hexdigest()])
        super().__init__(name, *args, **kwargs)
cbuild.ctypes.CDLL = Recording
warnings.simplefilter("error", cbuild.DtdynFallbackWarning)
out = {}
for src, name, fn, args in json.loads(sys.argv[1]):
    f = getattr(cbuild.load_library(src, name), fn)
    f.restype = ctypes.c_double
    f.argtypes = [ctypes.c_double] * len(args)
    out[name] = f(*args)
print(json.dumps({"loaded": loaded, "values": out}))
"""


def _load_in_child(cache, calls):
    import json

    proc = subprocess.run([sys.executable, "-c", CHILD_LOAD, json.dumps(calls)],
                          capture_output=True, text=True, timeout=300,
                          env=dict(os.environ, DTDYN_CACHE=str(cache)))
    assert proc.returncode == 0, f"child died ({proc.returncode}): {proc.stderr[-2000:]}"
    return json.loads(proc.stdout)


def _sha(data: bytes) -> str:
    import hashlib

    return hashlib.sha256(data).hexdigest()


@needs_cc
@pytest.mark.parametrize("cut", [0.5, 0.9, 0.99])
def test_truncated_library_with_matching_sidecar_is_rebuilt_never_loaded(_isolated, cut):
    """The issue's SIGBUS: a cached kernel cut short with its sidecar rewritten to match passes
    the hash check; its ELF headers put segments or sections past the end of the file, so it is
    rebuilt and the loader only ever sees the complete file."""
    _build_in_child(_isolated, (AXPY_SRC, "axpy_cut"))
    (so,) = _isolated.glob("axpy_cut-*.so")
    data = so.read_bytes()
    short = data[: int(len(data) * cut)]
    so.write_bytes(short)
    so.with_name(so.name + ".sha256").write_text(cbuild._digest(so))
    assert cbuild._sidecar_problem(so) is None  # the hash alone would let it through
    assert "cut short" in cbuild._elf_problem(so)
    result = _load_in_child(_isolated, [(AXPY_SRC, "axpy_cut", "axpy", [2.0, 3.0, 0.5])])
    assert result["values"] == {"axpy_cut": 6.5}
    assert [size for _, size, _ in result["loaded"]] == [len(data)]  # never the short file
    assert so.read_bytes() == data and cbuild._verified(so)


@needs_cc
def test_libraries_swapped_with_their_sidecars_are_rebuilt(_isolated):
    """Two cached kernels swapped together with their sidecars: each is a complete library whose
    hash matches, but it carries the other key's stamp and lacks the entry point its own key
    promises; both are rebuilt (the swapped one was loaded, looked up, never called)."""
    _build_in_child(_isolated, (AXPY_SRC, "axpy_swap"), (OTHER_SRC, "other_swap"))
    (a,) = _isolated.glob("axpy_swap-*.so")
    (b,) = _isolated.glob("other_swap-*.so")
    a_data, b_data = a.read_bytes(), b.read_bytes()
    for src, dst in ((a, b), (b, a)):  # swap the libraries and their sidecars
        dst.with_name(dst.name + ".new").write_bytes(src.read_bytes())
        dst.with_name(dst.name + ".sha256.new").write_text(
            src.with_name(src.name + ".sha256").read_text())
    for path in (a, b):
        os.replace(path.with_name(path.name + ".new"), path)
        os.replace(path.with_name(path.name + ".sha256.new"), path.with_name(path.name + ".sha256"))
    assert cbuild._verified(a) and cbuild._verified(b) and a.read_bytes() == b_data
    result = _load_in_child(_isolated, [(AXPY_SRC, "axpy_swap", "axpy", [2.0, 3.0, 0.5]),
                                        (OTHER_SRC, "other_swap", "other", [4.0])])
    assert result["values"] == {"axpy_swap": 6.5, "other_swap": -4.0}
    assert a.read_bytes() == a_data and b.read_bytes() == b_data


@needs_cc
def test_a_library_that_stays_bad_is_a_named_error(_isolated, monkeypatch):
    """Rebuilt once; if the rebuilt library still lacks what its key promises (here: a source
    whose entry point is promised but compiled away), DtdynCacheError names the file and why."""
    monkeypatch.setattr(cbuild, "entry_points", lambda source: ("axpy", "no_such_symbol"))
    with pytest.raises(cbuild.DtdynCacheError, match=r"axpy_bad-.*\.so does not export "
                                                     r"no_such_symbol, again after.*rebuilt"):
        cbuild.load_library(AXPY_SRC, "axpy_bad")
    import dtdyn

    assert dtdyn.DtdynCacheError is cbuild.DtdynCacheError


@needs_cc
def test_elf_check_refuses_what_the_loader_cannot_map(_isolated):
    """The header parser on a real library and on copies damaged field by field: another word
    size or byte order, a non-shared object, tables and segments past the end of the file."""
    import struct

    assert cbuild.load_library(AXPY_SRC, "axpy_elf") is not None
    (so,) = _isolated.glob("axpy_elf-*.so")
    data = so.read_bytes()
    assert cbuild._elf_problem(so) is None
    bad = _isolated / "bad.so"

    def problem(blob):
        bad.write_bytes(blob)
        return cbuild._elf_problem(bad)

    def patched(offset, fmt, value):
        blob = bytearray(data)
        struct.pack_into(fmt, blob, offset, value)
        return bytes(blob)

    assert "not an ELF file" in problem(b"")
    assert "not an ELF file" in problem(b"MZ\x90\x00" + data[4:])
    assert "32-bit" in problem(data[:4] + b"\x01" + data[5:])
    assert "big-endian" in problem(data[:5] + b"\x02" + data[6:])
    assert "ELF header" in problem(data[:40])
    assert "not a shared library" in problem(patched(16, "<H", 2))  # ET_EXEC
    phoff, shoff = struct.unpack_from("<QQ", data, 32)
    assert "section header table ends" in problem(patched(40, "<Q", len(data)))
    assert "program header table ends" in problem(patched(32, "<Q", len(data) - 8))
    assert "segment 0" in problem(patched(phoff + 32, "<Q", len(data)))  # p_filesz
    for n in (64, len(data) // 3, len(data) - 1):
        assert "cut short" in problem(data[:n]), n


def test_entry_points_are_read_conservatively():
    """What a source promises: externally visible definitions only; static, inline, macro-typed,
    #define'd names and prototypes promise nothing (a macro may hide a static)."""
    src = """
    #define EXPORT static
    #define twice_name hidden_name
    /* int commented(void) { return 0; } */
    static int helper(int a) { return a; }
    inline int inl(void) { return 1; }
    EXPORT int macro_typed(void) { return 2; }
    int declared_only(int);
    double twice_name(double x) { return 2 * x; }
    struct s { int a; };
    const char *text = "int in_string(void) { }";
    unsigned long long
    dtdyn_multi_line(long n,
                     const double *restrict x) { if (n) { return 1; } return 0; }
    int dtdyn_plain(void) { return helper(3); }
    """
    assert cbuild.entry_points(src) == ("dtdyn_multi_line", "dtdyn_plain")
    assert cbuild.entry_points("int f(void) { {\n") == ()  # unbalanced: nothing promised
    from importlib import resources

    folder = resources.files("dtdyn.generated")
    for name in ("sturm.c", "mck_loop.c", "chain_newmark.c", "modal_states.c"):
        names = cbuild.entry_points(cbuild.generated_source(name))
        assert names and all(n.startswith("dtdyn_") for n in names), (name, names)
    assert folder.joinpath("sturm.c").is_file()
