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


CSRC = resources.files("dtdyn._engine") / "csrc"
HAND_WRITTEN = sorted(p.name for p in CSRC.iterdir() if p.name.endswith(".h"))


@pytest.mark.skipif(CC is None, reason="no C compiler on this machine")
@pytest.mark.parametrize("name", SOURCES)
def test_compiles_in_place_with_the_runtime_flags(name, tmp_path):
    """As the files are, with the include path instead of the runtime's inlining, and with the
    runtime's optimisation (-O3: some warnings, e.g. maybe-uninitialized, need it)."""
    flags = [f for f in cbuild.CFLAGS if f not in ("-shared", "-fPIC")]
    dirs = [f"-I{d}" for d in cbuild.include_dirs()]
    proc = subprocess.run([CC, *flags, "-Wall", "-Wextra", "-Werror", *dirs,
                           *DEFINES.get(name, []), "-c",
                           str(resources.files("dtdyn.generated").joinpath(name)),
                           "-o", str(tmp_path / "k.o")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_hand_written_c_is_c_and_each_file_is_used():
    """The hand-written C is plain C (no template syntax), kept once (not copied into
    generated/), and every file is included by a generated source."""
    generated = resources.files("dtdyn.generated")
    texts = [cbuild.generated_source(n) for n in SOURCES]
    assert {"chain_loop.h", "shaft_loop.h", "nl_loop.h", "nl_chain.h", "mck_loop.h"} <= set(
        HAND_WRITTEN)
    for name in HAND_WRITTEN:
        text = CSRC.joinpath(name).read_text()
        assert "{%" not in text and "{{" not in text, name
        assert not generated.joinpath(name).is_file(), f"{name} is also in generated/"
        first = text.splitlines()[0]
        assert any(first in t for t in texts), f"{name} is included by no generated source"
