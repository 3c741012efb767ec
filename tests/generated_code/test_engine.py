"""The private engine's own parts, seen from inside (the tests that reach into `dtdyn._engine`
live here, in its room; the behaviour they guard is tested through the public names elsewhere):
the result path check and the atomic writes of result files (tests/application/test_result_io.py),
a warning raised many times in one call shown once (test_warnings.py), the dense-conversion
memory check (tests/behaviour/test_fault_suite_escapes.py), the time loop's blocks between its
checks (test_mck_c_loop.py, test_mck_sparse.py)."""
import warnings

import numpy as np
import pytest

import dtdyn as dd
from dtdyn._engine import atomic, result_io, stepping, validate
from dtdyn._engine.public import public, warn


# --- result files (tests/application/test_result_io.py) ---------------------------------------
@pytest.fixture(scope="module")
def chain_result():
    r = dd.chain_response([2.0, 3.0], [20.0, 15.0], [5.0, 6.0], np.ones(201), 0.02,
                          force_dofs=[1], scheme="hht", alpha=-0.1, outputs=[1, 0],
                          quantities=("x", "a"))
    r.meta.update(title="P2", units={"x": "m", "a": "m/s^2"})
    return r


@pytest.mark.parametrize("name, message", [
    ("r.txt", "unknown result format '.txt'"), ("r", r"unknown result format '\(none\)'"),
    ("missing/r.npz", "does not exist"),
])
def test_bad_paths_are_refused_by_the_check_before_writing(tmp_path, name, message):
    """The check `dtdyn simulate` makes before a run (Response.save makes it too)."""
    with pytest.raises(ValueError, match=message):
        result_io.check_result_path(tmp_path / name)
    assert list(tmp_path.iterdir()) == []


def test_csv_and_sidecar_are_written_together(tmp_path, chain_result, monkeypatch):
    """A failure while writing leaves the earlier table and sidecar as they were and no
    temporary file; the pair is replaced only once both are complete."""
    path = chain_result.save(tmp_path / "r.csv")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    real = result_io._csv_files

    def broken(response, p):
        table, _ = real(response, p)
        return table, None  # the sidecar's writer fails (bytes expected)

    monkeypatch.setattr(result_io, "_csv_files", broken)
    changed = dd.Response(chain_result.t, chain_result.outputs, x=2 * chain_result.x)
    with pytest.raises(TypeError):
        changed.save(path)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before

    def second_fails(fh):
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        atomic.write_atomic_files([(tmp_path / "a.txt", lambda fh: fh.write(b"a")),
                                   (tmp_path / "b.txt", second_fails)])
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


# --- warnings (tests/application/test_warnings.py) --------------------------------------------
def test_a_warning_raised_many_times_in_one_call_is_shown_once():
    """`warn` inside a public call: the same (category, message) three times is one warning;
    another message is a second; a new call warns again."""
    @public
    def noisy(n):
        for _ in range(n):
            warn("the same thing", dd.SRSSamplingWarning)
        warn("something else", dd.SRSSamplingWarning)

    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        noisy(3)
        noisy(3)
    assert [str(w.message) for w in rec] == ["the same thing", "something else"] * 2


# --- memory (tests/behaviour/test_fault_suite_escapes.py) -------------------------------------
def _chain_sparse(n):
    return dd.chain_matrices(np.ones(n), np.ones(n), np.ones(n), sparse=True)


def test_dense_conversion_check_names_the_size_before_allocating(monkeypatch):
    """The one dense-conversion check (validate.dense_conversion) counts n x n x 8 B per copy
    and names the sparse paths; a model that fits passes untouched."""
    monkeypatch.setattr(validate, "available_memory", lambda: 10 * 2**20)  # 10 MiB
    M, C, K = _chain_sparse(1000)  # dense: 8 MB each, 24 MB for the three
    with pytest.raises(MemoryError, match=r"exact_response: M is a sparse 1,000 x 1,000 matrix; "
                       r"as dense matrices \(3 of this size\) they would need 22.9 MiB, more "
                       r"than the 10 MiB available"):
        dd.exact_response(M, C, K, np.ones(11), 1e-3, force_dofs=[0])
    M, C, K = _chain_sparse(300)  # 0.7 MB each: converted
    r = dd.exact_response(M, C, K, np.ones(11), 1e-3, force_dofs=[0], outputs=[0])
    assert r.x.shape == (11, 1)


# --- the time loop's blocks (tests/behaviour/test_mck_c_loop.py, test_mck_sparse.py) -----------
@pytest.fixture(scope="module")
def model():
    """test_mck_c_loop.py's dense model: a 10-mass chain with a consistent mass coupling."""
    rng = np.random.default_rng(0)
    n = 10
    M, C, K = dd.chain_matrices(rng.uniform(1, 2, n), rng.uniform(1e3, 2e3, n),
                                rng.uniform(0.1, 1, n), sparse=False)
    M[0, 3] = M[3, 0] = 0.2        # a consistent (non-diagonal) mass matrix
    return M, C, K, rng.standard_normal((3001, 2))


@pytest.fixture(scope="module")
def chain():
    """test_mck_sparse.py's sparse 200-mass chain."""
    rng = np.random.default_rng(1)
    n = 200
    M, C, K = dd.chain_matrices(rng.uniform(1, 2, n), rng.uniform(1e5, 2e5, n),
                                rng.uniform(0.1, 1, n), sparse=True)
    return M, C, K


def test_c_loop_stores_only_what_is_asked_and_runs_in_blocks(model, monkeypatch):
    M, C, K, f = model
    monkeypatch.setattr(stepping, "CHECK_BLOCK", 7)   # many calls, the history carried
    a = dd.mck_response(M, C, K, f, 1e-3, force_dofs=[3, 9], quantities=("v",), backend="numpy")
    b = dd.mck_response(M, C, K, f, 1e-3, force_dofs=[3, 9], quantities=("v",))
    assert b.x is None and b.a is None
    assert np.abs(b.v - a.v).max() <= 1e-12 * np.abs(a.v).max()
    with pytest.raises(ValueError, match="backend must be 'c' or 'numpy'"):
        dd.mck_response(M, C, K, f, 1e-3, force_dofs=[3, 9], backend="fortran")


def test_sparse_c_loop_in_blocks_stores_only_what_is_asked(chain, monkeypatch):
    M, C, K = chain
    f = np.random.default_rng(4).standard_normal(2001)
    monkeypatch.setattr(stepping, "CHECK_BLOCK", 7)  # many calls, the history carried
    kw = dict(force_dofs=[199], quantities=("v",), outputs=[5, 150], scheme="park")
    a = dd.mck_response(M, C, K, f, 1e-3, backend="numpy", **kw)
    b = dd.mck_response(M, C, K, f, 1e-3, **kw)
    assert b.x is None and b.a is None and b.v.shape == (2001, 2)
    assert np.abs(b.v - a.v).max() <= 1e-12 * np.abs(a.v).max()
