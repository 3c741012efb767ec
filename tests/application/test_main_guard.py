"""run_batch from a script without a __main__ guard stops before any worker process starts."""
import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("distributed")

from dtdyn.app._batch.main_guard import _guarded_lines  # noqa: E402

SCENE = """\
import dtdyn as dd
scene = {"model": {"mass": [1.0, 1.0], "stiffness": [4e3, 4e3], "damping": [2.0, 2.0]},
         "load": [{"dof": 1, "kind": "step", "amplitude": 1.0}],
         "time": {"dt": 1e-3, "duration": 0.01}}
"""


def test_unguarded_script_fails_at_once_with_one_line(tmp_path):
    script = tmp_path / "unguarded.py"
    script.write_text(SCENE + "ds = dd.run_batch(scene, vary=[{}], workers=1, progress=False)\n")
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=60, cwd=tmp_path)
    assert proc.returncode != 0
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("RuntimeError: run_batch starts worker processes that re-import")
    assert "if __name__ == \"__main__\":" in last and "(line 5 is outside it)" in last
    assert "Nanny" not in proc.stderr                 # no worker was started


def test_guarded_lines_found_by_the_parser():
    source = textwrap.dedent("""\
        import x
        def main():
            run()
        if __name__ == "__main__":
            main()
            more()
        if "__main__" == __name__:
            again()
        if __name__ != "__main__":
            not_this()
        """)
    assert _guarded_lines(source) == [(5, 6), (8, 8)]
