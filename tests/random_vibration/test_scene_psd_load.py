"""Scenes with `kind = "psd"` loads: a chain driven by a synthesized random force answers with
the variance `chain_random_response` predicts (within the statistical error of a finite
record), a `[ground]` record of that kind has the table's mean square, and errors name the
field."""
import textwrap

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.random_vibration import chain_random_response, psd_table

BREAKPOINTS = [[5.0, 1.0], [40.0, 1.0], [100.0, "-6 dB/oct"]]
SCENE = """
title = "a chain under a random force"
[model]
mass = [1.0, 1.0, 1.0]
stiffness = [4e4, 4e4, 4e4]
damping = [60.0, 60.0, 60.0]
[[load]]
dof = 2
kind = "psd"
psd = [[5.0, 1.0], [40.0, 1.0], [100.0, "-6 dB/oct"]]   # N^2/Hz
seed = 3
[scheme]
name = "average_acceleration"
[time]
dt = 5e-4
duration = 100.0
[output]
quantities = ["x"]
"""


def test_chain_under_a_psd_load_has_the_predicted_variance(tmp_path):
    path = tmp_path / "random.toml"
    path.write_text(textwrap.dedent(SCENE))
    scene = dd.load_scene(path)
    table = psd_table(BREAKPOINTS)
    force = scene.force[:, 0]
    T = scene.n_steps * 5e-4
    f = np.geomspace(5.0, 100.0, 20_001)
    assert abs(force.var() / table.mean_square - 1) < 4 * np.sqrt(
        np.trapezoid(table(f) ** 2, f) / T) / table.mean_square
    response, report = dd.run_scene(scene)
    assert report["check"] == "done" and report["max_rel_error"] < 1e-2
    r = chain_random_response([1.0] * 3, [4e4] * 3, [60.0] * 3, table, f, force_dofs=[2],
                              quantities=("x",))
    # the sample variance of a Gaussian output: std sqrt(int G_x^2 df / T); average
    # acceleration's period error (omega dt)^2 / 12 <= 3e-4 here is far below it
    G = np.real(np.einsum("fii->fi", r.x_psd))
    std = np.sqrt(np.trapezoid(G**2, f, axis=0) / T)
    measured = np.mean(response.x[response.t > 1.0] ** 2, axis=0)   # past the start-up
    assert np.all(np.abs(measured - r.m0["x"]) < 4 * std), (measured / r.m0["x"], std / r.m0["x"])


def test_ground_record_of_kind_psd(tmp_path):
    path = tmp_path / "ground.toml"
    path.write_text(textwrap.dedent("""
        [model]
        mass = [1.0, 1.0]
        stiffness = [4e4, 4e4]
        damping = [60.0, 60.0]
        [ground]
        kind = "psd"
        psd = [[5.0, 0.01], [80.0, 0.04], [200.0, 0.04]]   # (m/s^2)^2/Hz
        seed = 1
        [time]
        dt = 1e-3
        duration = 200.0
        """))
    scene = dd.load_scene(path)
    table = psd_table([[5.0, 0.01], [80.0, 0.04], [200.0, 0.04]])
    f = np.geomspace(5.0, 200.0, 20_001)
    std = np.sqrt(np.trapezoid(table(f) ** 2, f) / 200.0)
    assert abs(scene.ground.var() - table.mean_square) < 4 * std
    again = dd.load_scene(path)
    np.testing.assert_array_equal(scene.ground, again.ground)      # seeded


@pytest.mark.parametrize("load, message", [
    ('psd = [[5.0, 1.0], [900.0, 1.0]]\nseed = 0', r"load\[0\]\.psd reaches 900 Hz.*Nyquist"),
    ('psd = [[5.0, 1.0], [4.0, 1.0]]\nseed = 0', r"load\[0\]\.psd = .*increasing"),
    ('psd = [[5.0, "+3 dB"], [40.0, 1.0]]\nseed = 0', r"load\[0\]\.psd = .*slope"),
    ('psd = "table.csv"\nseed = 0', r"load\[0\]\.psd = 'table.csv': give breakpoints"),
    ('psd = [[5.0, 1.0], [40.0, 1.0]]', r"load\[0\]\.seed is required"),
    ('psd = [[5.0, 1.0], [40.0, 1.0]]\nseed = 1.5', r"load\[0\]\.seed = 1.5"),
])
def test_errors_name_the_field(tmp_path, load, message):
    path = tmp_path / "bad.toml"
    path.write_text('[model]\nmass = [1.0]\nstiffness = [1e4]\ndamping = [1.0]\n'
                    f'[[load]]\ndof = 0\nkind = "psd"\n{load}\n'
                    '[time]\ndt = 1e-3\nduration = 1.0\n')
    with pytest.raises(ValueError, match=message):
        dd.load_scene(path)


def test_ground_shock_load_meets_its_srs(tmp_path):
    """`[ground] kind = "shock"`: the record starts at t0 and its SRS (an independent run of
    shock_response_spectrum on the 1/12-octave grid) is within 1.5 dB of the target."""
    scene = dd.scene_from_dict({
        "model": {"mass": [1.0, 1.0], "stiffness": [4e4, 4e4], "damping": [10.0, 10.0]},
        "ground": {"kind": "shock", "srs": [[20.0, 10.0], [100.0, 50.0], [500.0, 50.0]],
                   "seed": 0, "t0": 0.05},
        "time": {"dt": 1e-4, "duration": 1.5}}, base_dir=tmp_path)
    a = scene.ground
    a = np.asarray(a if not isinstance(a, tuple) else a[0]).ravel()
    assert not a[:int(0.05 / 1e-4)].any() and np.abs(a).max() > 0
    f = np.geomspace(20.0, 500.0, int(np.ceil(12 * np.log2(25.0))) + 1)
    target = np.interp(np.log(f), np.log([20.0, 100.0, 500.0]), np.log([10.0, 50.0, 50.0]))
    srs = dd.shock_response_spectrum(a, 1e-4, freqs_hz=f, damping_ratio=0.05).maximax
    assert np.abs(20 * np.log10(srs / np.exp(target))).max() < 1.5
    with pytest.raises(ValueError, match="ground: the shock lasts"):
        dd.scene_from_dict({
            "model": {"mass": [1.0], "stiffness": [4e4]},
            "ground": {"kind": "shock", "srs": [[20.0, 10.0], [500.0, 50.0]], "seed": 0},
            "time": {"dt": 1e-4, "duration": 0.2}}, base_dir=tmp_path)
