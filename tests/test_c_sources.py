"""The generated C sources compile cleanly as C99 with warnings as errors."""
import shutil
import subprocess
from importlib import resources

import pytest

from dtdyn.generated import SCHEMES

CC = shutil.which("cc") or shutil.which("gcc")


@pytest.mark.skipif(CC is None, reason="no C compiler on this machine")
@pytest.mark.parametrize("name", [f"chain_{s}" for s in SCHEMES] + ["ss_response"])
def test_compiles_without_warnings(name, tmp_path):
    src = tmp_path / f"{name}.c"
    src.write_text(resources.files("dtdyn.generated").joinpath(f"{name}.c").read_text())
    proc = subprocess.run([CC, "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-c",
                           str(src), "-o", str(tmp_path / "k.o")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
