"""Optional dependencies: one import helper that names the extra to install."""
from __future__ import annotations

import importlib


def require(module: str, extra: str | None, what: str):
    """Import ``module`` or raise ImportError naming ``what`` needs it and the extra to install,
    e.g. ``require("casadi", "nonlinear", "nonlinear_mck_response")`` (``extra`` None: the package
    itself, ``pip install module``)."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        hint = f'"dtdyn[{extra}]"' if extra else module.split(".")[0]
        raise ImportError(f"{what} needs {module.split('.')[0]}, which is not installed: "
                          f"pip install {hint}") from exc
