"""Scenes with general M, C, K: inline, .npz and Matrix Market matrices, Rayleigh and modal
damping, named DOFs, errors, the CLI and the two_story example."""
from __future__ import annotations

import importlib.resources
import textwrap
from pathlib import Path

import numpy as np
import pytest
import scipy.io
import scipy.linalg
import scipy.sparse as sps
from numpy.testing import assert_allclose, assert_array_equal

from dtdyn.app._cli import main
from dtdyn.linear import mck_response
from dtdyn.app._scene import load_scene, plot_response, run_scene, save_results

M2 = np.array([[2.0, 0.5], [0.5, 1.0]])          # consistent-mass-like: not diagonal
K2 = np.array([[30.0, -10.0], [-10.0, 10.0]])
C2 = np.array([[0.4, -0.1], [-0.1, 0.1]])

SCHEME = '[scheme]\nname = "newmark"\nbeta = 0.3\ngamma = 0.6\n'
TIME = "[time]\ndt = 0.02\nduration = 1.0\n"      # 50 steps
LOAD = '[[load]]\ndof = 1\nkind = "step"\n'


def toml_matrix(A) -> str:
    return "[" + ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]" for row in A) + "]"


def inline_model(M=M2, K=K2, C=C2, extra="") -> str:
    text = f'[model]\nkind = "matrices"\nM = {toml_matrix(M)}\nK = {toml_matrix(K)}\n'
    if C is not None:
        text += f"C = {toml_matrix(C)}\n"
    return text + extra


def write_scene(tmp_path: Path, model: str, *, loads=LOAD, scheme=SCHEME, time=TIME, extra="",
                name="scene.toml") -> Path:
    path = tmp_path / name
    # model last but one: its sub-tables ([model.damping]) must not swallow later keys
    path.write_text(textwrap.dedent(f'title = "m"\n{loads}\n{scheme}\n{time}\n{extra}\n{model}'))
    return path


# ---------------------------------------------------------------------------------------------
# matrices from the scene, an .npz or Matrix Market files

def test_inline_scene_equals_simulate_mck(tmp_path):
    s = load_scene(write_scene(tmp_path, inline_model(),
                               extra='[output]\nquantities = ["x", "v", "a"]\n'))
    assert s.kind == "matrices" and s.n_dof == 2 and not s.sparse
    assert s.dof_names == ("0", "1")
    assert s.mass is None and s.form == "acceleration" and s.sweep is None
    assert s.backend == "c"
    assert_array_equal(s.M, M2)
    assert_array_equal(s.K, K2)
    assert_array_equal(s.C, C2)
    response, report = run_scene(s)
    ref = mck_response(M2, C2, K2, np.ones((51, 1)), 0.02, force_dofs=[1], scheme="newmark",
                       beta=0.3, gamma=0.6)
    for q in "xva":
        assert_array_equal(getattr(response, q), getattr(ref, q))
    assert report["scheme"] == "newmark" and report["scheme_params"] == {"beta": 0.3, "gamma": 0.6}
    assert report["n_dof"] == 2 and report["n_outputs"] == 2 and report["backend"] == "c"
    assert report["max_rel_error"] is not None and report["max_rel_error"] < 5e-2
    assert set(report) == {"title", "scheme", "scheme_params", "form", "sweep", "backend", "dt",
                           "n_steps", "n_dof", "n_outputs", "run_time_s", "exact_time_s",
                           "max_rel_error", "check"}
    assert report["check"] == "done"


def test_c_is_optional(tmp_path):
    s = load_scene(write_scene(tmp_path, inline_model(C=None)))
    assert_array_equal(s.C, np.zeros((2, 2)))


def test_npz_file_equals_inline(tmp_path):
    np.savez(tmp_path / "model.npz", M=M2, K=K2, C=C2)
    s = load_scene(write_scene(tmp_path, '[model]\nkind = "matrices"\nfile = "model.npz"\n'))
    inline = load_scene(write_scene(tmp_path, inline_model(), name="inline.toml"))
    for key in "MCK":
        assert_array_equal(getattr(s, key), getattr(inline, key))
    assert_array_equal(run_scene(s)[0].x, run_scene(inline)[0].x)
    # C optional in the file too
    np.savez(tmp_path / "mk.npz", M=M2, K=K2)
    s = load_scene(write_scene(tmp_path, '[model]\nkind = "matrices"\nfile = "mk.npz"\n'))
    assert_array_equal(s.C, 0.0)


def test_matrix_market_files_give_sparse_scene(tmp_path):
    (tmp_path / "mats").mkdir()
    for name, A in (("m", M2), ("k", K2), ("c", C2)):
        scipy.io.mmwrite(tmp_path / "mats" / f"{name}.mtx", sps.coo_matrix(A))
    model = ('[model]\nkind = "matrices"\nM = "mats/m.mtx"\nK = "mats/k.mtx"\n'
             'C = "mats/c.mtx"\n')
    s = load_scene(write_scene(tmp_path, model))
    assert s.sparse and s.backend == "c"
    assert all(sps.isspmatrix_csr(A) for A in (s.M, s.C, s.K))
    assert_allclose(s.M.toarray(), M2, rtol=1e-15)
    assert_allclose(s.K.toarray(), K2, rtol=1e-15)
    response, report = run_scene(s)
    assert report["backend"] == "c" and report["max_rel_error"] is not None
    dense = run_scene(load_scene(write_scene(tmp_path, inline_model(), name="d.toml")))[0]
    assert_allclose(response.x, dense.x, rtol=1e-12, atol=1e-15)

    # sparse = false turns files into dense arrays; sparse = true turns inline ones sparse
    s = load_scene(write_scene(tmp_path, model + "sparse = false\n"))
    assert not s.sparse and all(isinstance(A, np.ndarray) for A in (s.M, s.C, s.K))
    s = load_scene(write_scene(tmp_path, inline_model(extra="sparse = true\n")))
    assert s.sparse and all(sps.isspmatrix_csr(A) for A in (s.M, s.C, s.K))
    # a mix of inline (dense) and .mtx (sparse) is held sparse
    s = load_scene(write_scene(tmp_path, f'[model]\nkind = "matrices"\nM = {toml_matrix(M2)}\n'
                                         'K = "mats/k.mtx"\n'))
    assert s.sparse and sps.isspmatrix_csr(s.C) and s.C.nnz == 0


@pytest.mark.parametrize("scheme", ["central_difference", "houbolt", "generalized_alpha", "wilson"])
def test_any_scheme_dense_and_sparse_agree(tmp_path, scheme):
    time = "[time]\ndt = 0.01\nduration = 0.5\n"
    dense = load_scene(write_scene(tmp_path, inline_model(),
                                   scheme=f'[scheme]\nname = "{scheme}"\n', time=time,
                                   name="d.toml"))
    sparse = load_scene(write_scene(tmp_path, inline_model(extra="sparse = true\n"),
                                    scheme=f'[scheme]\nname = "{scheme}"\n', time=time))
    rd, rep_d = run_scene(dense)
    rs, rep_s = run_scene(sparse)
    assert_allclose(rs.x, rd.x, rtol=1e-12, atol=1e-14 * np.max(np.abs(rd.x)))
    assert rep_d["max_rel_error"] < 5e-2 and rep_s["max_rel_error"] < 5e-2


# ---------------------------------------------------------------------------------------------
# damping options

def test_rayleigh_damping_adds_alpha_m_plus_beta_k(tmp_path):
    s = load_scene(write_scene(tmp_path, inline_model(
        extra="[model.damping]\nrayleigh = [0.3, 0.02]\n")))
    assert_allclose(s.C, C2 + 0.3 * M2 + 0.02 * K2, rtol=1e-15)
    s = load_scene(write_scene(tmp_path, inline_model(
        C=None, extra="sparse = true\n[model.damping]\nrayleigh = [0.3, 0.02]\n")))
    assert sps.isspmatrix_csr(s.C)
    assert_allclose(s.C.toarray(), 0.3 * M2 + 0.02 * K2, rtol=1e-15)


def _modes(M, K):
    lam, phi = scipy.linalg.eigh(K, M)
    return np.sqrt(lam), phi


M3 = np.array([[4.0, 1.0, 0.0], [1.0, 4.0, 1.0], [0.0, 1.0, 2.0]])
K3 = np.array([[200.0, -100.0, 0.0], [-100.0, 180.0, -80.0], [0.0, -80.0, 80.0]])


@pytest.mark.parametrize("zeta", [[0.05], [0.02, 0.03, 0.1]])
@pytest.mark.parametrize("sparse", [False, True])
def test_modal_damping_gives_each_mode_its_ratio(tmp_path, zeta, sparse):
    extra = f"sparse = {str(sparse).lower()}\n[model.damping]\nmodal = {zeta}\n"
    s = load_scene(write_scene(tmp_path, inline_model(M=M3, K=K3, C=None, extra=extra)))
    C = s.C.toarray() if sparse else s.C
    omega, phi = _modes(M3, K3)
    z = np.broadcast_to(np.array(zeta), omega.shape)
    assert_allclose(phi.T @ C @ phi, np.diag(2.0 * z * omega), atol=1e-12 * omega.max())
    assert_allclose(C, C.T, atol=1e-13 * omega.max())
    # the damped free vibration decays with the modal ratio: check via the exact response
    response, report = run_scene(s)
    assert report["max_rel_error"] < 5e-2


def test_modal_damping_adds_to_c(tmp_path):
    C0 = np.diag([0.1, 0.2, 0.3])
    s = load_scene(write_scene(tmp_path, inline_model(M=M3, K=K3, C=C0,
                                                      extra="[model.damping]\nmodal = [0.0]\n")))
    assert_allclose(s.C, C0, atol=1e-15)


# ---------------------------------------------------------------------------------------------
# named DOFs

def test_named_dofs_in_loads_and_outputs(tmp_path):
    loads = ('[[load]]\ndof = "roof"\nkind = "step"\n'
             '[[load]]\ndof = 1\nkind = "ramp"\nslope = 2.0\n'
             '[[load]]\ndof = "floor"\nkind = "step"\namplitude = 0.5\n')
    model = inline_model(extra='dofs = ["floor", "roof"]\n')
    s = load_scene(write_scene(tmp_path, model, loads=loads,
                               extra='[output]\noutputs = ["roof", 0]\nquantities = ["x", "v"]\n'))
    assert s.dof_names == ("floor", "roof")
    assert_array_equal(s.loaded, [0, 1])
    assert_array_equal(s.force[:, 0], 0.5)
    assert_allclose(s.force[:, 1], 1.0 + 2.0 * s.t)
    assert_array_equal(s.outputs, [1, 0])
    response, _ = run_scene(s)
    ref = mck_response(M2, C2, K2, s.force, 0.02, force_dofs=[0, 1], scheme="newmark",
                       outputs=[1, 0], beta=0.3, gamma=0.6)
    assert_array_equal(response.x, ref.x)
    assert_array_equal(response.v, ref.v)

    out = tmp_path / "r.npz"
    save_results(out, response, s)
    with np.load(out) as z:
        assert sorted(z.files) == ["dof_names", "dtdyn_metadata", "outputs", "t", "v", "x"]
        assert z["dof_names"].tolist() == ["roof", "floor"]
        assert_array_equal(z["x"], response.x)
    plot = tmp_path / "r.png"
    plot_response(plot, response, s)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_default_dof_names_are_indices_as_strings(tmp_path):
    s = load_scene(write_scene(tmp_path, inline_model(),
                               loads='[[load]]\ndof = "1"\nkind = "step"\n'))
    assert_array_equal(s.loaded, [1])


def test_chain_scene_with_explicit_kind_and_no_names(tmp_path):
    model = '[model]\nkind = "chain"\nmass = [1.0, 2.0]\nstiffness = [10.0, 20.0]\n'
    s = load_scene(write_scene(tmp_path, model))
    assert s.kind == "chain" and s.n_dof == 2 and s.M is None and s.dof_names is None
    assert (s.form, s.sweep, s.backend) == (None, "stable", "c")  # form: the scheme's own
    with pytest.raises(ValueError, match=r"load\[0\]\.dof = 'roof': must be an integer mass index"):
        load_scene(write_scene(tmp_path, model, loads='[[load]]\ndof = "roof"\nkind = "step"\n'))


# ---------------------------------------------------------------------------------------------
# errors name the field and the value

NAN_M = "[model]\nkind = \"matrices\"\nM = [[1.0, 0.0], [0.0, nan]]\nK = [[1.0, 0.0], [0.0, 1.0]]\n"
BAD = {
    "unknown kind": ('[model]\nkind = "plate"\n', r"model\.kind = 'plate': unknown value, "
                                                  r"allowed: 'chain', 'matrices', 'shaft', 'beam'"),
    "chain key in matrices": (inline_model(extra="mass = [1.0, 1.0]\n"),
                              r"model\.mass = \[1\.0, 1\.0\]: unknown key, allowed: kind, M, K"),
    "missing K": ('[model]\nkind = "matrices"\nM = [[1.0]]\n', r"model\.K is required"),
    "non-square": (inline_model(M=[[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]),
                   r"model\.M has shape \(3, 2\): must be a non-empty square matrix"),
    "ragged rows": ('[model]\nkind = "matrices"\nM = [[1.0, 0.0], [1.0]]\nK = [[1.0]]\n',
                    r"model\.M\[1\] has 1 entries, row 0 has 2"),
    "flat array": ('[model]\nkind = "matrices"\nM = [1.0, 2.0]\nK = [[1.0]]\n',
                   r"model\.M\[0\] = 1\.0: every row must be an array"),
    "mismatched shape": (inline_model(K=np.eye(3)),
                         r"model\.K has shape \(3, 3\), expected \(2, 2\) to match model\.M"),
    "non-finite entry": (NAN_M, r"model\.M\[1\]\[1\] = nan: must be finite"),
    "string entry": ('[model]\nkind = "matrices"\nM = [[1.0, "x"], [0.0, 1.0]]\nK = [[1.0]]\n',
                     r"model\.M\[0\]\[1\] = 'x': must be a number"),
    "wrong dof name count": (inline_model(extra='dofs = ["a"]\n'),
                             r"model\.dofs has 1 names, expected 2"),
    "repeated dof name": (inline_model(extra='dofs = ["a", "a"]\n'),
                          r"model\.dofs\[1\] = 'a': repeats a DOF name"),
    "dof name not a string": (inline_model(extra='dofs = ["a", 2]\n'), r"model\.dofs\[1\] = 2"),
    "sparse not a bool": (inline_model(extra='sparse = "yes"\n'), r"model\.sparse = 'yes'"),
    "both rayleigh and modal": (inline_model(extra="[model.damping]\nrayleigh = [0.1, 0.0]\n"
                                                   "modal = [0.02]\n"),
                                r"model\.damping\.rayleigh = \[0\.1, 0\.0\] and "
                                r"model\.damping\.modal = \[0\.02\] are both given"),
    "rayleigh length": (inline_model(extra="[model.damping]\nrayleigh = [0.1]\n"),
                        r"model\.damping\.rayleigh = \[0\.1\]: must be \[alpha, beta\]"),
    "negative rayleigh": (inline_model(extra="[model.damping]\nrayleigh = [0.1, -1.0]\n"),
                          r"model\.damping\.rayleigh\[1\] = -1\.0"),
    "modal length": (inline_model(extra="[model.damping]\nmodal = [0.1, 0.2, 0.3]\n"),
                     r"model\.damping\.modal = \[0\.1, 0\.2, 0\.3\]: has 3 ratios, "
                     r"give one .* or 2"),
    "unknown damping key": (inline_model(extra="[model.damping]\nstiffness_proportional = 0.1\n"),
                            r"model\.damping\.stiffness_proportional = 0\.1: unknown key"),
    "modal with indefinite M": (inline_model(M=[[1.0, 0.0], [0.0, -1.0]],
                                             extra="[model.damping]\nmodal = [0.02]\n"),
                                r"model\.damping\.modal needs a symmetric positive definite "
                                r"model\.M; "
                                r"M is not positive definite"),
    "modal with unsymmetric M": (inline_model(M=[[1.0, 0.5], [0.0, 1.0]],
                                              extra="[model.damping]\nmodal = [0.02]\n"),
                                 r"model\.M; M is not symmetric"),
    "modal with unsymmetric K": (inline_model(K=[[2.0, -1.0], [0.0, 1.0]],
                                              extra="[model.damping]\nmodal = [0.02]\n"),
                                 r"model\.damping\.modal needs a symmetric model\.K"),
    "missing npz": ('[model]\nkind = "matrices"\nfile = "absent.npz"\n',
                    r"model\.file = 'absent\.npz': no such file"),
    "npz suffix": ('[model]\nkind = "matrices"\nfile = "m.mtx"\n',
                   r"model\.file = 'm\.mtx': unsupported file type, allowed: '\.npz'"),
    "missing mtx": ('[model]\nkind = "matrices"\nM = "absent.mtx"\nK = [[1.0]]\n',
                    r"model\.M = 'absent\.mtx': no such file"),
    "file and inline": ('[model]\nkind = "matrices"\nfile = "m.npz"\nM = [[1.0]]\n',
                        r"model\.file = 'm\.npz' and model\.M are both given"),
    "unknown load dof name": (inline_model(extra='dofs = ["floor", "roof"]\n'),
                              r"load\[0\]\.dof = 'attic': unknown DOF name, model\.dofs has "
                              r"'floor', 'roof'", '[[load]]\ndof = "attic"\nkind = "step"\n'),
    "load dof index out of range": (inline_model(),
                                    r"load\[0\]\.dof = 2: must be a DOF index in 0\.\.1 "
                                    r"or a DOF name", '[[load]]\ndof = 2\nkind = "step"\n'),
    "unknown output dof name": (inline_model(extra='dofs = ["floor", "roof"]\n'),
                                r"output\.outputs\[1\] = 'cellar': unknown DOF name"),
    "repeated output dof": (inline_model(extra='dofs = ["floor", "roof"]\n'),
                            r"output\.outputs = \['roof', 1\]: entry 1 \(1\) repeats DOF 1 "
                            r"\('roof'\)"),
    "chain-only form": (inline_model(), r"scheme\.form = 'displacement': only for chain models",
                        None, '[scheme]\nname = "newmark"\nform = "displacement"\n'),
    "chain-only sweep": (inline_model(), r"scheme\.sweep = 'plain': only for chain models",
                         None, '[scheme]\nname = "newmark"\nsweep = "plain"\n'),
    "chain-only backend": (inline_model(), r"scheme\.backend = 'c': only for chain models",
                           None, '[scheme]\nname = "houbolt"\nbackend = "c"\n'),
}
OUTPUTS = {"unknown output dof name": '[output]\noutputs = ["roof", "cellar"]\n',
           "repeated output dof": '[output]\noutputs = ["roof", 1]\n'}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_matrix_scene_names_the_field(tmp_path, case):
    model, pattern, *rest = BAD[case]
    loads = rest[0] if rest and rest[0] else LOAD
    scheme = rest[1] if len(rest) > 1 else SCHEME
    path = write_scene(tmp_path, model, loads=loads, scheme=scheme, extra=OUTPUTS.get(case, ""))
    with pytest.raises(ValueError, match=pattern) as info:
        load_scene(path)
    assert str(path) in str(info.value)


def test_bad_matrix_files(tmp_path):
    model = '[model]\nkind = "matrices"\nfile = "m.npz"\n'
    np.savez(tmp_path / "m.npz", M=M2)
    with pytest.raises(ValueError, match=r"model\.file = 'm\.npz': has no array 'K' \(found: M\)"):
        load_scene(write_scene(tmp_path, model))
    np.savez(tmp_path / "m.npz", M=M2, K=K2, k=K2)
    with pytest.raises(ValueError, match=r"model\.file = 'm\.npz': unexpected array\(s\) k"):
        load_scene(write_scene(tmp_path, model))
    bad = K2.copy()
    bad[0, 1] = np.inf
    np.savez(tmp_path / "m.npz", M=M2, K=bad)
    with pytest.raises(ValueError, match=r"model\.file = 'm\.npz': array K\[0, 1\] = inf: every "
                                         r"entry must be finite"):
        load_scene(write_scene(tmp_path, model))
    np.savez(tmp_path / "m.npz", M=np.ones((2, 3)), K=K2)
    with pytest.raises(ValueError, match=r"array M has shape \(2, 3\): must be a non-empty square"):
        load_scene(write_scene(tmp_path, model))
    (tmp_path / "m.npz").write_bytes(b"not an npz file")
    with pytest.raises(ValueError, match=r"model\.file = 'm\.npz': cannot read"):
        load_scene(write_scene(tmp_path, model))

    # Matrix Market: non-finite entry, mismatched shape, unparsable file
    mtx = '[model]\nkind = "matrices"\nM = "m.mtx"\nK = "k.mtx"\n'
    scipy.io.mmwrite(tmp_path / "m.mtx", sps.coo_matrix(M2))
    scipy.io.mmwrite(tmp_path / "k.mtx", sps.coo_matrix(np.eye(3)))
    with pytest.raises(ValueError, match=r"model\.K = 'k\.mtx': matrix has shape \(3, 3\), "
                                         r"expected \(2, 2\)"):
        load_scene(write_scene(tmp_path, mtx))
    scipy.io.mmwrite(tmp_path / "k.mtx", sps.coo_matrix(np.array([[1.0, np.nan], [0.0, 1.0]])))
    with pytest.raises(ValueError, match=r"model\.K = 'k\.mtx': matrix\[0, 1\] = nan"):
        load_scene(write_scene(tmp_path, mtx))
    (tmp_path / "k.mtx").write_text("garbage\n")
    with pytest.raises(ValueError, match=r"model\.K = 'k\.mtx': cannot read .* as Matrix Market"):
        load_scene(write_scene(tmp_path, mtx))


# ---------------------------------------------------------------------------------------------
# the command line and the example scene

def test_cli_runs_a_matrices_scene(tmp_path, capsys):
    path = write_scene(tmp_path, inline_model(extra='dofs = ["floor", "roof"]\n'),
                       loads='[[load]]\ndof = "roof"\nkind = "step"\n')
    out, plot = tmp_path / "r.npz", tmp_path / "r.png"
    assert main(["simulate", str(path), "--out", str(out), "--plot", str(plot)]) == 0
    text = capsys.readouterr().out
    assert "2 DOF" in text and "assembled dense M, C, K" in text
    assert "run time" in text and "error against the exact response" in text
    with np.load(out) as z:
        assert z["x"].shape == (51, 2)
        assert z["dof_names"].tolist() == ["floor", "roof"]
    assert plot.stat().st_size > 1000


def test_cli_reports_a_bad_matrices_scene(tmp_path, capsys):
    path = write_scene(tmp_path, inline_model(extra="[model.damping]\nrayleigh = [0.1, 0.0]\n"
                                                    "modal = [0.02]\n"))
    out = tmp_path / "r.npz"
    assert main(["simulate", str(path), "--out", str(out)]) == 2
    assert "model.damping.rayleigh" in capsys.readouterr().err
    assert not out.exists()


def test_two_story_example(tmp_path, capsys):
    path = importlib.resources.files("dtdyn.app").joinpath("scenes/two_story.toml")
    s = load_scene(Path(str(path)))
    assert s.kind == "matrices" and s.n_dof == 3
    assert s.dof_names == ("floor_1", "floor_2", "roof")
    assert_array_equal(s.loaded, [2])
    assert_allclose(s.force[:, 0], 1e4 * np.sin(2 * np.pi * 2.5 * s.t), atol=1e-9)
    assert_allclose(s.C, 0.5712 * s.M + 4.762e-4 * s.K, rtol=1e-15)
    # Rayleigh coefficients give 2 % damping in modes 1 and 3
    omega, phi = _modes(s.M, s.K)
    zeta = np.diag(phi.T @ s.C @ phi) / (2.0 * omega)
    assert_allclose(zeta[[0, 2]], 0.02, rtol=1e-3)
    response, report = run_scene(s)
    assert response.x.shape == response.a.shape == (801, 3)
    assert report["max_rel_error"] < 2e-2
    assert main(["simulate", str(path), "--out", str(tmp_path / "b.npz")]) == 0
    assert "error against the exact response" in capsys.readouterr().out


def test_massless_dof_scene_reports_its_error(tmp_path):
    """A massless DOF with damping: mck_response runs it and exact_response reduces it."""
    M = np.diag([1.0, 0.0])
    C = np.array([[0.0, 0.0], [0.0, 2.0]])
    s = load_scene(write_scene(tmp_path, inline_model(M=M, C=C),
                               loads='[[load]]\ndof = 0\nkind = "step"\n',
                               scheme='[scheme]\nname = "average_acceleration"\n'))
    response, report = run_scene(s)
    assert np.isfinite(response.x).all()
    # average acceleration at dt = 0.02 against omega ~ 6.5 rad/s: (omega dt)^2 / 12 ~ 1e-3
    assert report["max_rel_error"] is not None and report["max_rel_error"] < 1e-2
