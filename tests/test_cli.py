"""The `dtdyn` command: drift check of generated/, show, simulate (and its errors)."""
import subprocess
import sys
from pathlib import Path

import numpy as np

from dtdyn.app.cli import main

REPO = Path(__file__).resolve().parents[1]


def test_generated_is_up_to_date():
    """Regenerates in memory and diffs against the checked-in generated/ of this checkout."""
    assert main(["generate", "--check", "--out", str(REPO / "generated")]) == 0


def test_check_detects_drift(tmp_path, capsys):
    assert main(["generate", "--out", str(tmp_path)]) == 0
    target = tmp_path / "scheme_houbolt.py"
    target.write_text(target.read_text().replace("2.0", "2.5", 1))
    assert main(["generate", "--check", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "scheme_houbolt.py" in err and "dtdyn generate" in err


def test_show_prints_coefficients(capsys):
    assert main(["show", "houbolt"]) == 0
    out = capsys.readouterr().out
    assert "A  = 2/dt**2" in out and "station matrix" in out
    assert main(["show", "nope"]) == 2


def test_simulate_default_scene(tmp_path, capsys):
    out, plot = tmp_path / "r.npz", tmp_path / "r.png"
    assert main(["simulate", "--out", str(out), "--plot", str(plot)]) == 0
    text = capsys.readouterr().out
    assert "run time" in text and "error against the exact response" in text
    data = np.load(out)
    assert data["x"].shape == (801, 15) and "v" not in data  # the scene asks for x only
    assert plot.stat().st_size > 10_000


def test_simulate_malformed_scene_writes_nothing(tmp_path, capsys):
    scene = tmp_path / "bad.toml"
    scene.write_text('[model]\nmass = [1.0, -2.0]\nstiffness = [1.0, 1.0]\n'
                     '[[load]]\ndof = 1\nkind = "step"\n[scheme]\nname = "newmark"\n'
                     '[time]\ndt = 0.01\nduration = 1.0\n')
    out = tmp_path / "r.npz"
    assert main(["simulate", str(scene), "--out", str(out)]) == 2
    assert "model.mass[1]" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [scene]


def test_console_script_runs():
    proc = subprocess.run([sys.executable, "-m", "dtdyn.app.cli", "show", "fox_euler"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "Fox-Euler" in proc.stdout
