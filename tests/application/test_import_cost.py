"""`import dtdyn` stays light: the heavy optional parts of SciPy and the extras load only when used.

scipy.signal (with scipy.stats, about 0.3 s), scipy.integrate and the extras (matplotlib, CasADi,
Dask, xarray) are imported inside the functions that need them (`DiscreteModel.to_dlti`,
`reference_response`, the nonlinear start-up, plots, batches). Each check runs in a fresh
interpreter: inside pytest other tests have long imported them. benchmarks/import_time.py
measures the time.
"""
import json
import subprocess
import sys

import numpy as np
import scipy.linalg

#: packages `import dtdyn` must not load, nor any of their submodules
DEFERRED = ("scipy.signal", "scipy.integrate", "scipy.stats", "matplotlib", "casadi", "dask",
            "distributed", "xarray")

_LOADED = f"""
import sys
def loaded():
    # the deferred packages of which the interpreter holds the package or a submodule
    return [p for p in {DEFERRED!r}
            if any(m == p or m.startswith(p + ".") for m in sys.modules)]
"""


def _fresh(code: str) -> dict:
    """Run ``code`` in a new interpreter; it prints one JSON line, returned decoded."""
    proc = subprocess.run([sys.executable, "-c", _LOADED + code], capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_import_dtdyn_loads_none_of_the_deferred_modules():
    out = _fresh("import dtdyn\nimport json\nprint(json.dumps({'loaded': loaded(), "
                 "'n': len(sys.modules)}))")
    assert out["loaded"] == [], f"`import dtdyn` loaded {out['loaded']}"
    # 974 modules with scipy.signal and scipy.integrate at import; about 600 without
    assert out["n"] < 750, out["n"]


def test_default_scene_runs_without_them_and_matches_modal_superposition(tmp_path):
    """`dd.run_scene(dd.load_scene())` (P3: 15-DOF undamped chain, unit step on DOF 14, average
    acceleration, dt = 1e-3, T = 0.8 s) in a fresh interpreter still runs, still loads none of
    the deferred modules, and its response agrees with the step response by modal
    superposition, computed here from the scene's masses and stiffnesses::

        K phi_i = omega_i^2 M phi_i,  phi_i^T M phi_i = 1,
        x(t) = sum_i phi_i (phi_i^T f) (1 - cos(omega_i t)) / omega_i^2.

    Average acceleration's period error at omega_max dt = 0.148 bounds the difference (the
    scene's own check against the matrix exponential reports 7.0e-4)."""
    path = tmp_path / "x.npy"
    out = _fresh(f"""
import json
import numpy as np
import dtdyn as dd
scene = dd.load_scene()
response, report = dd.run_scene(scene)
np.save({str(path)!r}, response.x)
print(json.dumps({{'loaded': loaded(), 'mass': list(map(float, scene.mass)),
                  'stiffness': list(map(float, scene.stiffness)), 'dt': scene.dt,
                  'error': report['max_rel_error']}}))
""")
    assert out["loaded"] == [], f"running the default scene loaded {out['loaded']}"
    m, k, dt = np.array(out["mass"]), np.array(out["stiffness"]), out["dt"]
    n = m.size
    K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    w2, phi = scipy.linalg.eigh(K, np.diag(m))
    f = np.zeros(n)
    f[n - 1] = 1.0
    x = np.load(path)
    t = dt * np.arange(x.shape[0])[:, None]
    truth = ((1.0 - np.cos(np.sqrt(w2) * t)) / w2 * (phi.T @ f)) @ phi.T
    error = np.abs(x - truth).max() / np.abs(truth).max()
    assert x.shape == (801, 15)
    assert error < 2e-3 and out["error"] < 2e-3, (error, out["error"])
    assert abs(error - out["error"]) < 1e-4, (error, out["error"])


def test_deferred_imports_load_where_they_are_used():
    """In a fresh interpreter (where nothing else imported them) `to_dlti` and
    `reference_response` load scipy.signal and scipy.integrate themselves and work."""
    out = _fresh("""
import json
import numpy as np
import dtdyn as dd
model = dd.newmark_ss(np.eye(1), 0.1 * np.eye(1), np.eye(1), 0.1)
before = loaded()
sys_d = model.to_dlti()
after_dlti = loaded()
r = dd.reference_response(np.eye(1), 0.1 * np.eye(1), np.eye(1), np.ones(51), 0.1, cache=False)
print(json.dumps({'before': before, 'dlti': type(sys_d).__name__, 'dt': sys_d.dt,
                  'A': np.asarray(sys_d.A).tolist(), 'A_model': np.asarray(model.A).tolist(),
                  'after_dlti': 'scipy.signal' in after_dlti,
                  'integrate': 'scipy.integrate' in loaded(), 'x': r.x[:, 0].tolist()}))
""")
    assert out["before"] == []
    assert out["dlti"] in ("StateSpaceDiscrete", "dlti") and out["dt"] == 0.1
    assert out["A"] == out["A_model"] and out["after_dlti"] and out["integrate"]
    # m x'' + c x' + k x = 1 from rest (m = k = 1, c = 0.1): the closed-form step response
    t = 0.1 * np.arange(51)
    zeta, wd = 0.05, np.sqrt(1 - 0.05 ** 2)
    truth = 1 - np.exp(-zeta * t) * (np.cos(wd * t) + zeta / wd * np.sin(wd * t))
    assert np.abs(np.array(out["x"]) - truth).max() < 1e-9
