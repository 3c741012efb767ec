"""Refuse to start local worker processes from an unguarded script.

Dask's local cluster starts its workers with multiprocessing's "spawn": each worker imports the
user's main script again (as ``__mp_main__``). A script that calls `run_batch` at its top level,
outside ``if __name__ == "__main__":``, would start the batch again in every worker, and the
workers fail to start after pages of logs. This module finds that case before any process starts.
"""
from __future__ import annotations

import ast
import multiprocessing
import sys

MESSAGE = ("run_batch starts worker processes that re-import {script}: put the code that calls "
           "run_batch under 'if __name__ == \"__main__\":' (line {line} is outside it)")


def _guarded_lines(source: str) -> list[tuple[int, int]]:
    """The line ranges of the bodies of ``if __name__ == "__main__":`` blocks."""
    ranges = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.If) and _is_main_test(node.test):
            ranges.append((node.body[0].lineno, node.body[-1].end_lineno))
    return ranges


def _is_main_test(test) -> bool:
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1
            and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = [test.left, test.comparators[0]]
    names = [s.id for s in sides if isinstance(s, ast.Name)]
    texts = [s.value for s in sides if isinstance(s, ast.Constant)]
    return names == ["__name__"] and texts == ["__main__"]


def check_main_guard() -> None:
    """Raise RuntimeError when the current call comes from the top level of a main script
    outside its ``__main__`` guard, or when this process is such a script's re-import."""
    main = sys.modules.get("__main__")
    script = getattr(main, "__file__", None)
    if script is None:                     # python -c, a notebook, an interactive session
        return
    if multiprocessing.parent_process() is not None and \
            getattr(main, "__name__", "") == "__mp_main__":
        raise RuntimeError(MESSAGE.format(script=script, line="?"))
    frame = sys._getframe(1)
    while frame is not None and not (frame.f_globals is vars(main)
                                     and frame.f_code.co_name == "<module>"):
        frame = frame.f_back
    if frame is None:
        return
    try:
        with open(script, encoding="utf-8") as f:
            ranges = _guarded_lines(f.read())
    except (OSError, SyntaxError, UnicodeDecodeError):
        return
    line = frame.f_lineno
    if not any(lo <= line <= hi for lo, hi in ranges):
        raise RuntimeError(MESSAGE.format(script=script, line=line))
