"""run_batch and `dtdyn batch` on a LocalCluster (2 worker processes, one thread each),
against the same cases run one by one in this process (scene files written by hand, not
through the batch's overrides), chain_response directly and numpy's SeedSequence."""
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import dtdyn as dd

distributed = pytest.importorskip("distributed")
xr = pytest.importorskip("xarray")
pytest.importorskip("zarr")

from dtdyn.app._batch import CBackendError, Spectrum  # noqa: E402
from dtdyn.app._batch.cases import apply_overrides, parse_key, read_table  # noqa: E402
from dtdyn.app._cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
P4 = (ROOT / "runtime/app/scenes/p4.toml").read_text()
EXAMPLE = ROOT / "examples/batch"


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0", silence_logs=40) as c:
        yield c


@pytest.fixture()
def client(cluster):
    with distributed.Client(cluster.scheduler_address) as c:  # addressed by its tcp address
        yield c


def p4_file(folder: Path, name: str, *, seed=0, k3="2e7", duration="1.999", max_iter=None):
    """P4 with a short record (2,000 samples), written as its own scene file."""
    text = P4.replace("seed = 0", f"seed = {seed}").replace("duration = 99.999",
                                                             f"duration = {duration}")
    text = text.replace("k3 = 2e7                 # N/m^3", f"k3 = {k3}")
    if max_iter is not None:
        text = text.replace("substeps = 3             # h = dt / 3",
                            f"substeps = 1\nmax_iter = {max_iter}")
    path = folder / name
    path.write_text(text)
    return path


def test_keys_and_overrides():
    assert parse_key("model.stiffness[2]") == ["model", "stiffness", 2]
    assert parse_key("load[0].seed") == ["load", 0, "seed"]
    base = {"model": {"stiffness": [1.0, 2.0, 3.0]}, "load": [{"kind": "step"}]}
    got = apply_overrides(base, {"model.stiffness[2]": 9.0, "ground.scale": 0.5,
                                 "load[0].amplitude": 2.0})
    assert got == {"model": {"stiffness": [1.0, 2.0, 9.0]}, "load": [{"kind": "step",
                                                                      "amplitude": 2.0}],
                   "ground": {"scale": 0.5}}
    assert base == {"model": {"stiffness": [1.0, 2.0, 3.0]}, "load": [{"kind": "step"}]}
    with pytest.raises(ValueError, match=r"'load\[3\].seed': load\[3\] is past the end .*1 "):
        apply_overrides(base, {"load[3].seed": 1})
    with pytest.raises(ValueError, match=r"vary key 'model..k': '' is not a name"):
        parse_key("model..k")


def test_csv_table(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("# a comment\nmodel.stiffness[0],ground.path,load[0].seed\n"
                    "1e4,a.csv,3\n2.5e4,,4\n")
    assert read_table(path) == [{"model.stiffness[0]": 1e4, "ground.path": "a.csv",
                                 "load[0].seed": 3},
                                {"model.stiffness[0]": 2.5e4, "load[0].seed": 4}]
    path.write_text("a.b,c\n1\n")
    with pytest.raises(ValueError, match="line 2 has 1 cells, the header 2"):
        read_table(path)


def test_bad_input_is_refused_before_anything_runs(tmp_path):
    scene = p4_file(tmp_path, "p4.toml")
    with pytest.raises(ValueError, match=r"case 1 \(.*p4.toml\): vary key 'element\[5\].k3'"):
        dd.run_batch(scene, vary=[{}, {"element[5].k3": 1.0}])
    with pytest.raises(ValueError, match="reduce = 'peaks': unknown reducer"):
        dd.run_batch(scene, reduce="peaks")
    with pytest.raises(ValueError, match="a batch writes a Zarr store"):
        dd.run_batch(scene, out=tmp_path / "r.nc")
    with pytest.raises(ValueError, match="seed = -1: the root seed"):
        dd.run_batch(scene, seed=-1)
    with pytest.raises(ValueError, match="chunk = 0"):
        dd.run_batch(scene, chunk=0)


def test_batch_equals_cases_one_by_one_bitwise(client, tmp_path):
    """Three seeds x two cubic stiffnesses of P4 (2,000 samples): the time histories the
    workers store equal, bit for bit, the same scenes written as files and run here."""
    base = p4_file(tmp_path, "p4.toml")
    rows = [{"load[0].seed": s, "element[1].k3": k} for s in (1, 2, 3) for k in (2e7, 5e7)]
    ds = dd.run_batch(base, vary=rows, client=client, chunk=2, progress=False)
    assert list(ds["status"].values) == ["done"] * 6
    assert set(ds["backend"].values) == {"c"}
    for i, row in enumerate(rows):
        text = p4_file(tmp_path, f"case{i}.toml", seed=row["load[0].seed"]).read_text()
        text = text.replace("j = 2\nk3 = 2e7", f"j = 2\nk3 = {row['element[1].k3']!r}")
        (tmp_path / f"case{i}.toml").write_text(text)
        response, _ = dd.run_scene(dd.load_scene(tmp_path / f"case{i}.toml"))
        for q in ("x", "v", "a"):
            assert np.array_equal(ds[q].values[i], getattr(response, q)), (i, q)
        assert ds["load[0].seed"].values[i] == row["load[0].seed"]
        np.testing.assert_array_equal(ds["error_estimate"].values[i],
                                      response.info.get("error_estimate", np.nan))
        assert json.loads(str(ds["params"].values[i])) == row
    assert np.array_equal(ds["time"].values, response.t)
    assert ds["x"].dims == ("case", "time", "output")


def _worker_settings():
    import dask
    return (dask.config.get("distributed.worker.profile.enabled"),
            {k: os.environ.get(k) for k in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_",
                                            "DTDYN_THREADS")})


def test_own_cluster_keeps_glibc_malloc_fast_and_the_profiler_off(tmp_path, monkeypatch):
    """The LocalCluster run_batch starts (client=None) gives its workers WORKER_ENVIRON (Dask's
    MALLOC_TRIM_THRESHOLD_=65536 alone made every case's large arrays fresh mmaps: 28 % slower
    on P4) even when an earlier Dask cluster of this process left 65536 in os.environ, which it
    puts back; the profiler is off; the cases still equal run_scene bitwise."""
    from dtdyn.app._batch.run import WORKER_ENVIRON, local_cluster

    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")   # as a plain Dask cluster leaves it
    monkeypatch.delenv("MALLOC_MMAP_THRESHOLD_", raising=False)
    base = p4_file(tmp_path, "p4.toml", seed=4)
    with local_cluster(1) as cluster, distributed.Client(cluster) as c:
        assert os.environ["MALLOC_TRIM_THRESHOLD_"] == "65536"
        assert "MALLOC_MMAP_THRESHOLD_" not in os.environ
        assert list(c.run(_worker_settings).values()) == [(False, WORKER_ENVIRON)]
        ds = dd.run_batch(base, client=c, progress=False)
    response, _ = dd.run_scene(dd.load_scene(base))
    for q in ("x", "v", "a"):
        assert np.array_equal(ds[q].values[0], getattr(response, q)), q


def test_failures_are_per_case(client, tmp_path):
    """A value the parser refuses, a Newton failure and an unstable scheme fail their own
    cases, with the messages they have alone; the other cases are done."""
    base = p4_file(tmp_path, "p4.toml")
    rows = [{}, {"model.K[0][0]": float("nan")}, {"nonlinear.max_iter": 1,
                                                  "nonlinear.substeps": 1}, {"load[0].seed": 5}]
    ds = dd.run_batch(base, vary=rows, client=client, reduce="peak", progress=False)
    assert list(ds["status"].values) == ["done", "failed", "failed", "done"]
    msg = [str(m) for m in ds["message"].values]
    assert re.match(r"ValueError: .*p4.toml: model.K\[0\]\[0\] = nan", msg[1]), msg[1]
    assert msg[2].startswith("NewtonError: ") and "Newton did not converge at step" in msg[2]
    assert np.isnan(ds["peak_x"].values[1:3]).all()
    assert np.isfinite(ds["peak_x"].values[[0, 3]]).all()
    chain = tmp_path / "chain.toml"
    chain.write_text('[model]\nmass = [1.0, 1.0]\nstiffness = [1e4, 1e4]\ndamping = [1.0, 1.0]\n'
                     '[[load]]\ndof = 1\nkind = "step"\n[scheme]\nname = "central_difference"\n'
                     'form = "acceleration"\n'
                     '[time]\ndt = 0.001\nduration = 1.0\n')
    with pytest.warns(dd.DtdynStabilityWarning, match="1 of 2 case"):   # the failed case's
        ds = dd.run_batch(chain, vary=[{}, {"time.dt": 0.05}], client=client, reduce="peak",
                          progress=False)
    assert list(ds["status"].values) == ["done", "failed"]
    assert str(ds["message"].values[1]).startswith(
        "DtdynUnstableError: scheme 'central_difference' is unstable at dt = 0.05 s")
    assert float(ds["max_rel_error"].values[0]) < 0.05   # the exact check of the linear case


def test_seeds_from_the_root_independent_of_chunking(client, tmp_path):
    base = p4_file(tmp_path, "p4.toml")
    rows = [{"element[0].k3": float(k)} for k in np.linspace(1e7, 3e7, 7)]
    one = dd.run_batch(base, vary=rows, seed=2024, client=client, chunk=1, progress=False,
                       reduce="peak,rms")
    three = dd.run_batch(base, vary=rows, seed=2024, client=client, chunk=3, progress=False,
                         reduce="peak,rms")
    children = np.random.SeedSequence(2024).spawn(7)
    want = [int(c.generate_state(1, np.uint64)[0] >> np.uint64(1)) for c in children]
    assert one["seed"].values.tolist() == want == three["seed"].values.tolist()
    assert len(set(want)) == 7
    for name in ("peak_x", "rms_a"):
        assert np.array_equal(one[name].values, three[name].values)
    # case 4 alone, with its seed written into its file: the same peaks
    text = p4_file(tmp_path, "c4.toml", seed=want[4]).read_text().replace(
        "i = 0                    # j omitted: to ground\nk3 = 2e7",
        f"i = 0\nk3 = {rows[4]['element[0].k3']!r}")
    (tmp_path / "c4.toml").write_text(text)
    response, _ = dd.run_scene(dd.load_scene(tmp_path / "c4.toml"))
    assert np.array_equal(one["peak_x"].values[4], np.abs(response.x).max(axis=0))


def test_zarr_store_opens_and_nothing_partial(client, tmp_path):
    base = p4_file(tmp_path, "p4.toml")
    rows = [{"load[0].seed": s} for s in range(5)]

    def energy(response, scene):   # a user reducer: runs on the workers
        return {"energy": float(np.sum(response.v ** 2)), "pair": (("side",), [1.0, 2.0])}

    out = tmp_path / "r.zarr"
    ds = dd.run_batch(base, vary=rows, client=client, out=out, chunk=2, progress=False,
                      reduce=["history", "peak", energy])
    mem = dd.run_batch(base, vary=rows, client=client, chunk=5, progress=False,
                       reduce=["history", "peak", energy])
    back = xr.open_zarr(out)
    for name in ("x", "v", "a", "peak_v", "energy", "pair", "seed"):
        assert np.array_equal(back[name].values, mem[name].values), name
    assert back["energy"].dims == ("case",) and back["pair"].dims == ("case", "side")
    assert np.array_equal(back["energy"].values, np.sum(back["v"].values ** 2, axis=(1, 2)))
    assert json.loads(back.attrs["dtdyn_batch"])["summary"]["done"] == 5
    assert sorted(p.name for p in tmp_path.iterdir() if "zarr" in p.name) == ["r.zarr"]
    with pytest.raises(ValueError, match="exists; remove it, pass resume=True to run its cases "
                                         "not yet done or overwrite=True"):
        dd.run_batch(base, vary=rows, client=client, out=out, progress=False)
    del ds


def test_missing_compiler_is_an_error_and_leaves_nothing(tmp_path):
    base = p4_file(tmp_path, "p4.toml")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=":0", silence_logs=40,
                                  env={"DTDYN_NO_C": "1"}) as cluster, \
            distributed.Client(cluster) as c:
        with pytest.raises(CBackendError, match="the C backend is unavailable: DTDYN_NO_C"):
            dd.run_batch(base, client=c, out=tmp_path / "r.zarr", progress=False)
    assert not [p for p in tmp_path.iterdir() if "zarr" in p.name]


def test_cli_on_a_scheduler_address_and_50_ground_motions(cluster, tmp_path, capsys):
    """`dtdyn batch` on 50 generated ground records (2,001 samples) against the building of
    examples/batch, on the LocalCluster by its tcp address: a Zarr store with the peak storey
    drifts, equal to chain_response run here on each record."""
    shutil.copy(EXAMPLE / "building.toml", tmp_path)
    subprocess.run([sys.executable, str(EXAMPLE / "make_records.py"), str(tmp_path)],
                   check=True, capture_output=True)
    out = tmp_path / "drifts.zarr"
    rc = main(["batch", str(tmp_path / "building.toml"), "--vary", str(tmp_path / "records.csv"),
               "--scheduler", cluster.scheduler_address, "--reduce", "drift,peak,srs",
               "--out", str(out), "--quiet"])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert re.search(r"50 cases: 50 done, 0 failed; wall time [\d.]+ s, [\d.]+ cases/s", text)
    ds = xr.open_zarr(out)
    assert ds["peak_drift"].shape == (50, 5) and ds["psa"].dims == ("case", "period", "output")
    chain = dd.load_scene(tmp_path / "building.toml")
    for i in (0, 17, 49):
        ag = np.loadtxt(tmp_path / f"records/gm_{i:03d}.csv") * 9.80665
        r = dd.chain_response(**chain.chain, force=None, dt=0.01, ground_acceleration=ag,
                              scheme="average_acceleration", quantities=("x", "a"))
        drift = np.abs(np.diff(np.c_[np.zeros(ag.size), r.x], axis=1)).max(axis=0)
        np.testing.assert_array_equal(ds["peak_drift"].values[i], drift)
        assert str(ds["ground.path"].values[i]) == f"records/gm_{i:03d}.csv"
        periods = Spectrum().resolved(0.01).periods    # the default: 10 dt = 0.1 s to 4 s
        np.testing.assert_array_equal(ds["period"].values, periods)
        psa = dd.response_spectrum(r.a_abs[:, 4], 0.01, periods).psa[0]
        np.testing.assert_array_equal(ds["psa"].values[i, :, 4], psa)
    # --workers starts its own cluster; a second run refuses the existing store
    rc = main(["batch", str(tmp_path / "building.toml"), "--workers", "1", "--out", str(out)])
    assert rc == 2 and "exists; remove it" in capsys.readouterr().err


def test_cluster_of_dask_scheduler_and_dask_worker(tmp_path):
    """The cluster instructions of docs/batch.md: `dask scheduler` and `dask worker` processes,
    `dtdyn batch --scheduler ADDRESS` run as a command."""
    dask = Path(sys.executable).with_name("dask")
    if not dask.exists():
        pytest.skip("no dask command next to this Python")
    info = tmp_path / "scheduler.json"
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    procs = [subprocess.Popen([str(dask), "scheduler", "--host", "127.0.0.1", "--port", "0",
                               "--no-dashboard", "--scheduler-file", str(info)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        procs.append(subprocess.Popen([str(dask), "worker", "--scheduler-file", str(info),
                                       "--nworkers", "1", "--nthreads", "1", "--no-dashboard"],
                                      env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL))
        with distributed.Client(scheduler_file=str(info), timeout="60s") as c:
            c.wait_for_workers(1, timeout=60)
            address = c.scheduler.address
        scene = p4_file(tmp_path, "p4.toml")
        out = tmp_path / "r.zarr"
        proc = subprocess.run([sys.executable, "-m", "dtdyn", "batch", str(scene),
                               "--seed", "3", "--scheduler", address, "--reduce", "peak",
                               "--out", str(out), "--quiet"], capture_output=True, text=True,
                              timeout=300)
        assert proc.returncode == 0, proc.stderr
        assert "1 cases: 1 done, 0 failed" in proc.stdout
        assert xr.open_zarr(out)["peak_x"].shape == (1, 4)
    finally:
        for p in reversed(procs):
            p.terminate()
            p.wait(timeout=30)


CHAIN = ('[model]\nmass = [1.0, 1.0]\nstiffness = [1e4, 1e4]\ndamping = [1.0, 1.0]\n'
         '[[load]]\ndof = 1\nkind = "step"\n[scheme]\nname = "average_acceleration"\n'
         '[time]\ndt = 0.001\nduration = 0.2\n')


def chain_file(folder: Path, name="chain.toml", extra=""):
    path = folder / name
    path.write_text(CHAIN + extra)
    return path


def test_unexpected_errors_and_non_finite_values_fail_their_case(client, tmp_path):
    """A user reducer raising TypeError, or returning NaN, fails that case (its message); the
    other cases are done; the linear case's error estimate metadata is there (NaN: none)."""
    base = chain_file(tmp_path)
    rows = [{"model.mass[0]": m} for m in (1.0, 2.0, 3.0, 4.0)]

    def picky(response, scene):
        if scene.mass[0] == 2.0:
            raise TypeError("unsupported operand")
        return {"m0": float(scene.mass[0]), "e": (("output",),
                                                  [np.nan if scene.mass[0] == 3.0 else 1.0]
                                                  * len(response.outputs))}

    ds = dd.run_batch(base, vary=rows, client=client, reduce=["peak", picky], chunk=1,
                      progress=False)
    assert list(ds["status"].values) == ["done", "failed", "failed", "done"]
    assert str(ds["message"].values[1]) == "reduce 'picky': TypeError: unsupported operand"
    assert str(ds["message"].values[2]) == \
        "FloatingPointError: non-finite values in e at output 0"
    assert np.isnan(ds["m0"].values[1:3]).all() and ds["m0"].values[3] == 4.0
    assert ds["error_estimate"].dtype == float


def _crash(response, scene):
    if scene.mass[0] == 2.0:
        os._exit(1)   # the worker process dies under this task
    return {"m0": float(scene.mass[0])}


def test_a_case_killing_its_worker_fails_alone_and_the_batch_goes_on(client, tmp_path):
    """One task per case: the task that kills its workers fails; the others are done, even when
    they lost the scattered scenes with the dead workers (they run again)."""
    base = chain_file(tmp_path)
    rows = [{"model.mass[0]": m} for m in (1.0, 2.0, 3.0)]
    ds = dd.run_batch(base, vary=rows, client=client, reduce=_crash, chunk=1, progress=False)
    assert list(ds["status"].values) == ["done", "failed", "done"]
    # the scheduler retries the task on the restarted workers, then gives it up (or the scenes
    # it needs were lost with the last worker holding them)
    assert re.match(r"(KilledWorker|FutureCancelledError): .*\(run alone",
                    str(ds["message"].values[1])), ds["message"].values[1]
    assert np.isnan(ds["m0"].values[1]) and ds["m0"].values[2] == 3.0
    client.wait_for_workers(2, timeout=60)


def test_the_cases_sharing_a_task_with_a_killer_are_done(client, tmp_path):
    """Two cases per task, into a store: the killer's task mate runs again alone and is done;
    the store holds every case that is done."""
    base = chain_file(tmp_path)
    rows = [{"model.mass[0]": m} for m in (1.0, 2.0, 3.0, 4.0, 5.0)]
    ds = dd.run_batch(base, vary=rows, client=client, reduce=_crash, chunk=2, progress=False,
                      out=tmp_path / "b.zarr")
    assert list(ds["status"].values) == ["done", "failed", "done", "done", "done"]
    m0 = ds["m0"].values
    assert np.isnan(m0[1]) and list(m0[[0, 2, 3, 4]]) == [1.0, 3.0, 4.0, 5.0]
    summary = json.loads(ds.attrs["dtdyn_batch"])["summary"]
    # the killer's task and then the killer alone, each lost with its worker (Dask retries a
    # task a few times by itself: the scheduler counts them)
    assert summary["lost_tasks"] >= 2 and summary["ran"] == 5, summary
    client.wait_for_workers(2, timeout=60)


def test_a_stopped_batch_waits_for_running_tasks_and_keeps_the_finished_cases(client, tmp_path):
    """A batch stopped by an error while another task still runs returns only once that task
    has ended (it writes its case to the store): the store holds every finished case, the
    case that stopped the batch is pending (a resume runs it); every worker's folder of the
    batch is removed."""
    import time as _time

    import zarr

    base = chain_file(tmp_path)
    marker = tmp_path / "slow-task-ended"
    rows = [{"model.mass[0]": m} for m in (1.0, 2.0, 3.0)]

    def slow_or_broken(response, scene):
        if scene.mass[0] == 2.0:
            _time.sleep(1.0)
            marker.write_text("")
        if scene.mass[0] == 3.0:
            raise CBackendError("no compiler (simulated)")
        return {"m0": float(scene.mass[0])}

    with pytest.raises(CBackendError, match="simulated"):
        dd.run_batch(base, vary=rows, client=client, reduce=slow_or_broken, chunk=1,
                     out=tmp_path / "r.zarr", progress=False)
    assert marker.exists()   # run_batch returned after the running task
    group = zarr.open_group(str(tmp_path / "r.zarr"), mode="r")
    assert list(group["status"][:]) == ["done", "done", "pending"]
    assert list(group["m0"][:2]) == [1.0, 2.0] and np.isnan(group["m0"][2])
    assert sorted(p.name for p in tmp_path.iterdir() if "zarr" in p.name) == ["r.zarr"]

    def folders():
        from dtdyn.app._batch import worker
        return dict(worker._FOLDERS)

    dd.run_batch(base, client=client, reduce="peak", progress=False)
    assert all(v == {} for v in client.run(folders).values())


def test_time_axis_and_name_clashes(client, tmp_path):
    base = chain_file(tmp_path)
    ds = dd.run_batch(base, vary=[{}, {"time.dt": 0.002, "time.duration": 0.4}], client=client,
                      progress=False)
    assert list(ds["status"].values) == ["done", "failed"]
    assert "the case's time axis (201 samples, dt = 0.002 s) differs from the batch's (201 " \
           "samples, dt = 0.001 s" in str(ds["message"].values[1])
    with pytest.raises(ValueError, match="reduce 'peak': the variable 'peak_x' is already made "
                                         "by the reducer 'peak'"):
        dd.run_batch(base, client=client, reduce="peak,peak", progress=False)

    def seed(response, scene):
        return {"seed": 1.0}

    with pytest.raises(ValueError, match="reduce 'seed': the variable 'seed' has the name of "
                                         "a batch's metadata"):
        dd.run_batch(base, client=client, reduce=seed, progress=False)

    def peak_x(response, scene):
        return {"peak_x": 1.0}

    with pytest.raises(ValueError, match="reduce 'peak_x': the variable 'peak_x' is already"):
        dd.run_batch(base, client=client, reduce=["peak", peak_x], progress=False)

    def varied(response, scene):
        return {"model.mass[0]": 1.0}

    with pytest.raises(ValueError, match=r"the variable 'model.mass\[0\]' has the name of a "
                                         "varied key"):
        dd.run_batch(base, vary=[{"model.mass[0]": 2.0}], client=client, reduce=varied,
                     progress=False)


def test_files_checked_when_the_batch_is_built(tmp_path):
    from dtdyn.app._batch.cases import build_cases

    (tmp_path / "017").write_text("0.0\n1.0\n")
    base = chain_file(tmp_path, extra='[ground]\nkind = "file"\npath = "017"\n')
    with pytest.raises(ValueError, match=r"case 1: ground.path = 'gm_9.csv': no such file in "):
        build_cases(base, vary=[{}, {"ground.path": "gm_9.csv"}])
    missing = chain_file(tmp_path, "m.toml", extra='[ground]\nkind = "file"\npath = "no.csv"\n')
    with pytest.raises(ValueError, match=r"m.toml: ground.path = 'no.csv': no such file in "):
        build_cases(missing)
    table = tmp_path / "t.csv"
    table.write_text("# comment\n\nground.path,ground.scale\n017,0.5\n# another\n017\n")
    with pytest.raises(ValueError, match="line 6 has 1 cells"):
        read_table(table)
    table.write_text("ground.path,ground.scale\n017,0.5\n017,\n")
    assert read_table(table) == [{"ground.path": "017", "ground.scale": 0.5},
                                 {"ground.path": "017"}]
    _, specs, _ = build_cases(base, vary=table)
    assert len(specs[0].files) == 1
    assert read_table({"a.b": [1.0, np.nan, None], "c": ["x", None, "y"]}) == \
        [{"a.b": 1.0, "c": "x"}, {}, {"c": "y"}]
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame({"a.b": [1.0, np.nan], "c": ["x", None]})
    assert read_table(frame) == [{"a.b": 1.0, "c": "x"}, {}]
