"""Atomic file writes: readers see the old file or the complete new one, never a part."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path


def write_atomic(path, write) -> None:
    """Call ``write(binary_file)`` on a temporary file next to ``path``, then rename it into place.

    On any failure the temporary file is removed and ``path`` is left as it was; racing writers
    each replace the file with complete content.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def write_atomic_files(files) -> None:
    """`write_atomic` for files that belong together, e.g. a table and its metadata sidecar.

    ``files`` is a sequence of ``(path, write)``. Every file is first written in full to a
    temporary file next to its path; only when all are complete are they renamed into place, in
    the given order (put the file readers look for last). A failure while writing removes the
    temporary files and leaves every path as it was.
    """
    temps = []
    try:
        for path, write in files:
            path = Path(path)
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
            temps.append((tmp, path))
            with os.fdopen(fd, "wb") as fh:
                write(fh)
                fh.flush()
                os.fsync(fh.fileno())
            os.chmod(tmp, 0o644)
        for tmp, path in temps:
            os.replace(tmp, path)
    except BaseException:
        for tmp, _ in temps:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
        raise
