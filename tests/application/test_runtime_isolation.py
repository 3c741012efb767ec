"""runtime/ imports without SymPy or jinja2, and falls back to NumPy (one warning) without C."""
import os
import subprocess
import sys

SCRIPT = r"""
import sys
sys.modules["sympy"] = None  # any import of SymPy or jinja2 now raises ImportError
sys.modules["jinja2"] = None
import warnings
import numpy as np
from dtdyn.linear import chain_response, mck_response, exact_response
from dtdyn.app import _scene as scene
from dtdyn.linear import chain_frequency_response  # its module, linear._tmm, imported whole
F = np.ones((101, 1))
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    a = chain_response([2, 3], [20, 15], [5, 6], F, 0.01, force_dofs=[1], backend="c")
    b = chain_response([2, 3], [20, 15], [5, 6], F, 0.01, force_dofs=[1], backend="c",
                       scheme="houbolt")
ours = [w for w in caught if "C backend unavailable" in str(w.message)]
print(a.info["backend"], len(ours), repr(float(a.x[-1, 1])))
"""


def _run(env_extra):
    env = dict(os.environ, **env_extra)
    proc = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                          env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.split()


def test_runtime_without_sympy_and_jinja2():
    backend, n_warn, x = _run({})
    assert backend == "c" and n_warn == "0"


def test_numpy_fallback_warns_once_and_agrees():
    backend_c, _, x_c = _run({})
    backend, n_warn, x = _run({"DTDYN_NO_C": "1"})
    assert backend == "numpy" and n_warn == "1"
    assert abs(float(x) - float(x_c)) <= 1e-13 * abs(float(x_c))


def test_import_dtdyn_needs_only_the_base_dependencies():
    """`import dtdyn` and a linear run load neither SymPy, jinja2, CasADi, matplotlib nor xarray
    (the extras); a nonlinear run without CasADi says which extra to install, in one line."""
    code = (
        "import sys\n"
        "for name in ('sympy', 'jinja2', 'casadi', 'matplotlib', 'xarray'):\n"
        "    sys.modules[name] = None\n"
        "import numpy as np, dtdyn as dd\n"
        "dd.mck_response(np.eye(2), np.zeros((2, 2)), np.eye(2), np.ones((11, 2)), 0.1)\n"
        "dd.modal_filter_response(np.eye(2), 0.1 * np.eye(2), np.eye(2), np.ones(11), 0.1,\n"
        "                         force_dofs=[1])\n"
        "try:\n"
        "    dd.nonlinear_mck_response(np.eye(1), np.eye(1), np.eye(1), np.ones(11), 0.1,\n"
        "                          elements=[dd.Cubic(0, k3=1.0)])\n"
        "except ImportError as exc:\n"
        "    print(exc)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert 'needs casadi, which is not installed: pip install "dtdyn[nonlinear]"' in proc.stdout
