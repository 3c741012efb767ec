"""`dtdyn generate --out DIR SCHEME_FILE`: a standalone copy of the C kernels for vendoring.

Every C source in DIR/vendor compiles there with `cc -O2 -c` and nothing else (its headers are
beside it), and example.c, linked with the HHT chain kernel, prints the response that
`dd.chain_response` gives for the same chain, force and scheme (the same kernel: to rounding).
"""
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import dtdyn as dd

pytest.importorskip("sympy")
CC = shutil.which("cc") or shutil.which("gcc")
pytestmark = [pytest.mark.skipif(CC is None, reason="no C compiler"), pytest.mark.slow]

SCHEME = """
name = "vendored"
relations = ["x1 = x0 + dt*v0 + dt**2/4*(a0 + a1)", "v1 = v0 + dt/2*(a0 + a1)",
             "xe = x1", "ve = v1", "ae = a1"]
"""


def test_vendor_copy_compiles_and_the_example_runs(tmp_path):
    (tmp_path / "vendored.toml").write_text(SCHEME)
    out = tmp_path / "out"
    subprocess.run([sys.executable, "-m", "dtdyn", "generate", "--out", str(out),
                    str(tmp_path / "vendored.toml")], check=True, capture_output=True)
    vendor = out / "vendor"
    sources = sorted(p.name for p in vendor.glob("*.c"))
    assert "chain_vendored.c" in sources and "shaft_vendored.c" in sources
    for name in sources:
        subprocess.run([CC, "-O2", "-c", name], cwd=vendor, check=True, capture_output=True)
    subprocess.run([CC, "-O2", "-o", "example", "example.o", "chain_hht.o", "-lm", "-lpthread"],
                   cwd=vendor, check=True, capture_output=True)
    printed = subprocess.run([str(vendor / "example")], check=True, capture_output=True,
                             text=True).stdout
    x = float(printed.split(":")[1])
    r = dd.chain_response([1.0, 1.0], [1e3, 1e3], [0.5, 0.5], np.ones(101), 1e-3,
                          force_dofs=[1], scheme="hht")
    assert abs(x - r.x[100, 1]) <= 1e-12 * abs(r.x[100, 1])
    assert Path(out / "scheme_table.py").is_file()             # the NumPy side as well
