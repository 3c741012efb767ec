"""What every public function of dtdyn does before its own work, in one decorator.

- A misspelled keyword is a TypeError that names it and the closest valid name
  (``simulate(..., outptus=[0])`` -> "unexpected keyword 'outptus'; did you mean 'outputs'?"),
  also where a function passes its remaining keywords on (``**scheme_params``).
- A keyword renamed in this release still works for one release, with a DeprecationWarning.
- Warnings raised through `warn` during the call point at the caller's line (the first frame
  outside dtdyn), and each distinct warning is shown once per outermost public call.
"""
from __future__ import annotations

import contextlib
import contextvars
import difflib
import functools
import inspect
import os
import sys
import warnings

_PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_SEEN = contextvars.ContextVar("dtdyn_warnings_seen", default=None)
_CALL = contextvars.ContextVar("dtdyn_public_call", default=None)


def current_call() -> str | None:
    """The name of the outermost public function being called (None outside one): what an
    error deep inside names as the entry point."""
    return _CALL.get()


def _scheme_parameter_names() -> frozenset:
    from dtdyn.generated.scheme_table import TABLE
    return frozenset(p for row in TABLE.values() for p in row["params"])


def suggest(name: str, valid) -> str:
    """' did you mean 'x'?' for the closest of ``valid`` to ``name``, or ''."""
    close = difflib.get_close_matches(name, sorted(valid), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def unknown_keyword(function: str, name: str, valid) -> TypeError:
    return TypeError(f"{function}() got an unexpected keyword argument {name!r}"
                     f"{suggest(name, valid)}")


def public(function=None, *, renamed: dict | None = None, scheme_keywords: bool | None = None):
    """Decorate a public function or class (its ``__init__``) as described in the module
    docstring. ``renamed`` maps old keyword -> new keyword. ``scheme_keywords``: the function
    takes a scheme's parameters as extra keywords (default: it has ``**scheme_params``)."""
    if function is None:
        return functools.partial(public, renamed=renamed, scheme_keywords=scheme_keywords)
    if inspect.isclass(function):
        function.__init__ = _wrap(function.__init__, function.__name__, renamed, scheme_keywords)
        return function
    return _wrap(function, function.__name__, renamed, scheme_keywords)


def _wrap(function, name, renamed, scheme_keywords):
    renamed = dict(renamed or {})
    parameters = inspect.signature(function).parameters
    var_kw = next((p.name for p in parameters.values() if p.kind is p.VAR_KEYWORD), None)
    named = frozenset(p.name for p in parameters.values()
                      if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY))
    if scheme_keywords is None:
        scheme_keywords = var_kw == "scheme_params"
    if var_kw is not None and not scheme_keywords:
        valid = None                       # free keywords (e.g. a Law's constants)
    else:
        valid = named | (_scheme_parameter_names() if scheme_keywords else frozenset())
    positional = [p.name for p in parameters.values()
                  if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    scheme_at = positional.index("scheme") if scheme_keywords and "scheme" in positional else None

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        for old, new in renamed.items():
            if old in kwargs:
                if new in kwargs:
                    raise TypeError(f"{name}() got both {old!r} and its new name {new!r}")
                warnings.warn(f"{name}(): the keyword {old!r} is now {new!r}; {old!r} will be "
                              "removed in the next release", DeprecationWarning, stacklevel=2)
                kwargs[new] = kwargs.pop(old)
        if valid is not None:
            for key in kwargs:
                if key not in valid:
                    extra = _file_scheme_parameters(kwargs, args, scheme_at)
                    if key not in extra:
                        raise unknown_keyword(name, key, valid | set(renamed) | extra)
        token = _CALL.set(name) if _CALL.get() is None else None
        try:
            with warning_scope():
                return function(*args, **kwargs)
        finally:
            if token is not None:
                _CALL.reset(token)

    wrapper.__dtdyn_public__ = True
    return wrapper


def _file_scheme_parameters(kwargs, args, scheme_at) -> set:
    """The parameters of a scheme file's scheme passed as ``scheme`` (empty set otherwise)."""
    from dtdyn._engine.scheme_files import FileScheme

    scheme = kwargs.get("scheme")
    if scheme is None and scheme_at is not None and len(args) > scheme_at:
        scheme = args[scheme_at]
    return set(scheme.params) if isinstance(scheme, FileScheme) else set()


@contextlib.contextmanager
def warning_scope():
    """Within it, each distinct warning raised through `warn` is shown once (as within one
    public call); the `dtdyn` command runs each command in one scope."""
    token = _SEEN.set(set()) if _SEEN.get() is None else None
    try:
        yield
    finally:
        if token is not None:
            _SEEN.reset(token)


def caller_stacklevel() -> int:
    """The ``stacklevel`` for `warnings.warn` called here that names the first frame outside
    the dtdyn package (the user's line)."""
    frame, level = sys._getframe(1), 1
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE_DIR):
        frame, level = frame.f_back, level + 1
    return level


def warn(message, category=UserWarning) -> None:
    """`warnings.warn` at the user's line, once per distinct (category, message) within one
    outermost public call."""
    seen = _SEEN.get()
    if seen is not None:
        key = (category, str(message))
        if key in seen:
            return
        seen.add(key)
    warnings.warn(message, category, stacklevel=caller_stacklevel())
