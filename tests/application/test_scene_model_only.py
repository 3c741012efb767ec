"""Scenes need only a [model]: `dtdyn modes` reads nothing else; [time] and a load are asked
for by what integrates, naming the command; [scheme] defaults to the entry points' own scheme;
``scheme.unstable`` and ``--unstable`` let a run past the stability limit go on with a warning."""
from __future__ import annotations

import inspect
import json

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import brentq

import dtdyn as dd
from dtdyn.app._cli import main
from dtdyn.app._scene import load_scene, run_scene
from dtdyn.app._scene.schema import DEFAULT_SCHEME

CHAIN = "[model]\nmass = [1.0, 2.0, 1.5]\nstiffness = [100.0, 200.0, 150.0]\n"
MATRICES = ('[model]\nkind = "matrices"\nM = [[2.0, 0.0], [0.0, 1.0]]\n'
            'K = [[30.0, -10.0], [-10.0, 10.0]]\ndofs = ["floor", "roof"]\n')
SHAFT = '[model]\nkind = "shaft"\ninertia = [1.0, 0.3, 0.9]\nstiffness = [1e4, 1.2e4, 9e3]\n'
EI, RHO_A, LENGTH = 2.1e11 * 8.0e-6, 20.0, 3.0
BEAM = ('[model]\nkind = "beam"\nE = 2.1e11\nI = 8.0e-6\nrho_A = 20.0\nlength = 3.0\n'
        'elements = 20\nleft = "clamped"\nright = "free"\n')
MODELS = {"chain": CHAIN, "matrices": MATRICES, "shaft": SHAFT, "beam": BEAM}


def _tridiagonal_chain(mass, stiffness):
    """K, M of a chain fixed at station 0 (free at the end), assembled here by hand: the
    pencil of the generalized eigenproblem K phi = omega^2 M phi."""
    k = np.asarray(stiffness, dtype=float)
    K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    return K, np.diag(mass)


def _cantilever_omegas(count):
    """omega_r = (beta_r L)^2 sqrt(EI / (rho A L^4)), beta_r L the roots of cos x cosh x = -1."""
    roots = [brentq(lambda x: np.cos(x) * np.cosh(x) + 1.0, (r + 0.5) * np.pi - 1.2,
                    (r + 0.5) * np.pi + 1.2) for r in range(count)]
    return np.array(roots) ** 2 * np.sqrt(EI / (RHO_A * LENGTH**4))


def _modes_json(path, capsys, *extra):
    assert main(["modes", str(path), "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("kind", list(MODELS))
def test_modes_of_a_scene_holding_only_a_model(tmp_path, capsys, kind):
    path = tmp_path / f"{kind}.toml"
    path.write_text(MODELS[kind])
    sc = load_scene(path)
    assert sc.kind == kind and sc.dt is None and sc.n_steps is None and sc.force is None
    assert sc.scheme == DEFAULT_SCHEME
    omega = np.array(_modes_json(path, capsys)["omega_rad_s"])
    if kind == "chain":  # hand-assembled K, M and the chain's own Wittrick-Williams count
        truth = np.sqrt(sla.eigh(*_tridiagonal_chain([1.0, 2.0, 1.5], [100.0, 200.0, 150.0]),
                                 eigvals_only=True))
        np.testing.assert_allclose(omega, truth, rtol=1e-12)
        np.testing.assert_allclose(omega, dd.chain_frequencies(sc.mass, sc.stiffness),
                                   rtol=1e-12)
    elif kind == "matrices":  # det(K - lambda M) = 2 (lambda - 5)(lambda - 20)
        np.testing.assert_allclose(omega, np.sqrt([5.0, 20.0]), rtol=1e-13)
    elif kind == "shaft":  # clamped-free, lumped disks: the same tridiagonal K as a chain
        truth = np.sqrt(sla.eigh(*_tridiagonal_chain([1.0, 0.3, 0.9], [1e4, 1.2e4, 9e3]),
                                 eigvals_only=True))
        np.testing.assert_allclose(omega, truth, rtol=1e-10)
        np.testing.assert_array_equal(omega, dd.shaft_frequencies(sc.model))
    else:  # the 20-element model's eigenvalues, above the continuous cantilever's
        assert omega.size == sc.n_dof == 40
        M, _, K = sc.matrices(sparse=False)
        np.testing.assert_allclose(omega, np.sqrt(sla.eigh(K, M, eigvals_only=True)),
                                   rtol=1e-9)
        exact = _cantilever_omegas(5)  # consistent mass: an upper bound, error O(h^4)
        assert np.all(omega[:5] >= exact * (1 - 1e-12))
        np.testing.assert_allclose(omega[:5], exact, rtol=2e-4)
        np.testing.assert_array_equal(omega, dd.beam_frequencies(sc.model))
    # the table prints too, and --count picks the lowest ones
    assert main(["modes", str(path)]) == 0
    assert sc.title in capsys.readouterr().out
    np.testing.assert_allclose(_modes_json(path, capsys, "--count", "2")["omega_rad_s"],
                               omega[:2], rtol=1e-9)


def test_a_load_without_time_is_checked_and_waits(tmp_path, capsys):
    """[[load]] without [time]: its DOF is checked now (by name or index), its samples wait for
    a time grid; modes runs, simulate asks for [time]."""
    path = tmp_path / "m.toml"
    path.write_text(MATRICES + '[[load]]\ndof = "roof"\nkind = "step"\n')
    sc = load_scene(path)
    assert sc.force is None and sc.loaded.tolist() == [1]
    assert _modes_json(path, capsys)["n_dof"] == 2
    path.write_text(MATRICES + '[[load]]\ndof = "attic"\nkind = "step"\n')
    with pytest.raises(ValueError, match=r"load\[0\]\.dof = 'attic': unknown DOF name"):
        load_scene(path)


def test_integrating_commands_name_themselves_and_the_missing_table(tmp_path, capsys):
    path = tmp_path / "chain.toml"
    path.write_text(CHAIN)
    sc = load_scene(path)
    with pytest.raises(ValueError, match=r"chain\.toml: run_scene needs a \[time\] table with "
                                         r"dt and duration"):
        run_scene(sc)
    assert main(["simulate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "dtdyn simulate needs a [time] table with dt and duration" in err
    assert err.count("\n") == 1
    # [time] but no load: the load is what is missing now
    path.write_text(CHAIN + "[time]\ndt = 0.01\nduration = 1.0\n")
    sc = load_scene(path)
    assert sc.n_steps == 100 and sc.duration == pytest.approx(1.0)
    with pytest.raises(ValueError, match=r"run_scene needs a load: one or more \[\[load\]\] "
                                         r"tables .* or a \[ground\] record"):
        run_scene(sc)
    assert main(["simulate", str(path)]) == 2
    assert "dtdyn simulate needs a load" in capsys.readouterr().err


def test_batch_refuses_a_scene_without_time_before_it_starts(tmp_path):
    for module in ("distributed", "xarray", "zarr"):
        pytest.importorskip(module)
    path = tmp_path / "chain.toml"
    path.write_text(CHAIN)
    with pytest.raises(ValueError, match=r"chain\.toml: run_batch needs a \[time\] table"):
        dd.run_batch(path, progress=False)
    # a vary column that sets the time grid is enough to get past the check (then the load)
    with pytest.raises(ValueError, match=r"chain\.toml: run_batch needs a load"):
        dd.run_batch(path, vary=[{"time.dt": 0.01, "time.duration": 1.0}], progress=False)


def test_default_scheme_is_the_entry_points_default(tmp_path):
    """No [scheme]: the scene runs exactly what chain_response runs with its defaults."""
    for fn in (dd.chain_response, dd.mck_response, dd.shaft_response, dd.beam_response):
        assert inspect.signature(fn).parameters["scheme"].default == DEFAULT_SCHEME, fn
    path = tmp_path / "chain.toml"
    path.write_text(CHAIN + '[[load]]\ndof = 2\nkind = "step"\n[time]\ndt = 0.01\n'
                    'duration = 1.0\n[output]\nquantities = ["x", "v", "a"]\n')
    sc = load_scene(path)
    assert (sc.scheme, sc.scheme_params, sc.form, sc.sweep, sc.backend, sc.unstable) == \
        ("newmark", {}, None, "stable", "c", "raise")     # form None: the scheme's own
    response, report = run_scene(sc)
    assert report["form"] == "displacement"
    ref = dd.chain_response([1.0, 2.0, 1.5], [100.0, 200.0, 150.0], np.zeros(3),
                            np.ones((101, 1)), 0.01, force_dofs=[2])
    for q in "xva":
        np.testing.assert_array_equal(getattr(response, q), getattr(ref, q))
    assert report["max_rel_error"] < 1e-2  # against the matrix exponential
    # an explicit scheme without a form: its only one, the acceleration form, as the
    # entry points take it
    damped = CHAIN.replace("]\n", "]\ndamping = [1.0, 1.0, 1.0]\n", 1)
    path.write_text(damped + '[[load]]\ndof = 2\nkind = "step"\n[time]\ndt = 0.01\n'
                    'duration = 1.0\n[scheme]\nname = "central_difference"\n')
    response, report = run_scene(load_scene(path))
    ref = dd.chain_response([1.0, 2.0, 1.5], [100.0, 200.0, 150.0], np.ones(3),
                            np.ones((101, 1)), 0.01, force_dofs=[2], scheme="central_difference")
    assert report["form"] == ref.info["form"] == "acceleration"
    np.testing.assert_array_equal(response.x, ref.x)
    path.write_text(CHAIN + '[[load]]\ndof = 2\nkind = "step"\n[time]\ndt = 0.01\n'
                    'duration = 1.0\n[output]\nquantities = ["x", "v", "a"]\n')
    # a [scheme] table without a name keeps the default name and takes its parameters
    path.write_text(path.read_text() + "[scheme]\nbeta = 0.3\ngamma = 0.6\n")
    sc = load_scene(path)
    assert (sc.scheme, sc.scheme_params) == ("newmark", {"beta": 0.3, "gamma": 0.6})


# ---------------------------------------------------------------------------------------------
# scheme.unstable and --unstable

UNSTABLE_CHAIN = ('[model]\nmass = [1.0, 1.0]\nstiffness = [1e4, 1e4]\ndamping = [1.0, 1.0]\n'
                  '[[load]]\ndof = 1\nkind = "step"\n'
                  '[scheme]\nname = "central_difference"\nform = "acceleration"\n{unstable}'
                  '[time]\ndt = 0.05\nduration = 0.5\n')  # Omega = 161.8 * 0.05 = 8.1 > 2


def test_unstable_dt_raises_by_default_and_says_how_to_run_it(tmp_path, capsys):
    path = tmp_path / "cd.toml"
    path.write_text(UNSTABLE_CHAIN.format(unstable=""))
    sc = load_scene(path)
    assert sc.unstable == "raise"
    with pytest.warns(dd.DtdynStabilityWarning, match="mode 2"):  # the pre-run check
        with pytest.raises(dd.DtdynUnstableError) as info:
            run_scene(sc)
    msg = str(info.value)
    assert "Omega = omega dt = 8.09 > 2" in msg
    assert "unstable='warn'" in msg and '[scheme] unstable = "warn"' in msg
    assert "--unstable warn" in msg
    assert main(["simulate", str(path), "--no-check"]) == 1
    err = capsys.readouterr().err                      # the command's one-line warning
    assert "dtdyn simulate: warning: DtdynStabilityWarning: " in err and "mode 2" in err
    assert "--unstable warn" in err


def test_scene_key_unstable_warn_runs_with_a_warning(tmp_path):
    path = tmp_path / "cd.toml"
    path.write_text(UNSTABLE_CHAIN.format(unstable='unstable = "warn"\n'))
    sc = load_scene(path)
    assert sc.unstable == "warn"
    with pytest.warns(dd.DtdynStabilityWarning, match=r"unstable at dt = 0\.05 s") as caught:
        response, _ = run_scene(sc, check=False)
    assert len(caught) == 1  # the entry point's warning, not also the pre-run check's
    with pytest.warns(dd.DtdynStabilityWarning):
        ref = dd.chain_response([1.0, 1.0], [1e4, 1e4], [1.0, 1.0], np.ones((11, 1)), 0.05,
                                force_dofs=[1], scheme="central_difference",
                                form="acceleration", outputs=sc.outputs, quantities=("x",),
                                unstable="warn")
    np.testing.assert_array_equal(response.x, ref.x)
    assert np.abs(response.x[-1]).max() > 1e6  # it did grow: the warning was worth giving


def test_unstable_keyword_and_cli_flag_override_the_scene(tmp_path, capsys):
    path = tmp_path / "cd.toml"
    path.write_text(UNSTABLE_CHAIN.format(unstable=""))
    with pytest.warns(dd.DtdynStabilityWarning):
        response, _ = run_scene(load_scene(path), check=False, unstable="warn")
    assert response.x.shape == (11, 2)
    with pytest.raises(ValueError, match=r"unstable = 'ignore': unknown value, allowed: "
                                         r"'raise', 'warn'"):
        run_scene(load_scene(path), unstable="ignore")
    assert main(["simulate", str(path), "--unstable", "warn", "--no-check"]) == 0
    out = capsys.readouterr()
    assert "run time:" in out.out
    assert "dtdyn simulate: warning: DtdynStabilityWarning: " in out.err
    # and the other way round: the flag refuses what the scene would run
    path.write_text(UNSTABLE_CHAIN.format(unstable='unstable = "warn"\n'))
    assert main(["simulate", str(path), "--unstable", "raise", "--no-check"]) == 1
    assert "run failed: scheme 'central_difference' is unstable" in capsys.readouterr().err
    assert main(["simulate", str(path), "--unstable", "maybe"]) == 2  # argparse's choices
    assert "invalid choice: 'maybe'" in capsys.readouterr().err


def test_batch_unstable_sets_every_linear_scene(tmp_path):
    """run_batch(unstable="warn") (dtdyn batch --unstable warn) runs the unstable case; a vary
    column scheme.unstable still wins over it."""
    for module in ("distributed", "xarray", "zarr"):
        pytest.importorskip(module)
    path = tmp_path / "cd.toml"
    path.write_text(UNSTABLE_CHAIN.format(unstable=""))
    with pytest.warns(dd.DtdynStabilityWarning):  # the batch passes the case's warning on
        ds = dd.run_batch(path, vary=[{"load[0].amplitude": 1.0}, {"scheme.unstable": "raise"}],
                          workers=1, reduce="peak", progress=False, check=False,
                          unstable="warn")
    assert list(ds["status"].values) == ["done", "failed"]
    assert str(ds["message"].values[1]).startswith("DtdynUnstableError: scheme "
                                                   "'central_difference' is unstable")
    with pytest.warns(dd.DtdynStabilityWarning):
        alone, _ = run_scene(load_scene(path), check=False, unstable="warn")
    np.testing.assert_array_equal(ds["peak_x"].values[0], np.abs(alone.x).max(axis=0))
    with pytest.raises(ValueError, match=r"unstable = 'sometimes': unknown value"):
        dd.run_batch(path, progress=False, unstable="sometimes")


def test_initial_state_without_load_is_free_vibration(tmp_path, capsys):
    """[initial] without [[load]] or [ground]: the free vibration from that state, what
    chain_response computes with a zero force, and close to the exact motion
    x(t) = Phi cos(Omega t) Phi^T M x0 (undamped chain; Newmark's period error
    (omega dt)^2 / 12 over omega T radians bounds the phase: omega_max^3 dt^2 T / 12 of the
    amplitude). An [initial] state of zeros is not a load: the error still says what is missing."""
    x0 = [0.01, -0.02, 0.03]
    path = tmp_path / "free.toml"
    path.write_text(CHAIN + f"[initial]\nx0 = {x0}\n[time]\ndt = 0.001\nduration = 2.0\n")
    sc = load_scene(path)
    r, report = run_scene(sc)
    mass, stiffness = [1.0, 2.0, 1.5], [100.0, 200.0, 150.0]
    ref = dd.chain_response(mass, stiffness, np.zeros(3), np.zeros((2001, 1)), 0.001,
                            force_dofs=[0], x0=np.array(x0))
    np.testing.assert_array_equal(r.x, ref.x)
    assert report["max_rel_error"] < 1e-3      # the run's own check against the exponential
    K, M = _tridiagonal_chain(mass, stiffness)
    w2, phi = sla.eigh(K, M)
    t = np.arange(2001) * 0.001
    exact = (phi * np.cos(np.outer(t, np.sqrt(w2)))[:, None, :]) @ (phi.T @ M @ x0)
    bound = np.sqrt(w2.max()) ** 3 * 0.001**2 * 2.0 / 12
    assert np.abs(r.x - exact).max() / np.abs(exact).max() < 2 * bound, bound
    assert main(["simulate", str(path), "--out", str(tmp_path / "free.npz"), "--no-check"]) == 0
    path.write_text(CHAIN + "[initial]\nx0 = [0.0, 0.0, 0.0]\n[time]\ndt = 0.01\n"
                    "duration = 1.0\n")
    with pytest.raises(ValueError, match=r"needs a load: .* \(or an \[initial\] x0 / v0 not "
                                         r"all zero: free vibration\)"):
        run_scene(load_scene(path))
