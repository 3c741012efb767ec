"""Steady-state scenes (issue #31 item 4): the [harmonic] table, `run_steady` against direct
`harmonic_balance` calls, `dtdyn steady` with --plot and --out, and the curve's save / load
round trip (.npz and .csv + .json)."""
import dataclasses
import importlib.resources
import json
import re
from pathlib import Path

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.app._cli import main
from dtdyn.app._scene import run_steady

DUFFING = Path(str(importlib.resources.files("dtdyn.app").joinpath(
    "scenes/duffing_steady.toml")))

#: a short Duffing scene (3 harmonics, a narrow band) for the checks that need a run
SMALL = """
[model]
mass = [1.0]
stiffness = [1.0]
damping = [0.02]

[[element]]
kind = "cubic"
i = 0
k3 = 0.5

[harmonic]
freqs_hz = [0.1, 0.2]
harmonics = 3
force_dofs = [0]
force = [0.1]
"""


def write(tmp_path, text, name="steady.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def small(tmp_path, replace=(), add="", name="steady.toml"):
    """The SMALL scene with lines replaced (old, new) and lines added to [harmonic]."""
    text = SMALL
    for old, new in replace:
        assert old in text, old
        text = text.replace(old, new)
    return write(tmp_path, text + add, name)


def duffing(**kw):
    kw = {"force_dofs": [0], "force": [0.1], "freqs_hz": (0.1, 0.2), "harmonics": 3, **kw}
    return dd.harmonic_balance(dd.Chain([1.0], [1.0], [0.02]), elements=[dd.Cubic(0, k3=0.5)],
                               **kw)


def assert_same(a, b):
    """Every field of two HarmonicBalanceResults equal, bitwise (info: the same keys, run
    times aside)."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "info":
            assert x.keys() <= y.keys()
            for key in x:
                if key == "run_time":
                    continue
                if key == "stability" and isinstance(x[key], dict):   # its time aside
                    assert ({k: v for k, v in x[key].items() if k != "time"}
                            == {k: v for k, v in y[key].items() if k != "time"})
                elif isinstance(x[key], np.ndarray):
                    np.testing.assert_array_equal(x[key], y[key], err_msg=key)
                elif isinstance(x[key], float) and np.isnan(x[key]):
                    assert np.isnan(y[key]), key
                else:
                    assert x[key] == y[key], key
        elif isinstance(x, np.ndarray):
            assert isinstance(y, np.ndarray) and x.dtype == y.dtype and x.shape == y.shape, f.name
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        else:
            assert x == y, f.name


@pytest.fixture(scope="module")
def embedded():
    scene = dd.load_scene(DUFFING)
    return scene, run_steady(scene)


# --- the scene equals the direct call -------------------------------------------------------


def test_embedded_duffing_scene_equals_harmonic_balance(embedded):
    """scenes/duffing_steady.toml: the curve of dd.harmonic_balance on the same chain, bitwise,
    with both folds and an unstable branch between them."""
    scene, (r, report) = embedded
    direct = dd.harmonic_balance(dd.Chain([1.0], [1.0], [0.02]),
                                 elements=[dd.Cubic(0, k3=0.5)], force_dofs=[0], force=[0.1],
                                 freqs_hz=(0.05, 0.4), harmonics=7)
    assert_same(direct, r)
    assert report["n_points"] == r.frequency_hz.size and report["harmonics"] == 7
    assert len(report["fold_frequency_hz"]) == 2 and 0 < report["stable_fraction"] < 1
    assert report["stop"] == "end of the range" and report["receptance"] == "banded"


def test_matrices_scene_gives_the_same_curve(tmp_path, embedded):
    """The same oscillator as kind = "matrices" with a named DOF: the modal receptance instead
    of the chain's banded one, the same folds and peak to 1e-9."""
    _, (r, _) = embedded
    path = write(tmp_path, DUFFING.read_text().replace(
        "mass = [1.0]             # kg\nstiffness = [1.0]        # N/m\n"
        "damping = [0.02]         # N s/m",
        'kind = "matrices"\nM = [[1.0]]\nK = [[1.0]]\nC = [[0.02]]\ndofs = ["mass"]').replace(
        "i = 0 ", 'i = "mass" ').replace("force_dofs = [0]", 'force_dofs = ["mass"]'))
    m, report = run_steady(dd.load_scene(path))
    assert report["receptance"] == "modal"
    np.testing.assert_allclose(m.fold_frequency_hz, r.fold_frequency_hz, rtol=1e-9)
    np.testing.assert_allclose(m.x_max.max(), r.x_max.max(), rtol=1e-9)


def test_complex_force_shifts_the_orbit_in_time(tmp_path):
    """force = [[0.0, 0.1]] is 0.1 i: the load delayed by a quarter period, so X_k -> i^k X_k
    (a shift of the time origin), the amplitudes unchanged; it equals the direct call."""
    real, _ = run_steady(dd.load_scene(small(tmp_path)))
    shifted, _ = run_steady(dd.load_scene(small(tmp_path, [("force = [0.1]",
                                                             "force = [[0.0, 0.1]]")])))
    assert_same(duffing(force=[0.1j]), shifted)
    k = np.arange(4)
    np.testing.assert_allclose(shifted.harmonics, real.harmonics * 1j ** k, atol=1e-12)
    np.testing.assert_allclose(shifted.x_max, real.x_max, rtol=1e-10)


def test_force_harmonics_and_ground_acceleration(tmp_path):
    """force_harmonics (a static part, the fundamental, a complex 2nd harmonic) and a ground
    acceleration given as [re, im]: the direct calls' curves, bitwise."""
    path = small(tmp_path, [("force = [0.1]", "force_harmonics = [[0.05, 0.1, [0.0, 0.02]]]")])
    r, _ = run_steady(dd.load_scene(path))
    assert_same(duffing(force=[[0.05, 0.1, 0.02j]]), r)
    path = small(tmp_path, [("force_dofs = [0]\nforce = [0.1]",
                             "ground_acceleration = [0.05, 0.02]\nstability = false")])
    g, _ = run_steady(dd.load_scene(path))
    assert_same(duffing(force=None, force_dofs=None, ground_acceleration=0.05 + 0.02j,
                        stability=False), g)
    assert g.stable is None and g.a_abs_max is not None


def test_amplitude_sweep(tmp_path):
    """frequency_hz and amplitudes: harmonic_balance_amplitude, bitwise."""
    path = small(tmp_path, [("freqs_hz = [0.1, 0.2]",
                             "frequency_hz = 0.25\namplitudes = [0.05, 2.0]")])
    r, report = run_steady(dd.load_scene(path))
    direct = dd.harmonic_balance_amplitude(
        dd.Chain([1.0], [1.0], [0.02]), elements=[dd.Cubic(0, k3=0.5)], force_dofs=[0],
        force=[0.1], frequency_hz=0.25, amplitudes=(0.05, 2.0), harmonics=3)
    assert_same(direct, r)
    assert report["sweep"] == "amplitude" and r.amplitude[-1] == 2.0


def test_beam_scene_without_scheme(tmp_path):
    """A beam with a cubic spring at its tip, [harmonic] and no [time] or [scheme] (the modal
    time-history default does not stop it) equals harmonic_balance on the same Beam; with a
    [time] table the time-history check is as before."""
    text = """
[model]
kind = "beam"
E = 2.1e11
I = 8e-6
rho_A = 20.0
length = 3.0
elements = 4
rayleigh = [2.0, 1e-5]

[[element]]
kind = "cubic"
i = "w4"
k3 = 2e11

[harmonic]
freqs_hz = [12.0, 20.0]
harmonics = 3
force_dofs = ["w4"]
force = [5.0]

[output]
outputs = ["w4", "w2"]
"""
    r, _ = run_steady(dd.load_scene(write(tmp_path, text)))
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=4, rayleigh=(2.0, 1e-5))
    direct = dd.harmonic_balance(beam, elements=[dd.Cubic(beam.dof("w4"), k3=2e11)],
                                 force_dofs=["w4"], force=[5.0], freqs_hz=(12.0, 20.0),
                                 harmonics=3, outputs=["w4", "w2"])
    assert_same(direct, r)
    with pytest.raises(ValueError, match=r"scheme\.name = 'modal_ramp': the modal methods"):
        dd.load_scene(write(tmp_path, text + "[time]\ndt = 1e-3\nduration = 0.1\n", "t.toml"))


def test_scene_with_both_kinds_of_table(tmp_path):
    """[harmonic] beside [time], [[load]] and [scheme]: run_scene runs the time history,
    run_steady the steady state."""
    path = small(tmp_path, add='\n[[load]]\ndof = 0\nkind = "sine"\namplitude = 0.1\n'
                               'frequency = 0.15\n[scheme]\nname = "newmark"\n'
                               '[time]\ndt = 0.1\nduration = 2.0\n')
    scene = dd.load_scene(path)
    response, report = dd.run_scene(scene)
    assert response.x.shape == (21, 1) and report["scheme"] == "newmark"
    r, _ = run_steady(scene)
    assert_same(duffing(), r)


# --- errors name the field and the value ----------------------------------------------------

ERRORS = [
    ([("freqs_hz = [0.1, 0.2]\n", "")], "", r"harmonic\.freqs_hz is required"),
    ([("freqs_hz = [0.1, 0.2]", "freqs_hz = [0.4]")], "",
     r"harmonic\.freqs_hz = \[0\.4\]: must be \[start, end\]"),
    ([("freqs_hz = [0.1, 0.2]", "freqs_hz = [0.1, -1.0]")], "",
     r"harmonic\.freqs_hz\[1\] = -1\.0: must be > 0"),
    ([("freqs_hz = [0.1, 0.2]", "freqs_hz = [0.1, 0.1]")], "",
     r"harmonic\.freqs_hz = \[0\.1, 0\.1\]: start and end must differ"),
    ([], "amplitudes = [0.1, 1.0]\n", r"harmonic\.amplitudes = \[0\.1, 1\.0\] with "
                                      r"harmonic\.freqs_hz"),
    ([("freqs_hz = [0.1, 0.2]", "amplitudes = [0.1, 1.0]")], "",
     r"harmonic\.frequency_hz is required"),
    ([("harmonics = 3", "harmonics = 0")], "", r"harmonic\.harmonics = 0: must be an integer >= 1"),
    ([("harmonics = 3", "harmonics = 2.5")], "", r"harmonic\.harmonics = 2\.5: must be an integer"),
    ([("force = [0.1]", "force = [0.1, 0.2]")], "",
     r"harmonic\.force = \[0\.1, 0\.2\]: must be an array with one entry per "
     r"harmonic\.force_dofs entry \(1\)"),
    ([("force = [0.1]", "force = [[0.1, 0.2, 0.3]]")], "",
     r"harmonic\.force\[0\] = \[0\.1, 0\.2, 0\.3\]: a complex amplitude is \[re, im\]"),
    ([("force = [0.1]", 'force = ["a"]')], "", r"harmonic\.force\[0\] = 'a': must be a number"),
    ([("force = [0.1]", "force = [[0.0, 0.0]]")], "", r"harmonic\.force = .*zero everywhere"),
    ([("force_dofs = [0]", "force_dofs = [3]")], "",
     r"harmonic\.force_dofs\[0\] = 3: must be an integer mass index in 0\.\.0"),
    ([("force_dofs = [0]\n", "")], "", r"harmonic\.force_dofs is required with harmonic\.force"),
    ([], "force_harmonics = [[0.0, 0.1]]\n", r"harmonic\.force and harmonic\.force_harmonics"),
    ([("force = [0.1]", "force_harmonics = [[[0.1, 0.2], 0.1]]")], "",
     r"harmonic\.force_harmonics\[0\]\[0\] = \[0\.1, 0\.2\]: harmonic 0 .* must be real"),
    ([("force = [0.1]", "force_harmonics = [[0.0, 0.1, 0.0, 0.0, 0.2]]")], "",
     r"harmonic\.force_harmonics\[0\] has 5 entries: at most harmonic\.harmonics \+ 1 = 4"),
    ([("force_dofs = [0]\nforce = [0.1]\n", "")], "", r"harmonic: no load"),
    ([("force_dofs = [0]\nforce = [0.1]", "ground_acceleration = 0.1")],
     "influence = [1.0]\n", r"harmonic\.influence: a chain moves with its base"),
    ([], 'stability = "yes"\n', r"harmonic\.stability = 'yes': must be true, false, 'auto'"),
    ([], "step = 0.5\n", r"harmonic\.step = 0\.5: need min_step <= step <= max_step"),
    ([], "max_step = -1.0\n", r"harmonic\.max_step = -1\.0: must be > 0"),
    ([], "max_points = 1\n", r"harmonic\.max_points = 1: must be an integer >= 2"),
    ([], "n_time = 4\n", r"harmonic\.n_time = 4: must be an integer >= 8"),
    ([], 'receptance = "fast"\n', r"harmonic\.receptance = 'fast': unknown value"),
    ([], "speed = 1\n", r"harmonic\.speed = 1: unknown key, allowed: freqs_hz"),
    ([('kind = "cubic"\ni = 0\nk3 = 0.5', 'kind = "bouc_wen"\ni = 0\nstiffness = 1.0\n'
                                          'beta = 0.5\ngamma = 0.5')], "",
     r"element\[0\] \(.*\): \[harmonic\] does not support elements with internal states"),
    ([('[[element]]\nkind = "cubic"\ni = 0\nk3 = 0.5\n', "")], "",
     r"harmonic: the steady state needs at least one \[\[element\]\] table"),
]


@pytest.mark.parametrize("replace, add, message", ERRORS,
                         ids=[re.sub(r"\W+", "_", e[2])[:40] for e in ERRORS])
def test_errors_name_the_field_and_value(tmp_path, replace, add, message):
    path = small(tmp_path, replace, add, name="bad.toml")
    with pytest.raises(ValueError, match=r"bad\.toml: " + message):
        dd.load_scene(path)


def test_run_steady_needs_a_harmonic_table():
    with pytest.raises(ValueError, match=r"p3\.toml: run_steady needs a \[harmonic\] table"):
        run_steady(dd.load_scene())


# --- the command ----------------------------------------------------------------------------


def test_cli_steady_plots_and_saves(tmp_path, capsys, embedded):
    """`dtdyn steady` prints the summary, writes the plot and the curve; the .csv reads back as
    the curve of run_steady (bitwise) with the scene in its info."""
    _, (r, _) = embedded
    out, plot = tmp_path / "frc.csv", tmp_path / "frc.png"
    assert main(["steady", str(DUFFING), "--plot", str(plot), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    for line in ("harmonic balance with H = 7 harmonics over 0.05 .. 0.4 Hz",
                 f"points: {r.frequency_hz.size} (end of the range); folds: "
                 f"{r.fold_frequency_hz[0]:.6g}, {r.fold_frequency_hz[1]:.6g} Hz",
                 f"stable: {np.count_nonzero(r.stable)} of {r.stable.size} points",
                 "harmonic truncation estimate", "run time", f"results: {out}",
                 f"plot: {plot}"):
        assert line in text, line
    assert plot.stat().st_size > 10_000 and (tmp_path / "frc.csv.json").is_file()
    back = dd.load_result(out)
    assert back.info["scene"]["title"].startswith("Duffing oscillator")
    assert back.info["scene"]["harmonic"]["force"] == [[0.1, 0.0]]
    assert_same(r, back)
    assert main(["steady", str(DUFFING), "--out", str(tmp_path / "frc.npz")]) == 0
    assert_same(r, dd.load_result(tmp_path / "frc.npz"))


def test_cli_steady_errors_write_nothing(tmp_path, capsys):
    assert main(["steady", str(DUFFING), "--out", str(tmp_path / "frc.nc")]) == 2
    assert "a frequency response curve is saved as .npz or .csv" in capsys.readouterr().err
    scene = write(tmp_path, "[model]\nmass = [1.0]\nstiffness = [1.0]\n", "plain.toml")
    assert main(["steady", str(scene), "--out", str(tmp_path / "x.npz")]) == 2
    assert "dtdyn steady needs a [harmonic] table" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plain.toml"]


def test_cli_steady_newton_failure_exits_1(tmp_path, capsys):
    """A continuation that cannot go on (max_iter = 1: no corrector converges) is a run
    failure, exit 1, naming the scene."""
    path = small(tmp_path, add="max_iter = 1\n")
    assert main(["steady", str(path)]) == 1
    assert "run failed: " + str(path) in capsys.readouterr().err


# --- saving and loading ---------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_save_load_round_trip(tmp_path, suffix):
    """Every field back bitwise (complex harmonics as re / im, None fields as None, info's
    arrays as arrays), for a forced curve with stability and a base-excited one without."""
    forced = duffing()
    based = duffing(force=None, force_dofs=None, ground_acceleration=0.05, stability=False)
    for name, r in (("forced", forced), ("based", based)):
        path = r.save(tmp_path / f"{name}{suffix}")
        back = dd.load_result(path)
        assert type(back) is dd.HarmonicBalanceResult
        assert_same(r, back)
        assert back.info["run_time"] == r.info["run_time"]
    assert dd.load_result(tmp_path / f"based{suffix}").stable is None


def test_csv_layout(tmp_path):
    """One row per point, columns named by field, entry, re / im and unit; the sidecar holds
    the other fields."""
    r = duffing(outputs=[0])
    path = r.save(tmp_path / "frc.csv")
    header = path.read_text().splitlines()[0].split(",")
    assert header[:4] == ["frequency_hz [Hz]", "omega [rad/s]", "harmonics[0][0] re",
                          "harmonics[0][0] im"]
    assert "x_max[0]" in header and "stable" in header
    assert len(path.read_text().splitlines()) == r.frequency_hz.size + 1
    side = json.loads((tmp_path / "frc.csv.json").read_text())
    assert side["format"] == "dtdyn curve table" and side["type"] == "HarmonicBalanceResult"
    assert set(side["other_arrays"]) >= {"folds", "fold_frequency_hz", "outputs"}
    with pytest.raises(ValueError, match=r"a frequency response curve is saved as \.npz or "
                                         r"\.csv"):
        r.save(tmp_path / "frc.nc")


def test_unsaveable_field_is_named(tmp_path):
    r = dataclasses.replace(duffing(), amplitude=object())
    with pytest.raises(ValueError, match=r"HarmonicBalanceResult\.amplitude holds a object"):
        r.save(tmp_path / "x.npz")
    assert not list(tmp_path.iterdir())


def test_convergence_points_reach_the_call(tmp_path):
    """[harmonic] convergence_points = 0 (no H -> 2H re-solve) and = 3: as the call's."""
    for n in (0, 3):
        path = small(tmp_path, add=f"convergence_points = {n}\n")
        r, _ = run_steady(dd.load_scene(path))
        checked = np.isfinite(r.harmonic_convergence).sum()
        assert (checked == 0) if n == 0 else (1 <= checked <= n + 1)
    with pytest.raises(ValueError, match="harmonic.convergence_points"):
        dd.load_scene(small(tmp_path, add="convergence_points = -1\n"))
