"""Every C entry point with scratch memory receives its size and refuses a short one at entry
(DTDYN_ERR_WORK, DtdynKernelError in Python): the mck loop, the block chain (beams), the modal
filters, the nonlinear loop (general and modal path), the nonlinear chain and the nonlinear beam
and shaft loop. The sizes come from the one spec (dtdyn.derive.c_api): the row counts as constants
of both generated/c_api.h and generated/c_api.py, or, where the size is a formula of the problem's
sizes (the modal filters, the nonlinear loops), a size function the kernel's own source defines and
the runtime calls. Each refusal test gives the runtime's side a size one short (a drifted side) and
expects the error, so a kernel that wrote past its buffer instead would fail it. (The chain and
shaft kernels: test_c_contract.py.)"""
import re
from importlib import resources

import numpy as np
import pytest

import dtdyn
from dtdyn._engine import cbuild
from dtdyn._engine.kernels import DtdynKernelError
from dtdyn.generated import c_api as gen

HEADER = resources.files("dtdyn.generated").joinpath("c_api.h").read_text()
CSRC = resources.files("dtdyn._engine") / "csrc"
needs_c = pytest.mark.skipif(not cbuild.c_available(), reason="no C compiler on this machine")


def defines(text):
    return {m[0]: int(m[1]) for m in re.findall(r"#define DTDYN_(\w+) \((-?\d+)\)", text)}


def test_every_work_array_comes_with_its_size():
    """In the spec, each kernel's work (iwork) pointer is followed by n_work (n_iwork), and the
    ctypes bindings pass it as a C long."""
    c_api = pytest.importorskip("dtdyn.derive.c_api")
    checked = 0
    for kernel, (_, params) in c_api.KERNELS.items():
        names = [re.findall(r"\w+", p)[-1] for p in params]
        for arr, size in (("work", "n_work"), ("iwork", "n_iwork")):
            if arr in names and kernel != "nl_residual":  # CasADi's own convention
                i = names.index(arr)
                assert names[i + 1:i + 2] == [size], (kernel, names)
                assert gen.SIGNATURES[kernel][1][i + 1] == "c_long", kernel
                checked += 1
    assert checked >= 9  # chain, shaft, mck, block chain, modal filters, nl_run x2, nl_chain x2


@pytest.mark.parametrize("name, value", [("MCK_ROWS", 9), ("BLOCK_CHAIN_GAP", 16),
                                         ("BLOCK_CHAIN_ROWS", 3), ("MODAL_BLOCK", 128)])
def test_a_count_changed_in_the_spec_changes_both_sides(monkeypatch, name, value):
    pytest.importorskip("jinja2")
    pytest.importorskip("sympy")
    from dtdyn.derive import c_api, emit

    monkeypatch.setitem(c_api.CONSTANTS, name, (value, c_api.CONSTANTS[name][1]))
    files = emit.render_contract()
    namespace = {}
    exec(files["c_api.py"], namespace)  # the module as the runtime would import it
    assert defines(files["c_api.h"])[name] == value == namespace[name]
    assert defines(files["c_api.h"]) == namespace["CONSTANTS"]


def test_mck_layout_check_refuses_overlapping_rows(monkeypatch):
    pytest.importorskip("jinja2")
    from dtdyn.derive import c_api

    c_api.check_layout()
    monkeypatch.setitem(c_api.CONSTANTS, "MCK_ROW_B", (6, "overlaps z"))
    with pytest.raises(ValueError, match="MCK_ROW_B"):
        c_api.check_layout()
    monkeypatch.setitem(c_api.CONSTANTS, "MCK_ROW_B", (7, ""))
    monkeypatch.setitem(c_api.CONSTANTS, "BLOCK_CHAIN_GAP", (4, "misaligned"))
    with pytest.raises(ValueError, match="BLOCK_CHAIN_GAP"):
        c_api.check_layout()


def test_the_loops_read_their_rows_from_the_contract():
    mck = CSRC.joinpath("mck_loop.h").read_text()
    assert "n_work < DTDYN_MCK_ROWS * n" in mck and not re.search(r"work \+ \d \* n", mck)
    block = CSRC.joinpath("block_chain.h").read_text()
    assert "DTDYN_BLOCK_CHAIN_ROWS * (P + DTDYN_BLOCK_CHAIN_GAP)" in block
    assert "work + 8" not in block and "P + 16" not in block
    assert "#define MODAL_BLOCK DTDYN_MODAL_BLOCK" in CSRC.joinpath("modal_filters.h").read_text()
    assert {"MCK_ROWS", "BLOCK_CHAIN_ROWS", "BLOCK_CHAIN_GAP", "MODAL_BLOCK"} <= set(
        defines(HEADER))


def test_modal_filters_template_holds_no_loop():
    """The hand-written bank lives in csrc (modal_bank.h, modal_filters.h); the generated source
    is the derived increments' comment, two includes and the entry point."""
    text = resources.files("dtdyn.generated").joinpath("modal_states.c").read_text()
    assert "for (" not in text.split("/* modal_filters_run with")[0]
    assert '#include "modal_filters.h"' in text
    bank = CSRC.joinpath("modal_bank.h").read_text()
    assert "{{" not in bank and "{%" not in bank and "MODAL_LANES" in bank


# -- the refusals, one per entry point -------------------------------------------------------

def _chain(N=7):
    rng = np.random.default_rng(5)
    m, k, c = 1 + rng.random(N), 1e4 * (1 + rng.random(N)), 0.5 + rng.random(N)
    return m, k, c, rng.standard_normal((21, 2))


@needs_c
def test_mck_loop_refuses_a_short_work_array(monkeypatch):
    m, k, c, f = _chain()
    M, C, K = dtdyn.chain_matrices(m, k, c)
    ok = dtdyn.mck_response(M, C, K, f, 1e-3, force_dofs=[0, 6], backend="c")
    assert np.isfinite(ok.x).all() and np.abs(ok.x).max() > 0
    monkeypatch.setattr(gen, "MCK_ROWS", gen.MCK_ROWS - 1)  # the Python side one row short
    with pytest.raises(DtdynKernelError, match="work array is too short") as info:
        dtdyn.mck_response(M, C, K, f, 1e-3, force_dofs=[0, 6], backend="c")
    assert info.value.code == gen.ERR_WORK and info.value.kernel == "dtdyn_mck_loop"


@needs_c
def test_block_chain_loop_refuses_a_short_work_array(monkeypatch):
    beam = dtdyn.Beam(E=2e11, I=1e-8, rho_A=1.0, length=1.0, elements=5)
    f = np.sin(np.arange(21.0))
    ok = dtdyn.beam_response(beam, f, 1e-4, force_dofs=[7], backend="c")
    assert np.isfinite(ok.x).all() and np.abs(ok.x).max() > 0
    monkeypatch.setattr(gen, "BLOCK_CHAIN_GAP", gen.BLOCK_CHAIN_GAP - 1)
    with pytest.raises(DtdynKernelError, match="work array is too short") as info:
        dtdyn.beam_response(beam, f, 1e-4, force_dofs=[7], backend="c")
    assert info.value.code == gen.ERR_WORK and info.value.kernel == "dtdyn_block_chain_loop"


def _modal_args(m, n_out, n=300):
    rng = np.random.default_rng(2)
    coef = np.concatenate([-1e-3 * rng.random(m), 0.05 * rng.standard_normal(m),
                           rng.standard_normal(4 * m)])
    return coef, rng.standard_normal((n_out, 2 * m)), rng.standard_normal((n + 1, 1))


@needs_c
@pytest.mark.parametrize("m, n_out", [(4, 1), (8, 3), (16, 15)])  # each chunk size, both outputs
def test_modal_filters_kernel_refuses_a_short_work_array_at_entry(m, n_out):
    from dtdyn.modal._filters import _c_modes

    fn, _, work_size, _ = _c_modes()
    assert work_size(m, n_out) == 2 * m * (gen.MODAL_BLOCK + n_out)  # the spec's block
    coef, wt, x = _modal_args(m, n_out)
    n = x.shape[0] - 1
    for short in (True, False):
        work = np.full(work_size(m, n_out) - short, 7.0)
        e, y = np.zeros(2 * m), np.zeros((n, n_out))
        rc = fn(n, m, 1, n_out, 0, coef.ctypes.data, wt.ctypes.data, x.ctypes.data,
                e.ctypes.data, y.ctypes.data, work.ctypes.data, work.size)
        if short:
            assert rc == gen.ERR_WORK and not y.any() and (work == 7.0).all()  # nothing written
        else:
            assert rc == gen.OK and y.any()


@needs_c
def test_modal_filter_response_names_the_refusal(monkeypatch):
    from dtdyn.modal import _filters as filters

    fn, lanes, work_size, lib = filters._c_modes()
    monkeypatch.setattr(filters, "_c_modes",
                        lambda: (fn, lanes, lambda m, n_out: work_size(m, n_out) - 1, lib))
    m, k, c, f = _chain()
    M, C, K = dtdyn.chain_matrices(m, k, c, sparse=False)
    with pytest.raises(DtdynKernelError, match="work array is too short") as info:
        dtdyn.modal_filter_response(M, C, K, f, 1e-3, force_dofs=[0, 6], algorithm="modes")
    assert info.value.code == gen.ERR_WORK and info.value.kernel == "dtdyn_modal_filters"


class _Shrunk:
    """A loaded library whose work-size function answers one double short (a drifted caller)."""

    def __init__(self, lib, name):
        self._lib, self._name = lib, name

    def __getattr__(self, attr):
        fn = getattr(self._lib, attr)
        if attr != self._name:
            return fn

        def short(*args):
            return fn(*args) - 1
        return short


@pytest.fixture
def shrunk(monkeypatch):
    """Libraries loaded during the test answer their size function ``name`` one short."""
    pytest.importorskip("casadi")
    if not cbuild.c_available():
        pytest.skip("no C compiler on this machine")
    from dtdyn.nonlinear import _chain as chain, _response as response, _stations as stations

    def install(name):
        load = cbuild.load_library
        monkeypatch.setattr(cbuild, "load_library",
                            lambda *a, **k: _Shrunk(load(*a, **k), name))
        response._c_runner.cache_clear()
        chain._c_driver.cache_clear()
        stations._c_driver.cache_clear()
    yield install
    response._c_runner.cache_clear()  # no shrunk library outlives the test
    chain._c_driver.cache_clear()
    stations._c_driver.cache_clear()


@pytest.mark.parametrize("scheme", ["modal_quintic", "modal_explicit"])
def test_nl_run_refuses_a_short_work_array(shrunk, scheme):
    """The modal path with its embedded estimate, whose block follows CasADi's work. (The
    general path needs CasADi's work alone, which the generated element laws report as 0
    doubles: nothing there to cut short; its check is the same line of nl_loop_run.)"""
    m, k, c, f = _chain()
    M, C, K = dtdyn.chain_matrices(m, k, c)
    kw = dict(force_dofs=[0, 6], elements=[dtdyn.Cubic(0, k3=1e8)], scheme=scheme)
    ok = dtdyn.nonlinear_mck_response(M, C, K, 50 * f, 1e-3, **kw)
    assert np.isfinite(ok.x).all()
    shrunk("dtdyn_nl_work")
    with pytest.raises(DtdynKernelError, match="work array is too short") as info:
        dtdyn.nonlinear_mck_response(M, C, K, 50 * f, 1e-3, **kw)
    assert info.value.code == gen.ERR_WORK and info.value.kernel == "dtdyn_nl_run"


def test_nl_chain_refuses_a_short_work_array(shrunk):
    m, k, c, f = _chain()
    kw = dict(force_dofs=[0, 6], elements=[dtdyn.Cubic(0, k3=1e8)])
    ok = dtdyn.nonlinear_chain_response(m, k, c, 50 * f, 1e-3, **kw)
    assert np.isfinite(ok.x).all()
    shrunk("dtdyn_nl_chain_work")
    with pytest.raises(DtdynKernelError, match="work array is too short") as info:
        dtdyn.nonlinear_chain_response(m, k, c, 50 * f, 1e-3, **kw)
    assert info.value.code == gen.ERR_WORK and info.value.kernel == "dtdyn_nl_chain"


@pytest.mark.parametrize("model", ["beam", "shaft"])
def test_nl_stations_refuses_a_short_work_array(shrunk, model):
    """The nonlinear beam and shaft loop (nl_stations.h): its work holds the step kernel's rows
    (block chain or tree sweep), the loop's scratch and CasADi's work."""
    el = dtdyn.Cubic(1, k3=1e8)
    if model == "beam":
        beam = dtdyn.Beam(E=2e11, I=1e-8, rho_A=1.0, length=1.0, elements=4)
        run = lambda: dtdyn.nonlinear_beam_response(  # noqa: E731
            beam, np.ones(21), 1e-4, force_dofs=[7], elements=[el])
    else:
        shaft = dtdyn.Shaft(np.ones(5), 1e4 * np.ones(5), 0.1 * np.ones(5))
        run = lambda: dtdyn.nonlinear_shaft_response(  # noqa: E731
            shaft, np.ones(21), 1e-3, force_dofs=[4], elements=[el])
    ok = run()
    assert np.isfinite(ok.x).all() and ok.info["loop"] == "c"
    shrunk("dtdyn_nl_stations_work")
    with pytest.raises(DtdynKernelError, match="work array is too short") as info:
        run()
    assert info.value.code == gen.ERR_WORK and info.value.kernel == "dtdyn_nl_stations"
