"""Kernels compiled on their own as C99 with -Wall -Wextra -Werror -pedantic (moved here from
the tests of the rooms that run them): the modal filter kernels (tests/behaviour/
test_modal_filters.py) and nl_loop.c's modal path in its variants (test_nonlinear.py)."""
import shutil
import subprocess
from importlib import resources

import pytest

from dtdyn._engine import cbuild
from dtdyn._engine.cbuild import include_dirs


@pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None,
                    reason="no C compiler on this machine")
@pytest.mark.parametrize("name", ["filter_bank", "modal_states"])
def test_filter_kernels_compile_without_warnings(name, tmp_path):
    cc = shutil.which("cc") or shutil.which("gcc")
    src = tmp_path / f"{name}.c"
    src.write_text(resources.files("dtdyn.generated").joinpath(f"{name}.c").read_text())
    includes = [f"-I{d}" for d in include_dirs()]       # c_api.h, the hand-written headers
    proc = subprocess.run([cc, "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", *includes,
                           "-c", str(src), "-o", str(tmp_path / "k.o")], capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("variant", [[], ["-DNL_EXPLICIT=1"], ["-DNL_EXPLICIT=1", "-DNL_NZ=0"],
                                     ["-mavx", "-mfma"],
                                     ["-mavx", "-mfma", "-DNL_EXPLICIT=1", "-DNL_NZ=0"]])
def test_modal_path_compiles_cleanly(tmp_path, variant):
    """nl_loop.c with the modal path compiled in (its vectors of 4 are GCC/Clang vector
    extensions) as C99 with -Wall -Wextra -Werror -pedantic, as the general path is checked here
    (test_c_sources.py): implicit and explicit (NL_EXPLICIT, with and without internal states),
    with and without the fused multiply-add intrinsics (VFMA)."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler on this machine")
    src = tmp_path / "nl_loop.c"
    src.write_text(cbuild.generated_source("nl_loop.c"))
    sizes = {"NS": 10, "NF": 1, "NE": 2, "NW": 4, "NZ": 1, "NO": 5, "NM": 6, "NH": 4, "NST": 7}
    for flag in variant:
        if flag.startswith("-DNL_N"):
            key, value = flag[5:].split("=")
            sizes[key] = int(value)
    defines = [f"-DNL_{k}={v}" for k, v in sizes.items()]
    defines += [f for f in variant if not f.startswith("-DNL_N")]
    proc = subprocess.run([cc, "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", *defines,
                           "-c", str(src), "-o", str(tmp_path / "k.o")],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
