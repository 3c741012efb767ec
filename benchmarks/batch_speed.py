"""run_batch throughput on 1 and 2 workers against a plain loop in one process (#15).

200 nonlinear P4 cases (runtime/app/scenes/p4.toml: 4 DOFs, two cubic springs, modal_ramp
with 3 sub-steps, the full 100,000-sample white-noise record), each with its own seed from
the root seed 0 (SeedSequence.spawn), reduced on the workers to the peak and RMS of x, v, a
per DOF and written to a Zarr store. In the same run:

- plain loop: the same 200 scenes (seeds set in their tables) through scene_from_dict and
  run_scene one after the other in this process (a plain Python process: glibc's default
  malloc settings), the same reductions computed here: the work a user's own loop does per
  case (parse, run, reduce);
- run_batch on a LocalCluster of 1, then 2 worker processes, started by
  dtdyn.app._batch.run.local_cluster as run_batch(client=None) starts them (one thread each,
  glibc's malloc thresholds of WORKER_ENVIRON, the profiler off; the cluster is started before
  the clock runs; the clock covers scatter, the warm-up, the tasks, the Zarr writes and the
  metadata);
- run_batch on 1 worker of a LocalCluster with Dask's default worker settings (what a user's
  own cluster gets: MALLOC_TRIM_THRESHOLD_=65536, the profiler on), for comparison;
- throughput ratio (2 workers / 1 worker; target >= 1.7), overhead per case (1-worker wall
  time minus the plain loop, per case, as a share of one P4 run; target < 5 %; also without
  the one-time warm-up, since the plain loop builds its kernels before its clock starts), peak
  resident memory of each worker process (ru_maxrss), the CPU time per case of the plain
  loop and of the worker process, whether all agree bitwise, and the load average (other
  processes on the machine make the wall times noisy); the spread of the case run times.

Each batch is one timed run (its 200 cases are the repeats: the run time of each case on the
workers is shown as median [min, max]); BLAS pinned to one thread in this process and, by
OPENBLAS_NUM_THREADS / OMP_NUM_THREADS / MKL_NUM_THREADS = 1 set before the workers start, in
theirs (dtdyn.app.pin_blas for this process).

    python benchmarks/batch_speed.py [N_CASES]        (default 200)
"""
import os
import resource
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

import dtdyn as dd
from dtdyn.app import Timing, pin_blas

SCENE = Path(dd.__file__).parent / "app" / "scenes" / "p4.toml"
ROOT_SEED = 0


def peak_memory_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def plain_loop(n):
    """The cases one by one in this process: (wall time, CPU time, peaks and RMS per case)."""
    data = tomllib.loads(SCENE.read_text())
    seeds = [int(c.generate_state(1, np.uint64)[0] >> np.uint64(1))
             for c in np.random.SeedSequence(ROOT_SEED).spawn(n)]
    dd.run_scene(dd.scene_from_dict(data, SCENE.parent))    # compile / load the kernels
    peaks, start, cpu = [], time.perf_counter(), time.process_time()
    for seed in seeds:
        data["load"][0]["seed"] = seed
        response, _ = dd.run_scene(dd.scene_from_dict(data, SCENE.parent, str(SCENE)))
        peaks.append([np.abs(getattr(response, q)).max(axis=0) for q in "xva"]
                     + [np.sqrt(np.mean(getattr(response, q) ** 2, axis=0)) for q in "xva"])
    return time.perf_counter() - start, time.process_time() - cpu, np.array(peaks)


def batch(n, workers, folder, dask_defaults=False):
    from distributed import Client, LocalCluster

    from dtdyn.app._batch.run import local_cluster

    t0 = time.perf_counter()
    if dask_defaults:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=40)
    else:
        cluster = local_cluster(workers)
    with cluster, Client(cluster) as client:
        started = time.perf_counter() - t0
        base = client.run(peak_memory_mb)
        cpu = client.run(time.process_time)
        out = Path(folder) / f"p4_{workers}{'_dask' if dask_defaults else ''}.zarr"
        ds = dd.run_batch(SCENE, vary=[{}] * n, seed=ROOT_SEED, client=client,
                          reduce="peak,rms", out=out, progress=False)
        cpu = sum(client.run(time.process_time)[w] - cpu[w] for w in cpu)
        memory = client.run(peak_memory_mb)
        import json
        summary = json.loads(ds.attrs["dtdyn_batch"])["summary"]
        values = np.stack([ds[f"{r}_{q}"].values for r in ("peak", "rms") for q in "xva"], 1)
        return summary, started, base, memory, values, ds, cpu


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    print(f"{n} P4 cases (100,000 samples, modal_ramp, 3 sub-steps, seeds from "
          f"SeedSequence({ROOT_SEED}).spawn), peak and RMS of x, v, a per DOF\n")
    load = [os.getloadavg()]
    loop_time, loop_cpu, loop_values = plain_loop(n)
    load.append(os.getloadavg())
    per_case = loop_time / n
    with tempfile.TemporaryDirectory() as folder:
        one, start1, base1, mem1, values1, ds1, cpu1 = batch(n, 1, folder)
        load.append(os.getloadavg())
        two, start2, base2, mem2, values2, ds2, _ = batch(n, 2, folder)
        load.append(os.getloadavg())
        dflt, start3, _, mem3, values3, ds3, cpu3 = batch(n, 1, folder, dask_defaults=True)
        load.append(os.getloadavg())
        done = int((ds1["status"] == "done").sum()), int((ds2["status"] == "done").sum())
        worker_run = float(ds1["run_time"].mean())
        default_run = float(ds3["run_time"].mean())
        spreads = [Timing(ds["run_time"].values) for ds in (ds1, ds2, ds3)]
    rows = [("plain loop, 1 process", loop_time, n / loop_time, "", ""),
            ("run_batch, 1 worker", one["wall_time_s"], one["cases_per_s"],
             f"{start1:.1f}", " ".join(f"{v:.0f}" for v in mem1.values())),
            ("run_batch, 2 workers", two["wall_time_s"], two["cases_per_s"],
             f"{start2:.1f}", " ".join(f"{v:.0f}" for v in mem2.values())),
            ("1 worker, Dask config", dflt["wall_time_s"], dflt["cases_per_s"],
             f"{start3:.1f}", " ".join(f"{v:.0f}" for v in mem3.values()))]
    print(f"| {'run':<22} | wall time [s] | cases/s | cluster start [s] | peak RSS per worker "
          "[MB] |")
    print(f"|{'-' * 24}|---------------|---------|-------------------|--------------------------|")
    for name, wall, rate, started, mem in rows:
        print(f"| {name:<22} | {wall:13.2f} | {rate:7.2f} | {started:>17} | {mem:>24} |")
    overhead = (one["wall_time_s"] - loop_time) / n
    steady = (one["wall_time_s"] - one["warm_up_s"] - loop_time) / n
    print(f"\nthroughput, 2 workers / 1 worker: {two['cases_per_s'] / one['cases_per_s']:.2f}x "
          "(target >= 1.7)")
    print(f"one P4 run in the plain loop: {per_case * 1e3:.1f} ms (parse, run, reduce); on a "
          f"worker: {worker_run * 1e3:.1f} ms (mean)")
    print("run time of a case on the workers, median [min, max] over the cases: "
          + ", ".join(f"{label} {t.format()}" for label, t in
                      zip(("1 worker", "2 workers", "1 worker, Dask config"), spreads)))
    print(f"overhead per case, 1 worker against the plain loop: {overhead * 1e3:.2f} ms = "
          f"{100 * overhead / per_case:.1f} % of a P4 run (target < 5 %)")
    print(f"  of which the warm-up ({one['warm_up_s']:.2f} s once per worker: kernels built or "
          f"loaded, one case run; the plain loop's clock starts after its own): "
          f"{(overhead - steady) * 1e3:.2f} ms per case; without it {steady * 1e3:.2f} ms = "
          f"{100 * steady / per_case:.1f} %")
    dflt_over = (dflt["wall_time_s"] - loop_time) / n
    print("1 worker with Dask's default worker settings (MALLOC_TRIM_THRESHOLD_=65536, profiler "
          "on): "
          f"{default_run * 1e3:.1f} ms a case on the worker, overhead {dflt_over * 1e3:.2f} ms "
          f"= {100 * dflt_over / per_case:.1f} %")
    print(f"CPU time per case: plain loop {loop_cpu / n * 1e3:.1f} ms, the 1-worker process "
          f"{cpu1 / n * 1e3:.1f} ms (all its threads; the scheduler and client run in this "
          f"process), with Dask's defaults {cpu3 / n * 1e3:.1f} ms")
    print(f"tasks: {one['tasks']} of up to {one['chunk']} cases (1 worker), {two['tasks']} of "
          f"up to {two['chunk']} (2 workers); cases done: {done[0]}, {done[1]} of {n}")
    print(f"worker memory at start (MB): {' '.join(f'{v:.0f}' for v in base1.values())} (1 "
          f"worker), {' '.join(f'{v:.0f}' for v in base2.values())} (2 workers)")
    same = (np.array_equal(values1, values2) and np.array_equal(values1, loop_values)
            and np.array_equal(values1, values3))
    print(f"peaks and RMS equal bitwise (plain loop, 1 worker, 2 workers, Dask defaults): "
          f"{same}")
    print(f"load average (1 min; 2 cores) at the start {load[0][0]:.2f}, after the plain loop "
          f"{load[1][0]:.2f}, 1 worker {load[2][0]:.2f}, 2 workers {load[3][0]:.2f}, Dask "
          f"defaults {load[4][0]:.2f}")


if __name__ == "__main__":
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"  # inherited by the worker processes
    with pin_blas(1) as pin:
        print(pin.describe() + "; worker processes: OPENBLAS_NUM_THREADS=1")
        main()
