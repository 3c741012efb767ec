"""Sphinx configuration of the dtdyn documentation site.

Build it from the repository root (needs the ``[docs]`` extra)::

    python -m sphinx -W -b html docs docs/_build/html

Everything under ``docs/api/`` and ``docs/gallery/`` is written at build time: the API index from
the groups of ``dtdyn.__all__`` (the comments in ``runtime/__init__.py``), one page per public name
by autosummary, and the example gallery by running ``examples/gallery/plot_*.py``.
"""
from __future__ import annotations

import os
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent

os.environ.setdefault("MPLBACKEND", "Agg")          # the gallery draws without a display

import dtdyn  # noqa: E402  (the installed package; `pip install -e .` or `pip install .`)

project = "dtdyn"
author = "the dtdyn developers"
copyright = "dtdyn developers"
release = version = dtdyn.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "**/GALLERY_HEADER.rst", "sg_execution_times.rst"]
templates_path = ["_templates"]

# --- Markdown pages (docs/*.md, docs/guide/*.md) as they are --------------------------------
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3
# the pages name repository files (benchmarks/*.py, generated/*.md, tests/...) in prose and
# links; those are not pages of this site
suppress_warnings = ["myst.xref_missing"]

# --- API reference ------------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": False}
autodoc_typehints = "none"                 # the numpydoc Parameters sections carry the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks = set()

# --- Example gallery ----------------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples" / "gallery"),
    "gallery_dirs": str(DOCS / "gallery"),
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "show_memory": False,
    "write_computation_times": False,
}

# --- HTML ---------------------------------------------------------------------------------------
html_theme = "alabaster"
html_title = f"dtdyn {release}"
html_static_path: list[str] = []
html_theme_options = {"description": "Discrete-time structural dynamics", "fixed_sidebar": True}


def _api_groups() -> list[tuple[str, list[str]]]:
    """`dtdyn.__all__` in the groups its comments in ``runtime/__init__.py`` give it."""
    source = (ROOT / "runtime" / "__init__.py").read_text(encoding="utf-8")
    block = re.search(r"^__all__\s*=\s*\[(.*?)^\]", source, flags=re.S | re.M)
    groups: list[tuple[str, list[str]]] = []
    if block:
        for line in block.group(1).splitlines():
            text = line.strip()
            if text.startswith("#"):
                title = text.lstrip("#").strip()
                groups.append((title[:1].upper() + title[1:], []))
                continue
            names = re.findall(r"[\"']([A-Za-z_][A-Za-z0-9_]*)[\"']", text)
            if names and not groups:
                groups.append(("Package", []))
            if names:
                groups[-1][1].extend(names)
    listed = {n for _, names in groups for n in names}
    missing = [n for n in dtdyn.__all__ if n not in listed]
    if missing:                             # names added to __all__ some other way
        groups.append(("Other", missing))
    public = set(dtdyn.__all__)
    return [(title, [n for n in names if n in public]) for title, names in groups
            if any(n in public for n in names)]


def _write_api_index() -> None:
    """docs/api/index.rst: one autosummary table per group, one generated page per name."""
    lines = ["API reference", "=============", "",
             "Every public name of ``dtdyn`` (``dtdyn.__all__``), importable as "
             "``import dtdyn as dd; dd.<name>``. Each page is the object's docstring.", "",
             ".. currentmodule:: dtdyn", ""]
    for title, names in _api_groups():
        lines += [title, "-" * len(title), "", ".. autosummary::", "   :toctree: generated",
                  "   :nosignatures:", ""]
        lines += [f"   {name}" for name in names]
        lines.append("")
    text = "\n".join(lines)
    path = DOCS / "api" / "index.rst"
    path.parent.mkdir(exist_ok=True)
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


_INLINE_LITERAL = re.compile(r"(``.+?``|`[^`]+`)")


def _escape_bars(line: str) -> str:
    """``|x|`` outside inline literals and roles, as text: a bar is not a substitution."""
    parts = _INLINE_LITERAL.split(line)
    return "".join(part if i % 2 else re.sub(r"(?<!\\)\|", r"\\|", part)
                   for i, part in enumerate(parts))


def plain_text_math(app, what, name, obj, options, lines) -> None:
    """dtdyn's docstrings write formulas in plain text, where ``|s|`` is an absolute value and
    ``|x_DOP853 - x_Radau|`` a norm; reStructuredText would read them as substitutions. Escape
    those bars, except in doctests, literal blocks, directive bodies (``.. math::``) and inline
    literals, where they are shown as written."""
    if what == "data" and name == "dtdyn.__version__":     # a str: not str's own docstring
        lines[:] = ["The version of the installed dtdyn package (PEP 440), e.g. ``'0.1.0'``."]
        return
    block_indent = None                    # indent of the line that opened a literal block
    for i, line in enumerate(lines):
        stripped = line.lstrip()
        indent = len(line) - len(stripped)
        if block_indent is not None:
            if not stripped or indent > block_indent:
                continue
            block_indent = None
        if stripped.startswith((">>>", "...", "| ", "+-", "+=")) or stripped == "|" or \
                (stripped.startswith("|") and stripped.endswith("|") and " | " in stripped):
            continue                       # doctests, line blocks, grid tables
        if stripped.startswith(".. ") or stripped.endswith("::"):
            block_indent = indent
            if stripped.startswith(".. "):
                continue
        if "|" in line:
            lines[i] = _escape_bars(line)


def setup(app):
    app.connect("autodoc-process-docstring", plain_text_math)


_write_api_index()
sys.path.insert(0, str(DOCS))
