"""Every Python example of README.md and docs/**/*.md runs as a user runs it: saved to its own
file and run as ``python file.py`` in a fresh interpreter, in a scratch folder.

Running a block with ``python -c`` would hide what only a script shows: Dask's local worker
processes import the main module again, so a batch example without its
``if __name__ == "__main__":`` guard fails as a file and not under ``-c``.

A block is skipped only when the line before its fence is a comment
``<!-- not a script: <why> -->``; the reason is required (e.g. it needs a running Dask
scheduler, or reads what a long shell command above it writes).
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
GENERATED = ("_build", "api", "gallery")          # written by the docs build, not sources
FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", flags=re.S | re.M)
SKIP = re.compile(r"<!--\s*not a script:\s*(\S.*?)\s*-->\s*\Z", flags=re.S)


def _pages() -> list[Path]:
    docs = [p for p in sorted((ROOT / "docs").rglob("*.md"))
            if p.relative_to(ROOT / "docs").parts[0] not in GENERATED]
    return [ROOT / "README.md"] + docs


def _blocks() -> tuple[list, list]:
    """(runnable, skipped): (page, line, code) for every ```python block of the pages;
    skipped ones carry their reason."""
    runnable, skipped = [], []
    for page in _pages():
        text = page.read_text(encoding="utf-8")
        for m in FENCE.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            before = text[:m.start()].rstrip()
            last_line = before.splitlines()[-1] if before else ""
            reason = (SKIP.search(last_line + "\n") if last_line.lstrip().startswith("<!--")
                      else None)
            name = f"{page.relative_to(ROOT)}:{line}"
            if reason:
                skipped.append((name, reason.group(1)))
            else:
                runnable.append((name, m.group(1)))
    return runnable, skipped


RUNNABLE, SKIPPED = _blocks()


def _run(code: str, folder: Path, timeout: float = 300.0) -> subprocess.CompletedProcess:
    script = folder / "example.py"
    script.write_text(code, encoding="utf-8")
    env = dict(os.environ, MPLBACKEND="Agg")
    env.pop("PYTHONPATH", None)
    return subprocess.run([sys.executable, str(script)], cwd=folder, capture_output=True,
                          text=True, timeout=timeout, env=env, stdin=subprocess.DEVNULL)


def test_pages_have_python_examples():
    names = [name for name, _ in RUNNABLE]
    assert sum(n.startswith("README.md:") for n in names) >= 5
    assert sum(n.startswith("docs/guide/") for n in names) >= 10
    assert len(SKIPPED) <= 3, SKIPPED               # a skip is the exception, with a reason


@pytest.mark.parametrize("name,code", RUNNABLE, ids=[name for name, _ in RUNNABLE])
def test_example_runs_as_a_script(name, code, tmp_path):
    proc = _run(code, tmp_path)
    assert proc.returncode == 0, f"{name}\n{code}\n--- stderr ---\n{proc.stderr[-3000:]}"
    # quiet: no warning at the example's own lines (dtdyn's warnings and deprecated names
    # point there), e.g. an old keyword or a response spectrum's sampling warning
    warned = re.findall(r"example\.py:\d+: \w*Warning: .*", proc.stderr)
    assert not warned, f"{name}\n" + "\n".join(warned)


def _batch_block() -> str:
    blocks = [code for name, code in RUNNABLE
              if name.startswith("README.md:") and "run_batch(" in code]
    assert len(blocks) == 1, "the README has one batch example"
    return blocks[0]


def test_readme_batch_example_is_guarded():
    code = _batch_block()
    guard = re.search(r'^if __name__ == "__main__":.*$', code, flags=re.M)
    assert guard, "the batch example must carry an if __name__ == \"__main__\": guard"
    call = code.index("run_batch(")
    assert call > guard.start(), "run_batch must be called under the guard"


def test_unguarded_batch_example_fails_at_once_with_one_line(tmp_path):
    """The README's batch block with its guard removed stops before any worker starts, with
    one line that says what to add (not pages of failing worker processes)."""
    lines = _batch_block().splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("if __name__"))
    body = [line[4:] if line.startswith("    ") else line for line in lines[at + 1:]]
    unguarded = "\n".join(lines[:at] + body) + "\n"
    start = time.perf_counter()
    proc = _run(unguarded, tmp_path, timeout=120.0)
    elapsed = time.perf_counter() - start
    assert proc.returncode != 0
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("RuntimeError: run_batch"), proc.stderr[-3000:]
    assert 'if __name__ == "__main__":' in last, last
    assert "Nanny" not in proc.stderr and len(proc.stderr.splitlines()) < 40, proc.stderr[-3000:]
    assert elapsed < 60.0
    assert not (tmp_path / "results.zarr").exists()


def test_readme_is_short_and_links_the_guide():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 200
    assert "python -m sphinx -b html docs docs/_build/html" in readme
    for link in re.findall(r"\]\(((?:docs)/[^)#]*)\)", readme):
        assert (ROOT / link).exists(), f"README links to {link}, which does not exist"


def test_docs_never_send_users_to_the_steering_folder():
    for page in _pages() + sorted((ROOT / "runtime").rglob("*.py")):
        text = page.read_text(encoding="utf-8")
        assert "../shared" not in text and "shared/" not in text, page
