"""Schemes from a user's scheme file: derived once, cached by content, loaded without SymPy.

`load_scheme(path)` reads a scheme file (TOML: the scheme's defining relations as text, its
parameters and their ranges; see docs/guide/scheme_files.md). The first time a file's content is
seen, the derivation (`dtdyn.derive.scheme_file`, needs the ``[derive]`` extra) checks it and
writes its coefficient module, its amplification matrix and its chain and shaft C kernels into
the compile cache under the SHA-256 of the text; later loads (any process) read them from there
and import neither SymPy nor jinja2. The folder appears complete or not at all (written beside
it, then renamed), so two processes may load the same file at once.
"""
from __future__ import annotations

import functools
import hashlib
import importlib.util
import json
import os
import shutil
import tempfile
from pathlib import Path

from dtdyn._engine import cbuild, validate
from dtdyn._engine.version import VERSION

#: bump when the cached files' layout changes (old folders are then ignored)
CACHE_FORMAT = "1"
#: files a complete cache folder holds besides the per-name ones
TABLE = "table.json"
#: the largest scheme file read (bytes)
MAX_BYTES = 64 * 1024


class FileScheme:
    """A scheme derived from a scheme file: pass it as ``scheme=`` wherever a scheme name goes.

    Attributes
    ----------
    name : str
        The file's ``name``.
    text : str
        The file's text.
    path : str
        The file it was loaded from.
    sha256 : str
        The hash of the file's text (the cache key).
    table : dict
        Title, parameters (default, range), order of accuracy (derived), explicitness,
        start-up, reference, as the built-ins' scheme table has them.
    folder : pathlib.Path
        The cache folder holding its derived files.

    Examples
    --------
    >>> import dtdyn as dd
    >>> _ = open("mine.toml", "w").write('''
    ... name = "mine"
    ... relations = ["x1 = x0 + dt*v0 + dt**2/4*(a0 + a1)", "v1 = v0 + dt/2*(a0 + a1)",
    ...              "xe = x1", "ve = v1", "ae = a1"]
    ... ''')
    >>> s = dd.load_scheme("mine.toml")
    >>> s.name, s.params, s.table["order"], s.table["explicit"]
    ('mine', (), 2, False)
    """

    def __init__(self, text: str, path: str, folder: Path, table: dict):
        self.text, self.path, self.folder, self.table = text, path, folder, table
        self.name = table["name"]
        self.sha256 = table["sha256"]
        self._modules = {}

    def __repr__(self):
        return f"<scheme {self.name!r} from {self.path} (sha256 {self.sha256[:12]})>"

    def __str__(self):
        return f"{self.name} (scheme file {self.path})"

    def __eq__(self, other):
        return isinstance(other, FileScheme) and other.sha256 == self.sha256

    def __hash__(self):
        return hash(self.sha256)

    def __reduce__(self):  # to batch workers: the text travels, the cache rebuilds or reads
        return (_from_text, (self.text, self.path))

    @property
    def params(self) -> tuple:
        """The parameters' names, in the file's order."""
        return tuple(self.table["params"])

    @property
    def key(self) -> str:
        """The name its kernels are cached under (name and content hash)."""
        return f"{self.name}_{self.sha256[:16]}"

    @property
    def stages(self) -> tuple:
        """The names of a composite scheme's sub-steps (empty: one step)."""
        return tuple(self.table.get("stages") or ())

    def module(self, kind: str = "scheme", name: str | None = None):
        """The cached Python module ``scheme`` (coefficients; of the stage ``name`` of a
        composite scheme) or ``stability`` (amplification matrix), imported from the cache."""
        name = name or self.name
        if (kind, name) not in self._modules:
            path = self.folder / f"{kind}_{name}.py"
            spec = importlib.util.spec_from_file_location(
                f"dtdyn_scheme_files.{kind}_{name}_{self.sha256[:16]}", path)
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
            self._modules[kind, name] = mod
        return self._modules[kind, name]

    def c_source(self, kind: str, name: str | None = None) -> str:
        """The C source of its (or its stage ``name``'s) ``chain`` or ``shaft`` kernel, as one
        translation unit."""
        path = self.folder / f"{kind}_{name or self.name}.c"
        return cbuild.expand_includes(path.read_text())

    def report(self, omega_dt=None) -> dict:
        """The checks of its derivation: order of accuracy (from the local truncation error's
        Taylor series), explicitness, spectral radius and period elongation over Omega = omega dt
        at the default parameters, rho at infinity and the stability limit (inf: none found up
        to Omega = 1e4)."""
        import numpy as np

        from dtdyn._engine.schemes import get_scheme

        info = get_scheme(self)
        W = (np.logspace(-2, 4, 61) if omega_dt is None
             else validate.vector("omega_dt", np.atleast_1d(omega_dt), positive=True))
        rho, elongation, damping = info.spectral(W)
        return {"name": self.name, "title": self.table["title"], "source": self.path,
                "order": self.table["order"], "claimed_order": self.table.get("claimed_order"),
                "explicit": self.table["explicit"],
                "params": {p: v["default"] for p, v in self.table["params"].items()},
                "rho_inf": float(info.spectral([1e8])[0][0]),
                "critical_omega_dt": float(info.critical_omega_dt()),
                "omega_dt": W.tolist(), "spectral_radius": rho.tolist(),
                "period_elongation": elongation.tolist(), "algorithmic_damping": damping.tolist()}


def _folder(text: str) -> Path:

    key = hashlib.sha256(f"{CACHE_FORMAT}\0{VERSION}\0{_derivation_digest()}\0{text}"
                         .encode()).hexdigest()[:32]
    return cbuild.cache_dir() / "schemes" / key


@functools.cache
def _derivation_digest() -> str:
    """The hash of what turns a scheme file into its cached files: the derivations
    (dtdyn.derive), their templates and the hand-written C they include. A change to any of
    them is a new cache folder, so an upgrade never reads files derived by older code."""
    from importlib import resources

    h = hashlib.sha256()
    roots = [resources.files("dtdyn.derive"), resources.files("dtdyn._engine") / "csrc"]
    for root in roots:
        for path in sorted(Path(str(root)).rglob("*"), key=str):
            if path.suffix in (".py", ".jinja", ".h") and path.is_file():
                h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


def _complete(folder: Path) -> dict | None:
    try:
        table = json.loads((folder / TABLE).read_text())
    except (OSError, ValueError):
        return None
    name = table.get("name", "")
    need = [f"stability_{name}.py"] + [f"{k}_{part}.{ext}" for part in table.get("stages") or [name]
                                       for k, ext in (("scheme", "py"), ("chain", "c"),
                                                      ("shaft", "c"))]
    return table if all((folder / f).is_file() for f in need) else None


def _from_text(text: str, path: str = "<scheme>", rebuild: bool = False) -> FileScheme:
    folder = _folder(text)
    table = None if rebuild else _complete(folder)
    if table is None:
        table = _derive(text, path, folder, rebuild)
    return FileScheme(text, path, folder, table)


def _derive(text: str, path: str, folder: Path, rebuild: bool) -> dict:
    """Derive ``text`` and rename its files into ``folder`` as one directory. A complete
    folder another process renamed in meanwhile is kept (its files are the same) unless
    ``rebuild``, which replaces it (readers of the old one may then miss files)."""
    from dtdyn._engine.extras import require

    require("sympy", "derive", "load_scheme (the first load of a scheme file derives it)")
    require("jinja2", "derive", "load_scheme (the first load of a scheme file derives it)")
    from dtdyn.derive import scheme_file

    _, files = scheme_file.build(text, path)
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".{folder.name}."))
    try:
        for name, body in files.items():
            (tmp / name).write_text(body, encoding="utf-8")
        if folder.exists() and (rebuild or _complete(folder) is None):  # replace it whole
            old = folder.parent / f".{folder.name}.old.{os.getpid()}"
            try:
                os.replace(folder, old)
                shutil.rmtree(old, ignore_errors=True)
            except OSError:
                pass
        try:
            os.replace(tmp, folder)
        except OSError:  # a complete copy is there (another process renamed it in first)
            shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    table = _complete(folder)
    if table is None:
        raise RuntimeError(f"{path}: the derived scheme could not be written to {folder}")
    return table


def load_scheme(path, *, rebuild: bool = False) -> FileScheme:
    """Load a user's scheme file: derive and check it (once per content), then return a value
    accepted as ``scheme=`` by every entry point that takes a scheme name.

    The file gives the defining relations of one step as text, e.g. Bossak-alpha::

        name = "my_bossak"
        relations = [
          "x1 = x0 + dt*v0 + dt**2*((1/2 - beta)*a0 + beta*a1)",
          "v1 = v0 + dt*((1 - gamma)*a0 + gamma*a1)",
          "xe = x1", "ve = v1",
          "ae = (1 - alpha_m)*a1 + alpha_m*a0",
        ]
        force_weights = ["0", "1"]          # Fe = w0 F_n + w1 F_n+1

        [parameters.alpha_m]
        default = -0.1
        range = [-0.5, 0.0]

        [substitutions]
        beta = "(1 - alpha_m)**2/4"
        gamma = "1/2 - alpha_m"

    with M ae + C ve + K xe = Fe enforced at the equilibrium point (xe, ve, ae). Nothing in the
    file is executed: each side of a relation is parsed by an allow-list parser.

    Parameters
    ----------
    path : str or os.PathLike
        The scheme file (TOML), or the name of one that ships with dtdyn: ``"bathe"`` (Bathe's
        composite method) and ``"rho_inf_bathe"`` (Noh & Bathe 2019), composite schemes of two
        sub-steps.
    rebuild : bool
        Derive again even when the cache holds this content.

    Returns
    -------
    FileScheme
        Its parameters are keywords of the entry points (``alpha_m=-0.2``), checked against
        the file's ranges; ``.report()`` gives the derivation's checks.

    Raises
    ------
    ValueError
        One line naming the relation or field: unknown symbols, expressions outside the
        allow-list, relations that are not linear in the new state, that leave part of it
        undetermined or contradict each other, a claimed ``order`` the derivation does not give.
    ImportError
        The first load of a content without the ``[derive]`` extra (SymPy, jinja2).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> _ = open("my_bossak.toml", "w").write('''
    ... name = "my_bossak"
    ... relations = ["x1 = x0 + dt*v0 + dt**2*((1/2 - beta)*a0 + beta*a1)",
    ...              "v1 = v0 + dt*((1 - gamma)*a0 + gamma*a1)",
    ...              "xe = x1", "ve = v1", "ae = (1 - alpha_m)*a1 + alpha_m*a0"]
    ... [parameters.alpha_m]
    ... default = -0.1
    ... range = [-0.5, 0.0]
    ... [substitutions]
    ... beta = "(1 - alpha_m)**2/4"
    ... gamma = "1/2 - alpha_m"
    ... ''')
    >>> scheme = dd.load_scheme("my_bossak.toml")
    >>> scheme.table["order"], round(float(dd.stability(scheme, [1e8]).spectral_radius[0]), 6)
    (2, 0.818182)
    >>> M, K = np.diag([1.0, 2.0]), np.array([[3e3, -1e3], [-1e3, 1e3]])
    >>> r = dd.mck_response(M, 0.01 * K, K, np.ones(101), 0.01, force_dofs=[1], scheme=scheme,
    ...                     alpha_m=-0.2)
    >>> r.info["scheme"], r.info["params"]
    ('my_bossak', {'alpha_m': -0.2})
    """
    shipped = SHIPPED / f"{path}.toml"
    if isinstance(path, str) and "/" not in path and not Path(path).exists() and shipped.is_file():
        path = shipped
    return _from_text(read_scheme_text(path), str(path), rebuild)


#: the scheme files that ship with dtdyn, loaded by name (``load_scheme("bathe")``)
SHIPPED = Path(__file__).resolve().parent.parent / "app" / "schemes"


def read_scheme_text(path) -> str:
    """The text of a scheme file (at most `MAX_BYTES`); ValueError naming the file otherwise."""
    path = Path(path)
    try:
        if not path.exists():
            raise ValueError(f"{path}: no such scheme file")
        if not path.is_file():   # a folder, a device (/dev/zero), a FIFO: refused unread
            raise ValueError(f"{path}: not a regular file; a scheme file is a TOML text file")
        with path.open("rb") as fh:
            data = fh.read(MAX_BYTES + 1)
        if len(data) > MAX_BYTES:
            raise ValueError(f"{path}: the scheme file is over {MAX_BYTES:,} bytes, the limit")
        return data.decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the scheme file: {exc}") from None
