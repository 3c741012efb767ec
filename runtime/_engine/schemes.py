"""Scheme registry: names users type -> generated coefficient modules, checked parameters."""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass

from dtdyn._engine.public import suggest
from dtdyn.generated.scheme_table import TABLE

NAMES = tuple(TABLE)


def check_parameter(scheme: str, key: str, value, field: str | None = None) -> float:
    """``value`` as a float inside the scheme table's range for ``key``; a ValueError names
    ``field`` (default ``key``), the value and the range otherwise."""
    field = field or key
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{field} must be a number, got {value!r}") from None
    lo, hi = TABLE[scheme]["params"][key]["range"]
    if v != v or (lo is not None and v < lo) or (hi is not None and v > hi):
        shown = f"[{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}]"
        raise ValueError(f"{field} = {value!r} is outside {shown} for scheme {scheme!r}")
    return v


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
        # the coefficients hold 1/dt and 1/dt^2: a dt so small that they overflow (dt^2
        # underflows below ~1e-308) is named here, not met as a ZeroDivisionError or an inf
        # in the step
        try:
            coef = self.module.coefficients(form, dt, *(self.params[p]
                                                        for p in self.module.PARAMS))
        except (ZeroDivisionError, OverflowError):
            coef = None
        if coef is None or not all(math.isfinite(v) for v in coef.values()
                                   if isinstance(v, (int, float))):
            raise ValueError(f"dt = {dt!r}: the coefficients of scheme {self.name!r} (1/dt, "
                             "1/dt^2) overflow a float; dt must be above about 1e-150 s (in "
                             "the model's units)")
        return coef


def get_scheme(name: str, **params) -> SchemeInfo:
    """Resolve a scheme name and its parameters (defaults filled in, ranges checked)."""
    if name not in NAMES:
        raise ValueError(f"unknown scheme {name!r}; available: {', '.join(NAMES)}")
    module = importlib.import_module(f"dtdyn.generated.scheme_{name}")
    unknown = sorted(set(params) - set(module.PARAMS))
    if unknown:
        allowed = ", ".join(module.PARAMS) or "none"
        raise TypeError(f"scheme {name!r} takes parameters ({allowed}), got "
                        f"{', '.join(unknown)}{suggest(unknown[0], module.PARAMS)}")
    values = dict(module.DEFAULTS)
    for key, value in params.items():
        values[key] = check_parameter(name, key, value)
    if name == "newmark" and values["beta"] == 0.0:
        module = importlib.import_module("dtdyn.generated.scheme_central_difference")
        if values["gamma"] != 0.5:
            raise ValueError("beta = 0 is supported with gamma = 0.5 (central difference) only, "
                             f"got gamma = {values['gamma']!r}")
        return SchemeInfo("central_difference", module, {})
    return SchemeInfo(name, module, values)
