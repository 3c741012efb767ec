"""`derivation`: a scheme's derived equations as SymPy objects, printed as a paper prints them.

SymPy is imported on the first call only (the [derive] extra), so ``import dtdyn`` stays free of
it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from dtdyn._engine.public import public


@dataclass(frozen=True)
class Derivation:
    """A scheme's derivation: SymPy objects, and the readable form they print as.

    ``relations`` are the defining relations (SymPy ``Eq``) as the scheme writes them, with
    ``substitutions`` giving their symbols in the scheme's parameters; ``coefficients`` the
    derived A, B, D, E (displacement form; absent for an explicit scheme), Dx, Ex, Dv, Ev
    (acceleration form) and the force weights w0, w1, equal to `derive_scheme`'s; ``updates``
    the new state (x1, v1, a1) per form; ``station_matrices`` the DT-TMM station matrix per form
    with every quantity substituted. ``arranged`` holds the same coefficients factored and
    collected as printed. ``str()`` is the aligned text, `latex` and `markdown` the other two
    renderings; notebooks show `_repr_latex_`.
    """

    name: str
    title: str
    reference: str
    explicit: bool
    relations: tuple
    substitutions: dict
    coefficients: dict
    arranged: dict
    updates: dict
    station_matrices: dict
    readable: object = field(repr=False)

    def __str__(self) -> str:
        return self.readable.text()

    def latex(self) -> str:
        """LaTeX (amsmath ``align*`` blocks, a comment line per group)."""
        return self.readable.latex()

    def markdown(self) -> str:
        """Markdown with ``$...$`` math."""
        return self.readable.markdown()

    def _repr_latex_(self) -> str:
        return self.readable.latex_block()


def _scheme(name_or_file):
    """A built-in name or a `Scheme` as it is; a ``*.toml`` path read as a scheme file."""
    if isinstance(name_or_file, (str, Path)) and str(name_or_file).endswith(".toml"):
        from dtdyn.derive import scheme_file

        return scheme_file.parse(name_or_file)
    return name_or_file


@public
def derivation(scheme) -> Derivation:
    """A scheme's derived equations: relations, coefficients and DT-TMM station matrices.

    Parameters
    ----------
    scheme : str, path or Scheme
        A built-in scheme's name ("hht", "newmark", ... as in `dtdyn scheme show`), the path of
        a scheme file (``*.toml``), or a scheme value.

    Returns
    -------
    Derivation
        The SymPy objects (``relations``, ``coefficients``, ``updates``, ``station_matrices``)
        and their readable form: ``print(d)`` shows them factored, collected on the history
        x0, v0, a0 (and lags) and with named subexpressions, lines at most 100 characters;
        ``d.latex()`` and ``d.markdown()`` give the other renderings.

    Notes
    -----
    The scheme's relations link the new state (x1, v1, a1) and the equilibrium point (xe, ve,
    ae) to the history; solved in SymPy they give

        displacement form:  ae = A xe + B,    ve = D xe + E
        acceleration form:  xe = Dx ae + Ex,  ve = Dv ae + Ev

    and, with the element laws, the DT-TMM station matrix T of each form, mapping
    [u_{n-1}, f_n, 1] to [u_n, f_{n+1}, 1] (derived in dtdyn.derive.integrators and
    dtdyn.derive.dttmm; the DT-TMM page of the documentation states it). Needs the ``[derive]``
    extra (SymPy).

    Examples
    --------
    >>> import dtdyn as dd
    >>> d = dd.derivation("hht")            # doctest: +SKIP
    >>> print(d)                            # doctest: +SKIP
    """
    from dtdyn._engine.extras import require

    sp = require("sympy", "derive", "dd.derivation")
    from dtdyn.derive import integrators as I, readable as R

    der = scheme if isinstance(scheme, I.Derived) else I.derive_scheme(_scheme(scheme))
    s = der.scheme
    names = (() if der.explicit else ("A", "B", "D", "E")) + ("Dx", "Ex", "Dv", "Ev", "w0", "w1")
    coefficients = {n: getattr(der, n) for n in names}
    updates = {"acceleration": dict(der.update_a)}
    if not der.explicit:
        updates = {"displacement": dict(der.update_x), **updates}
    forms = [f for f in ("displacement", "acceleration") if f != "displacement" or
             not der.explicit]
    return Derivation(
        name=s.name, title=s.title, reference=s.reference, explicit=der.explicit,
        relations=tuple(s.relations), substitutions=dict(s.substitutions),
        coefficients=coefficients,
        arranged={n: R.arrange(e) for n, e in coefficients.items()},
        updates=updates,
        station_matrices={f: sp.ImmutableMatrix(R.station_matrix(der, f)) for f in forms},
        readable=R.readable(der))
