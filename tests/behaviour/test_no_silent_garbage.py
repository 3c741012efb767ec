"""No silent garbage: a linear run whose scheme is unstable at this dt for the model's highest
mode is refused before it starts (DtdynUnstableError naming the mode, Omega and the limit), a
discrete model whose recursion grows likewise, and a run that leaves the finite numbers stops at
its first non-finite step; the command exits 1 and writes nothing."""
import numpy as np
import pytest

import dtdyn as dd
from dtdyn.app import main

MASS, STIFF, DAMP = [1.0, 1.0], [1e4, 1e4], [0.0, 0.0]   # omega_max = 161.8 rad/s


def test_chain_and_mck_refuse_an_unstable_step():
    """Central difference at Omega = 161.8 * 0.0278 = 4.5 > 2 on a 2-mass chain (it used to
    return 5.7e30 without a word)."""
    dt = 4.5 / 161.80339887498948
    with pytest.raises(dd.DtdynUnstableError, match=r"Omega = omega dt = 4.5 > 2"):
        dd.chain_response(MASS, STIFF, [0.1, 0.1], np.ones(201), dt, force_dofs=[1],
                          scheme="central_difference", form="acceleration")
    M, C, K = dd.chain_matrices(MASS, STIFF, DAMP)
    with pytest.raises(dd.DtdynUnstableError, match=r"use dt < 0.01236"):
        dd.mck_response(M, C, K, np.ones(201), dt, force_dofs=[1], scheme="central_difference")
    # just inside the limit it runs and stays bounded
    r = dd.mck_response(M, C, K, np.ones(2001), 0.0123, force_dofs=[1],
                        scheme="central_difference")
    assert np.abs(r.x).max() < 1e-3
    # the chain's cheap Gershgorin bound (173 rad/s) exceeds the limit here, the exact top mode
    # (161.8 rad/s) does not: the run goes ahead
    r = dd.chain_response(MASS, STIFF, [0.1, 0.1], np.ones(2001), 0.0123, force_dofs=[1],
                          scheme="central_difference", form="acceleration")
    assert np.abs(r.x).max() < 1e-3
    # unconditionally stable schemes are never refused, whatever the step
    dd.mck_response(M, C, K, np.ones(21), 10.0, force_dofs=[1], scheme="average_acceleration")


def test_a_blow_up_stops_at_its_first_non_finite_step():
    M, C, K = dd.chain_matrices(MASS, STIFF, DAMP)
    with pytest.warns(dd.DtdynStabilityWarning), np.errstate(over="ignore", invalid="ignore"):
        with pytest.raises(FloatingPointError, match=r"not finite from step \d+ \(t = "):
            dd.mck_response(M, C, K, np.ones(20001), 0.05, force_dofs=[1],
                            scheme="central_difference", unstable="warn")


def test_state_space_refuses_a_growing_recursion():
    A = np.array([[1.01, 0.0], [0.0, 0.5]])
    model = dd.DiscreteModel(A, np.eye(2)[:, :1], np.eye(2), np.zeros((2, 1)), 0.1,
                             quantities=("x", "v"), n_dof=1,
                             _physical_state=lambda q, v, f: np.r_[q, v])
    with pytest.raises(dd.DtdynUnstableError, match=r"spectral radius of A is 1.01 > 1"):
        dd.state_space_response(model, np.ones(11))
    with pytest.warns(dd.DtdynStabilityWarning):
        r = dd.state_space_response(model, np.ones(11), unstable="warn")
    assert np.isfinite(r.x).all()


def test_command_exits_1_and_writes_nothing(tmp_path, capsys):
    scene = tmp_path / "cd.toml"
    scene.write_text('[model]\nmass = [1.0, 1.0]\nstiffness = [1e4, 1e4]\ndamping = [1.0, 1.0]\n'
                     '[[load]]\ndof = 1\nkind = "step"\n'
                     '[scheme]\nname = "central_difference"\nform = "acceleration"\n'
                     '[time]\ndt = 0.05\nduration = 0.5\n')
    out = tmp_path / "r.npz"
    assert main(["simulate", str(scene), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "dtdyn simulate: warning: DtdynStabilityWarning: " in err and "mode 2" in err
    assert "run failed: scheme 'central_difference' is unstable" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cd.toml"]
