"""Scene nonlinear elements (``[[element]]``) and their options (``[nonlinear]``, ``[scheme]``)."""
from __future__ import annotations


from dtdyn.app._loads import finite_number
from dtdyn.app._scene.schema import (ELEMENT_KINDS, NONLINEAR_BACKENDS, SCHEMES,
                                    _DEFAULT_NONLINEAR_METHOD, _ELEMENT_FIELDS, _LAW_RESERVED,
                                    _NONLINEAR_KEYS, _choice, _dof_index, _scheme_name_params,
                                    _table)

def _element_field(name: str, value, what):
    """One element field checked as ``_ELEMENT_FIELDS`` says; ``name`` e.g. ``element[0].k3``."""
    if isinstance(what, tuple):
        return _choice(name, value, what)
    if what == "text":
        if not isinstance(value, str):
            raise ValueError(f"{name} = {value!r}: must be a string (an expression such as "
                             "'k*x**3 + c*v')")
        return value
    if what == "numbers":
        if not isinstance(value, list) or not value:
            raise ValueError(f"{name} = {value!r}: must be a non-empty array of numbers")
        return [finite_number(f"{name}[{p}]", c) for p, c in enumerate(value)]
    if what == "table":
        if not isinstance(value, dict):
            raise ValueError(f"{name} = {value!r}: must be a table of numbers")
        consts = {}
        for key, c in value.items():
            if key in _LAW_RESERVED:
                raise ValueError(f"{name}.{key} = {c!r}: the name {key!r} is reserved "
                                 f"({', '.join(_LAW_RESERVED)} are the element's own fields)")
            consts[key] = finite_number(f"{name}.{key}", c)
        return consts
    v = finite_number(name, value)
    bound = {"> 0": v > 0, ">= 0": v >= 0, ">= 1": v >= 1}.get(what, True)
    if not bound:
        raise ValueError(f"{name} = {value!r}: must be {what}")
    return v


def _parse_element(k: int, spec, n_dof: int, names: tuple[str, ...] | None):
    """The element of ``[[element]]`` number k (0-based), built from checked fields."""
    from dtdyn.nonlinear import _elements as el_mod

    name = f"element[{k}]"
    if not isinstance(spec, dict):
        raise ValueError(f"{name} = {spec!r}: must be an [[element]] table")
    kind = spec.get("kind")
    if kind is None:
        raise ValueError(f"{name}.kind is required, allowed: {', '.join(map(repr, ELEMENT_KINDS))}")
    _choice(f"{name}.kind", kind, tuple(ELEMENT_KINDS))
    cls_name, required, optional = ELEMENT_KINDS[kind]
    allowed = ("kind", "i", "j", *required, *optional)
    for key in spec:
        if key not in allowed:
            raise ValueError(f"{name}.{key} = {spec[key]!r}: unknown key for kind {kind!r}, "
                             f"allowed: {', '.join(allowed)}")
    for key in ("i", *required):
        if key not in spec:
            raise ValueError(f"{name}.{key} is required for kind {kind!r}")
    i = _dof_index(f"{name}.i", spec["i"], n_dof, names)
    j = None
    if "j" in spec:
        j = _dof_index(f"{name}.j", spec["j"], n_dof, names)
        if j == i:
            raise ValueError(f"{name}.j = {spec['j']!r}: the same DOF as {name}.i = {spec['i']!r}; "
                             "an element joins two different DOFs (omit j for ground)")
    fields = {key: _element_field(f"{name}.{key}", spec[key], _ELEMENT_FIELDS[key])
              for key in (*required, *optional) if key in spec}
    if kind == "law":  # parsed here so that a refused expression names this field
        from dtdyn.nonlinear._expressions import parse_expression

        constants = fields.pop("constants", {})
        parse_expression(fields["expression"], variables=("x", "v"), constants=tuple(constants),
                         name=f"{name}.expression")
        fields.update(constants)
    try:
        return getattr(el_mod, cls_name)(i, j, **fields)
    except ValueError as exc:  # a rule across fields (e.g. Bouc-Wen's beta + gamma > 0)
        raise ValueError(f"{name} (kind {kind!r}): {exc}") from None


def _parse_elements(tables, n_dof: int, names: tuple[str, ...] | None) -> tuple:
    if not isinstance(tables, list) or not all(isinstance(x, dict) for x in tables):
        raise ValueError(f"element = {tables!r}: must be zero or more [[element]] tables")
    return tuple(_parse_element(k, spec, n_dof, names) for k, spec in enumerate(tables))


def _nonlinear_methods() -> tuple[str, ...]:
    from dtdyn.nonlinear._linear_step import MODAL, MULTISTEP

    return MODAL + tuple(s for s in SCHEMES if s not in MULTISTEP)


def _parse_nonlinear(tbl, scheme_tbl) -> tuple[str, dict, dict, str]:  # noqa: C901 (one check per key)
    """(method, scheme parameters, options, backend) of a nonlinear scene (module docstring)."""
    from dtdyn.nonlinear._linear_step import MODAL

    _table("nonlinear", tbl, _NONLINEAR_KEYS)
    methods = _nonlinear_methods()
    method, params = _DEFAULT_NONLINEAR_METHOD, {}
    options, modal = {}, MODAL + ("auto",)  # "auto" picks a modal method where it can
    if "accuracy" in tbl:  # a target instead of a sub-step count: the method picked ("auto")
        target = finite_number("nonlinear.accuracy", tbl["accuracy"])
        if target <= 0:
            raise ValueError(f"nonlinear.accuracy = {tbl['accuracy']!r}: must be > 0 (a "
                             "relative error such as 1e-6)")
        options["accuracy"], method = target, "auto"
        methods += ("auto",)
    elif "max_substeps" in tbl:
        raise ValueError(f"nonlinear.max_substeps = {tbl['max_substeps']!r}: caps the sub-steps "
                         "an accuracy target may take; give nonlinear.accuracy too")
    if scheme_tbl is not None:
        if not isinstance(scheme_tbl, dict):
            raise ValueError(f"scheme = {scheme_tbl!r}: must be a table [scheme]")
        for key in ("form", "sweep", "backend"):
            if key in scheme_tbl:
                raise ValueError(f"scheme.{key} = {scheme_tbl[key]!r}: only for linear chains; a "
                                 "scene with [[element]] runs nonlinear_mck_response (set "
                                 "nonlinear.backend): remove the key")
        if "unstable" in scheme_tbl:
            raise ValueError(f"scheme.unstable = {scheme_tbl['unstable']!r}: only for linear "
                             "scenes; a scene with [[element]] checks each step's stability as "
                             "it runs (DtdynStepStabilityError; more nonlinear.substeps or a "
                             "smaller time.dt fix it): remove the key")
        name = scheme_tbl.get("name", method)  # no name: the default method
        if name == "auto" and "accuracy" not in options:
            raise ValueError("scheme.name = 'auto': picks the method for an accuracy target; "
                             "give nonlinear.accuracy too")
        if name not in methods:
            raise ValueError(f"scheme.name = {name!r}: a scene with [[element]] takes one of "
                             f"{', '.join(map(repr, methods))} (multistep schemes cannot run "
                             "nonlinear elements)")
        if name in modal:
            _table("scheme", scheme_tbl, ("name",))
            method = name
        else:
            method, params = _scheme_name_params(scheme_tbl)
    for key in ("substeps", "max_iter", "max_substeps"):
        if key in tbl:
            v = tbl[key]
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"nonlinear.{key} = {v!r}: must be an integer >= 1")
            options[key] = v
    if "tol" in tbl:
        tol = finite_number("nonlinear.tol", tbl["tol"])
        if tol <= 0:
            raise ValueError(f"nonlinear.tol = {tbl['tol']!r}: must be > 0")
        options["tol"] = tol
    if "modes" in tbl:
        modes = tbl["modes"]
        if method not in modal:
            raise ValueError(f"nonlinear.modes = {modes!r}: selects modal filters; method "
                             f"{method!r} integrates all DOFs (remove modes)")
        if (not isinstance(modes, list) or not modes
                or any(isinstance(m, bool) or not isinstance(m, int) or m < 0 for m in modes)):
            raise ValueError(f"nonlinear.modes = {modes!r}: must be a non-empty array of 0-based "
                             "mode indices (integers >= 0)")
        if len(set(modes)) != len(modes):
            raise ValueError(f"nonlinear.modes = {modes!r}: repeats a mode")
        options["modes"] = list(modes)
    backend = _choice("nonlinear.backend", tbl.get("backend", "c"), NONLINEAR_BACKENDS)
    if "backend" in tbl:
        options["backend"] = backend
    return method, params, options, backend
