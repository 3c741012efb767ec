"""The kernels' C/Python contract comes from one spec (dtdyn.derive.c_api): the codes and work
rows are the same numbers in generated/c_api.h and generated/c_api.py, a change in the spec alone
changes both, and a kernel handed a work array shorter than its rows refuses at entry."""
import re
from importlib import resources

import numpy as np
import pytest

from dtdyn._engine import cbuild, kernels
from dtdyn._engine.kernels import DtdynKernelError
from dtdyn.generated import c_api as gen

HEADER = resources.files("dtdyn.generated").joinpath("c_api.h").read_text()
CSRC = resources.files("dtdyn._engine") / "csrc"


def defines(text):
    return {m[0]: int(m[1]) for m in re.findall(r"#define DTDYN_(\w+) \((-?\d+)\)", text)}


def test_header_and_bindings_carry_the_same_numbers():
    assert defines(HEADER) == gen.CONSTANTS
    assert kernels.WORK_ROWS == {"stable": gen.CHAIN_ROWS_STABLE, "plain": gen.CHAIN_ROWS_PLAIN}


def test_generated_files_agree_with_the_spec():
    c_api = pytest.importorskip("dtdyn.derive.c_api")
    assert gen.CONSTANTS == {n: v for n, (v, _) in c_api.CONSTANTS.items()}
    assert defines(HEADER) == gen.CONSTANTS
    c_api.check_layout()


def test_a_row_count_changed_in_the_spec_changes_both_sides(monkeypatch):
    pytest.importorskip("jinja2")
    pytest.importorskip("sympy")
    from dtdyn.derive import c_api, emit

    monkeypatch.setitem(c_api.CONSTANTS, "CHAIN_ROWS_PLAIN", (31, "rows of the plain sweep"))
    files = emit.render_contract()
    assert defines(files["c_api.h"])["CHAIN_ROWS_PLAIN"] == 31
    namespace = {}
    exec(files["c_api.py"], namespace)  # the module as the runtime would import it
    assert namespace["CHAIN_ROWS_PLAIN"] == 31 and namespace["CONSTANTS"]["CHAIN_ROWS_PLAIN"] == 31
    assert defines(files["c_api.h"]) == namespace["CONSTANTS"]


def test_layout_check_refuses_overlapping_rows(monkeypatch):
    pytest.importorskip("jinja2")
    from dtdyn.derive import c_api

    monkeypatch.setitem(c_api.CONSTANTS, "CHAIN_ROW_PLAIN", (19, "overlaps the last pair"))
    with pytest.raises(ValueError, match="CHAIN_ROW_PLAIN"):
        c_api.check_layout()
    monkeypatch.setitem(c_api.CONSTANTS, "CHAIN_ROW_PLAIN", (20, ""))
    with pytest.raises(ValueError, match="too small for 11"):
        c_api.check_layout(11)


def test_the_loops_read_offsets_from_the_contract():
    loop = CSRC.joinpath("chain_loop.h").read_text()
    assert "DTDYN_CHAIN_ROW_DEN * N" in loop and "DTDYN_CHAIN_ROW_PAIRS * N" in loop
    assert not re.search(r"work \+ 1[1-9] \* N", loop)
    chain = resources.files("dtdyn.generated").joinpath("chain_newmark.c").read_text()
    assert "work + (DTDYN_CHAIN_ROW_PLAIN + 0) * N" in chain
    assert "DTDYN_CHAIN_ROWS_STABLE * N" in CSRC.joinpath("nl_chain.h").read_text()


def _chain_call(fn, N, sweep, work, n_work):
    rng = np.random.default_rng(3)
    m, k, c = 1 + rng.random(N), 1e4 * (1 + rng.random(N)), rng.random(N)
    params = np.array([0.25, 0.5])
    loaded = np.array([N - 1], dtype=np.int64)
    force = np.ones((3, 1))
    hist = np.zeros((3, N))
    ehist = np.zeros((3, N, 2)) if sweep == gen.SWEEP_PLAIN else None
    err = np.zeros(3) if sweep == gen.SWEEP_PLAIN else None
    p = lambda a: None if a is None else a.ctypes.data  # noqa: E731
    rc = fn(gen.FORM_DISPLACEMENT, sweep, N, 2, m.ctypes.data, k.ctypes.data, c.ctypes.data,
            None, None, 1e-3, params.ctypes.data, 1, loaded.ctypes.data, force.ctypes.data,
            hist.ctypes.data, 0, None, None, None, None, work.ctypes.data, n_work, p(ehist),
            p(err), 1)
    return rc, hist


@pytest.mark.skipif(not cbuild.c_available(), reason="no C compiler on this machine")
@pytest.mark.parametrize("sweep, rows", [(gen.SWEEP_STABLE, gen.CHAIN_ROWS_STABLE),
                                         (gen.SWEEP_PLAIN, gen.CHAIN_ROWS_PLAIN)])
def test_chain_kernel_refuses_a_short_work_array_at_entry(sweep, rows):
    fn = kernels.c_chain_function("newmark")
    N = 7
    work = np.full(rows * N - 1, 7.0)
    rc, hist = _chain_call(fn, N, sweep, work, work.size)
    assert rc == gen.ERR_WORK
    assert not hist.any() and (work == 7.0).all()  # nothing written
    work = np.zeros(rows * N)
    rc, hist = _chain_call(fn, N, sweep, work, work.size)
    assert rc == gen.OK and hist.any()


@pytest.mark.skipif(not cbuild.c_available(), reason="no C compiler on this machine")
def test_python_side_names_the_refusal(monkeypatch):
    import dtdyn

    monkeypatch.setitem(kernels.WORK_ROWS, "stable", gen.CHAIN_ROWS_STABLE - 1)  # a drifted side
    with pytest.raises(DtdynKernelError, match="work array is too short") as info:
        dtdyn.chain_response(np.ones(5), 1e4 * np.ones(5), np.zeros(5), np.ones(4), 1e-3,
                             force_dofs=[4])
    assert info.value.code == gen.ERR_WORK and info.value.kernel == "dtdyn_chain_newmark"


@pytest.mark.skipif(not cbuild.c_available(), reason="no C compiler on this machine")
def test_shaft_kernel_refuses_a_short_work_array_at_entry():
    fn = kernels.c_scheme_function("shaft", "newmark")
    N = 4
    work = np.full(gen.SHAFT_ROWS * N - 1, 7.0)
    parent = np.array([-1, 0, 1, 2], dtype=np.int64)
    ones, hist = np.ones(N), np.zeros((3, N))
    loaded = np.array([3], dtype=np.int64)
    force, params = np.ones((3, 1)), np.array([0.25, 0.5])
    rc = fn(gen.FORM_DISPLACEMENT, gen.SWEEP_STABLE, N, 2, parent.ctypes.data, ones.ctypes.data,
            ones.ctypes.data, ones.ctypes.data, ones.ctypes.data, ones.ctypes.data,
            ones.ctypes.data, None, None,
            1e-3, params.ctypes.data, 1, loaded.ctypes.data, force.ctypes.data,
            hist.ctypes.data, 0, None, None, None, None, work.ctypes.data, work.size)
    assert rc == gen.ERR_WORK and not hist.any() and (work == 7.0).all()
