"""Pages in docs/ that show a command's output show what it prints at this version."""
import contextlib
import io
import pathlib

from dtdyn.app._cli import main

DOCS = pathlib.Path(__file__).resolve().parents[2] / "docs"


def test_stability_page_shows_what_the_command_prints():
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["stability"]) == 0
    page = (DOCS / "stability.md").read_text()
    assert buf.getvalue() in page, "rerun: python benchmarks/stability_table.py"
