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
