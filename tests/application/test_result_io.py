"""Results save and load both ways with their metadata (.npz, .nc, .csv), atomically, and an
unknown extension or a bad folder is refused before anything is written."""
import numpy as np
import pytest

import dtdyn as dd
from dtdyn._engine.result_io import check_result_path

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
    if ext != "csv":  # one table: array-valued info is not kept there
        np.testing.assert_array_equal(back.info["history"], r.info["history"])


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
    with pytest.raises(ValueError, match=message):
        check_result_path(tmp_path / name)
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
