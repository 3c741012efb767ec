"""Scheme registry: names users type (or a scheme file's `FileScheme`) -> generated coefficient
modules, checked parameters, C kernel sources."""
from __future__ import annotations

import numpy as np

import importlib
import math
from dataclasses import dataclass

from dtdyn._engine.public import suggest
from dtdyn._engine.scheme_files import FileScheme
from dtdyn.generated.scheme_table import TABLE

NAMES = tuple(TABLE)


def row(scheme) -> dict:
    """The scheme table's row of a built-in name or a `FileScheme`."""
    return scheme.table if isinstance(scheme, FileScheme) else TABLE[scheme]


def check_parameter(scheme, key: str, value, field: str | None = None) -> float:
    """``value`` as a float inside the scheme table's range for ``key``; a ValueError names
    ``field`` (default ``key``), the value and the range otherwise."""
    field = field or key
    name = getattr(scheme, "name", scheme)
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{field} must be a number, got {value!r}") from None
    lo, hi = row(scheme)["params"][key]["range"]
    if v != v or (lo is not None and v < lo) or (hi is not None and v > hi):
        shown = f"[{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}]"
        raise ValueError(f"{field} = {value!r} is outside {shown} for scheme {name!r}")
    return v


@dataclass(frozen=True)
class SchemeInfo:
    """A resolved scheme: its coefficient module, checked parameter values and, for a scheme
    file, the `FileScheme` it came from (None: built-in)."""

    name: str
    module: object
    params: dict
    file: FileScheme | None = None
    #: a composite scheme's sub-steps, each a SchemeInfo run in turn within one step
    stages: tuple = ()

    @property
    def table(self) -> dict:
        """Its scheme-table row (title, parameters, start-up, order, ...)."""
        return self.file.table if self.file else TABLE[self.name]

    @property
    def ref(self):
        """What `get_scheme` takes to resolve it again: the name, or the FileScheme."""
        return self.file or self.name

    @property
    def key(self) -> str:
        """The name its compiled kernels are cached under."""
        return f"{self.name}_{self.file.sha256[:16]}" if self.file else self.name

    def c_source(self, kind: str) -> str:
        """The C source of its ``chain`` or ``shaft`` kernel (one translation unit)."""
        if self.file:
            return self.file.c_source(kind, self.name)
        from dtdyn._engine import cbuild
        return cbuild.generated_source(f"{kind}_{self.name}.c")

    def amplification(self, omega_dt, zeta, params):
        """Its amplification matrices A(Omega, zeta) (dtdyn.generated.stability)."""
        if self.file:
            return self.file.module("stability").amplification(self.name, omega_dt, zeta, params)
        from dtdyn.generated import stability
        return stability.amplification(self.name, omega_dt, zeta, params)

    def spectral(self, omega_dt, zeta=0.0):
        """(rho, period elongation, algorithmic damping) per Omega = omega dt: rho = max |eig A|
        and, from the principal eigenvalue pair lambda = e^{(-xi + i) w dt}, T_num / T - 1 =
        Omega sqrt(1 - zeta^2) / (w dt) - 1 and xi (NaN where that pair is real)."""
        W = np.atleast_1d(np.asarray(omega_dt, dtype=float))
        params = [self.params[p] for p in self.module.PARAMS]
        lam = np.linalg.eigvals(self.amplification(W, zeta, params))
        rho = np.abs(lam).max(axis=1)
        exact = np.exp((-zeta + 1j * np.sqrt(1.0 - zeta**2)) * W)[:, None]
        cand = np.where(lam.imag > 1e-14, lam, np.inf)
        k = np.argmin(np.abs(cand - exact), axis=1)
        principal = lam[np.arange(W.size), k]
        osc = np.isfinite(cand[np.arange(W.size), k])
        with np.errstate(divide="ignore", invalid="ignore"):
            w_bar = np.where(osc, np.angle(principal), np.nan)
            xi_bar = np.where(osc, -np.log(np.abs(principal)) / w_bar, np.nan)
            elong = W * np.sqrt(1.0 - zeta**2) / w_bar - 1.0
        return rho, elong, xi_bar

    def critical_omega_dt(self, zeta=0.0, upper=1e4) -> float:
        """The largest Omega below which rho <= 1 + 1e-10 (inf when stable up to ``upper``): a
        grid of 4,000 points from 1e-3, then bisection."""
        grid = np.geomspace(1e-3, upper, 4000)
        unstable = self.spectral(grid, zeta)[0] > 1.0 + 1e-10
        if not unstable.any():
            return float("inf")
        i = int(np.argmax(unstable))
        lo, hi = (grid[i - 1] if i else 0.0), grid[i]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if self.spectral([mid], zeta)[0][0] > 1.0 + 1e-10 else (mid, hi)
        return lo

    def startup(self):
        """The `SchemeInfo` of the scheme that starts a multistep one (None: one-step)."""
        first = self.table["startup_scheme"]
        return get_scheme(first) if self.startup_steps and first else None

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
        """The per-run constants of ``form`` at ``dt`` (not of a composite scheme: of each of
        its `stages`)."""
        if self.stages:
            raise ValueError(f"scheme {self.name!r} is a composite of {len(self.stages)} "
                             "sub-steps: this entry point does not run composite schemes yet "
                             "(the linear time histories do)")
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
            if self.file is None or abs(dt) < 1e-150:
                raise ValueError(f"dt = {dt!r}: the coefficients of scheme {self.name!r} (1/dt, "
                                 "1/dt^2) overflow a float; dt must be above about 1e-150 s (in "
                                 "the model's units)")
            raise ValueError(f"scheme {self.name!r} with {self.params}: the coefficients of its "
                             f"{form} form are not finite at dt = {dt!r} (a parameter value that "
                             "makes the form singular, e.g. explicit: then only "
                             "form='acceleration')")
        return coef


def get_scheme(name, **params) -> SchemeInfo:
    """Resolve a scheme name (or a scheme file's `FileScheme`, from `load_scheme`) and its
    parameters (defaults filled in, ranges checked)."""
    if isinstance(name, SchemeInfo):
        return name if not params else get_scheme(name.file or name.name, **params)
    if isinstance(name, FileScheme):
        parts = [name.module("scheme", part) for part in name.stages or (name.name,)]
        _check_names(name.name, parts[0], params)
        values = dict(parts[0].DEFAULTS)
        values.update({k: check_parameter(name, k, v) for k, v in params.items()})
        stages = tuple(SchemeInfo(part, module, values, name)
                       for part, module in zip(name.stages, parts))
        return SchemeInfo(name.name, parts[0], values, name, stages)
    if not isinstance(name, str) or name not in NAMES:
        raise ValueError(f"unknown scheme {name!r}; available: {', '.join(NAMES)}")
    module = importlib.import_module(f"dtdyn.generated.scheme_{name}")
    _check_names(name, module, params)
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


def _check_names(name: str, module, params) -> None:
    unknown = sorted(set(params) - set(module.PARAMS))
    if unknown:
        allowed = ", ".join(module.PARAMS) or "none"
        raise TypeError(f"scheme {name!r} takes parameters ({allowed}), got "
                        f"{', '.join(unknown)}{suggest(unknown[0], module.PARAMS)}")
