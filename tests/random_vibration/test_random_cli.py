"""`dtdyn random SCENE --psd table.csv`: a chain scene's loads and a matrices scene's [ground]
under a PSD table, the CSV and its JSON sidecar against `random_response` on the assembled
matrices (a dense solve per frequency, not the chain's transfer matrices), the plot, and bad
input."""
import json

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.app import main
from dtdyn.random_vibration import psd_table, random_response

ROWS = [(5.0, 1.0), (40.0, 1.0), (100.0, 0.16)]
CHAIN = """
title = "three masses"
[model]
mass = [1.0, 1.0, 1.0]
stiffness = [4e4, 4e4, 4e4]
damping = [60.0, 60.0, 60.0]
[[load]]
dof = 2
kind = "step"
[[load]]
dof = 0
kind = "step"
[time]
dt = 1e-3
duration = 1.0
[output]
outputs = [0, 2]
quantities = ["x", "a"]
"""
BUILDING = """
title = "two storeys on a shaking support"
[model]
kind = "matrices"
M = [[2.0, 0.0], [0.0, 1.0]]
K = [[6e4, -2e4], [-2e4, 2e4]]
C = [[12.0, -4.0], [-4.0, 4.0]]
[ground]
kind = "psd"
psd = [[5.0, 1.0], [100.0, 1.0]]
seed = 1
[time]
dt = 1e-3
duration = 1.0
[output]
quantities = ["x", "a"]
"""


@pytest.fixture
def spec(tmp_path):
    path = tmp_path / "spec.csv"
    path.write_text("f_hz,psd\n" + "".join(f"{f},{g}\n" for f, g in ROWS))
    return path


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_random_command_on_a_chain_equals_the_assembled_model(spec, tmp_path, capsys):
    scene = write(tmp_path, "chain.toml", CHAIN)
    out = tmp_path / "random.csv"
    assert main(["random", str(scene), "--psd", str(spec), "--freqs", "5", "100", "40",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    table = psd_table(ROWS)
    assert f"{table.grms:.4g} grms" in text and "independent loads at DOF(s) 0, 2" in text
    M, C, K = dd.chain_matrices([1.0] * 3, [4e4] * 3, [60.0] * 3, sparse=False)
    f = np.geomspace(5.0, 100.0, 40)
    ref = random_response(M, C, K, [table, table], f, force_dofs=[0, 2], outputs=[0, 2],
                          quantities=("x", "a"))
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    meta = json.loads(out.with_name("random.csv.json").read_text())
    assert meta["columns"] == ["freq_hz", "input_psd", "x_psd 0", "x_psd 2", "a_psd 0",
                               "a_psd 2"]
    np.testing.assert_array_equal(data[:, 0], f)
    np.testing.assert_allclose(data[:, 1], table(f), rtol=1e-15)
    G = np.concatenate([np.real(np.einsum("fii->fi", p)) for p in (ref.x_psd, ref.a_psd)], 1)
    np.testing.assert_allclose(data[:, 2:], G, rtol=1e-9)     # two solvers, to rounding
    for q in ("x", "a"):                     # both integrals to their accuracy 1e-8
        np.testing.assert_allclose(meta["rms"][q], ref.rms[q], rtol=1e-7)
        assert f"{ref.rms[q][1]:.6g}" in text
    assert meta["psd_grms"] == pytest.approx(table.grms) and meta["input"] == "psd"
    assert meta["outputs"] == ["0", "2"] and meta["rms_error_estimate"] < 1e-7


def test_random_command_under_support_motion(spec, tmp_path, capsys):
    scene = write(tmp_path, "building.toml", BUILDING)
    out = tmp_path / "building.csv"
    assert main(["random", str(scene), "--psd", str(spec), "--out", str(out)]) == 0
    assert "as support acceleration ([ground])" in capsys.readouterr().out
    meta = json.loads(out.with_name("building.csv.json").read_text())
    table = psd_table(ROWS)
    ref = random_response([[2.0, 0.0], [0.0, 1.0]], [[12.0, -4.0], [-4.0, 4.0]],
                          [[6e4, -2e4], [-2e4, 2e4]], None, np.geomspace(5.0, 100.0, 200),
                          ground_acceleration_psd=table, quantities=("x", "a"))
    assert meta["input"] == "ground_acceleration_psd"
    assert meta["columns"][-2:] == ["a_abs_psd 0", "a_abs_psd 1"]
    for q in ("x", "a", "a_abs"):
        np.testing.assert_allclose(meta["rms"][q], ref.rms[q], rtol=1e-12)


def test_random_command_plots(spec, tmp_path):
    pytest.importorskip("matplotlib")
    scene = write(tmp_path, "chain.toml", CHAIN)
    plot = tmp_path / "random.png"
    assert main(["random", str(scene), "--psd", str(spec), "--plot", str(plot)]) == 0
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("scene, extra, message", [
    (CHAIN, ["--freqs", "100", "10", "5"], "--freqs: need 0 < FMIN < FMAX"),
    (CHAIN, ["--plot", "nofolder/x.png"], "cannot plot to 'nofolder/x.png': not a file"),
    (CHAIN.split("[[load]]")[0] + "[time]\ndt = 1e-3\nduration = 1.0\n", [],
     "applies the PSD at the scene's loaded DOFs"),
    (CHAIN.replace("damping = [60.0, 60.0, 60.0]", "damping = [0.0, 0.0, 0.0]"), [],
     "undamped"),
])
def test_random_command_bad_input(spec, tmp_path, capsys, scene, extra, message):
    path = write(tmp_path, "bad.toml", scene)
    assert main(["random", str(path), "--psd", str(spec), *extra]) == 2
    assert message in capsys.readouterr().err
