"""`import dtdyn` is the one public face: every name in dtdyn.__all__ is a function, class or
exception (never a submodule), and resolves to the same object however and in whatever order it
is imported."""
import importlib
import inspect
import subprocess
import sys

import dtdyn


def test_all_names_exist_and_are_not_modules():
    for name in dtdyn.__all__:
        obj = getattr(dtdyn, name)
        assert not inspect.ismodule(obj), name
        if name != "__version__":
            assert callable(obj), name


def test_face_functions_named_in_the_issue():
    for name in ("discretize", "stability", "chain_response", "state_space_response"):
        assert inspect.isfunction(getattr(dtdyn, name)), name


def test_same_object_from_its_home_module():
    for name in dtdyn.__all__:
        obj = getattr(dtdyn, name)
        home = getattr(obj, "__module__", None)
        if home and home.startswith("dtdyn."):
            assert getattr(importlib.import_module(home), name) is obj, name


def test_same_objects_whatever_the_import_order():
    """Submodules imported first (the order that once made `from dtdyn.runtime import
    discretize` return the module) must not shadow the face's functions: every module of the
    rooms, found on disk, is imported before the face."""
    code = (
        "import importlib, importlib.util, inspect, pathlib\n"
        "top = pathlib.Path(importlib.util.find_spec('dtdyn').origin).parent\n"
        "rooms = ['linear', 'modal', 'nonlinear', 'random_vibration', 'app']\n"
        "mods = sorted('.'.join(('dtdyn',) + p.relative_to(top).with_suffix('').parts)\n"
        "              for r in rooms for p in (top / r).rglob('*.py'))\n"
        "for m in mods: importlib.import_module(m.removesuffix('.__init__'))\n"
        "import dtdyn\n"
        "from dtdyn import *\n"
        "for name in dtdyn.__all__:\n"
        "    obj = getattr(dtdyn, name)\n"
        "    assert not inspect.ismodule(obj), name\n"
        "    assert globals()[name] is obj, name\n"
        "print(len(dtdyn.__all__))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout) == len(dtdyn.__all__)
