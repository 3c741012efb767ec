"""Render the derivations through the jinja2 templates into generated/.

`render_all()` returns {file name: text}; `write(dest)` writes them (atomically, each file) plus a
manifest; `check(dest)` regenerates in memory and lists the files that differ.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
from importlib import resources
from pathlib import Path

import jinja2
import sympy as sp

from . import (beam, c_api, dttmm, integrators as I, kernels, modal_filters, nonlinear, printing,
               stability, state_space, tmm)

TEMPLATES = Path(__file__).parent / "templates"
#: the hand-written C (.h files compiled as they are: the runtime inlines them into the generated
#: sources that include them, dtdyn._engine.cbuild); the templates only #include them
CSOURCES = Path(str(resources.files("dtdyn._engine") / "csrc"))  # checkout or installed
GENERATED = Path(__file__).resolve().parent.parent / "generated"


def environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(TEMPLATES)),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    env.filters["pyrepr"] = repr  # plain data (dicts, tuples, floats, str, None) as Python
    return env


def _names(mapping):
    """Symbols of dttmm renamed to the variables the kernels use."""
    return {getattr(dttmm, k): sp.Symbol(v) for k, v in mapping.items()}


# scalar names inside station loops (C and the NumPy plain sweep)
SCALAR = _names({"mu": "mu", "kappa": "kp", "S_R": "S_R", "S_L": "S_L", "R_R": "R_R",
                 "Delta": "Dn", "F_n": "Fn", "beta": "bn", "R_L": "R_L"})
C_ARRAY = _names({"mu": "mu", "kappa": "kp", "S_R": "SR[n]", "R_R": "R_R", "Delta": "Dl[n]",
                  "F_n": "Fe[n]", "beta": "b[n]", "R_L": "R[n]", "S_L": "S_L"})
T_ENTRIES = ((0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2))
PY_ARRAY = _names({"mu": "mu", "kappa": "kp", "S_R": "SR", "Delta": "Dl", "F_n": "Fe",
                   "beta": "b", "R_L": "R", "R_R": "R_R"})


def _lin(prefix: str, coeffs: dict, array: str = "", zero: str = "0.0") -> str:
    """C text of sum_h prefix_h * h[i] (h = "u" is the primary unknown: the loop's local un, or
    eu[i] of the error histories; an increment dx0 is (x0[i] - xm1[i]),
    kernels.in_increments), ``zero`` when empty; ``array`` is prepended to the array names
    ("e": the plain sweep's error histories ex0, ..., and eu)."""
    def term(h):
        if h == "u" and not array:
            return "un"  # the station's unknown, a local of the loop
        if h.startswith("d"):
            new, old = kernels.increment_pair(h)
            return f"({array}{new}[i] - {array}{old}[i])"
        return f"{array}{h}[i]"
    return " + ".join(f"{prefix}_{h} * {term(h)}" for h in coeffs) or zero


def _shift_lines(history, array: str = ""):
    lines = []
    for qty in "xva":
        lags = sorted((int(h[2:]) for h in history if h.startswith(qty + "m")), reverse=True)
        for lag in lags:
            prev = f"{qty}0" if lag == 1 else f"{qty}m{lag - 1}"
            lines.append(f"{array}{qty}m{lag}[i] = {array}{prev}[i];")
    lines += [f"{array}{q}0[i] = {array}{q}1;" for q in "xva"]
    return lines


def _plain_entries(T, printer, element: str) -> dict:
    """The station matrix's entries as the plain sweep uses them: numbers inline, entries in
    mu and kappa only computed once per run ("run"), entries with Delta, F_n or beta once per
    step in the first pass and reused in the second ("step"); ``element`` formats the array
    element."""
    per_step = {dttmm.Delta, dttmm.F_n, dttmm.beta}
    out = {"run": [], "step": [], "use": []}
    for i, j in T_ENTRIES:
        name, e = f"T{i + 1}{j + 1}", sp.sympify(T[i, j])
        if e.is_number:
            out["use"].append("(" + printer(e) + ")")
            continue
        out["step" if e.free_symbols & per_step else "run"].append((name, "(" + printer(e) + ")"))
        out["use"].append(element.format(name))
    return out


def _scheme_context(scheme: str | I.Scheme) -> dict:
    spec = kernels.scheme_spec(scheme)
    sch, name = spec.scheme, spec.name
    sw = dttmm.derive_sweeps()
    forms_py, forms_c = [], []
    for form, fs in spec.forms.items():
        rows = kernels.constant_table(spec, form)
        temps, reduced = printing.cse_assignments(rows, prefix="k")
        forms_py.append({"form": form,
                         "temps": [(str(t), printing.py_array(e)) for t, e in temps],
                         "rows": [(n, printing.py_array(e)) for n, e in reduced]})
        # C: the sweep expressions exactly as the NumPy sweep evaluates them (alpha_u = 1 and
        # b = 0 of the acceleration form are not folded into mu and beta), so both backends
        # round alike

        def cc(expr, names=C_ARRAY):
            return printing.c(sp.sympify(expr).xreplace(names))

        forms_c.append({
            "form": form,
            "temps": [(str(t), printing.c(e)) for t, e in temps],
            "rows": [(n, printing.c(e)) for n, e in reduced],
            "g": cc(sw.g), "S": cc(sw.S_expr), "den": cc(sw.den), "hD": cc(sw.hD),
            "error_step": [(n, cc(e)) for n, e in sw.error_step.items()],
            "plain": _plain_entries(sw.T, cc, "{}[n]"),
            **{n: _lin(n, fs.hist_terms[n]) for n in ("q", "s", "b")},
            **{n: _lin(n, fs.update[n]) for n in ("x1", "v1", "a1")},
            # the plain sweep's two error histories, as pairs (rows as the history; names
            # prefixed with e; dtdyn.derive.dttmm)
            "error": {"shift": _shift_lines(spec.history, "e"),
                      **{n: _lin(n, fs.hist_terms[n], "e", "zero2") for n in ("q", "s", "b")},
                      **{n: _lin(n, fs.update[n], "e", "zero2") for n in ("x1", "v1", "a1")}},
        })
    return {
        "name": name, "title": sch.title, "reference": sch.reference, "notes": sch.notes,
        "params": list(sch.params), "defaults": sch.defaults, "history": list(spec.history),
        "startup_steps": sch.startup_steps, "order": sch.order, "explicit": spec.derived.explicit,
        "forms_py": forms_py, "forms_c": forms_c, "shift": _shift_lines(spec.history),
        "uses_numpy": any("np." in e for f in forms_py for _, e in f["temps"] + f["rows"]),
        "random_spread": repr(float(dttmm.RANDOM_SPREAD)),
        "derived": spec.derived, "spec": spec,
    }


def _dttmm_context() -> dict:
    sw = dttmm.derive_sweeps()
    scalar = lambda e: printing.py(sp.sympify(e).xreplace(SCALAR))  # noqa: E731
    T = sw.T
    ctx = {"T_rows": [str(list(T.row(i))) for i in range(3)],
           "S_expr": str(sw.S_expr), "g": str(sw.g), "h": str(sw.h), "a_fwd": str(sw.a_fwd),
           "b_fwd": str(sw.b_fwd), "hD": str(sw.hD), "den": str(sw.den),
           "g_py": scalar(sw.g), "S_py": scalar(sw.S_expr),
           "den_py": scalar(sw.den),
           "error_step": [(n, scalar(e)) for n, e in sw.error_step.items()],
           "error_step_doc": [(n, str(e)) for n, e in sw.error_step.items()],
           "random_spread": repr(float(dttmm.RANDOM_SPREAD))}
    for i, j in T_ENTRIES:
        ctx[f"T{i + 1}{j + 1}_py"] = "(" + scalar(T[i, j]) + ")"
    plain = _plain_entries(T, scalar, "{}[n]")
    both = plain["run"] + plain["step"]
    ctx["plain"] = dict(
        plain, names=", ".join(n for n, _ in both), alloc=", ".join("[0.0] * N" for _ in both),
        **{f"{w}_{side}": ", ".join(f"{n}[n]" if side == "lhs" else e for n, e in plain[w])
           for w in ("run", "step") for side in ("lhs", "rhs")})
    return ctx


def _readable_markdown(der: I.Derived) -> str:
    """The derivation as `dtdyn scheme show --markdown` prints it (dtdyn.derive.readable)."""
    from . import readable

    return readable.readable(der).markdown(level=2)


def _increment_rows(spec: kernels.SchemeSpec) -> list[tuple[str, str]]:
    """B_u = A x_0 + B and E_u = D x_0 + E as the displacement-form kernels evaluate them: in
    the increment u = x_e - x_0, with lags of x as increments (kernels.in_increments)."""
    fs = spec.forms.get("displacement")
    if fs is None:
        return []

    def symbol(h):
        if h.startswith("d"):
            new, old = kernels.increment_pair(h)
            return sp.Symbol(rf"\delta {new[0]}_{{{new[1:]}}}")  # new - old
        return sp.Symbol(h)
    dt = {I.dt: sp.Symbol(r"\Delta t")}  # as dtdyn.derive.readable writes it
    return [(name, sp.latex(sp.Add(*(cf.xreplace(dt) * symbol(h)
                                     for h, cf in fs.hist_terms[key].items()),
                                   evaluate=False)))
            for name, key in (("B_u", "b"), ("E_u", "s"))]


def _tmm_context() -> dict:
    m1, m2 = sp.symbols("m1 m2")
    return {
        "spring": sp.latex(tmm.spring_damper(*sp.symbols("k c"))),
        "mass": sp.latex(tmm.mass(sp.Symbol("m"))),
        "force": sp.latex(tmm.force(sp.Symbol("F"))),
        "x1F": sp.latex(tmm.transfer_function(2, 1, 1)),
        "x2F": sp.latex(tmm.transfer_function(2, 2, 1)),
        "P2": sp.latex(sp.collect(tmm.characteristic_polynomial(2), tmm.s)),
        "spring_py": [[printing.py(e) for e in row] for row in
                      tmm.spring_damper(*sp.symbols("k c")).tolist()],
        "mass_py": [[printing.py(e) for e in row] for row in tmm.mass(sp.Symbol("m")).tolist()],
        "force_py": [[printing.py(e) for e in row] for row in tmm.force(sp.Symbol("F")).tolist()],
        "ground": sp.latex(tmm.ground_spring_damper(*sp.symbols("k_g c_g"))),
        "ground_py": [[printing.py(e) for e in row] for row in
                      tmm.ground_spring_damper(*sp.symbols("kg cg")).tolist()],
    }


def _beam_context() -> dict:
    spec = beam.derive_beam()
    closed, series = beam.krylov_functions()
    rows = lambda A: [[printing.py(e) for e in row] for row in A.tolist()]  # noqa: E731
    A = beam.field_generator().subs(beam.s**2, -beam.b**4 * beam.EI / beam.rho_A)
    return {
        "K": rows(spec.K), "M": rows(spec.M), "ML": rows(spec.M_lumped),
        "T": rows(beam.field_matrix_scaled()), "series": [printing.py(e) for e in series],
        "closed": [printing.py(e) for e in closed], "series_limit": "1.0",
        "Z": rows(beam.dynamic_stiffness_matrix()),
        "latex": {"N": sp.latex(beam.shape_functions()), "K": sp.latex(spec.K),
                  "Z": sp.latex(beam.dynamic_stiffness_matrix()),
                  "M": sp.latex(spec.M), "ML": sp.latex(spec.M_lumped), "A": sp.latex(A),
                  "T": sp.latex(beam.field_matrix_scaled()),
                  "closed": [sp.latex(e) for e in closed],
                  "series": [sp.latex(e) for e in series], "series_limit": "1.0"},
    }


def _newmark_ss_context() -> dict:
    def block(d):
        code = " + ".join(f"({printing.py(v)}) * {k}" for k, v in d.items()) or "Z"
        text = " + ".join(f"({sp.sstr(v)}) {k}" for k, v in d.items()) or "0"
        return {"code": code, "text": text}

    blocks = state_space.newmark_blocks()
    num_damp, params = state_space.sharpy_alpha_params()
    return {"blocks": [(n, [[block(b) for b in row] for row in rows])
                       for n, rows in blocks.items()],
            "sharpy_beta": printing.py(params[I.beta]),
            "sharpy_gamma": printing.py(params[I.gamma]),
            "sharpy_text": ", ".join(f"{k} = {sp.sstr(v)}" for k, v in params.items())}


def _modal_filters_context() -> dict:
    mf = modal_filters
    inv = [mf.derive_invariant(n) for n in mf.INVARIANTS]
    fold = mf.fold_pair()
    return {
        "closed": [(i.name, sp.sstr(i.c0), sp.sstr(i.c1)) for i in inv],
        "phi": [(i.name, i.phi) for i in inv],
        "series": [[repr(float(c)) for c in ser] for ser in mf.phi_series()],
        "fold": [(k, sp.sstr(e)) for k, e in fold.items()],
        "fold_py": [printing.py(fold[k]) for k in ("b0", "b1", "b2", "a1", "a2")],
    }


def _nonlinear_context() -> dict:
    m = nonlinear.modal_step()
    one_step = [n for n in I.SCHEMES if not I.SCHEMES[n].lags]
    return {"modal_B0": sp.latex(m["B0"]), "modal_Q": sp.latex(m["Q"]),
            "schemes": [(n, sp.latex(nonlinear.scheme_coefficient(n)),
                         *(sp.latex(e) for e in nonlinear.scheme_effective(n)))
                        for n in one_step]}


def _stability_context(schemes=None) -> dict:
    out = []
    for sch in schemes or I.SCHEMES.values():
        name = sch.name
        A = stability.amplification_matrix(sch)
        n = A.shape[0]
        rows = [((i, j), A[i, j]) for i in range(n) for j in range(n)]
        temps, reduced = printing.cse_assignments([(f"{i},{j}", e) for (i, j), e in rows], "t")
        out.append({"name": name, "params": list(sch.params), "history": list(sch.history),
                    "n": n, "temps": [(str(t), printing.py_array(e)) for t, e in temps],
                    "entries": [(tuple(map(int, k.split(","))), printing.py_array(e))
                                for k, e in reduced]})
    return {"schemes": out}


def _chain_macros(ctx) -> dict:
    """The statements the chain_loop.h macros hold, per form (chain.c.jinja defines them)."""
    history = ctx["history"]
    forms = []
    for f in ctx["forms_c"]:
        plain = f["error_step"] + f["plain"]["run"] + f["plain"]["step"]
        c_api.check_layout(len(plain))  # the rows fit the work the runtime allocates
        forms.append({
            **f,
            "constants": [f"const double {p} = params[{i}];" for i, p in enumerate(ctx["params"])]
                         + [f"const double {n} = {e};" for n, e in f["temps"] + f["rows"]],
            "plain_rows": [f"double *{n} = work + (DTDYN_CHAIN_ROW_PLAIN + {i}) * N;"
                           for i, (n, _) in enumerate(plain)],
            "plain_voids": [f"(void){n};" for n, _ in plain],
            "error_step_lines": [f"{n}[n] = {e};" for n, e in f["error_step"]],
            "plain_run_lines": [f"{n}[n] = {e};" for n, e in f["plain"]["run"]],
            "plain_step_lines": [f"{n}[n] = {e};" for n, e in f["plain"]["step"]],
        })
    rows = [f"double *{h} = hist + {i} * N;" for i, h in enumerate(history)]
    errors = [f"pair *e{h} = sweep ? (pair *)(ehist + {2 * i} * N) : NULL;"
              for i, h in enumerate(history)]
    return {"forms": forms, "history_lines": rows + errors, "state_lines": rows}


def _contract(env) -> dict[str, str]:
    """generated/c_api.h and c_api.py, both from dtdyn.derive.c_api (unformatted)."""
    names = list(I.SCHEMES)
    src = "dtdyn.derive.c_api"
    return {"c_api.h": env.get_template("c/c_api.h.jinja").render(
                template="c/c_api.h.jinja", source=src, **c_api.header(names, names)),
            "c_api.py": env.get_template("numpy/c_api.py.jinja").render(
                template="numpy/c_api.py.jinja", source=src, bindings=c_api.bindings(),
                constants=c_api.CONSTANTS)}


def render_contract() -> dict[str, str]:
    """The two sides of the kernels' contract, c_api.h and c_api.py, as `render_all` writes
    them (from the spec as it is now: a test changes it and sees both sides change)."""
    return format_sources(_contract(environment()))


def _render_scheme(render, scheme, src: str, shaft: bool = True) -> None:
    """A scheme's own files through ``render`` (render_all's): scheme_<name>.py, .md,
    chain_<name>.c and (``shaft``) shaft_<name>.c."""
    ctx = _scheme_context(scheme)
    name = ctx["name"]
    render("numpy/scheme.py.jinja", f"scheme_{name}.py", src, **ctx, forms=ctx["forms_py"])
    render("c/chain.c.jinja", f"chain_{name}.c", src, **ctx, **_chain_macros(ctx))
    render("markdown/scheme.md.jinja", f"scheme_{name}.md", src, **ctx,
           derivation=_readable_markdown(ctx["derived"]),
           increments=_increment_rows(ctx["spec"]))
    if shaft:
        from . import shaft as shaft_module
        render("c/shaft.c.jinja", f"shaft_{name}.c", f"dtdyn.derive.shaft with {src}",
               **shaft_module.c_context(ctx, _chain_macros(ctx)))


def render_scheme(scheme: I.Scheme, src: str) -> dict[str, str]:
    """A scheme file's kernels, unformatted: the files `_render_scheme` writes (for each stage
    of a composite scheme), plus stability_<name>.py (its amplification matrix). They #include
    "c_api.h"."""
    env = environment()
    out: dict[str, str] = {}

    def render(template, dest, source, **ctx):
        out[dest] = env.get_template(template).render(template=template, source=source, **ctx)

    for part in scheme.stages or (scheme,):
        _render_scheme(render, part, src)
    render("numpy/stability.py.jinja", f"stability_{scheme.name}.py", src,
           **_stability_context([scheme]))
    return out


def render_all() -> dict[str, str]:
    """Every generated file as {name: text}."""
    env = environment()
    out: dict[str, str] = {}

    def render(template, dest, source, **ctx):
        if dest in c_api.SOURCES:  # the entry points from the signature spec
            ctx.setdefault("flushed_entries", c_api.flushed_entries(dest))
            ctx.setdefault("body", c_api.BODIES.get(dest))
        out[dest] = env.get_template(template).render(template=template, source=source, **ctx)

    render("numpy/dttmm.py.jinja", "dttmm_sweep.py", "dtdyn.derive.dttmm", **_dttmm_context())
    render("numpy/tmm.py.jinja", "tmm.py", "dtdyn.derive.tmm", **_tmm_context())
    beam_ctx = _beam_context()
    render("numpy/beam.py.jinja", "beam.py", "dtdyn.derive.beam", **beam_ctx)
    render("markdown/beam.md.jinja", "beam.md", "dtdyn.derive.beam", **beam_ctx["latex"])
    render("markdown/tmm.md.jinja", "tmm.md", "dtdyn.derive.tmm", **_tmm_context())
    render("numpy/newmark_ss.py.jinja", "newmark_ss.py", "dtdyn.derive.state_space",
           **_newmark_ss_context())
    for dest, body in c_api.BODIES.items():  # hand-written loops, entry points from the spec
        render("c/verbatim.c.jinja", dest, f"dtdyn/_engine/csrc/{body} (hand-written)")
    render("numpy/modal_filters.py.jinja", "modal_filters.py", "dtdyn.derive.modal_filters",
           **_modal_filters_context())
    render("c/modal_states.c.jinja", "modal_states.c",
           "dtdyn.derive.modal_filters.increment_form",
           increments=[(k, sp.sstr(v)) for k, v in modal_filters.increment_form().items()])
    render("markdown/nonlinear.md.jinja", "nonlinear.md", "dtdyn.derive.nonlinear",
           **_nonlinear_context(), **nonlinear.polynomial_context())
    par = nonlinear.parabola_coefficient()
    render("numpy/nl_modal.py.jinja", "nl_modal.py", "dtdyn.derive.nonlinear.parabola_coefficient",
           closed=sp.sstr(par["closed"]), kernel=sp.sstr(par["kernel"]),
           kernel_py=printing.py(par["kernel"].subs(nonlinear.zz, sp.Symbol("zs"))
                                 .replace(sp.exp, lambda a: sp.Symbol("e"))),
           series=[repr(float(c)) for c in par["series"]], **nonlinear.polynomial_context())
    render("numpy/stability.py.jinja", "stability.py", "dtdyn.derive.stability",
           **_stability_context())
    names = list(I.SCHEMES)
    for name in names:
        _render_scheme(render, name, f"dtdyn.derive.integrators.SCHEMES[{name!r}]", shaft=False)
    from . import shaft  # torsional shafts and trees: shaft.py, shaft.md, shaft_<scheme>.c
    shaft.render(render, _scheme_context, _chain_macros, names)
    render("numpy/init.py.jinja", "__init__.py", "dtdyn.derive.integrators.scheme_table")
    out.update(_contract(env))
    render("numpy/scheme_table.py.jinja", "scheme_table.py",
           "dtdyn.derive.integrators.scheme_table and dtdyn.derive.nonlinear.method_table",
           table=I.scheme_table(), methods=nonlinear.method_table(), auto=nonlinear.AUTO)
    out = format_sources(out)
    manifest = {n: {"sha256": hashlib.sha256(t.encode()).hexdigest()}
                for n, t in sorted(out.items())}
    out["manifest.json"] = json.dumps(manifest, indent=1, sort_keys=True) + "\n"
    return out


#: the formatters of the generated sources, pinned in the [derive] extra so that regenerating
#: gives the same bytes on every machine
FORMATTERS = {"ruff": "0.8.6", "clang-format": "19.1.6"}
CLANG_STYLE = ("{BasedOnStyle: LLVM, IndentWidth: 4, ColumnLimit: 100, "
               "AllowShortFunctionsOnASingleLine: None, SortIncludes: Never, "
               "AlignEscapedNewlines: DontAlign}")


def _formatter(name: str) -> str:
    """Path of a pinned formatter (next to this Python, else on PATH), its version checked."""
    exe = Path(sys.executable).parent / name
    path = str(exe) if exe.is_file() else shutil.which(name)
    want = FORMATTERS[name]
    if path is None:
        raise RuntimeError(f"dtdyn generate needs {name} {want}: pip install \"dtdyn[derive]\"")
    version = subprocess.run([path, "--version"], capture_output=True, text=True).stdout
    if want not in version:
        raise RuntimeError(f"dtdyn generate needs {name} {want} (the bytes of generated/ depend "
                           f"on it), found: {version.strip()}; pip install \"dtdyn[derive]\"")
    return path


def format_sources(files: dict[str, str]) -> dict[str, str]:
    """Every generated .py through ruff format and every .c through clang-format (pinned)."""
    ruff, clang = _formatter("ruff"), _formatter("clang-format")
    out = {}
    for name, text in files.items():
        if name.endswith(".py"):
            cmd = [ruff, "format", "--line-length", "100", "--stdin-filename", name, "-"]
        elif name.endswith((".c", ".h")):
            cmd = [clang, f"--style={CLANG_STYLE}", f"--assume-filename={name}"]
        else:
            out[name] = text
            continue
        proc = subprocess.run(cmd, input=text, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"formatting {name} failed: {proc.stderr.strip()}")
        out[name] = proc.stdout
    return out


def _atomic_write(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def write(dest: Path = GENERATED) -> list[str]:
    """Render everything into ``dest`` (rendering completes before anything is written)."""
    files = render_all()
    dest.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        _atomic_write(dest / name, text)
    stale = [p.name for p in dest.iterdir() if p.is_file() and p.name not in files
             and p.suffix in (".py", ".c", ".h", ".md", ".json")]
    for name in stale:
        (dest / name).unlink()
    return sorted(files)


def write_vendor(dest: Path, schemes=()) -> list[str]:
    """A standalone copy of the C kernels in ``dest`` (created if missing), for vendoring: every
    generated C source and header (but nl_loop.c, which the run completes with the elements'
    CasADi code), the hand-written headers they include, the kernels of the
    scheme files' ``schemes`` (`integrators.Scheme` values) and example.c, each source of which
    compiles as it is there (``cc -O2 -c chain_hht.c``)."""
    # nl_loop.c is completed at run time by the CasADi code of the user's elements: not vendored
    files = {n: t for n, t in render_all().items()
             if n.endswith((".c", ".h")) and n != "nl_loop.c"}
    for sch in schemes:
        rendered = {n: t for n, t in render_scheme(sch, f"scheme file {sch.name!r}").items()
                    if n.endswith(".c")}
        twice = sorted(set(rendered) & set(files))
        if twice:
            raise ValueError(f"scheme file {sch.name!r}: {twice[0]} is written already (two "
                             "scheme files, or a scheme and a stage, of one name)")
        files.update(rendered)
    env = environment()
    files["example.c"] = env.get_template("c/example.c.jinja").render(scheme="hht", params="-0.05")
    files = format_sources(files)
    for path in sorted(CSOURCES.glob("*.h")):
        files[path.name] = path.read_text()
    dest.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        _atomic_write(dest / name, text)
    return sorted(files)


def check(dest: Path = GENERATED) -> list[str]:
    """Names of generated files that are missing, stale, extra or differ from a fresh render."""
    files = render_all()
    bad = [n for n, t in files.items()
           if not (dest / n).is_file() or (dest / n).read_text(encoding="utf-8") != t]
    bad += [p.name for p in dest.iterdir() if p.is_file() and p.name not in files
            and p.suffix in (".py", ".c", ".h", ".md", ".json")]
    return sorted(bad)
