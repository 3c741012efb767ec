"""Property-based fuzzing of the public entry points, the scene reader and the force-law parser.

The property, for every input: a *named* error or a finite, correct result. Named means one of
dtdyn's own exception classes, or a ValueError / TypeError / MemoryError / FloatingPointError
whose message names the argument (or the scene field) that is wrong. Anything else (an
IndexError, a ZeroDivisionError, a LinAlgError, a message from deep inside NumPy that names
nothing the user typed) fails the test, and so does a result holding NaN or inf.

Inputs: small models (1-4 DOFs, <= 60 samples) with one or two arguments replaced by hostile
values: NaN, inf, empty, 0-d and 3-d arrays, complex, object, bool, int and string arrays, huge and
tiny numbers, None, strings, nested lists. Valid random inputs are also compared with
independent truths (eigenvalues from scipy.linalg.eigh, the same scheme on the matrices, SymPy).

The profiles (CI: fixed seed, bounded examples; ``-m fuzz``: the long run) are in conftest.py.
"""
from __future__ import annotations

import dataclasses
import math
import re
import warnings

import numpy as np
import pytest
import scipy.linalg
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import dtdyn as dd

CI, LONG = settings.get_profile("ci"), settings.get_profile("fuzz")

OWN_ERRORS = tuple(getattr(dd, n) for n in dir(dd) if isinstance(getattr(dd, n), type)
                   and issubclass(getattr(dd, n), Exception)
                   and not issubclass(getattr(dd, n), Warning))
PLAIN_ERRORS = (ValueError, TypeError, MemoryError, FloatingPointError)


# --- the property -----------------------------------------------------------------------------

def _names_one(message: str, names) -> bool:
    return any(re.search(rf"(?<![A-Za-z0-9_]){re.escape(n)}(?![A-Za-z0-9_])", message)
               for n in names)


def _arrays(result, seen=None):
    """Every numeric array in a result (ndarray, sparse matrix, dataclass, Response, tuple)."""
    seen = set() if seen is None else seen
    if id(result) in seen:
        return
    seen.add(id(result))
    if isinstance(result, np.ndarray):
        yield result
    elif hasattr(result, "tocsr") and hasattr(result, "data"):  # scipy.sparse
        yield np.asarray(result.data)
    elif isinstance(result, (tuple, list)):
        for item in result:
            yield from _arrays(item, seen)
    elif isinstance(result, (float, complex, np.floating, np.complexfloating)):
        yield np.asarray(result)
    elif dataclasses.is_dataclass(result) or hasattr(result, "__dict__"):
        fields = (vars(result) if hasattr(result, "__dict__")
                  else {f.name: getattr(result, f.name) for f in dataclasses.fields(result)})
        for key, value in fields.items():
            if key not in ("info", "meta") and not callable(value):
                yield from _arrays(value, seen)


def named_or_finite(call, names, what=""):
    """Run ``call()``; return its result when every array in it is finite, None when it raised a
    named error (see the module docstring); fail otherwise, with the exception chained."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # warnings are allowed; only the outcome is judged
            with np.errstate(all="ignore"):
                result = call()
    except OWN_ERRORS:
        return None
    except PLAIN_ERRORS as exc:
        if _names_one(str(exc), names):
            return None
        raise AssertionError(f"{what}: unnamed {type(exc).__name__} (names none of "
                             f"{sorted(names)}): {exc}") from exc
    except Exception as exc:  # noqa: BLE001 - the property under test
        raise AssertionError(f"{what}: unnamed {type(exc).__name__}: {exc}") from exc
    for a in _arrays(result):
        if a.dtype.kind in "fc" and not np.isfinite(a).all():
            raise AssertionError(f"{what}: a result holds NaN or inf (no error raised)")
    return result


# --- hostile values ---------------------------------------------------------------------------

_WILD_FLOATS = st.one_of(
    st.sampled_from([0.0, -0.0, -1.0, np.nan, np.inf, -np.inf, 1e300, -1e300, 1e-300, 5e-324,
                     1e-12, 1e12]),
    st.floats(allow_nan=True, allow_infinity=True, width=64))
_SCALARS = st.one_of(
    _WILD_FLOATS,
    st.sampled_from([None, "abc", "", "1e-3", True, False, 1j, 1 + 2j, 0, -1, 2**63, 10**400,
                     b"\x00", [], [[]], {}, (), object(), [1.0, 2.0], "x" * 1000]),
    st.integers(min_value=-(2**70), max_value=2**70))


def _shapes(n: int):
    return st.sampled_from([(), (0,), (n,), (n + 1,), (1, n), (n, n), (n, 0), (2, 2, 2),
                            (n, n, n), (0, 0), (1,), (n, n + 1)])


def _hostile_arrays(n: int):
    shapes = _shapes(n)
    return st.one_of(
        hnp.arrays(np.float64, shapes, elements=_WILD_FLOATS),
        hnp.arrays(np.float64, shapes, elements=st.floats(-1e3, 1e3)),
        hnp.arrays(np.complex128, shapes,
                   elements=st.complex_numbers(max_magnitude=1e3, allow_nan=False)),
        hnp.arrays(np.int64, shapes, elements=st.integers(-10, 10)),
        hnp.arrays(np.bool_, shapes),
        hnp.arrays(np.float32, shapes, elements=st.floats(-1e3, 1e3, width=32)),
        hnp.arrays(np.dtype("U3"), shapes),
        shapes.map(lambda s: np.full(s, None, dtype=object)),
        shapes.map(lambda s: np.ones(s, dtype=object)),
        st.just(np.ones(n, dtype=float)).map(lambda a: a[::-1]),  # a negative stride
        st.lists(st.one_of(st.floats(-10, 10), st.text(max_size=2), st.none()), max_size=n + 1),
    )


def hostile(n: int):
    return st.one_of(_SCALARS, _hostile_arrays(n))


# --- valid random models ----------------------------------------------------------------------

@st.composite
def chains(draw, max_dofs=4):
    n = draw(st.integers(1, max_dofs))
    pos = st.floats(0.1, 10.0)
    mass = draw(st.lists(pos, min_size=n, max_size=n))
    stiffness = draw(st.lists(st.floats(1e2, 1e5), min_size=n, max_size=n))
    damping = draw(st.lists(st.floats(0.0, 5.0), min_size=n, max_size=n))
    return np.array(mass), np.array(stiffness), np.array(damping)


def _setup(data, n_max=4, samples=(5, 40)):
    mass, stiffness, damping = data.draw(chains(n_max), label="chain")
    n = mass.size
    M, C, K = dd.chain_matrices(mass, stiffness, damping, sparse=False)
    omega_max = math.sqrt(np.linalg.eigvalsh(np.linalg.solve(np.diag(mass), K)).max().real
                          if n > 1 else stiffness[0] / mass[0])
    dt = data.draw(st.floats(0.02, 0.5), label="omega_max dt") / omega_max
    steps = data.draw(st.integers(*samples), label="samples")
    force = data.draw(hnp.arrays(np.float64, steps, elements=st.floats(-10, 10)), label="force")
    return dict(mass=mass, stiffness=stiffness, damping=damping, M=M, C=C, K=K, dt=dt,
                force=force, n=n, force_dofs=[n - 1])


def _mutate(data, args: dict, fuzzable, n):
    """Replace one or two of ``fuzzable`` in ``args`` by hostile values; return their names."""
    chosen = data.draw(st.lists(st.sampled_from(fuzzable), min_size=1, max_size=2, unique=True),
                       label="fuzzed arguments")
    for name in chosen:
        args[name] = data.draw(hostile(n), label=name)
    return chosen


#: argument name -> the names a message may use for it (the matrices are also "M, C, K" etc.)
ALIASES = {"force_dofs": ("force_dofs", "force_dof", "dof", "dofs", "force"),
           "outputs": ("outputs", "output", "dof", "dofs"),
           "ground_acceleration": ("ground_acceleration", "acceleration", "record"),
           "freqs_hz": ("freqs_hz", "frequencies", "frequency"),
           "damping_ratio": ("damping_ratio", "zeta"),
           "mass": ("mass", "masses", "m"), "stiffness": ("stiffness", "k"),
           "damping": ("damping", "c"), "M": ("M", "mass"), "K": ("K", "stiffness"),
           "C": ("C", "damping"), "omega": ("omega",), "model": ("model",)}


#: an argument whose size must match another's: a mismatch may be reported under the other name
#: ("stiffness has length 2, expected 1" when mass has the wrong length)
RELATED = {"mass": ("stiffness", "damping", "ground_stiffness"), "M": ("C", "K"),
           "force": ("force_dofs",), "force_dofs": ("force",), "dt": ("freqs_hz", "periods")}


def _names(chosen):
    names = set(chosen)
    for name in chosen:
        names.update(RELATED.get(name, ()))
    return {alias for name in names for alias in ALIASES.get(name, (name,))}


def _run(fn, pos, kw, args, chosen, what):
    return named_or_finite(lambda: fn(*(args[p] for p in pos), **{k: args[k] for k in kw}),
                           _names(chosen), what)


# --- the entry points -------------------------------------------------------------------------

def _time_history(fn, pos, kw, extra=()):
    def case(data):
        args = _setup(data)
        fuzzable = [*pos, *kw, *extra]
        chosen = _mutate(data, args, fuzzable, args["n"])
        kw_all = [k for k in (*kw, *extra) if k in args]
        _run(fn, pos, kw_all, args, chosen, fn.__name__)
    return case


def _mck_response(data):
    _time_history(dd.mck_response, ("M", "C", "K", "force", "dt"), ("force_dofs",),
                  ("outputs", "x0", "v0"))(data)


def _chain_response(data):
    _time_history(dd.chain_response, ("mass", "stiffness", "damping", "force", "dt"),
                  ("force_dofs",), ("outputs", "x0", "ground_stiffness"))(data)


def _exact_response(data):
    _time_history(dd.exact_response, ("M", "C", "K", "force", "dt"), ("force_dofs",),
                  ("outputs", "v0"))(data)


def _modal_filter_response(data):
    _time_history(dd.modal_filter_response, ("M", "C", "K", "force", "dt"), ("force_dofs",),
                  ("outputs",))(data)


def _state_space_response(data):
    args = _setup(data)
    args["model"] = dd.discretize(args["M"], args["C"], args["K"], args["dt"])
    chosen = _mutate(data, args, ["model", "force", "force_dofs", "outputs", "x0"], args["n"])
    kw = [k for k in ("force_dofs", "outputs", "x0") if k in args]
    _run(dd.state_space_response, ("model", "force"), kw, args, chosen, "state_space_response")


def _discretize(data):
    args = _setup(data)
    chosen = _mutate(data, args, ["M", "C", "K", "dt"], args["n"])
    _run(dd.discretize, ("M", "C", "K", "dt"), (), args, chosen, "discretize")


def _mck_modes(data):
    args = _setup(data)
    chosen = _mutate(data, args, ["M", "C", "K", "count"], args["n"])
    _run(dd.mck_modes, ("M", "C", "K"), [k for k in ("count",) if k in args], args, chosen,
         "mck_modes")


def _chain_frequencies(data):
    args = _setup(data)
    chosen = _mutate(data, args, ["mass", "stiffness", "count", "below", "ground_stiffness"],
                     args["n"])
    kw = [k for k in ("count", "below", "ground_stiffness") if k in args]
    _run(dd.chain_frequencies, ("mass", "stiffness"), kw, args, chosen, "chain_frequencies")


def _chain_matrices(data):
    args = _setup(data)
    chosen = _mutate(data, args, ["mass", "stiffness", "damping", "ground_stiffness"], args["n"])
    kw = [k for k in ("ground_stiffness",) if k in args]
    _run(dd.chain_matrices, ("mass", "stiffness", "damping"), kw, args, chosen, "chain_matrices")


def _chain_frequency_response(data):
    args = _setup(data)
    args["omega"] = np.linspace(1.0, 100.0, 7)
    args["outputs"] = [0]
    chosen = _mutate(data, args, ["mass", "stiffness", "damping", "omega", "force_dofs",
                                  "outputs"], args["n"])
    _run(dd.chain_frequency_response,
         ("mass", "stiffness", "damping", "omega", "force_dofs", "outputs"), (), args, chosen,
         "chain_frequency_response")


def _srs(data):
    args = _setup(data, samples=(5, 60))
    args["ground_acceleration"] = args["force"]
    args["freqs_hz"] = data.draw(hnp.arrays(np.float64, st.integers(1, 5),
                                            elements=st.floats(0.5, 50.0)), label="freqs_hz")
    args["damping_ratio"] = 0.05
    chosen = _mutate(data, args, ["ground_acceleration", "dt", "freqs_hz", "damping_ratio"], 3)
    _run(dd.shock_response_spectrum, ("ground_acceleration", "dt", "freqs_hz"),
         ("damping_ratio",), args, chosen, "shock_response_spectrum")


def _response_spectrum(data):
    args = _setup(data, samples=(5, 60))
    args["ground_acceleration"] = args["force"]
    args["periods"] = data.draw(hnp.arrays(np.float64, st.integers(1, 5),
                                           elements=st.floats(0.02, 5.0)), label="periods")
    args["damping_ratio"] = 0.05
    chosen = _mutate(data, args, ["ground_acceleration", "dt", "periods", "damping_ratio"], 3)
    _run(dd.response_spectrum, ("ground_acceleration", "dt"), ("periods", "damping_ratio"),
         args, chosen, "response_spectrum")


ENTRY_POINTS = {
    "mck_response": _mck_response,
    "chain_response": _chain_response,
    "exact_response": _exact_response,
    "modal_filter_response": _modal_filter_response,
    "state_space_response": _state_space_response,
    "discretize": _discretize,
    "mck_modes": _mck_modes,
    "chain_frequencies": _chain_frequencies,
    "chain_matrices": _chain_matrices,
    "chain_frequency_response": _chain_frequency_response,
    "shock_response_spectrum": _srs,
    "response_spectrum": _response_spectrum,
}


@pytest.mark.parametrize("name", ENTRY_POINTS)
@CI
@given(data=st.data())
def test_entry_point_hostile_arguments(name, data):
    ENTRY_POINTS[name](data)


@pytest.mark.fuzz
@pytest.mark.parametrize("name", ENTRY_POINTS)
@LONG
@given(data=st.data())
def test_entry_point_hostile_arguments_long(name, data):
    ENTRY_POINTS[name](data)


# --- valid random inputs: finite and correct --------------------------------------------------

def _correct_frequencies_and_responses(data):
    args = _setup(data, samples=(5, 30))
    mass, stiffness, damping, M, C, K = (args[k] for k in ("mass", "stiffness", "damping",
                                                           "M", "C", "K"))
    # frequencies: the Sturm count / bisection against LAPACK on the same matrices
    exact = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True))
    got = named_or_finite(lambda: dd.chain_frequencies(mass, stiffness), {"mass"}, "freqs")
    # bisection to a relative 1e-12 plus LAPACK's own error (cond ~ k_max/k_min / m ratios)
    np.testing.assert_allclose(got, exact, rtol=1e-9)
    modes = named_or_finite(lambda: dd.mck_modes(M, None, K), {"M"}, "mck_modes")
    np.testing.assert_allclose(modes.omega, exact, rtol=1e-9)
    # the same scheme on the chain (C sweep) and on the matrices (dense solve): round-off apart
    force, dt, dofs = args["force"], args["dt"], args["force_dofs"]
    a = named_or_finite(lambda: dd.chain_response(mass, stiffness, damping, force, dt,
                                                  force_dofs=dofs), {"force"}, "chain")
    b = named_or_finite(lambda: dd.mck_response(M, C, K, force, dt, force_dofs=dofs),
                        {"force"}, "mck")
    scale = max(np.abs(b.x).max(), 1e-300)
    # both solve the same linear recursion; each step's error is a few ulps of the state and the
    # average-acceleration recursion does not amplify it (|eigenvalues| <= 1): 1e-9 of the peak
    assert np.abs(a.x - b.x).max() <= 1e-9 * scale + 1e-300


@CI
@given(data=st.data())
def test_valid_chains_give_correct_results(data):
    _correct_frequencies_and_responses(data)


@pytest.mark.fuzz
@LONG
@given(data=st.data())
def test_valid_chains_give_correct_results_long(data):
    _correct_frequencies_and_responses(data)


# --- force laws: expressions from a grammar, and junk -----------------------------------------

_LEAVES = st.sampled_from(["x", "v", "k", "c", "pi", "2", "0.5", "1e3", "3"])
_FUNCS = ["sqrt", "exp", "log", "sin", "cos", "tan", "sinh", "cosh", "tanh", "atan", "abs",
          "sign"]


def _expressions():
    def extend(inner):
        return st.one_of(
            st.tuples(inner, st.sampled_from(["+", "-", "*", "/", "**"]), inner).map(
                lambda t: f"({t[0]} {t[1]} {t[2]})"),
            st.tuples(st.sampled_from(["-", "+"]), inner).map(lambda t: f"{t[0]}{t[1]}"),
            st.tuples(st.sampled_from(_FUNCS), inner).map(lambda t: f"{t[0]}({t[1]})"),
            st.tuples(st.sampled_from(["min", "max"]), inner, inner).map(
                lambda t: f"{t[0]}({t[1]}, {t[2]})"),
        )
    return st.recursive(_LEAVES, extend, max_leaves=12)


_JUNK = st.one_of(
    st.text(max_size=40),
    st.text(alphabet="xvkc0123456789.+-*/()eE ,_[]{}'\"%@<>=!:;\\", max_size=60),
    st.sampled_from(["__import__('os').system('true')", "x.real", "x[0]", "lambda: 1",
                     "x if v else k", "1j*x", "'s'", "x % 2", "x // 2", "f(x)", "min(x)",
                     "sqrt(x, v)",
                     "(" * 300 + "x" + ")" * 300, "x" + "+x" * 600, "k" * 2000, "", " ",
                     "x ** 1e9", "10 ** 400", "1e999 * x", "nan", "inf", "True", "None"]),
)


def _law(data):
    grammar = data.draw(st.booleans(), label="from the grammar")
    text = data.draw(_expressions() if grammar else _JUNK, label="expression")
    if data.draw(st.booleans(), label="junk spliced in") and text:
        at = data.draw(st.integers(0, len(text)), label="at")
        text = text[:at] + data.draw(_JUNK, label="junk") + text[at:]
    constants = data.draw(st.fixed_dictionaries({}, optional={
        "k": st.one_of(st.floats(allow_nan=True, allow_infinity=True), _SCALARS),
        "c": st.floats(-1e3, 1e3)}), label="constants")
    law = named_or_finite(lambda: dd.Law(0, expression=text, **constants),
                          {"expression", "Law.expression", *constants}, f"Law({text!r})")
    if law is None or not grammar:
        return
    # a law that was accepted evaluates like SymPy's reading of the same text
    from dtdyn.nonlinear._elements import NUMPY_OPS

    x, v = data.draw(st.floats(-2, 2), label="x"), data.draw(st.floats(-2, 2), label="v")
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        got = complex(np.asarray(law.force(np.float64(x), np.float64(v), None, NUMPY_OPS)))
    sympy = pytest.importorskip("sympy")
    expr = law.to_sympy()
    subs = {sympy.Symbol(s): val for s, val in (("x", x), ("v", v), *constants.items())}
    try:
        want = complex(expr.subs(subs).evalf(30))
    except (TypeError, ValueError, OverflowError, ZeroDivisionError):
        return  # SymPy's own value is not a number (zoo, nan, complex infinity)
    assume(np.isfinite(got) and np.isfinite(want) and abs(got.imag) == 0)
    if want.imag == 0:
        # the NumPy walk rounds every operation: a few ulps per node, amplified by the
        # condition of the expression; 1e-6 relative to the larger of the value and 1
        assert abs(got.real - want.real) <= 1e-6 * max(1.0, abs(want.real)), (text, got, want)


@CI
@given(data=st.data())
def test_force_law_expressions(data):
    _law(data)


@pytest.mark.fuzz
@LONG
@given(data=st.data())
def test_force_law_expressions_long(data):
    _law(data)


# --- scenes: random tables, and corrupted TOML text -------------------------------------------

_SCHEMES = ["newmark", "average_acceleration", "hht", "generalized_alpha", "central_difference",
            "wilson", "houbolt", "fox_goodwin", "no_such_scheme"]


@st.composite
def scene_dicts(draw):
    n = draw(st.integers(1, 3))
    model = {"mass": draw(st.lists(st.floats(0.5, 5.0), min_size=n, max_size=n)),
             "stiffness": draw(st.lists(st.floats(1e2, 1e4), min_size=n, max_size=n))}
    if draw(st.booleans()):
        model["damping"] = draw(st.lists(st.floats(0.0, 2.0), min_size=n, max_size=n))
    kind = draw(st.sampled_from(["step", "ramp", "sine", "white_noise"]))
    load = {"dof": draw(st.integers(0, n - 1)), "kind": kind}
    load.update({"ramp": {"slope": 1.0}, "sine": {"amplitude": 1.0, "frequency": 2.0},
                 "white_noise": {"std": 1.0, "seed": 3}}.get(kind, {}))
    data = {"model": model, "load": [load],
            "time": {"dt": 1e-3, "duration": draw(st.sampled_from([0.01, 0.02, 0.05]))}}
    if draw(st.booleans()):
        data["scheme"] = {"name": draw(st.sampled_from(_SCHEMES[:-1]))}
    if draw(st.booleans()):
        data["output"] = {"quantities": draw(st.lists(st.sampled_from(["x", "v", "a"]),
                                                      min_size=1, max_size=3, unique=True))}
    return data


def _flatten_keys(obj, out):
    if isinstance(obj, dict):
        for key, value in obj.items():
            out.add(str(key))
            _flatten_keys(value, out)
    elif isinstance(obj, list):
        for item in obj:
            _flatten_keys(item, out)
    return out


_SCENE_WORDS = {"model", "load", "time", "scheme", "output", "scene", "TOML", "toml", "initial",
                "ground", "title", "element", "nonlinear", "dof", "kind", "name"}


def _corrupt_dict(draw, data):
    """Replace, delete or add one value somewhere in the table."""
    paths = []

    def walk(obj, path):
        if isinstance(obj, dict):
            for key, value in obj.items():
                paths.append((*path, key))
                walk(value, (*path, key))
        elif isinstance(obj, list):
            for i, item in enumerate(obj):
                paths.append((*path, i))
                walk(item, (*path, i))
    walk(data, ())
    path = draw(st.sampled_from(paths))
    parent = data
    for step in path[:-1]:
        parent = parent[step]
    action = draw(st.sampled_from(["replace", "delete", "add"]))
    if action == "delete" and isinstance(parent, dict):
        del parent[path[-1]]
    elif action == "add" and isinstance(parent, dict):
        parent[draw(st.sampled_from(["speed", "dt", "kind", "", "mass", "x" * 50]))] = 1.0
    else:
        parent[path[-1]] = draw(st.one_of(_SCALARS, st.lists(_WILD_FLOATS, max_size=4),
                                          st.dictionaries(st.text(max_size=3), st.integers(),
                                                          max_size=2)))


def _run_scene(scene):
    return dd.run_scene(scene)


def _scene_dict(data):
    table = data.draw(scene_dicts(), label="scene")
    corrupt = data.draw(st.booleans(), label="corrupt")
    if corrupt:
        _corrupt_dict(data.draw, table)
    names = _flatten_keys(table, set(_SCENE_WORDS))
    scene = named_or_finite(lambda: dd.scene_from_dict(table), names, "scene_from_dict")
    if scene is not None:
        named_or_finite(lambda: _run_scene(scene), names, "run_scene")


def _toml(data: dict) -> str:
    """A small TOML writer for the scene tables (strings, numbers, lists, tables, [[arrays]])."""
    def value(v):
        if isinstance(v, str):
            return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, float):
            return repr(v) if math.isfinite(v) else ("nan" if v != v else
                                                      ("inf" if v > 0 else "-inf"))
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return str(v)
    lines = []
    for key, v in data.items():
        if isinstance(v, dict):
            lines.append(f"[{key}]")
            lines += [f"{k} = {value(x)}" for k, x in v.items()]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                lines.append(f"[[{key}]]")
                lines += [f"{k} = {value(x)}" for k, x in item.items()]
        else:
            lines.insert(0, f"{key} = {value(v)}")
    return "\n".join(lines) + "\n"


def _scene_text(data, tmp_path_factory):
    text = _toml(data.draw(scene_dicts(), label="scene"))
    how = data.draw(st.sampled_from(["none", "cut", "delete", "insert", "duplicate", "swap",
                                     "deep", "binary"]), label="corruption")
    if how == "cut":
        text = text[:data.draw(st.integers(0, len(text)), label="at")]
    elif how == "delete":
        a = data.draw(st.integers(0, len(text)), label="from")
        text = text[:a] + text[a + data.draw(st.integers(1, 20), label="n"):]
    elif how == "insert":
        a = data.draw(st.integers(0, len(text)), label="at")
        text = text[:a] + data.draw(st.text(max_size=10), label="junk") + text[a:]
    elif how == "duplicate":
        lines = text.splitlines(keepends=True)
        i = data.draw(st.integers(0, len(lines) - 1), label="line")
        text = "".join(lines[:i + 1] + lines[i:])
    elif how == "swap":
        lines = text.splitlines(keepends=True)
        i, j = (data.draw(st.integers(0, len(lines) - 1), label=s) for s in "ij")
        lines[i], lines[j] = lines[j], lines[i]
        text = "".join(lines)
    elif how == "deep":
        depth = data.draw(st.sampled_from([10, 1000, 100_000]), label="depth")
        text = text.replace("[model]", f"deep = {'[' * depth}{']' * depth}\n[model]")
    elif how == "binary":
        text = text.encode("utf-8")[:50].decode("latin-1") + "\x00\xff\ufffd"
    path = tmp_path_factory.mktemp("scene") / "fuzz.toml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    table = None
    names = set(_SCENE_WORDS) | {str(path), path.name, "fuzz.toml", "deep"}
    for word in re.findall(r"[A-Za-z_]+", text):
        names.add(word)  # a message quoting the key or table at fault names it
    scene = named_or_finite(lambda: dd.load_scene(path), names, f"load_scene ({how})")
    del table
    if scene is not None:
        named_or_finite(lambda: _run_scene(scene), names, f"run_scene ({how})")


@CI
@given(data=st.data())
def test_scene_tables(data):
    _scene_dict(data)


@pytest.mark.fuzz
@LONG
@given(data=st.data())
def test_scene_tables_long(data):
    _scene_dict(data)


@CI
@given(data=st.data())
def test_scene_files(data, tmp_path_factory):
    _scene_text(data, tmp_path_factory)


@pytest.mark.fuzz
@LONG
@given(data=st.data())
def test_scene_files_long(data, tmp_path_factory):
    _scene_text(data, tmp_path_factory)
