"""Solvers reused across scenes and batch cases (issue #27): `run_scene` with a `SolverCache`
makes one solver per model and settings and runs every later load case on it; `run_batch` does
so in each worker process. The results equal, bitwise, the same scenes run alone (a fresh
solver each, as `mck_response`, `chain_response`, `beam_response`, `shaft_response` make)."""
import dataclasses
import warnings

import numpy as np
import pytest

import dtdyn as dd
from dtdyn.app._scene.run import SolverCache, model_digest

TIME = {"dt": 1e-4, "duration": 0.02}
SCENES = {
    "chain": {"model": {"mass": [1.0, 2.0, 1.5, 1.2], "stiffness": [2e4, 1e4, 3e4, 2e4],
                        "damping": [1.0, 2.0, 0.5, 1.0], "ground_stiffness": [0, 0, 1e3, 0]},
              "load": [{"dof": 3, "kind": "white_noise", "std": 1.0, "seed": 0}],
              "scheme": {"name": "hht", "alpha": -0.1}, "time": TIME,
              "output": {"outputs": [0, 3], "quantities": ["x", "v", "a"]}},
    "matrices": {"model": {"kind": "matrices", "M": [[2.0, 0.0], [0.0, 1.0]],
                           "K": [[3e4, -1e4], [-1e4, 1e4]], "C": [[2.0, -1.0], [-1.0, 1.0]]},
                 "load": [{"dof": 1, "kind": "white_noise", "std": 1.0, "seed": 0}],
                 "scheme": {"name": "wilson", "theta": 1.42}, "time": TIME},
    "beam": {"model": {"kind": "beam", "E": 2.1e11, "I": 8e-6, "rho_A": 20.0, "length": 3.0,
                       "elements": 20, "rayleigh": [0.5, 1e-5],
                       "supports": [{"node": 10, "k_w": 1e5, "c_w": 20.0}]},
             "load": [{"dof": "w20", "kind": "white_noise", "std": 100.0, "seed": 0}],
             "scheme": {"name": "houbolt"}, "time": TIME,
             "output": {"outputs": ["w20", "psi10"], "quantities": ["x", "a"]}},
    "shaft": {"model": {"kind": "shaft", "inertia": [1.0, 0.3, 0.9],
                        "stiffness": [1e4, 1.2e4, 9e3], "damping": [0.5, 0.8, 0.3]},
              "branch": [{"name": "out", "at": 1, "ratio": 2.0, "inertia": [0.5, 0.4],
                          "stiffness": [6e3, 5e3]}],
              "load": [{"dof": "main.2", "kind": "white_noise", "std": 10.0, "seed": 0}],
              "scheme": {"name": "generalized_alpha", "rho_inf": 0.6, "form": "acceleration"},
              "time": TIME, "ground": {"kind": "sine", "amplitude": 1.0, "frequency": 20.0}},
}


def with_seed(kind, seed):
    scene = {k: (list(v) if isinstance(v, list) else dict(v)) for k, v in SCENES[kind].items()}
    scene["load"] = [{**scene["load"][0], "seed": seed}]
    return scene


def assert_same(a, b, what):
    for q in ("x", "v", "a", "a_abs", "x_abs"):
        A, B = getattr(a, q), getattr(b, q)
        assert (A is None) == (B is None), (what, q)
        if A is not None:
            assert A.tobytes() == B.tobytes(), (what, q)  # bitwise
    assert {k: v for k, v in a.info.items() if k != "run_time"} == \
        {k: v for k, v in b.info.items() if k != "run_time"}, what


@pytest.mark.parametrize("kind", list(SCENES))
def test_one_solver_per_model_and_settings(kind):
    cache = SolverCache()
    for seed in (1, 2, 3):
        scene = dd.scene_from_dict(with_seed(kind, seed))
        got, report = dd.run_scene(scene, check=False, solvers=cache)
        alone, report_alone = dd.run_scene(dd.scene_from_dict(with_seed(kind, seed)),
                                           check=False)
        assert_same(got, alone, (kind, seed))
        assert report["backend"] == report_alone["backend"] == "c"
    assert (cache.built, cache.reused, len(cache)) == (1, 2, 1)
    # another dt, another scheme parameter, another model: a solver each
    other = with_seed(kind, 1)
    other["time"] = {"dt": 5e-5, "duration": 0.01}
    dd.run_scene(dd.scene_from_dict(other), check=False, solvers=cache)
    assert cache.built == 2
    scene = dd.scene_from_dict(with_seed(kind, 4))
    changed = dd.scene_from_dict(with_seed(kind, 4))
    if kind == "chain":
        changed.stiffness = changed.stiffness * 1.01
    elif kind == "matrices":
        changed.K = changed.K * 1.01
    elif kind == "beam":
        changed.model = dd.Beam(**{**dict(E=2.1e11 * 1.01, I=8e-6, rho_A=20.0, length=3.0,
                                          elements=20, rayleigh=(0.5, 1e-5)),
                                   "supports": scene.model.supports})
    else:
        changed.model = dd.Shaft([1.0, 0.3, 0.91], [1e4, 1.2e4, 9e3], [0.5, 0.8, 0.3],
                                 branches=[dd.Branch(1, [0.5, 0.4], [6e3, 5e3], ratio=2.0,
                                                     name="out")])
    assert model_digest(changed) != model_digest(scene)
    assert_same(dd.run_scene(changed, check=False, solvers=cache)[0],
                dd.run_scene(changed, check=False)[0], "changed")
    assert cache.built == 3


def test_the_cache_keeps_size_solvers_and_gives_their_warnings_again():
    cache = SolverCache(size=2)
    for dt in (1e-4, 5e-5, 2.5e-5, 1e-4):
        scene = with_seed("chain", 1)
        scene["time"] = {"dt": dt, "duration": 40 * dt}
        dd.run_scene(dd.scene_from_dict(scene), check=False, solvers=cache)
    assert (cache.built, cache.reused, len(cache)) == (4, 0, 2)  # 1e-4 was dropped
    # a dt past central difference's limit, run with unstable = "warn": each run warns
    scene = with_seed("chain", 1)
    scene["scheme"] = {"name": "central_difference", "form": "acceleration", "unstable": "warn"}
    scene["time"] = {"dt": 2e-2, "duration": 0.1}
    for _ in range(2):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            dd.run_scene(dd.scene_from_dict(scene), check=False, solvers=cache)
        assert [w.category for w in caught] == [dd.DtdynStabilityWarning]
    assert cache.reused == 1
    with pytest.raises(ValueError, match="size = 0: must be an integer >= 1"):
        SolverCache(0)


distributed = pytest.importorskip("distributed")
pytest.importorskip("xarray")
pytest.importorskip("zarr")


def test_run_batch_makes_one_solver_per_model_and_worker():
    """Two models (a chain and the same chain stiffer) x five load cases on two worker
    processes: each worker makes at most one solver per model (counted there), every case runs
    through the cache, and the stored time histories equal the scenes run alone, bitwise."""
    from dtdyn.app._batch import worker

    def counts():
        cache = worker.solvers()
        return cache.built, cache.reused

    stiffer = with_seed("chain", 0)
    stiffer["model"] = {**stiffer["model"], "stiffness": [3e4, 1e4, 3e4, 2e4]}
    seeds = [{"load[0].seed": s} for s in range(1, 6)]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0", silence_logs=40) as cluster, \
            distributed.Client(cluster) as client:
        before = client.run(counts)
        ds = dd.run_batch([SCENES["chain"], stiffer], vary=seeds, client=client, chunk=2,
                          progress=False, check=False)
        after = client.run(counts)
    assert list(ds["status"].values) == ["done"] * 10
    built = {w: after[w][0] - before[w][0] for w in after}
    runs = {w: built[w] + after[w][1] - before[w][1] for w in after}
    assert all(b <= 2 for b in built.values()), built         # <= one per model per worker
    assert sum(runs.values()) >= 10 and sum(built.values()) <= 4, (built, runs)
    for i, (base, row) in enumerate((b, r) for b in (SCENES["chain"], stiffer) for r in seeds):
        scene = {**base, "load": [{**base["load"][0], **{"seed": row["load[0].seed"]}}]}
        alone, _ = dd.run_scene(dd.scene_from_dict(scene), check=False)
        for q in ("x", "v", "a"):
            assert np.array_equal(ds[q].values[i], getattr(alone, q)), (i, q)


def test_nonlinear_scenes_reuse_one_solver_bitwise():
    """Scenes with elements on matrices (P4's scene, modal_ramp at 3 sub-steps): the cache's
    solver runs them bitwise as run_scene without a cache (nonlinear_mck_response); other
    elements or options make another solver, an accuracy target none (a call)."""
    from importlib.resources import files
    base = dd.load_scene(files("dtdyn.app") / "scenes" / "p4.toml")
    cache = SolverCache()
    plain, _ = dd.run_scene(base, check=False)
    for _ in range(3):
        r, report = dd.run_scene(base, check=False, solvers=cache)
        assert np.array_equal(r.x, plain.x) and np.array_equal(r.v, plain.v)
        assert report["substeps"] == 3
    assert (cache.built, cache.reused) == (1, 2)
    stiffer = dataclasses.replace(base, elements=[dataclasses.replace(base.elements[0],
                                                                      k3=2 * base.elements[0].k3),
                                                  *base.elements[1:]])
    r, _ = dd.run_scene(stiffer, check=False, solvers=cache)
    assert cache.built == 2 and not np.array_equal(r.x, plain.x)
    target = dataclasses.replace(base, nonlinear={"accuracy": 1e-3})
    assert cache.nonlinear_solver(target) is None


@pytest.mark.parametrize("kind", ["beam", "shaft"])
def test_nonlinear_beam_and_shaft_scenes_reuse_their_solver(kind):
    """A beam's scene with a gap and a shaft's with two cubics (test_station_scene_elements'):
    the cache's solver (Beam.solver, Shaft.solver with elements) gives run_scene's result
    without a cache, bitwise."""
    from test_station_scene_elements import BEAM, SHAFT
    scene = dd.scene_from_dict(BEAM if kind == "beam" else SHAFT)
    cache = SolverCache()
    plain, _ = dd.run_scene(scene, check=False)
    for _ in range(2):
        r, _ = dd.run_scene(scene, check=False, solvers=cache)
        assert np.array_equal(r.x, plain.x)
    assert (cache.built, cache.reused) == (1, 1)
