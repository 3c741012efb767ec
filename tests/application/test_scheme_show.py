"""`dtdyn scheme show` / `dd.derivation`: the derived equations factored, at most 100
characters a line, and equal to the raw derivation (symbolic identity, and the printed text
parsed back)."""
from __future__ import annotations

import pytest

sp = pytest.importorskip("sympy")

from dtdyn.app._cli import main  # noqa: E402
from dtdyn.app._derivation import derivation  # noqa: E402
from dtdyn.derive import integrators as I, readable as R  # noqa: E402

SCHEMES = list(I.SCHEMES)


def _parse(text: str):
    """The text form read back by SymPy's parser (juxtaposition is a product, ^ a power)."""
    from sympy.parsing.sympy_parser import (convert_xor, implicit_multiplication,
                                            parse_expr, standard_transformations)
    names = {str(s): s for s in (I.dt, I.x0, I.v0, I.a0, I.xm1, I.xm2, I.vm1, I.vm2, I.xe,
                                 I.ae, I.beta, I.gamma, I.theta, I.alpha, I.rho_inf,
                                 I.alpha_m, I.alpha_f)}
    return parse_expr(text, local_dict=names,
                      transformations=standard_transformations + (implicit_multiplication,
                                                                  convert_xor))


@pytest.mark.parametrize("name", SCHEMES)
def test_every_scheme_shows_within_100_characters(name, capsys):
    assert main(["scheme", "show", name]) == 0
    out = capsys.readouterr().out
    assert "station matrix" in out and "Acceleration form" in out
    assert max(len(line) for line in out.splitlines()) <= R.WIDTH


@pytest.mark.parametrize("name", SCHEMES)
def test_shown_forms_equal_the_derived_ones(name):
    """simplify(shown - derived) == 0 for every coefficient, update and station matrix, and the
    printed text of every coefficient and update, parsed back, equals the derived expression
    (this checks the printer's regrouping of signs too)."""
    der = I.derive_scheme(name)
    d = derivation(name)
    raw = {n: getattr(der, n) for n in d.coefficients}
    for n, e in d.arranged.items():
        assert sp.simplify(e - raw[n]) == 0, n
    r = d.readable
    for sec in r.sections:
        if sec.matrix:
            form = "displacement" if "displacement form" in sec.title else "acceleration"
            diff = sp.simplify(sp.Matrix(sec.substituted()) - R.station_matrix(der, form))
            assert diff == sp.zeros(3, 3), (sec.title, diff)
            continue
        truth = (raw if "form:" in sec.title or "Equilibrium" in sec.title else
                 der.update_x if "from xe" in sec.title else der.update_a)
        for ln, value in zip(sec.lines, sec.substituted()):
            assert sp.simplify(value - truth[ln.name]) == 0, (sec.title, ln.name)
            if not sec.where:  # text in the symbols of the scheme: parse it back
                assert sp.simplify(_parse(ln.text_rhs) - truth[ln.name]) == 0, \
                    (sec.title, ln.name, ln.text_rhs)


def test_station_matrix_reference_is_the_dttmm_one():
    """The reference of the test above is dtdyn.derive.dttmm's station step, checked against
    a hand-written T for average acceleration (displacement form, u = xe - x0): kappa = k +
    2 c / dt, mu = 4 m / dt^2 + k_g + 2 c_g / dt."""
    from dtdyn.derive import dttmm as T
    der = I.derive_scheme("average_acceleration")
    M = R.station_matrix(der, "displacement")
    dt, k, c, m, kg, cg = I.dt, T.k, T.c, T.m, T.kg, T.cg
    kappa, mu = k + 2 * c / dt, 4 * m / dt**2 + kg + 2 * cg / dt
    assert sp.simplify(M[0, 1] - 1 / kappa) == 0 and sp.simplify(M[1, 0] - mu) == 0
    assert sp.simplify(M[1, 1] - (1 + mu / kappa)) == 0


def test_hht_prints_factored(capsys):
    assert main(["scheme", "show", "hht"]) == 0
    out = capsys.readouterr().out
    assert "  A = 4 / (dt^2 (1 - alpha)^2 (1 + alpha))\n" in out
    assert "  D = 2 (1 - 2 alpha) / (dt (1 - alpha)^2)\n" in out
    assert "  Dx = dt^2 (1 - alpha)^2 (1 + alpha) / 4\n" in out
    assert "    gamma   = (1 - 2 alpha) / 2\n" in out
    assert "Eq(" not in out and "**" not in out


def test_houbolt_reads_like_the_source(capsys):
    assert main(["scheme", "show", "houbolt"]) == 0
    out = capsys.readouterr().out
    assert "  B = -(5 x0 - 4 xm1 + xm2) / dt^2\n" in out  # the source's B, its misprint fixed
    assert "  v1 = (11 x1 - 18 x0 + 9 xm1 - 2 xm2) / (6 dt)\n" in out


def test_latex_and_markdown(capsys):
    assert main(["scheme", "show", "hht", "--latex"]) == 0
    tex = capsys.readouterr().out
    assert "\\begin{align*}" in tex and "\\begin{bmatrix}" in tex
    assert (r"A &= \frac{4}{\Delta t^{2} \left(1 - \alpha\right)^{2} \left(1 + \alpha\right)}"
            in tex)
    assert main(["scheme", "show", "hht", "--markdown"]) == 0
    md = capsys.readouterr().out
    assert (r"| $A$ | $\frac{4}{\Delta t^{2} \left(1 - \alpha\right)^{2} "
            r"\left(1 + \alpha\right)}$ |" in md)
    assert md.count("$$") % 2 == 0 and "## DT-TMM station matrix" in md
    assert main(["scheme", "show", "hht", "--latex", "--markdown"]) == 2  # one or the other


def test_show_is_an_alias_and_errors_are_one_line(capsys):
    assert main(["scheme", "show", "hht"]) == 0
    first = capsys.readouterr().out
    assert main(["show", "hht"]) == 0
    assert capsys.readouterr().out == first
    assert main(["scheme", "show", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown scheme 'nope'" in err and err.count("\n") == 1
    assert main(["scheme"]) == 2  # an action is required


def test_derivation_returns_the_derived_objects():
    der = I.derive_scheme("hht")
    d = derivation("hht")
    for n in ("A", "B", "D", "E", "Dx", "Ex", "Dv", "Ev", "w0", "w1"):
        assert d.coefficients[n] == getattr(der, n), n
    assert d.updates["displacement"] == der.update_x and d.updates["acceleration"] == \
        der.update_a
    assert d.relations == I.SCHEMES["hht"].relations
    assert set(d.station_matrices) == {"displacement", "acceleration"}
    assert str(d) == R.readable(der).text()
    assert d._repr_latex_().startswith("\\begin{align*}")
    assert derivation(I.SCHEMES["hht"]).coefficients == d.coefficients  # a Scheme value too
    cd = derivation("central_difference")
    assert cd.explicit and "A" not in cd.coefficients and set(cd.station_matrices) == \
        {"acceleration"}


def test_scheme_file(tmp_path, capsys):
    """A scheme file (*.toml) shows like a built-in: Bossak's A = (1 - alpha_m) / (beta dt^2)
    with beta = (1 - alpha_m)^2 / 4."""
    path = tmp_path / "my_bossak.toml"
    path.write_text(
        'name = "my_bossak"\ntitle = "Wood-Bossak-Zienkiewicz alpha"\n'
        'relations = ["x1 = x0 + dt*v0 + dt**2*((1/2 - beta)*a0 + beta*a1)",\n'
        '  "v1 = v0 + dt*((1 - gamma)*a0 + gamma*a1)", "xe = x1", "ve = v1",\n'
        '  "ae = (1 - alpha_m)*a1 + alpha_m*a0"]\nforce_weights = ["0", "1"]\n'
        '[parameters.alpha_m]\ndefault = -0.1\nrange = [-0.5, 0.0]\n'
        '[substitutions]\nbeta = "(1 - alpha_m)**2/4"\ngamma = "1/2 - alpha_m"\n')
    assert main(["scheme", "show", str(path)]) == 0
    out = capsys.readouterr().out
    assert "  A = 4 / (dt^2 (1 - alpha_m))\n" in out
    assert max(len(line) for line in out.splitlines()) <= R.WIDTH


def test_narrow_width_names_common_subexpressions():
    """Below the width a wrapped line fits in, sympy.cse names subexpressions (c1, c2, ...) in
    a "where" list; substituted back, the lines are the derived ones."""
    der = I.derive_scheme("generalized_alpha")
    r = R.readable(der, width=60)
    named = [sec for sec in r.sections if sec.where and not sec.matrix]
    assert named and all(w.name.startswith("c") for sec in named for w in sec.where)
    for sec in named:
        truth = der.update_a if "from ae" in sec.title else {n: getattr(der, n) for n in
                                                             ("Dx", "Ex", "Dv", "Ev")}
        for ln, value in zip(sec.lines, sec.substituted()):
            assert sp.simplify(value - truth[ln.name]) == 0, (sec.title, ln.name)


def test_guide_page_shows_what_the_command_prints(capsys):
    import pathlib
    page = (pathlib.Path(__file__).resolve().parents[2] / "docs" / "guide" / "schemes.md")
    block = page.read_text().split("$ dtdyn scheme show hht\n", 1)[1].split("...\n```", 1)[0]
    assert main(["scheme", "show", "hht"]) == 0
    assert capsys.readouterr().out.startswith(block), "rerun `dtdyn scheme show hht` into the page"
