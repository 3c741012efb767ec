"""Results save and load both ways with their metadata (.npz, .nc, .csv), atomically, and an
unknown extension or a bad folder is refused before anything is written. A .csv is a plain
table that pandas reads with its defaults (one header row, ``t [s]``, columns named by
quantity, DOF and unit), its metadata in the JSON sidecar ``<name>.csv.json``."""
import json
from pathlib import Path

import numpy as np
import pytest

import dtdyn as dd

FORMATS = ["npz", "nc", "csv"]


@pytest.fixture(scope="module")
def chain_result():
    r = dd.chain_response([2.0, 3.0], [20.0, 15.0], [5.0, 6.0], np.ones(201), 0.02,
                          force_dofs=[1], scheme="hht", alpha=-0.1, outputs=[1, 0],
                          quantities=("x", "a"))
    r.meta.update(title="P2", units={"x": "m", "a": "m/s^2"})
    return r


@pytest.mark.parametrize("ext", FORMATS)
def test_round_trip_is_bitwise(chain_result, tmp_path, ext):
    r = chain_result
    back = dd.load_result(r.save(tmp_path / f"r.{ext}"))
    np.testing.assert_array_equal(back.t, r.t)
    np.testing.assert_array_equal(back.outputs, r.outputs)
    for q in ("x", "a"):
        np.testing.assert_array_equal(getattr(back, q), getattr(r, q))
    assert back.v is None
    assert back.info["scheme"] == "hht" and back.info["params"] == {"alpha": -0.1}
    assert back.info["dt"] == 0.02 and back.info["n_steps"] == 200
    assert back.meta["title"] == "P2" and back.meta["units"]["a"] == "m/s^2"
    assert set(back.meta["versions"]) == {"dtdyn", "numpy", "scipy"}


@pytest.mark.parametrize("ext", FORMATS)
def test_dof_names_and_array_info(tmp_path, ext):
    r = dd.Response(np.arange(4) * 0.5, np.array([3, 7]), x=np.arange(8.0).reshape(4, 2),
                    info={"history": np.linspace(0, 1, 4), "count": np.int64(3)},
                    dof_names=("roof", "floor"))
    back = dd.load_result(r.save(tmp_path / f"r.{ext}"))
    assert back.dof_names == ("roof", "floor") and back.info["count"] == 3
    np.testing.assert_array_equal(back.info["history"], r.info["history"])  # .csv: in the sidecar


def test_xarray_view(chain_result):
    ds = chain_result.to_xarray()
    assert ds["x"].dims == ("time", "dof") and list(ds["dof"].values) == [1, 0]
    assert "v" not in ds and "dtdyn_metadata" in ds.attrs


@pytest.mark.parametrize("name, message", [
    ("r.txt", "unknown result format '.txt'"), ("r", r"unknown result format '\(none\)'"),
    ("missing/r.npz", "does not exist"),
])
def test_bad_paths_are_refused_before_writing(chain_result, tmp_path, name, message):
    with pytest.raises(ValueError, match=message):
        chain_result.save(tmp_path / name)
    assert list(tmp_path.iterdir()) == []


def test_a_folder_is_not_a_file(chain_result, tmp_path):
    (tmp_path / "out.npz").mkdir()
    with pytest.raises(ValueError, match="is a folder"):
        chain_result.save(tmp_path / "out.npz")


@pytest.mark.parametrize("ext, junk", [("npz", b"not a zip"), ("nc", b"CDF\x01 broken"),
                                       ("csv", b"t,x[0]\n1,2\n")])
def test_corrupt_file_gives_a_clear_error(tmp_path, ext, junk):
    path = tmp_path / f"bad.{ext}"
    path.write_bytes(junk)
    with pytest.raises(ValueError, match="not a dtdyn result file"):
        dd.load_result(path)
    with pytest.raises(FileNotFoundError):
        dd.load_result(tmp_path / f"none.{ext}")


# ---------------------------------------------------------------------------------------------
# the CSV table: one header row, t [s], columns by quantity, DOF name and unit; a JSON sidecar

TWO_STORY = Path(dd.__file__).parent / "app" / "scenes" / "two_story.toml"


def test_cli_out_csv_reads_with_pandas_defaults(tmp_path, capsys):
    """`dtdyn simulate --out ts.csv` on the shipped two-story scene: pandas.read_csv with
    default arguments gives ``t [s]`` and one column per stored quantity and DOF named as the
    scene names it, with the values of the same scene run through the API."""
    pd = pytest.importorskip("pandas")
    from dtdyn.app._cli import main

    out = tmp_path / "ts.csv"
    assert main(["simulate", str(TWO_STORY), "--no-check", "--out", str(out)]) == 0
    assert f"results: {out} (metadata: {out}.json)" in capsys.readouterr().out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ts.csv", "ts.csv.json"]
    df = pd.read_csv(out)
    names = ("floor_1", "floor_2", "roof")
    assert list(df.columns) == (["t [s]"] + [f"x {n} [m]" for n in names]
                                + [f"a {n} [m/s^2]" for n in names])
    assert df.shape == (801, 7) and all(dt.kind == "f" for dt in df.dtypes)
    r, _ = dd.run_scene(dd.load_scene(TWO_STORY), check=False)
    np.testing.assert_array_equal(df["t [s]"].to_numpy(), r.t)
    for j, name in enumerate(names):  # pandas' own float parser: to the last bit or one ulp
        np.testing.assert_allclose(df[f"x {name} [m]"], r.x[:, j], rtol=4e-16, atol=0)
        np.testing.assert_allclose(df[f"a {name} [m/s^2]"], r.a[:, j], rtol=4e-16, atol=0)
    back = dd.load_result(out)  # bitwise, with the scene's metadata
    np.testing.assert_array_equal(back.x, r.x)
    np.testing.assert_array_equal(back.a, r.a)
    assert back.v is None and back.dof_names == names and back.outputs.tolist() == [0, 1, 2]
    assert back.meta["scene"]["kind"] == "matrices" and back.info["scheme"] == r.info["scheme"]


def _same(back, r):
    """Every array, the DOF names and kinds, and the JSON-safe info of ``r`` in ``back``."""
    for q in ("t", "outputs", "x", "v", "a", "a_abs", "x_abs", "g", "z"):
        mine, theirs = getattr(r, q), getattr(back, q)
        assert (mine is None) == (theirs is None), q
        if mine is not None:
            np.testing.assert_array_equal(theirs, mine, err_msg=q)
    for name in ("dof_names", "dof_kinds", "element_kinds", "state_kinds"):
        assert getattr(back, name) == getattr(r, name), name
    for key, value in r.info.items():
        if isinstance(value, np.ndarray) and value.size > 1:
            np.testing.assert_array_equal(back.info[key], value, err_msg=key)
        else:
            assert json.dumps(back.info[key]) == json.dumps(value, default=lambda v: v.item()), key


@pytest.mark.parametrize("ext", FORMATS)
def test_round_trip_keeps_dof_names_and_kinds(tmp_path, ext):
    """A shaft (rotations), a beam mixing w and psi outputs, and a nonlinear beam with a gap on
    a w DOF and a Bouc-Wen spring on a psi DOF (g, z) read back equal, kinds and all."""
    shaft = dd.Shaft([1.0, 2.0, 1.5], [1e4, 2e4, 2e4], [1.0, 1.0, 1.0])
    beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=10)
    runs = {
        "shaft": dd.shaft_response(shaft, np.ones(101), 1e-3, force_dofs=["main.2"]),
        "beam": dd.beam_response(beam, np.ones(51), 1e-4, force_dofs=["w10"],
                                 outputs=["w10", "psi10", "w5"], backend="numpy"),
        "nonlinear beam": dd.nonlinear_beam_response(
            beam, np.full(51, 100.0), 1e-4, force_dofs=["w10"], backend="numpy",
            elements=[dd.Gap(beam.dof("w10"), gap=1e-6, stiffness=1e7),
                      dd.BoucWen(beam.dof("psi5"), stiffness=1e5, beta=50.0, gamma=50.0)],
            outputs=["psi10", "w10"], quantities=("x", "a", "g", "z")),
    }
    assert runs["shaft"].dof_kinds == ("rotation",) * 3
    assert runs["beam"].dof_kinds == ("translation", "rotation", "translation")
    nl = runs["nonlinear beam"]
    assert nl.element_kinds == ("translation", "rotation") and nl.state_kinds == ("rotation",)
    for what, r in runs.items():
        back = dd.load_result(r.save(tmp_path / f"{what.replace(' ', '_')}.{ext}"))
        _same(back, r)


def test_csv_columns_carry_units_from_the_dof_kinds(tmp_path):
    shaft = dd.Shaft([1.0, 2.0], [1e4, 2e4], [1.0, 1.0])
    r = dd.nonlinear_shaft_response(shaft, np.full(51, 5.0), 1e-3, force_dofs=["main.1"],
                                    elements=[dd.BoucWen(1, stiffness=1e3, beta=50.0,
                                                         gamma=50.0)],
                                    quantities=("v", "a", "g", "z"), backend="numpy")
    path = r.save(tmp_path / "s.csv")
    assert path.read_text().splitlines()[0] == (
        "t [s],v main.0 [rad/s],v main.1 [rad/s],a main.0 [rad/s^2],a main.1 [rad/s^2],"
        "g 0 [N m],z 0 [rad]")
    chain = dd.Response(np.arange(3.0), np.array([4, 1]), x=np.zeros((3, 2)),
                        a_abs=np.ones((3, 2)), dof_names=("top, left", "b"))
    path = chain.save(tmp_path / "c.csv")  # a comma in a name is quoted, as CSV says
    assert path.read_text().splitlines()[0] == (
        't [s],"x top, left [m]",x b [m],"a_abs top, left [m/s^2]",a_abs b [m/s^2]')
    assert dd.load_result(path).dof_names == ("top, left", "b")
    unnamed = dd.Response(np.arange(3.0), np.array([4, 1]), x=np.zeros((3, 2)))
    assert unnamed.save(tmp_path / "u.csv").read_text().startswith("t [s],x 4 [m],x 1 [m]\n")


def test_sidecar_holds_the_metadata(tmp_path, chain_result):
    path = chain_result.save(tmp_path / "r.csv")
    text = path.read_text()
    assert not text.startswith("#") and text.count("\n") == 202  # header + 201 samples
    side = json.loads((tmp_path / "r.csv.json").read_text())
    assert side["format"] == "dtdyn result table" and side["table"] == "r.csv"
    assert side["columns"] == text.splitlines()[0].split(",")
    assert side["layout"] == [["x", 2], ["a", 2]] and side["outputs"] == [1, 0]
    assert side["info"]["scheme"] == "hht" and side["meta"]["title"] == "P2"


def test_csv_sidecar_missing_or_not_matching(tmp_path, chain_result):
    path = chain_result.save(tmp_path / "r.csv")
    side = tmp_path / "r.csv.json"
    good = side.read_text()
    side.unlink()
    with pytest.raises(ValueError, match=r"sidecar 'r\.csv\.json' is missing"):
        dd.load_result(path)
    meta = json.loads(good)
    meta["columns"][1] = "x 7 [m]"
    side.write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="differs from the columns in 'r.csv.json'"):
        dd.load_result(path)
    side.write_text(good)
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:-1]))  # one sample short
    with pytest.raises(ValueError, match=r"the table is 200 x 5; 'r.csv.json' says 201 x 5"):
        dd.load_result(path)
    lines[5] = lines[5].replace(lines[5].split(",")[1], "0.5", 1)  # a value edited by hand
    path.write_text("".join(lines))
    with pytest.warns(UserWarning, match="r.csv changed after it was saved"):
        back = dd.load_result(path)
    assert back.x[4, 0] == 0.5


def test_earlier_commented_csv_still_loads(tmp_path):
    """The single-file CSV of earlier releases: metadata as a first comment line."""
    path = tmp_path / "old.csv"
    meta = {"info": {"scheme": "newmark", "dt": 0.5}, "meta": {"title": "old"},
            "dof_names": ["roof", "floor"]}
    path.write_text(f"# dtdyn_metadata: {json.dumps(meta)}\nt,x[3],x[7],a[3],a[7]\n"
                    "0,1,2,3,4\n0.5,5,6,7,8\n")
    back = dd.load_result(path)
    assert back.outputs.tolist() == [3, 7] and back.dof_names == ("roof", "floor")
    np.testing.assert_array_equal(back.x, [[1, 2], [5, 6]])
    np.testing.assert_array_equal(back.a, [[3, 4], [7, 8]])
    assert back.info["dt"] == 0.5 and back.meta["title"] == "old" and back.v is None
