"""Warnings as a user meets them: at the line of the user's script (never dtdyn's source),
each distinct one once per call, none from the default spectra of an ordinary record, and in a
batch once each in the summary with a count instead of one line per case; the renamed SRS
keywords and fields still work for one release with a DeprecationWarning."""
import os
import re
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

import dtdyn as dd
from dtdyn import DtdynStabilityWarning, SRSSamplingWarning
from dtdyn.app._batch import Spectrum
from dtdyn.app._cli import main

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = Path(dd.__file__).resolve().parent
EXAMPLE = ROOT / "examples/batch"


def _run_script(path: Path, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHONWARNINGS")}
    return subprocess.run([sys.executable, str(path)], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, env=env)


def _warning_lines(stderr: str, category: str) -> list[tuple[str, int]]:
    """(file, line) of each ``file:line: Category: message`` line of a warnings printout."""
    return [(m.group(1), int(m.group(2)))
            for m in re.finditer(rf"^(.*?):(\d+): {category}: ", stderr, re.MULTILINE)]


def _ordinary_record(n=2001, dt=0.01, seed=0) -> np.ndarray:
    """A 100 Hz earthquake-like record (m/s^2): white noise through a Kanai-Tajimi filter
    (2.5 Hz, 0.6) under a trapezoidal envelope, as examples/batch/make_records.py."""
    import scipy.signal

    t = np.arange(n) * dt
    wg, zg = 2 * np.pi * 2.5, 0.6
    _, ag, _ = scipy.signal.lsim(([2 * zg * wg, wg**2], [1.0, 2 * zg * wg, wg**2]),
                                 np.random.default_rng(seed).standard_normal(n), t)
    ag *= np.minimum(t / 2.0, 1.0) * np.where(t > 8.0, np.exp(-0.5 * (t - 8.0)), 1.0)
    return 3.0 * ag / np.abs(ag).max()


# --- at the user's line ----------------------------------------------------------------------
def test_warnings_point_at_the_script_line(tmp_path):
    """A stability warning from chain_response, from a scene (check_stability, what run_scene
    and `dtdyn simulate` call) and an SRS sampling warning, in a script run as a user runs it:
    each printed line names the script and the line of the call, none names dtdyn's source."""
    (tmp_path / "scene.toml").write_text(textwrap.dedent("""\
        title = "three masses, dt past fox_goodwin's limit"
        [model]
        mass = [1.0, 1.0, 1.0]
        stiffness = [1e4, 1e4, 1e4]
        [[load]]
        dof = 0
        kind = "step"
        amplitude = 1.0
        [scheme]
        name = "fox_goodwin"
        [time]
        dt = 0.1
        duration = 1.0
        """))
    script = tmp_path / "user_script.py"
    script.write_text(textwrap.dedent("""\
        import numpy as np
        import dtdyn as dd
        from dtdyn.app._scene import check_stability, run_scene

        m, k, c = np.ones(3), np.full(3, 1e4), np.zeros(3)
        F = np.zeros((50, 3)); F[:, 0] = 1.0
        r = dd.chain_response(m, k, c, F, 0.1, scheme="fox_goodwin", unstable="warn")  # line 7
        scene = dd.load_scene("scene.toml")
        check_stability(scene)                                                      # line 9
        a = np.sin(np.arange(200) / 3.0)
        s = dd.shock_response_spectrum(a, 0.001, [10.0, 250.0])                     # line 11
        response, report = run_scene(scene, unstable="warn", check=False)           # line 12
        print("done")
        """))
    proc = _run_script(script, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "done"
    stability = _warning_lines(proc.stderr, "DtdynStabilityWarning")
    sampling = _warning_lines(proc.stderr, "SRSSamplingWarning")
    assert stability == [(str(script), 7), (str(script), 9), (str(script), 12)], proc.stderr
    assert sampling == [(str(script), 11)], proc.stderr
    assert str(PACKAGE) not in proc.stderr, proc.stderr


def test_warn_names_the_first_frame_outside_dtdyn():
    """In-process: the warning's filename is this file, through public wrappers and a
    scene's internal helpers."""
    m, k, c = np.ones(3), np.full(3, 1e4), np.zeros(3)
    F = np.zeros((20, 3))
    with pytest.warns(DtdynStabilityWarning) as rec:
        dd.chain_response(m, k, c, F, 0.1, scheme="fox_goodwin", unstable="warn")
    assert [Path(w.filename).resolve() for w in rec] == [Path(__file__).resolve()]


# --- once per call ---------------------------------------------------------------------------
def test_response_spectrum_warns_once_for_all_damping_ratios():
    """Periods too short for the record, four damping ratios (eight filter banks): one
    SRSSamplingWarning, naming the shortest period, its samples and its bias bound."""
    ag = _ordinary_record()
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        dd.response_spectrum(ag, 0.01, [0.02, 0.05, 1.0], damping_ratio=[0.0, 0.02, 0.05, 0.1])
    assert [w.category for w in rec] == [SRSSamplingWarning]
    text = str(rec[0].message)
    bound = 1 - np.sinc(0.01 / 0.02) ** 2          # 59.5 % at 2 samples per period
    assert "T = 0.02 s spans 2 samples" in text and f"{100 * bound:.3g} %" in text, text
    assert "2 of 3 periods" in text, text


# --- the defaults stay within what the record resolves ---------------------------------------
def test_default_spectrum_of_a_100_hz_record_is_quiet():
    """response_spectrum's default periods, `dtdyn spectrum` and `dtdyn srs` with their
    defaults, and the batch's srs reducer on a 100 Hz record: no SRSSamplingWarning."""
    ag = _ordinary_record()
    with warnings.catch_warnings():
        warnings.simplefilter("error", SRSSamplingWarning)
        s = dd.response_spectrum(ag, 0.01)
        T = Spectrum().resolved(0.01).periods       # the batch's srs reducer's periods
        dd.response_spectrum(ag, 0.01, T)
        fs = 100.0
        dd.shock_response_spectrum(ag, 0.01, np.geomspace(fs / 1e4, fs / 10, 100))
    assert s.periods[0] == pytest.approx(0.1) and s.periods[-1] == pytest.approx(5.0)
    # the explicit periods of the old defaults still warn: the user chose them
    for old in (np.geomspace(0.02, 5.0, 60), np.geomspace(0.05, 4.0, 40)):
        with pytest.warns(SRSSamplingWarning):
            dd.response_spectrum(ag, 0.01, old)


def test_default_commands_on_a_100_hz_record_print_no_warning(tmp_path, capsys):
    rec = tmp_path / "eq.csv"
    np.savetxt(rec, _ordinary_record())
    assert main(["spectrum", str(rec), "--dt", "0.01"]) == 0
    out = capsys.readouterr()
    assert "warning" not in out.err and "T [s]" in out.out, out.err
    assert main(["srs", str(rec), "--dt", "0.01"]) == 0
    out = capsys.readouterr()
    assert "warning" not in out.err and "maximax" in out.out, out.err
    assert main(["spectrum", str(rec), "--dt", "0.01", "--periods", "0.02", "5", "10"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning:") == 1 and "T = 0.02 s spans 2 samples" in err, err


def test_srs_default_frequencies_sampled_peaks_against_exact():
    """`dtdyn srs`'s default frequencies (fs/1e4 .. fs/10) with peaks picked at the samples:
    at most 1 - cos(pi/10) = 4.9 % below the exact peaks (the bound), on an ordinary record."""
    ag = _ordinary_record(seed=2)
    f = np.geomspace(1e-2, 10.0, 100)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SRSSamplingWarning)
        sampled = dd.shock_response_spectrum(ag, 0.01, f)
        exact = dd.shock_response_spectrum(ag, 0.01, f, exact_peaks=True)
    shortfall = 1 - sampled.maximax / exact.maximax
    assert shortfall.min() >= -1e-12
    assert shortfall.max() <= 1 - np.cos(np.pi / 10)


# --- renamed SRS keywords and fields ---------------------------------------------------------
def test_renamed_srs_keywords_and_fields_warn_and_agree():
    a = np.sin(np.arange(400) / 7.0) * np.hanning(400)
    new = dd.shock_response_spectrum(ground_acceleration=a, dt=1e-3, freqs_hz=[5.0, 20.0],
                                     damping_ratio=0.02)
    with pytest.warns(DeprecationWarning, match="'accel' is now 'ground_acceleration'"):
        old = dd.shock_response_spectrum(accel=a, dt=1e-3, freqs_hz=[5.0, 20.0],
                                         damping_ratio=0.02)
    np.testing.assert_array_equal(old.maximax, new.maximax)
    with pytest.warns(DeprecationWarning) as rec:
        old = dd.shock_response_spectrum(a, 1e-3, freqs=[5.0, 20.0], damping=0.02)
    assert {str(w.message).split(":")[1].split(";")[0].strip() for w in rec} == {
        "the keyword 'freqs' is now 'freqs_hz'", "the keyword 'damping' is now 'damping_ratio'"}
    np.testing.assert_array_equal(old.maximax, new.maximax)
    assert new.info["damping_ratio"] == 0.02
    with pytest.warns(DeprecationWarning, match="SRS.freqs is now SRS.freqs_hz"):
        np.testing.assert_array_equal(new.freqs, new.freqs_hz)
    with pytest.raises(AttributeError):
        new.freqs = np.zeros(2)                         # read-only
    with pytest.raises(TypeError, match="both 'damping' and its new name 'damping_ratio'"):
        dd.shock_response_spectrum(a, 1e-3, [5.0], damping=0.02, damping_ratio=0.02)

    t, y = dd.sdof_response(ground_acceleration=a, dt=1e-3, freqs_hz=[5.0], damping_ratio=0.1)
    with pytest.warns(DeprecationWarning):
        t_old, y_old = dd.sdof_response(accel=a, dt=1e-3, freqs=[5.0], damping=0.1)
    np.testing.assert_array_equal(y_old, y)

    ag = _ordinary_record(n=501)
    spec = dd.response_spectrum(ag, 0.01, [0.2, 1.0], damping_ratio=[0.02, 0.05])
    with pytest.warns(DeprecationWarning, match="'damping' is now 'damping_ratio'"):
        old = dd.response_spectrum(ag, 0.01, [0.2, 1.0], damping=[0.02, 0.05])
    np.testing.assert_array_equal(old.sa, spec.sa)
    with pytest.warns(DeprecationWarning, match="ResponseSpectrum.damping is now"):
        np.testing.assert_array_equal(spec.damping, [0.02, 0.05])
    with pytest.raises(AttributeError):
        spec.damping = np.zeros(2)


def test_batch_spectrum_damping_ratio():
    with pytest.warns(DeprecationWarning, match="'damping' is now 'damping_ratio'"):
        old = Spectrum(periods=(0.1, 1.0), damping=0.02)
    assert old == Spectrum(periods=(0.1, 1.0), damping_ratio=0.02)
    with pytest.warns(DeprecationWarning):
        assert old.damping == 0.02
    # 40 periods from max(0.05 s, 10 dt) to 4 s (docs/batch.md)
    assert Spectrum().resolved(0.01).periods == tuple(np.geomspace(max(0.05, 10 * 0.01), 4.0, 40))
    assert Spectrum().resolved(0.001).periods[0] == pytest.approx(0.05)


# --- a batch: the workers' warnings once each, with a count -----------------------------------
BATCH_SCRIPT = """\
import numpy as np
from distributed import Client, LocalCluster

from dtdyn.app._batch import Spectrum, run_batch
from dtdyn.app._cli import main

if __name__ == "__main__":
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=40) as cluster, \\
            Client(cluster) as client:
        print("== cli", flush=True)
        rc = main(["batch", "building.toml", "--vary", "records.csv", "--reduce",
                   "drift,peak,srs", "--scheduler", cluster.scheduler_address,
                   "--out", "cli.zarr"])
        print("rc", rc, flush=True)
        print("== explicit", flush=True)
        short = Spectrum(periods=tuple(np.geomspace(0.05, 4.0, 40)))
        ds = run_batch("building.toml", vary="records.csv", client=client,
                       reduce=["drift", short])
        print("message0", str(ds["message"].values[0])[:60], flush=True)
        print("== quiet", flush=True)
        ds = run_batch("building.toml", vary="records.csv", client=client,
                       reduce=["drift", short], progress=False)
        print("end", flush=True)
"""


@pytest.mark.skipif(not all(__import__("importlib").util.find_spec(m)
                            for m in ("distributed", "xarray", "zarr")),
                    reason="needs the [batch] extra")
def test_batch_prints_each_warning_once_with_a_count(tmp_path):
    """`dtdyn batch ... --reduce drift,peak,srs` on the building example and its records:
    no warning at all (the default periods). With periods the records do not resolve
    (0.05 s = 5 samples): the summary prints one line `SRSSamplingWarning x4: ...`, no line
    per case, each case's message holds it; with progress=False it is one Python warning at
    the script's line, counted."""
    import shutil

    shutil.copy(EXAMPLE / "building.toml", tmp_path)
    subprocess.run([sys.executable, str(EXAMPLE / "make_records.py"), str(tmp_path),
                    "--count", "4"], check=True, capture_output=True)
    script = tmp_path / "batch_script.py"
    script.write_text(BATCH_SCRIPT)
    proc = _run_script(script, tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    out, err = proc.stdout, proc.stderr
    cli = out.split("== cli")[1].split("== explicit")[0]
    explicit = out.split("== explicit")[1].split("== quiet")[0]
    assert "rc 0" in cli and "4 cases: 4 done, 0 failed" in cli, out
    assert "Warning" not in cli, out
    assert len(re.findall(r"SRSSamplingWarning", explicit)) == 1, out
    assert re.search(r"^  SRSSamplingWarning x4: the shortest period T = 0.05 s spans 5 "
                     r"samples", explicit, re.MULTILINE), out
    assert "message0 warning: the shortest period T = 0.05 s" in explicit, out
    # no warning printed by the workers, one Python warning (progress=False) at the line of
    # the call (its first line)
    quiet_line = BATCH_SCRIPT.splitlines().index('        print("== quiet", flush=True)') + 2
    assert err.count("SRSSamplingWarning") == 1, err
    assert _warning_lines(err, "SRSSamplingWarning") == [(str(script), quiet_line)], err
    assert "4 of 4 case(s): the shortest period" in err, err
    assert str(PACKAGE) not in err, err


def test_command_prints_a_warning_as_one_line_naming_the_command(tmp_path, capsys):
    scene = tmp_path / "unstable.toml"
    scene.write_text('[model]\nmass = [1.0, 1.0]\nstiffness = [1e6, 1e6]\ndamping = [1.0, 1.0]\n'
                     '[[load]]\ndof = 1\nkind = "step"\n[time]\ndt = 0.01\nduration = 0.1\n'
                     '[scheme]\nname = "average_acceleration"\n')
    assert main(["simulate", str(scene), "--no-check", "--out", str(tmp_path / "r.npz")]) == 0
    assert main(["simulate", str(scene), "--no-check"]) == 0
    scene.write_text(scene.read_text().replace("average_acceleration", "linear_acceleration")
                     + 'unstable = "warn"\n')
    capsys.readouterr()
    assert main(["simulate", str(scene), "--no-check"]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(err) == 1, err                          # once, though two checks see it
    assert err[0].startswith("dtdyn simulate: warning: DtdynStabilityWarning: scheme "
                             "'linear_acceleration' is unstable at dt = 0.01 s")
    assert ".py:" not in err[0] and "bin/dtdyn" not in err[0]
