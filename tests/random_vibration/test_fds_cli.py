"""`dtdyn fds`: a PSD table CSV to its VRS, ERS and FDS (and the FDS-equivalent test PSD), the
CSV and its JSON sidecar equal to the library's results, the plot, and bad input."""
import json

import numpy as np
import pytest

from dtdyn.app import main
from dtdyn.random_vibration import psd_table
from dtdyn.random_vibration._spectra import (extreme_response_spectrum, fatigue_damage_spectrum,
                                            fds_equivalent_psd, vibration_response_spectrum)

ROWS = [(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)]


@pytest.fixture
def spec(tmp_path):
    path = tmp_path / "spec.csv"
    path.write_text("f_hz,g2_hz\n" + "".join(f"{f},{g}\n" for f, g in ROWS))
    return path


def test_fds_command_writes_the_library_results(spec, tmp_path, capsys):
    out = tmp_path / "fds.csv"
    code = main([
        "fds", str(spec), "--slope", "6", "--duration", "3600", "--q", "20",
        "--freqs", "30", "1500", "9", "--test-duration", "360", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "6.058 grms" in text and "PSD equivalent to the FDS over 360 s" in text
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    meta = json.loads(out.with_name("fds.csv.json").read_text())
    assert meta["columns"] == ["freq_hz", "vrs", "ers", "fds", "test_psd"]
    assert meta["damping_ratio"] == 0.025 and meta["fds"]["slope"] == 6.0
    table = psd_table(ROWS)
    f_n = np.geomspace(30, 1500, 9)
    np.testing.assert_array_equal(data[:, 0], f_n)
    np.testing.assert_allclose(data[:, 1], vibration_response_spectrum(table, f_n, 0.025).values,
                               rtol=1e-15)
    np.testing.assert_allclose(data[:, 2], extreme_response_spectrum(
        table, f_n, 0.025, duration=3600.0).values, rtol=1e-15)
    fds = fatigue_damage_spectrum(table, f_n, 0.025, slope=6.0, duration=3600.0)
    np.testing.assert_allclose(data[:, 3], fds.values, rtol=1e-15)
    np.testing.assert_allclose(data[:, 4], fds_equivalent_psd(fds, 360.0).values, rtol=1e-15)
    assert meta["test_psd_grms"] == pytest.approx(psd_table(list(zip(f_n, data[:, 4]))).grms)


def test_fds_command_plots(spec, tmp_path):
    pytest.importorskip("matplotlib")
    plot = tmp_path / "fds.png"
    assert main(["fds", str(spec), "--slope", "8", "--duration", "60",
                 "--damping-ratio", "0.05", "--freqs", "20", "2000", "20",
                 "--plot", str(plot)]) == 0
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("extra, message", [
    (["--q", "0.4"], "--q must be finite and > 0.5"),
    (["--freqs", "100", "10", "5"], "--freqs"),
    (["--damping-ratio", "0"], "damping_ratio"),
    (["--out", "no/such/folder/x.csv"], "--out"),
])
def test_fds_command_bad_input(spec, capsys, extra, message):
    code = main(["fds", str(spec), "--slope", "4", "--duration", "10"] + extra)
    assert code == 2
    assert message in capsys.readouterr().err


def test_fds_command_bad_table(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("20,0.01,1\n80,0.04,1\n")
    assert main(["fds", str(bad), "--slope", "4", "--duration", "10"]) == 2
    assert "two columns" in capsys.readouterr().err
    assert main(["fds", str(bad), "--slope", "4", "--duration", "10", "--q", "5",
                 "--damping-ratio", "0.1"]) == 2            # argparse: not both
