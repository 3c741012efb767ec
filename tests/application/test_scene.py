"""Scenes: TOML layout, load kinds, field-naming errors, atomic result files."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from dtdyn.app._loads import sample_load
from dtdyn import Response, load_result
from dtdyn.app._scene import load_scene, plot_response, run_scene, save_results

from dtdyn.app._problems import P3_MASS, P3_STIFFNESS  # the scene file must hold P3

MODEL = """
[model]
mass = [2.0, 3.0, 1.0]
stiffness = [20.0, 15.0, 10.0]
damping = [0.5, 0.6, 0.1]
"""
SCHEME = """
[scheme]
name = "newmark"
beta = 0.25
gamma = 0.5
"""
TIME = """
[time]
dt = 0.01
duration = 1.0
"""
STEP_LOAD = """
[[load]]
dof = 2
kind = "step"
"""


def write_scene(tmp_path: Path, *, model=MODEL, loads=STEP_LOAD, scheme=SCHEME, time=TIME,
                extra="", name="scene.toml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(f'title = "test"\n{model}\n{loads}\n{scheme}\n{time}\n{extra}'))
    return path


# ---------------------------------------------------------------------------------------------
# the default scene

def test_default_scene_is_p3():
    s = load_scene(None)
    assert s.n_dof == 15
    assert_array_equal(s.mass, P3_MASS)
    assert_array_equal(s.stiffness, P3_STIFFNESS)
    assert_array_equal(s.damping, np.zeros(15))
    assert_array_equal(s.loaded, [14])
    assert s.force.shape == (801, 1)
    assert_array_equal(s.force, 1.0)
    assert s.dt == 1e-3 and s.n_steps == 800
    assert s.duration == pytest.approx(0.8)
    assert s.scheme == "average_acceleration" and s.scheme_params == {}
    assert (s.form, s.sweep, s.backend) == ("displacement", "stable", "c")
    assert_array_equal(s.outputs, np.arange(15))
    assert s.quantities == ("x",)


# ---------------------------------------------------------------------------------------------
# load kinds

def test_each_load_kind_gives_expected_samples(tmp_path):
    n = 101  # duration 1.0 / dt 0.01 -> t_0 .. t_100
    t = np.arange(n) * 0.01
    csv = np.column_stack([np.linspace(0.0, 1.0, n), np.cos(t)])
    np.savetxt(tmp_path / "f.csv", csv, delimiter=",")
    np.save(tmp_path / "g.npy", np.sin(3.0 * t))
    model = """
    [model]
    mass = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    stiffness = [10.0, 10.0, 10.0, 10.0, 10.0, 10.0, 10.0]
    """
    loads = """
    [[load]]
    dof = 0
    kind = "step"
    amplitude = 2.5
    t0 = 0.3
    [[load]]
    dof = 1
    kind = "ramp"
    slope = 3.0
    t0 = 0.25
    [[load]]
    dof = 2
    kind = "sine"
    amplitude = 0.5
    frequency = 5.0
    phase = 0.3
    [[load]]
    dof = 3
    kind = "white_noise"
    std = 2.0
    seed = 7
    [[load]]
    dof = 4
    kind = "file"
    path = "f.csv"
    column = 1
    [[load]]
    dof = 6
    kind = "file"
    path = "g.npy"
    """
    s = load_scene(write_scene(tmp_path, model=model, loads=loads))
    assert_array_equal(s.loaded, [0, 1, 2, 3, 4, 6])
    f = s.force
    assert f.shape == (n, 6)
    # step: 0 before t0 = 0.3 (sample 30), amplitude from it on
    assert_array_equal(f[:30, 0], 0.0)
    assert_array_equal(f[30:, 0], 2.5)
    # ramp: slope (t - t0) from t0 = 0.25 (sample 25)
    assert_array_equal(f[:25, 1], 0.0)
    assert_allclose(f[25:, 1], 3.0 * (t[25:] - 0.25), atol=1e-14)
    assert f[35, 1] == pytest.approx(0.3)
    # sine: amplitude sin(2 pi f t + phase)
    assert_allclose(f[:, 2], 0.5 * np.sin(2 * np.pi * 5.0 * t + 0.3), atol=1e-14)
    assert f[0, 2] == pytest.approx(0.5 * np.sin(0.3))
    assert f[5, 2] == pytest.approx(0.5 * np.sin(np.pi / 2 + 0.3))  # t = 0.05: quarter period
    # white noise: reproducible from the seed, same on a second read
    assert_array_equal(f[:, 3], 2.0 * np.random.default_rng(7).standard_normal(n))
    assert_array_equal(load_scene(s.source).force[:, 3], f[:, 3])
    # files: csv column 1, npy 1-D
    assert_allclose(f[:, 4], np.cos(t), rtol=1e-15)
    assert_array_equal(f[:, 5], np.sin(3.0 * t))


def test_loads_on_one_dof_add_up(tmp_path):
    loads = """
    [[load]]
    dof = 2
    kind = "step"
    [[load]]
    dof = 0
    kind = "ramp"
    slope = 1.0
    [[load]]
    dof = 2
    kind = "step"
    amplitude = -0.25
    t0 = 0.5
    """
    s = load_scene(write_scene(tmp_path, loads=loads))
    assert_array_equal(s.loaded, [0, 2])
    assert_allclose(s.force[:, 0], s.t)
    assert_array_equal(s.force[:50, 1], 1.0)
    assert_array_equal(s.force[50:, 1], 0.75)


def test_sample_load_direct():
    t = np.array([0.0, 0.5, 1.0, 1.5])
    assert_array_equal(sample_load({"kind": "step"}, t, Path(".")), [1.0, 1.0, 1.0, 1.0])
    assert_array_equal(sample_load({"kind": "ramp", "slope": 2.0, "t0": 0.5}, t, Path(".")),
                       [0.0, 0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match=r"load\[4\]\.std = -1\.0"):
        sample_load({"kind": "white_noise", "std": -1.0, "seed": 1}, t, Path("."), name="load[4]")


# ---------------------------------------------------------------------------------------------
# malformed scenes: every error names the field

BAD_SCENES = {
    "negative mass": (dict(model="[model]\nmass = [2.0, 3.0, 1.0, -1.0]\n"
                                 "stiffness = [1.0, 1.0, 1.0, 1.0]\n"),
                      r"model\.mass\[3\] = -1\.0"),
    "string mass": (dict(model='[model]\nmass = [2.0, "3"]\nstiffness = [1.0, 1.0]\n'),
                    r"model\.mass\[1\] = '3'"),
    "stiffness length": (dict(model="[model]\nmass = [1.0, 1.0]\nstiffness = [1.0]\n"),
                         r"model\.stiffness has length 1"),
    "zero dt": (dict(time="[time]\ndt = 0\nduration = 1.0\n"), r"time\.dt .*0"),
    "duration not a multiple": (dict(time="[time]\ndt = 0.03\nduration = 1.0\n"),
                                r"time\.duration = 1\.0"),
    "unknown scheme key": (dict(scheme='[scheme]\nname = "newmark"\nbetta = 0.25\n'),
                           r"scheme\.betta = 0\.25: unknown key, allowed: .*beta, gamma"),
    "unknown scheme": (dict(scheme='[scheme]\nname = "rk4"\n'), r"scheme\.name = 'rk4'.*houbolt"),
    "hht alpha range": (dict(scheme='[scheme]\nname = "hht"\nalpha = 0.2\n'),
                        r"scheme\.alpha = 0\.2"),
    "unknown backend": (dict(scheme='[scheme]\nname = "houbolt"\nbackend = "fortran"\n'),
                        r"scheme\.backend = 'fortran'"),
    "unknown top-level table": (dict(extra="[solver]\ntol = 1.0\n"),
                                r"solver: unknown top-level key or table, allowed: title, model"),
    "time without duration": (dict(time="[time]\ndt = 0.01\n"), r"time\.duration is required"),
    "unknown unstable": (dict(scheme='[scheme]\nunstable = "ignore"\n'),
                         r"scheme\.unstable = 'ignore': unknown value, allowed: 'raise', 'warn'"),
    "unknown load kind": (dict(loads='[[load]]\ndof = 0\nkind = "impulse"\n'),
                          r"load\[0\]\.kind = 'impulse': unknown load kind, allowed: 'step'"),
    "unknown load key": (dict(loads='[[load]]\ndof = 0\nkind = "sine"\namplitude = 1.0\n'
                                    'frequency = 2.0\nfreq = 3.0\n'),
                         r"load\[0\]\.freq = 3\.0: unknown key .*frequency"),
    "missing load field": (dict(loads='[[load]]\ndof = 0\nkind = "ramp"\n'),
                           r"load\[0\]\.slope is required"),
    "negative frequency": (dict(loads='[[load]]\ndof = 0\nkind = "sine"\namplitude = 1.0\n'
                                      'frequency = -2.0\n'), r"load\[0\]\.frequency .*-2\.0"),
    "dof out of range": (dict(loads=STEP_LOAD + '[[load]]\ndof = 3\nkind = "step"\n'),
                         r"load\[1\]\.dof = 3"),
    "seed not an integer": (dict(loads='[[load]]\ndof = 0\nkind = "white_noise"\nstd = 1.0\n'
                                       'seed = 1.5\n'), r"load\[0\]\.seed = 1\.5"),
    "load as a table": (dict(loads='[load]\ndof = 0\nkind = "step"\n'), r"\[\[load\]\]"),
    "bad output quantity": (dict(extra='[output]\nquantities = ["x", "f"]\n'),
                            r"output\.quantities\[1\] = 'f'"),
    "bad output dof": (dict(extra='[output]\noutputs = [0, 7]\n'), r"output\.outputs = \[0, 7\]"),
    "negative ground spring": (dict(model=MODEL + "ground_stiffness = [0.0, -5.0, 0.0]\n"),
                               r"model\.ground_stiffness\[1\] = -5\.0"),
    "ground damper length": (dict(model=MODEL + "ground_damping = [1.0]\n"),
                             r"model\.ground_damping has length 1"),
    "rayleigh of three": (dict(model=MODEL + "rayleigh = [0.1, 0.2, 0.3]\n"),
                          r"model\.rayleigh = \[0\.1, 0\.2, 0\.3\]: must be \[alpha, beta\]"),
}


@pytest.mark.parametrize("case", list(BAD_SCENES))
def test_malformed_scene_names_the_field(tmp_path, case):
    kwargs, pattern = BAD_SCENES[case]
    path = write_scene(tmp_path, **kwargs)
    with pytest.raises(ValueError, match=pattern) as info:
        load_scene(path)
    assert str(path) in str(info.value)


def test_toml_syntax_error_names_the_file(tmp_path):
    path = write_scene(tmp_path, extra="[output\nquantities = ['x']\n", name="broken.toml")
    with pytest.raises(ValueError, match=r"broken\.toml: invalid TOML"):
        load_scene(path)


def test_missing_scene_file(tmp_path):
    with pytest.raises(ValueError, match=r"nope\.toml"):
        load_scene(tmp_path / "nope.toml")


@pytest.mark.parametrize("suffix", [".csv", ".npy"])
def test_load_file_with_wrong_length(tmp_path, suffix):
    data = np.ones(100)  # the scene needs 101 samples
    if suffix == ".csv":
        np.savetxt(tmp_path / "f.csv", data, delimiter=",")
    else:
        np.save(tmp_path / "f.npy", data)
    loads = f'[[load]]\ndof = 1\nkind = "file"\npath = "f{suffix}"\n'
    with pytest.raises(ValueError,
                       match=rf"load\[0\]\.path = 'f{suffix}': has 100 samples, expected 101"):
        load_scene(write_scene(tmp_path, loads=loads))


def test_load_file_missing_or_bad_column(tmp_path):
    loads = '[[load]]\ndof = 1\nkind = "file"\npath = "absent.csv"\n'
    with pytest.raises(ValueError, match=r"load\[0\]\.path = 'absent\.csv': no such file"):
        load_scene(write_scene(tmp_path, loads=loads))
    np.savetxt(tmp_path / "f.csv", np.ones((101, 2)), delimiter=",")
    loads = '[[load]]\ndof = 1\nkind = "file"\npath = "f.csv"\ncolumn = 2\n'
    with pytest.raises(ValueError, match=r"load\[0\]\.column = 2: .* 2 column"):
        load_scene(write_scene(tmp_path, loads=loads))


# ---------------------------------------------------------------------------------------------
# result files

def fake_response(scene) -> Response:
    t = scene.t
    cols = scene.outputs.size
    x = np.outer(np.sin(t), np.arange(1, cols + 1))
    return Response(t=t, outputs=scene.outputs.copy(), x=x, v=2 * x, a=3 * x, info={})


def test_save_results_stores_requested_quantities(tmp_path):
    s = load_scene(write_scene(tmp_path,
                               extra='[output]\noutputs = [2, 0]\nquantities = ["x", "a"]\n'))
    r = fake_response(s)
    out = tmp_path / "res.npz"
    save_results(out, r, s)
    with np.load(out) as z:
        assert sorted(z.files) == ["a", "dtdyn_metadata", "outputs", "t", "x"]
        assert_array_equal(z["t"], r.t)
        assert_array_equal(z["outputs"], [2, 0])
        assert_array_equal(z["x"], r.x)
        assert_array_equal(z["a"], r.a)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res.npz", "scene.toml"]
    back = load_result(out)  # the scene's summary travels with the result
    assert back.v is None and back.meta["scene"]["quantities"] == ["x", "a"]
    assert back.meta["scene"]["title"] == s.title and back.meta["scene"]["dt"] == s.dt


def test_save_results_leaves_nothing_behind_on_failure(tmp_path, monkeypatch):
    s = load_scene(write_scene(tmp_path))
    r = fake_response(s)
    # a folder that does not exist: an error naming it, and nothing created anywhere
    with pytest.raises(ValueError, match="does not exist"):
        save_results(tmp_path / "missing" / "res.npz", r, s)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]

    # a write that fails half-way keeps an existing file intact and removes the temporary
    out = tmp_path / "res.npz"
    out.write_bytes(b"previous")

    def broken_savez(f, **arrays):
        f.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", broken_savez)   # the numpy the result files write with
    with pytest.raises(OSError, match="disk full"):
        save_results(out, r, s)
    assert out.read_bytes() == b"previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res.npz", "scene.toml"]


def test_save_results_missing_quantity(tmp_path):
    s = load_scene(write_scene(tmp_path, extra='[output]\nquantities = ["v"]\n'))
    r = fake_response(s)
    r.v = None
    with pytest.raises(ValueError, match=r"'v'"):
        save_results(tmp_path / "res.npz", r, s)
    assert not (tmp_path / "res.npz").exists()


def test_plot_response_writes_png(tmp_path):
    s = load_scene(write_scene(tmp_path))
    out = tmp_path / "plot.png"
    plot_response(out, fake_response(s), s)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plot.png", "scene.toml"]
    with pytest.raises(ValueError, match="unsupported format"):
        plot_response(tmp_path / "plot.xyz", fake_response(s), s)


# ---------------------------------------------------------------------------------------------
# end to end (runs once dtdyn.linear._chain.chain_response and exact.exact_response exist)

def test_run_default_scene_against_exact(tmp_path):
    s = load_scene(None)
    response, report = run_scene(s)
    assert response.x.shape == (801, 15)
    assert_array_equal(response.outputs, np.arange(15))
    assert report["n_steps"] == 800 and report["n_dof"] == 15
    assert report["scheme"] == "average_acceleration"
    # average acceleration at omega_max dt = 0.148: period error below 0.2 % per period
    assert report["max_rel_error"] is not None and report["max_rel_error"] < 1e-2
    save_results(tmp_path / "p3.npz", response, s)
    with np.load(tmp_path / "p3.npz") as z:
        assert_array_equal(z["x"], response.x)


def test_run_scene_error_shrinks_with_dt(tmp_path):
    """Newmark average acceleration is second order: halving dt quarters the error."""
    errors = []
    for dt in (0.02, 0.01):
        time = f"[time]\ndt = {dt}\nduration = 2.0\n"
        s = load_scene(write_scene(tmp_path, time=time, extra='[output]\noutputs = [0, 2]\n'))
        response, report = run_scene(s)
        assert response.x.shape == (s.n_steps + 1, 2)
        errors.append(report["max_rel_error"])
    assert errors[1] < errors[0] / 3.0


def test_ground_scene_runs_relative_to_the_support(tmp_path):
    """[ground] in units of g with no [[load]]: the run equals exact_response under the same
    record (the scene's exact check says so), and the saved result carries a_abs."""
    import dtdyn as dd
    from dtdyn.app._cli import main

    np.savetxt(tmp_path / "rec.csv", 0.3 * np.sin(2 * np.pi * 2.0 * np.arange(501) * 0.01))
    (tmp_path / "quake.toml").write_text(
        '[model]\nmass = [2e5, 2e5, 2e5]\nstiffness = [3e8, 3e8, 2e8]\ndamping = [4e5, 4e5, 4e5]\n'
        '[ground]\nkind = "file"\npath = "rec.csv"\nunits = "g"\n'
        '[scheme]\nname = "average_acceleration"\n[time]\ndt = 0.01\nduration = 5.0\n'
        '[output]\nquantities = ["x", "a"]\n')
    scene = dd.load_scene(tmp_path / "quake.toml")
    assert scene.force is None and scene.ground.max() == pytest.approx(0.3 * 9.80665, rel=1e-2)
    response, report = dd.run_scene(scene)
    assert report["check"] == "done" and np.isfinite(report["max_rel_error"])
    ag = scene.ground
    same = dd.chain_response(scene.mass, scene.stiffness, scene.damping, None, 0.01,
                             ground_acceleration=ag, scheme="average_acceleration")
    np.testing.assert_array_equal(response.x, same.x)
    M, C, K = scene.matrices()   # a 3-mass chain: dense
    ref = dd.exact_response(M, C, K, None, 0.01, ground_acceleration=ag, quantities=("x",))
    # the scene's check compares with the same exact run
    err = np.abs(response.x - ref.x).max() / np.abs(ref.x).max()
    assert err == pytest.approx(report["max_rel_error"], rel=1e-12)
    np.testing.assert_allclose(response.a_abs, response.a + ag[:, None], atol=1e-9)
    out = tmp_path / "r.npz"
    assert main(["simulate", str(tmp_path / "quake.toml"), "--out", str(out)]) == 0
    back = dd.load_result(out)
    np.testing.assert_array_equal(back.a_abs, response.a_abs)
    assert back.meta["scene"]["ground_peak_m_s2"] == pytest.approx(np.abs(ag).max())


def test_initial_state_scene(tmp_path):
    """[initial] x0, v0: free vibration of a chain with no load but the state at t_0; the run
    equals chain_response with the same x0, v0 and its exact check uses them too."""
    import dtdyn as dd

    path = tmp_path / "free.toml"
    path.write_text('[model]\nmass = [1.0, 1.0]\nstiffness = [1e4, 1e4]\ndamping = [1.0, 1.0]\n'
                    '[[load]]\ndof = 1\nkind = "step"\namplitude = 0.0\n'
                    '[initial]\nx0 = [0.0, 0.01]\nv0 = [0.5, 0.0]\n'
                    '[scheme]\nname = "average_acceleration"\n[time]\ndt = 1e-4\nduration = 0.5\n')
    scene = dd.load_scene(path)
    response, report = dd.run_scene(scene)
    same = dd.chain_response([1.0, 1.0], [1e4, 1e4], [1.0, 1.0], np.zeros(5001), 1e-4,
                             force_dofs=[1], scheme="average_acceleration", x0=[0.0, 0.01],
                             v0=[0.5, 0.0], quantities=("x",))
    np.testing.assert_array_equal(response.x, same.x)
    assert response.x[0, 1] == 0.01
    assert report["check"] == "done" and report["max_rel_error"] < 1e-3   # (omega dt)^2 / 12
    bad = path.read_text().replace("x0 = [0.0, 0.01]", "x0 = [0.0]")
    path.write_text(bad)
    with pytest.raises(ValueError, match="initial.x0 has 1 entries"):
        dd.load_scene(path)


def test_ground_record_at_its_own_step(tmp_path):
    """[ground] dt: a record sampled at 0.005 s, a scene at 0.002 s: the scene's samples are
    the record linear between its samples, and 0 after its end (the building then rings)."""
    import dtdyn as dd

    rec = np.sin(np.arange(201) * 0.005 * 2 * np.pi * 1.5)           # 1 s of record
    np.save(tmp_path / "rec.npy", rec)
    (tmp_path / "q.toml").write_text(
        '[model]\nmass = [2e5, 2e5]\nstiffness = [3e8, 2e8]\ndamping = [4e5, 4e5]\n'
        '[ground]\nkind = "file"\npath = "rec.npy"\ndt = 0.005\n'
        '[scheme]\nname = "average_acceleration"\n[time]\ndt = 0.002\nduration = 1.5\n')
    scene = dd.load_scene(tmp_path / "q.toml")
    t = np.arange(751) * 0.002
    np.testing.assert_allclose(scene.ground, np.interp(t, np.arange(201) * 0.005, rec, right=0),
                               rtol=0, atol=1e-15)
    assert np.all(scene.ground[t > 1.0 + 1e-9] == 0.0)
    (tmp_path / "bad.toml").write_text((tmp_path / "q.toml").read_text().replace(
        'kind = "file"\npath = "rec.npy"\n', 'kind = "sine"\namplitude = 1.0\nfrequency = 1.0\n'))
    with pytest.raises(ValueError, match="only a kind = \"file\" record"):
        dd.load_scene(tmp_path / "bad.toml")


def test_ground_scene_displacement_and_velocity_records(tmp_path):
    """[ground] quantity = "displacement" (m) or "velocity" (m/s): the scene runs the entry
    point with ground_displacement / ground_velocity (the same numbers), the exact check runs
    the same record, and a displacement scene saves x_abs = x + u_g. Units other than the SI
    unit of the quantity, and "g" for anything but an acceleration, are errors naming the key."""
    import dtdyn as dd
    from dtdyn.app._cli import main

    t = np.arange(301) * 0.01
    u = 0.01 * (1 - np.cos(2 * np.pi * 1.5 * t))
    np.savetxt(tmp_path / "disp.csv", u)
    np.savetxt(tmp_path / "vel.csv", np.gradient(u, 0.01))
    chain = ('[model]\nmass = [2e5, 2e5, 2e5]\nstiffness = [3e8, 3e8, 2e8]\n'
             'damping = [4e5, 4e5, 4e5]\n')
    rest = ('[scheme]\nname = "average_acceleration"\n[time]\ndt = 0.01\nduration = 3.0\n'
            '[output]\nquantities = ["x", "a"]\n')
    for quantity, name in (("displacement", "disp.csv"), ("velocity", "vel.csv")):
        path = tmp_path / f"{quantity}.toml"
        path.write_text(chain + f'[ground]\nkind = "file"\npath = "{name}"\n'
                        f'quantity = "{quantity}"\n' + rest)
        scene = dd.load_scene(path)
        assert scene.ground_quantity == quantity
        response, report = dd.run_scene(scene)
        same = dd.chain_response(scene.mass, scene.stiffness, scene.damping, None, 0.01,
                                 scheme="average_acceleration",
                                 **{f"ground_{quantity}": np.loadtxt(tmp_path / name)})
        np.testing.assert_array_equal(response.x, same.x)
        assert report["check"] == "done" and report["max_rel_error"] < 0.05
        out = tmp_path / f"{quantity}.npz"
        assert main(["simulate", str(path), "--out", str(out)]) == 0
        back = dd.load_result(out)
        assert back.meta["scene"]["ground_quantity"] == quantity
        if quantity == "displacement":
            np.testing.assert_array_equal(back.x_abs, response.x + u[:, None])
            assert back.meta["scene"]["ground_peak_m"] == pytest.approx(np.abs(u).max())
        else:
            assert back.x_abs is None
    for units, match in (('"g"', "a displacement record is in 'm' .*acceleration record"),
                         ('"m/s"', "ground.units = 'm/s': a displacement record is in 'm'")):
        path.write_text(chain + '[ground]\nkind = "file"\npath = "disp.csv"\n'
                        f'quantity = "displacement"\nunits = {units}\n' + rest)
        with pytest.raises(ValueError, match=match):
            dd.load_scene(path)
    path.write_text(chain + '[ground]\nkind = "file"\npath = "disp.csv"\nquantity = "strain"\n'
                    + rest)
    with pytest.raises(ValueError, match="ground.quantity = 'strain'"):
        dd.load_scene(path)


def test_ground_displacement_at_its_own_step_holds_its_last_sample(tmp_path):
    """A displacement record shorter than the scene, at its own dt: linear between its samples,
    then the ground stays where the record ends (an acceleration record is 0 there)."""
    import dtdyn as dd

    rec = 0.01 * np.sin(np.arange(201) * 0.005 * np.pi / 2)        # 1 s, ends at 0.01 m
    np.save(tmp_path / "d.npy", rec)
    (tmp_path / "q.toml").write_text(
        '[model]\nmass = [2e5, 2e5]\nstiffness = [3e8, 2e8]\ndamping = [4e5, 4e5]\n'
        '[ground]\nkind = "file"\npath = "d.npy"\ndt = 0.005\nquantity = "displacement"\n'
        '[scheme]\nname = "average_acceleration"\n[time]\ndt = 0.002\nduration = 1.5\n')
    scene = dd.load_scene(tmp_path / "q.toml")
    t = np.arange(751) * 0.002
    np.testing.assert_allclose(scene.ground, np.interp(t, np.arange(201) * 0.005, rec),
                               rtol=0, atol=1e-15)
    assert np.all(scene.ground[t > 1.0] == rec[-1])


def test_chain_scene_with_ground_elements_and_rayleigh(tmp_path):
    """[model] ground_stiffness, ground_damping and rayleigh (chain form of alpha M + beta K):
    the scene's matrices are the hand assembly, its run equals chain_response with the same
    keywords, and the exact check passes at the scheme's error."""
    import dtdyn as dd

    model = MODEL + "ground_stiffness = [0.0, 12.0, 4.0]\nground_damping = [0.3, 0.0, 0.0]\n" \
                    "rayleigh = [0.2, 1e-3]\n"
    scene = load_scene(write_scene(tmp_path, model=model))
    M, C, K = scene.matrices(sparse=False)
    k, c = np.array([20.0, 15.0, 10.0]), np.array([0.5, 0.6, 0.1])
    K_hand = np.diag(k + np.append(k[1:], 0.0) + [0.0, 12.0, 4.0]) \
        - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    C_plain = np.diag(c + np.append(c[1:], 0.0) + [0.3, 0.0, 0.0]) \
        - np.diag(c[1:], 1) - np.diag(c[1:], -1)
    assert_allclose(K, K_hand, rtol=1e-15)
    assert_allclose(C, C_plain + 0.2 * M + 1e-3 * K_hand, rtol=1e-14)
    response, report = run_scene(scene)
    same = dd.chain_response(**scene.chain, force=scene.force, dt=scene.dt,
                             force_dofs=scene.loaded, scheme="newmark")
    assert_array_equal(response.x, same.x)
    # average acceleration at dt = 0.01 on this model: error ~ (omega dt)^2 / 12 of the response
    assert report["max_rel_error"] < 1e-3
