"""Every C source dtdyn ships (generated/*.c) compiles cleanly as C99 with -Wall -Wextra -Werror
-pedantic. nl_loop.c takes its problem sizes as macros at compile time (the runtime defines them
for each set of elements); here they get sample values."""
import shutil
import subprocess
from importlib import resources

import pytest

from dtdyn._engine import cbuild

CC = shutil.which("cc") or shutil.which("gcc")
SOURCES = sorted(p.name for p in resources.files("dtdyn.generated").iterdir()
                 if p.name.endswith(".c"))
DEFINES = {"nl_loop.c": ["-DNL_NS=8", "-DNL_NF=1", "-DNL_NE=2", "-DNL_NW=2", "-DNL_NZ=0",
                         "-DNL_NO=4"]}


def test_every_source_is_listed():
    assert len(SOURCES) >= 17 and "nl_chain.c" in SOURCES and "filter_bank.c" in SOURCES


@pytest.mark.skipif(CC is None, reason="no C compiler on this machine")
@pytest.mark.parametrize("name", SOURCES)
def test_compiles_without_warnings(name, tmp_path):
    src = tmp_path / name  # as the runtime compiles it: included headers inlined
    src.write_text(cbuild.generated_source(name))
    proc = subprocess.run([CC, "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic",
                           *DEFINES.get(name, []), "-c", str(src), "-o", str(tmp_path / "k.o")],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
