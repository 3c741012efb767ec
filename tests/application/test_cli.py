"""The `dtdyn` command: drift check of generated/, show, simulate (and its errors)."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dtdyn.app._cli import main

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_generated_is_up_to_date():
    """Regenerates in memory and diffs against the checked-in generated/ of this checkout."""
    assert main(["generate", "--check", "--out", str(REPO / "generated")]) == 0


@pytest.mark.slow
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
    assert "  A = 2 / dt^2\n" in out and "station matrix" in out
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
    proc = subprocess.run([sys.executable, "-m", "dtdyn", "show", "fox_euler"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "Fox-Euler" in proc.stdout


def test_help_lists_every_command_and_version(capsys):
    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    for command in ("simulate", "srs", "stability", "bench", "show", "generate"):
        assert f"    {command}" in text, command
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("dtdyn 0.")


def test_show_latex_and_scheme_list(capsys):
    assert main(["show", "average_acceleration", "--latex"]) == 0
    assert "\\begin{bmatrix}" in capsys.readouterr().out
    assert main(["show", "--help"]) == 0
    assert "generalized_alpha" in capsys.readouterr().out


def test_bad_output_paths_are_refused_before_the_run(tmp_path, capsys):
    for args, words in ((["--out", str(tmp_path / "r.txt")], "unknown result format '.txt'"),
                        (["--out", str(tmp_path / "none" / "r.npz")], "does not exist"),
                        (["--out", str(tmp_path)], "is a folder"),
                        (["--plot", str(tmp_path / "r.xyz")], "unsupported format 'xyz'")):
        assert main(["simulate", *args]) == 2
        err = capsys.readouterr()
        assert words in err.err and "run time" not in err.out, args
    assert list(tmp_path.iterdir()) == []


def test_simulate_no_check_and_other_formats(tmp_path, capsys):
    out = tmp_path / "r.csv"
    assert main(["simulate", "--no-check", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "checking against the exact response" not in text and "error against" not in text
    from dtdyn import load_result
    back = load_result(out)
    assert back.x.shape == (801, 15) and back.meta["scene"]["scheme"] == "average_acceleration"
    assert main(["simulate"]) == 0
    text = capsys.readouterr().out
    assert "checking against the exact response" in text and "check took" in text


def test_generate_outside_a_checkout_refuses(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["generate"]) == 2
    assert "source checkout" in capsys.readouterr().err


def test_piped_output_closed_early_is_quiet():
    proc = subprocess.run(f"{sys.executable} -m dtdyn stability | head -n 1",
                          shell=True, capture_output=True, text=True, timeout=300)
    assert proc.stdout.startswith("scheme") and "Traceback" not in proc.stderr


def test_cli_imports_without_derive_or_sympy():
    """The command's module and `dtdyn --help` need neither dtdyn.derive nor SymPy nor jinja2;
    `dtdyn show` then says which extra it needs, in one line."""
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('sympy', 'jinja2') or name.startswith('dtdyn.derive'):\n"
        "            raise ImportError(f'blocked: {name}')\n"
        "sys.meta_path.insert(0, Block())\n"
        "from dtdyn.app._cli import main\n"
        "assert main(['--help']) == 0\n"
        "assert main(['show', 'newmark']) == 2\n"
        "assert not [m for m in sys.modules\n"
        "            if m.startswith(('sympy', 'jinja2', 'dtdyn.derive'))]\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert 'needs sympy, which is not installed: pip install "dtdyn[derive]"' in proc.stderr


def test_modes_command(capsys, tmp_path):
    """`dtdyn modes`: the table of the embedded P3 scene, JSON equal to dd.modes, errors in one
    line."""
    import json

    import dtdyn as dd

    assert main(["modes", "--count", "3"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1].split()[:3] == ["mode", "f", "[Hz]"] and len(out) == 5
    assert main(["modes", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    p = dd.problem("P3")
    ref = dd.mck_modes(p["M"], None, p["K"])
    np.testing.assert_allclose(data["omega_rad_s"], ref.omega, rtol=1e-14)
    assert sum(data["effective_mass"]) == pytest.approx(p["mass"].sum(), rel=1e-12)
    assert main(["modes", "--count", "0"]) == 2
    assert capsys.readouterr().err.count("\n") == 1
