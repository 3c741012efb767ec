"""Each subpackage's `__all__` names its public objects: those `dtdyn` exports too are the very
same objects (the keyword-checked functions), none of them a module, and importing the
subpackages alone loads none of the deferred modules (test_import_cost.py). The tests import
public names: a room's private modules only in the tests of that room's folder."""
import ast
import importlib
import re
from pathlib import Path

import pytest

import dtdyn
from test_import_cost import _fresh

ROOMS = ["dtdyn.linear", "dtdyn.modal", "dtdyn.nonlinear", "dtdyn.random_vibration", "dtdyn.app",
         "dtdyn._engine"]


@pytest.mark.parametrize("room", ROOMS)
def test_all_names_are_the_public_objects(room):
    package = importlib.import_module(room)
    for name in package.__all__:
        obj = getattr(package, name)
        assert not isinstance(obj, type(dtdyn)), f"{room}.{name} is a module"
        if name in dtdyn.__all__:      # a room may offer more (random_vibration.PsdTable)
            assert obj is getattr(dtdyn, name), f"{room}.{name} is not dtdyn.{name}"
        assert name in dir(package)
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        _ = package.not_a_name


def test_engine_offers_nothing_and_rooms_cover_the_library():
    assert dtdyn._engine.__all__ == []
    rooms = set().union(*(importlib.import_module(r).__all__ for r in ROOMS))
    assert {"chain_response", "Modes", "modal_model", "nonlinear_mck_response", "psd_table",
            "run_scene", "problem"} <= rooms


def test_importing_a_room_loads_none_of_the_deferred_modules():
    out = _fresh("import dtdyn.linear, dtdyn.modal, dtdyn.nonlinear\nimport json\n"
                 "print(json.dumps({'loaded': loaded()}))")
    assert out["loaded"] == []


# --- tests import public names; a room's private modules only in the tests of that room ---------
TESTS = Path(__file__).resolve().parents[1]
#: the rooms whose private modules the tests of each folder may import (the folder's own rooms);
#: symbolic/ tests dtdyn.derive, no room of the runtime; fuzz/ fuzzes the library's behaviour
#: (the accepted laws as the nonlinear room evaluates them); conftest.py, problems.py: none
FOLDER_ROOMS = {"application": {"app"}, "behaviour": {"linear", "modal", "nonlinear"},
                "random_vibration": {"random_vibration"},
                # the compiled kernels, white-box: the engine and each room's kernel drivers
                "generated_code": {"_engine", "linear", "modal", "nonlinear", "random_vibration"},
                "symbolic": set(), "fuzz": {"linear", "modal", "nonlinear"}}
#: the calls whose first argument names a module or an attribute by a dotted string
_BY_STRING = {"setattr", "delattr", "setitem", "patch", "import_module"}
ROOMS_BY_NAME = {room.split(".")[1] for room in ROOMS}


def private_room(dotted: str) -> str | None:
    """The room whose private part ``dotted`` (a module or name path) reaches, else None: any of
    its parts after ``dtdyn`` starting with one ``_`` (a room's ``__all__`` is its face)."""
    parts = dotted.split(".")
    if len(parts) < 2 or parts[0] != "dtdyn" or parts[1] not in ROOMS_BY_NAME:
        return None
    if parts[2:] == ["__all__"]:
        return None
    private = any(p.startswith("_") and not p.startswith("__") for p in parts[1:])
    return parts[1] if private else None



def _attribute_path(node) -> tuple[str | None, list[str]]:
    """(the root name, the attribute names) of ``a.b.c``; (None, []) if the root is no name."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    return (node.id, parts[::-1]) if isinstance(node, ast.Name) else (None, [])


def _paths_of(node: ast.AST, bound: dict) -> list[tuple[int, str]]:
    """(line, dotted path) of one node: the modules and names an import takes (noting in
    ``bound`` the names it binds to dtdyn modules), the dotted string a patch or an
    import_module call takes, or what a string constant that is Python code imports."""
    if isinstance(node, (ast.Import, ast.ImportFrom)):
        if isinstance(node, ast.ImportFrom) and (node.level or not node.module):
            return []
        found = []
        for alias in node.names:
            path = alias.name if isinstance(node, ast.Import) else f"{node.module}.{alias.name}"
            found.append((node.lineno, path))
            if path.split(".")[0] == "dtdyn":
                top = isinstance(node, ast.Import) and not alias.asname
                bound["dtdyn" if top else alias.asname or alias.name] = "dtdyn" if top else path
        return found
    if isinstance(node, ast.Call) and node.args:
        func, first = node.func, node.args[0]
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
        if name in _BY_STRING and isinstance(first, ast.Constant) and isinstance(first.value, str):
            return [(node.lineno, first.value)]
    if isinstance(node, ast.Constant) and isinstance(node.value, str) and "dtdyn" in node.value:
        text = node.value
        if re.fullmatch(r"dtdyn(\.\w+)+", text):        # ["python", "-m", "dtdyn.x._y"]
            return [(node.lineno, text)]
        found = [(node.lineno, m) for m in re.findall(r"-m\s+(dtdyn(?:\.\w+)*)", text)]
        if "import" in text:
            found += [(node.lineno + line - 1, path) for line, path in _code_paths(text)]
        return found
    return []


def _code_paths(text: str) -> list[tuple[int, str]]:
    """`imported_paths` of a string that is Python code; of its lines one by one where it is
    not whole (a template with ``{name!r}`` fields)."""
    try:
        return imported_paths(ast.parse(text))
    except SyntaxError:
        pass
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        try:
            found += [(number, path) for _, path in imported_paths(ast.parse(line.strip()))]
        except SyntaxError:
            continue
    return found


def imported_paths(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, dotted path) of what ``tree`` imports from dtdyn and what it reaches by attribute
    from a name bound to a dtdyn module; the dotted strings it patches or imports by name; and
    the same inside string constants that are Python code (a script run in a subprocess)."""
    bound = {}
    found = [path for node in ast.walk(tree) for path in _paths_of(node, bound)]
    inner = set()                               # a.b of a.b.c: the longest path only
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and id(node) not in inner:
            value = node.value
            while isinstance(value, ast.Attribute):
                inner.add(id(value))
                value = value.value
            root, attrs = _attribute_path(node)
            if root in bound and private_room(bound[root]) is None:
                found.append((node.lineno, ".".join([bound[root], *attrs])))
    return sorted(set(found))


def room_violations(path: Path) -> list[str]:
    """Each private import of ``path`` (a file under tests/) from a room not of its folder."""
    rel = path.relative_to(TESTS)
    rooms = FOLDER_ROOMS.get(rel.parts[0], set()) if len(rel.parts) > 1 else set()
    out = []
    for line, dotted in imported_paths(ast.parse(path.read_text(), str(path))):
        room = private_room(dotted)
        if room is not None and room not in rooms:
            out.append(f"tests/{rel.as_posix()}:{line} imports {dotted} (room {room}; this "
                       f"folder's rooms: {', '.join(sorted(rooms)) or 'none'})")
    return out


def test_tests_import_private_names_only_of_their_own_rooms():
    """A test imports the public names (`dtdyn`, a room's ``__all__``); a room's private
    modules (``dtdyn.linear._chain``, ``from dtdyn.modal import _filters``, ``dtdyn._engine``,
    also as a patched string) only in the tests of that room's folder."""
    assert set(FOLDER_ROOMS) == {p.name for p in TESTS.iterdir()
                                 if p.is_dir() and any(p.glob("*.py"))}
    found = [v for path in sorted(TESTS.rglob("*.py")) if path != Path(__file__).resolve()
             for v in room_violations(path)]          # this file names them to test the rule
    assert not found, "\n".join(found)


def test_the_rule_sees_every_kind_of_import():
    # "@" stands for dtdyn: the rule does not read this sample as this file's own imports
    code = ("import @ as dd\nfrom @.linear import _chain\nimport @._engine.cbuild\n"
            "from @.modal._srs import sdof_response\nfrom @.linear import chain_response\n"
            "dd.nonlinear._chain.x\nmonkeypatch.setattr('@.app._cli.main', None)\n"
            "S = '''\nfrom @.random_vibration._psd import psd_table\nf({x!r})'''\n"
            "dd._engine.__all__, dd.linear.__all__, dd.app.main, dd._engine.kernels.WORK_ROWS\n"
            "run([exe, '-m', '@.app._cli', 'show']); run(f'{exe} -m @.linear._beam | head')\n")
    tree = ast.parse(code.replace("@", "dtdyn"))
    got = [(line, path) for line, path in imported_paths(tree) if private_room(path)]
    assert got == [(2, "dtdyn.linear._chain"), (3, "dtdyn._engine.cbuild"),
                   (4, "dtdyn.modal._srs.sdof_response"), (6, "dtdyn.nonlinear._chain.x"),
                   (7, "dtdyn.app._cli.main"), (9, "dtdyn.random_vibration._psd.psd_table"),
                   (11, "dtdyn._engine.kernels.WORK_ROWS"), (12, "dtdyn.app._cli"),
                   (12, "dtdyn.linear._beam")]
