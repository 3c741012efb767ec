"""Scheme registry: names users type -> generated coefficient modules, checked parameters."""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass

from dtdyn.generated import SCHEMES as NAMES

#: admissible parameter ranges (closed intervals); the reasons are in the schemes' stability analysis (docs/stability.md)
RANGES = {
    "beta": (0.0, math.inf),  # beta = 0 is explicit (acceleration form only)
    "gamma": (0.5, math.inf),  # gamma < 1/2 adds negative algorithmic damping
    "theta": (1.0, math.inf),  # unconditionally stable only from (1 + sqrt 3)/2
    "alpha": (-1.0 / 3.0, 0.0),  # HHT
    "rho_inf": (0.0, 1.0),  # generalized-alpha
}


@dataclass(frozen=True)
class SchemeInfo:
    name: str
    module: object
    params: dict

    @property
    def history(self) -> tuple:
        return self.module.HISTORY

    @property
    def startup_steps(self) -> int:
        return self.module.STARTUP_STEPS

    @property
    def explicit(self) -> bool:
        return self.module.EXPLICIT

    def coefficients(self, form: str, dt: float) -> dict:
        if form not in self.module.FORMS:
            if form == "displacement" and self.explicit:
                raise ValueError(f"scheme {self.name!r} is explicit (beta = 0): it has no "
                                 "displacement form; use form='acceleration'")
            raise ValueError(f"form must be 'displacement' or 'acceleration', got {form!r}")
        return self.module.coefficients(form, dt, *(self.params[p] for p in self.module.PARAMS))


def get_scheme(name: str, **params) -> SchemeInfo:
    """Resolve a scheme name and its parameters (defaults filled in, ranges checked)."""
    if name not in NAMES:
        raise ValueError(f"unknown scheme {name!r}; available: {', '.join(NAMES)}")
    module = importlib.import_module(f"dtdyn.generated.scheme_{name}")
    unknown = sorted(set(params) - set(module.PARAMS))
    if unknown:
        allowed = ", ".join(module.PARAMS) or "none"
        raise ValueError(f"scheme {name!r} takes parameters ({allowed}), got {', '.join(unknown)}")
    values = dict(module.DEFAULTS)
    for key, value in params.items():
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{key} must be a number, got {value!r}") from None
        lo, hi = RANGES[key]
        if not (lo <= v <= hi):
            raise ValueError(f"{key} = {v!r} is outside [{lo}, {hi}] for scheme {name!r}")
        values[key] = v
    if name == "newmark" and values["beta"] == 0.0:
        module = importlib.import_module("dtdyn.generated.scheme_central_difference")
        if values["gamma"] != 0.5:
            raise ValueError("beta = 0 is supported with gamma = 0.5 (central difference) only, "
                             f"got gamma = {values['gamma']!r}")
        return SchemeInfo("central_difference", module, {})
    return SchemeInfo(name, module, values)
