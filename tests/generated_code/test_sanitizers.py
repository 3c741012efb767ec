"""One AddressSanitizer/UndefinedBehaviorSanitizer run of the chain, shaft, beam, mck and
nonlinear loops: sanitized_loops.py, in a subprocess with libasan and libubsan preloaded (the
kernels are compiled on first use, with -fsanitize=address,undefined, into a fresh cache). A
second run tells the chain kernel its work is one double longer than it is: ASan must catch the
write past the end, so the first run's silence means something."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

CC = shutil.which("gcc")
SCRIPT = Path(__file__).with_name("sanitized_loops.py")


def _runtime(name):
    if CC is None:
        return None
    path = subprocess.run([CC, f"-print-file-name={name}"], capture_output=True,
                          text=True).stdout.strip()
    return path if os.path.isabs(path) and os.path.exists(path) else None


ASAN, UBSAN = _runtime("libasan.so"), _runtime("libubsan.so")
pytestmark = [pytest.mark.slow, pytest.mark.skipif(
    None in (ASAN, UBSAN), reason="needs gcc with libasan and libubsan (the sanitizer runtimes)")]


def _run(tmp_path, *args):
    env = {**os.environ, "DTDYN_CACHE": str(tmp_path / "cache"), "CC": CC,
           "LD_PRELOAD": f"{ASAN} {UBSAN}",
           "ASAN_OPTIONS": "detect_leaks=0:abort_on_error=0:exitcode=23",
           "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1:exitcode=24"}
    env.pop("DTDYN_NO_C", None)
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          env=env, timeout=900)


def test_loops_run_clean_under_asan_and_ubsan(tmp_path):
    proc = _run(tmp_path)
    assert proc.returncode == 0 and proc.stdout.strip().endswith("ok"), proc.stderr[-4000:]
    assert "runtime error" not in proc.stderr and "AddressSanitizer" not in proc.stderr


def test_asan_catches_a_write_past_the_work_array(tmp_path):
    proc = _run(tmp_path, "overflow")
    assert proc.returncode == 23, (proc.returncode, proc.stdout, proc.stderr[-2000:])
    assert "heap-buffer-overflow" in proc.stderr
