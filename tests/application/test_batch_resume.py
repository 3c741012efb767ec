"""Batches that lose nothing: a batch killed (SIGKILL, its whole process group: the client and
its LocalCluster) after about half its cases, resumed, runs only the other half and ends with
a store equal, per case and bit for bit, to an uninterrupted run; a resume with other cases,
reducers or code is refused by name; a stuck case is failed by case_timeout (a worker lost
mid-case is counted: test_batch.py's killer test)."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import dtdyn as dd

distributed = pytest.importorskip("distributed")
xr = pytest.importorskip("xarray")
zarr = pytest.importorskip("zarr")

from dtdyn.app._batch import ResumeMismatchError  # noqa: E402
from dtdyn.app._cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
P4 = (ROOT / "runtime/app/scenes/p4.toml").read_text()
CHAIN = ('[model]\nmass = [1.0, 1.0]\nstiffness = [1e4, 1e4]\ndamping = [1.0, 1.0]\n'
         '[[load]]\ndof = 1\nkind = "step"\n[scheme]\nname = "average_acceleration"\n'
         '[time]\ndt = 0.001\nduration = 0.2\n')
#: what may differ between two runs of the same cases: when and where each case ran, and the
#: summary's account of the run (its timing, the cases it ran and skipped)
RUN_ONLY = ("run_time", "worker")
SUMMARY_RUN_ONLY = ("wall_time_s", "cases_per_s", "cluster_start_s", "warm_up_s", "workers",
                    "tasks", "chunk", "ran", "skipped", "lost_tasks")


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0", silence_logs=40) as c:
        yield c


@pytest.fixture()
def client(cluster):
    with distributed.Client(cluster.scheduler_address) as c:
        c.wait_for_workers(2, timeout=60)
        yield c


def summary_of(ds) -> dict:
    return json.loads(ds.attrs["dtdyn_batch"])["summary"]


def assert_same_store(a: Path, b: Path) -> None:
    """Two batch stores hold the same cases: every variable and coordinate equal bit for bit
    per case (NaN where NaN), the same dims and attributes, except when and where each case
    ran and the summary's account of the run."""
    x = xr.open_zarr(a).load()
    y = xr.open_zarr(b).load()
    assert set(x.variables) == set(y.variables)
    assert dict(x.sizes) == dict(y.sizes)
    for name in x.variables:
        assert x[name].dims == y[name].dims, name
        if name in RUN_ONLY:
            continue
        u, v = x[name].values, y[name].values
        if name == "case_record":
            u = [{k: w for k, w in json.loads(str(r)).items() if k not in RUN_ONLY} for r in u]
            v = [{k: w for k, w in json.loads(str(r)).items() if k not in RUN_ONLY} for r in v]
            assert u == v
        elif u.dtype.kind == "f":
            assert u.tobytes() == v.tobytes(), name        # bitwise, NaN included
        else:
            assert [str(e) for e in u.ravel()] == [str(e) for e in v.ravel()], name
    ax, ay = json.loads(x.attrs["dtdyn_batch"]), json.loads(y.attrs["dtdyn_batch"])
    sx, sy = ax.pop("summary"), ay.pop("summary")
    assert ax == ay
    for key in SUMMARY_RUN_ONLY:
        sx.pop(key), sy.pop(key)
    assert sx == sy


KILLED_SCRIPT = """\
import sys
import dtdyn as dd

if __name__ == "__main__":
    rows = [{"load[0].seed": s} for s in range(12)]
    dd.run_batch(sys.argv[1], vary=rows, workers=1, out=sys.argv[2], reduce="peak,rms",
                 progress=False)
    print("finished", flush=True)
"""


def done_count(store: Path) -> int:
    try:
        return list(zarr.open_group(str(store), mode="r")["status"][:]).count("done")
    except Exception:  # noqa: BLE001 - not created yet
        return -1


def test_a_killed_batch_resumes_the_other_half_and_equals_an_uninterrupted_run(client,
                                                                                 tmp_path):
    """12 P4 cases (200,000 samples, about 0.13 s each) on one worker in a child process,
    killed with SIGKILL (client, scheduler and worker: a power cut) once the store shows 6
    done; resumed on another cluster it runs exactly the cases not done, and the store equals
    an uninterrupted run's bitwise per case."""
    scene = tmp_path / "p4.toml"
    scene.write_text(P4.replace("duration = 99.999", "duration = 199.999"))
    script = tmp_path / "killed.py"
    script.write_text(KILLED_SCRIPT)
    store = tmp_path / "killed.zarr"
    proc = subprocess.Popen([sys.executable, str(script), str(scene), str(store)],
                            cwd=tmp_path, start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True,
                            env=dict(os.environ, PYTHONWARNINGS="ignore"))
    try:
        deadline = time.monotonic() + 120
        while done_count(store) < 6:
            assert proc.poll() is None, proc.stdout.read()
            assert time.monotonic() < deadline, "the batch did not get to 6 cases in 120 s"
            time.sleep(0.02)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    time.sleep(0.5)
    status = list(zarr.open_group(str(store), mode="r")["status"][:])
    done = status.count("done")
    assert 6 <= done < 12 and set(status) == {"done", "pending"}, status
    time.sleep(0.5)   # nothing of the killed batch still writes
    assert list(zarr.open_group(str(store), mode="r")["status"][:]) == status
    killed = xr.open_zarr(store)          # what a killed store holds: the finished cases
    assert np.isfinite(killed["peak_x"].values[np.array(status) == "done"]).all()

    rows = [{"load[0].seed": s} for s in range(12)]
    resumed = dd.run_batch(scene, vary=rows, client=client, out=store, reduce="peak,rms",
                           progress=False, resume=True)
    s = summary_of(resumed)
    assert (s["ran"], s["skipped"], s["done"], s["pending"]) == (12 - done, done, 12, 0)
    assert dd.run_batch(scene, vary=rows, client=client, out=store, reduce="peak,rms",
                        progress=False, resume=True).attrs["dtdyn_batch"]  # nothing to run
    whole = tmp_path / "whole.zarr"
    dd.run_batch(scene, vary=rows, client=client, out=whole, reduce="peak,rms", progress=False)
    assert_same_store(store, whole)
    # and both equal the cases run here one by one
    for i in (0, 11):
        case = tmp_path / f"case{i}.toml"
        case.write_text(scene.read_text().replace("seed = 0", f"seed = {i}"))
        response, _ = dd.run_scene(dd.load_scene(case))
        assert np.array_equal(resumed["peak_x"].values[i], np.abs(response.x).max(axis=0))


def chain_file(folder: Path, name="chain.toml") -> Path:
    path = folder / name
    path.write_text(CHAIN)
    return path


def test_resume_refuses_other_cases_reducers_or_code_and_reruns_failed_on_request(
        client, tmp_path, monkeypatch, capsys):
    base = chain_file(tmp_path)
    rows = [{"model.mass[0]": m} for m in (1.0, 2.0, -1.0, 4.0)]   # case 2 fails (mass < 0)
    out = tmp_path / "r.zarr"
    first = dd.run_batch(base, vary=rows, client=client, out=out, reduce="peak", progress=False)
    assert list(first["status"].values) == ["done", "done", "failed", "done"]
    again = dd.run_batch(base, vary=rows, client=client, out=out, reduce="peak",
                         progress=False, resume=True)
    assert (summary_of(again)["ran"], summary_of(again)["skipped"]) == (0, 4)
    rerun = dd.run_batch(base, vary=rows, client=client, out=out, reduce="peak",
                         progress=False, resume=True, rerun_failed=True)
    assert (summary_of(rerun)["ran"], summary_of(rerun)["failed"]) == (1, 1)
    assert str(rerun["message"].values[2]) == str(first["message"].values[2])
    # a chunk the disk lost (a power cut): its cases are pending again and run again
    peak0 = first["peak_x"].values[0].copy()
    (out / "peak_x" / "0.0").write_bytes(b"\0" * 7)
    repaired = dd.run_batch(base, vary=rows, client=client, out=out, reduce="peak",
                            progress=False, resume=True)
    assert (summary_of(repaired)["ran"], summary_of(repaired)["done"]) == (1, 3)
    assert repaired["peak_x"].values[0].tobytes() == peak0.tobytes()

    changed = [*rows[:1], {"model.mass[0]": 2.5}, *rows[2:]]
    with pytest.raises(ResumeMismatchError, match=r"1 of its 4 cases differ from this "
                       r"batch's .*cases 1; case 1 has params \{\"model.mass\[0\]\": 2.0\} in "
                       r"the store and \{\"model.mass\[0\]\": 2.5\} here"):
        dd.run_batch(base, vary=changed, client=client, out=out, reduce="peak", resume=True)
    with pytest.raises(ResumeMismatchError, match="it has 4 cases, this batch 5"):
        dd.run_batch(base, vary=[*rows, {}], client=client, out=out, reduce="peak",
                     resume=True)
    with pytest.raises(ResumeMismatchError, match=r"its reducers are \['peak'\], this "
                                                  r"batch's \['peak', 'rms'\]"):
        dd.run_batch(base, vary=rows, client=client, out=out, reduce="peak,rms", resume=True)
    with pytest.raises(ResumeMismatchError, match="check=True, this batch with check=False"):
        dd.run_batch(base, vary=rows, client=client, out=out, reduce="peak", resume=True,
                     check=False)
    from dtdyn.app._batch import store
    real = store.code_version()
    monkeypatch.setattr(store, "code_version", lambda: {**real, "generated": "0123abcd"})
    with pytest.raises(ResumeMismatchError, match=f"written by dtdyn {dd.__version__} with "
                       f"the generated kernels {real['generated']}, this is dtdyn "
                       f"{dd.__version__} with 0123abcd"):
        dd.run_batch(base, vary=rows, client=client, out=out, reduce="peak", resume=True)
    monkeypatch.undo()
    with pytest.raises(ValueError, match="resume=True and overwrite=True"):
        dd.run_batch(base, vary=rows, out=out, resume=True, overwrite=True)
    with pytest.raises(ValueError, match="resume=True continues a store: give out="):
        dd.run_batch(base, vary=rows, resume=True)
    with pytest.raises(ValueError, match="rerun_failed=True reruns the failed cases of a "
                                         "resumed store: give resume=True"):
        dd.run_batch(base, vary=rows, out=tmp_path / "n.zarr", rerun_failed=True)
    with pytest.raises(ValueError, match="case_timeout = 0: must be a number of seconds > 0"):
        dd.run_batch(base, vary=rows, case_timeout=0)
    plain = tmp_path / "plain.zarr"     # a Zarr store a resumable batch did not write
    xr.Dataset({"a": ("case", np.zeros(4))}).to_zarr(plain, zarr_format=2)
    with pytest.raises(ResumeMismatchError, match="plain.zarr' is not a batch store"):
        dd.run_batch(base, vary=rows, client=client, out=plain, reduce="peak", resume=True)
    # the CLI: --resume --rerun-failed; a mismatch is an error naming it (exit 2)
    table = tmp_path / "rows.csv"
    table.write_text("model.mass[0]\n1.0\n2.0\n-1.0\n4.0\n")
    address = client.scheduler.address
    rc = main(["batch", str(base), "--vary", str(table), "--scheduler", address, "--reduce",
               "peak", "--out", str(out), "--resume", "--rerun-failed"])
    text = capsys.readouterr().out
    assert rc == 1, text      # case 2 failed again
    assert "4 cases: 3 done, 1 failed" in text and "resumed: 3 case(s) finished before, " \
        "1 run now" in text, text
    table.write_text("model.mass[0]\n1.0\n2.0\n-1.0\n4.5\n")
    rc = main(["batch", str(base), "--vary", str(table), "--scheduler", address, "--reduce",
               "peak", "--out", str(out), "--resume"])
    err = capsys.readouterr().err
    assert rc == 2 and "cannot be resumed by this batch: 1 of its 4 cases differ" in err, err


def _sleepy(response, scene):
    if scene.mass[0] == 2.0:
        time.sleep(600)        # stuck: only the worker's restart ends it
    return {"m0": float(scene.mass[0])}


def test_case_timeout_fails_a_stuck_case_and_the_batch_goes_on(client, tmp_path):
    """One task of three cases; the second sleeps for 10 minutes: with case_timeout=2 it is
    failed ("TimeoutError: case exceeded 2 s") within seconds, its worker is restarted, the
    third case runs in a task of its own and is done."""
    base = chain_file(tmp_path)
    rows = [{"model.mass[0]": m} for m in (1.0, 2.0, 3.0)]
    t0 = time.perf_counter()
    ds = dd.run_batch(base, vary=rows, client=client, out=tmp_path / "t.zarr", reduce=_sleepy,
                      chunk=3, progress=False, case_timeout=2)
    assert time.perf_counter() - t0 < 60
    assert list(ds["status"].values) == ["done", "failed", "done"]
    assert str(ds["message"].values[1]) == "TimeoutError: case exceeded 2 s"
    assert list(ds["m0"].values[[0, 2]]) == [1.0, 3.0] and np.isnan(ds["m0"].values[1])
    assert summary_of(ds)["timed_out"] == 1
    client.wait_for_workers(2, timeout=60)
