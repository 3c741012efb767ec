"""Every public name of `dtdyn` has a numpydoc docstring (Parameters or Attributes, and an
Examples section) whose parameters match its signature (numpydoc's validation), and the examples
run and print what they show."""
import doctest
import inspect

import pytest
from numpydoc.validate import Validator, get_doc_object, validate

import dtdyn

NAMES = [n for n in dtdyn.__all__ if n != "__version__"]
ERRORS = [n for n in NAMES if isinstance(getattr(dtdyn, n), type)
          and issubclass(getattr(dtdyn, n), BaseException)]


@pytest.mark.parametrize("name", NAMES)
def test_docstring_sections(name):
    doc = inspect.getdoc(getattr(dtdyn, name)) or ""
    assert len(doc) > 40, name
    if name in ERRORS:
        return
    assert "Parameters" in doc or "Attributes" in doc, name
    assert "Examples\n--------\n>>> " in doc, name


@pytest.mark.parametrize("name", [n for n in NAMES if n not in ERRORS])
def test_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    finder = doctest.DocTestFinder(recurse=False)
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS)
    tests = finder.find(getattr(dtdyn, name), name)
    assert tests and tests[0].examples, name
    for test in tests:
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, name


#: numpydoc's checks of the parameters: GL08 no docstring, PR01 a parameter of the signature not
#: documented, PR02 a documented parameter not in the signature, PR03 the parameters documented
#: in another order than the signature's, PR10 "name: type" (the space before the colon
#: missing: numpydoc then reads the whole line as a name)
CHECKS = ("GL08", "PR01", "PR02", "PR03", "PR10")


def _names(section):
    """The names of a numpydoc section's entries ("i, j : int" documents i and j)."""
    return {n.strip().lstrip("*") for entry in section for n in entry.name.split(",")}


@pytest.mark.parametrize("name", [n for n in NAMES if n not in ERRORS])
def test_parameters_match_signature(name):
    """numpydoc.validate on the public name; the signature is the function's own (the keyword
    check of `dtdyn._engine.public` keeps it as ``__wrapped__``). A class documents its
    constructor's parameters under Parameters or, for the fields of a dataclass that the user
    reads back, under Attributes; a parameter whose name starts with ``_`` is private."""
    obj = getattr(dtdyn, name)
    errors = [f"{code}: {message}" for code, message in validate(f"dtdyn.{name}")["errors"]
              if code in CHECKS and not (code == "PR01" and inspect.isclass(obj))]
    if inspect.isclass(obj):
        validator = Validator(get_doc_object(obj))
        documented = {p.lstrip("*") for p in validator.doc_all_parameters}
        documented |= _names(validator.doc["Attributes"])
        missing = [p for p in validator.signature_parameters
                   if p.lstrip("*") not in documented and not p.lstrip("*").startswith("_")]
        if missing:
            errors.append(f"PR01: the constructor's {missing} are documented neither under "
                          "Parameters nor under Attributes")
    assert not errors, "\n".join([name] + errors)


def test_parameter_check_sees_wrapped_signatures():
    """The check compares with the real signature, not the keyword-check wrapper's
    (*args, **kwargs): an undocumented parameter of a wrapped function is found."""
    assert hasattr(dtdyn.mck_response, "__wrapped__")
    params = Validator(get_doc_object(dtdyn.mck_response)).signature_parameters
    assert params[:5] == ("M", "C", "K", "force", "dt") and "**scheme_params" in params

    def undocumented(a, b):
        """Do nothing.

        Parameters
        ----------
        a : int
            Documented.
        c : int
            Not a parameter.
        """
    codes = {code for code, _ in Validator(get_doc_object(undocumented)).parameter_mismatches}
    assert codes == {"PR01", "PR02"}


def test_parameter_check_sees_the_order():
    """PR03: parameters documented in another order than the signature's are found (the
    order a reader compares with the call)."""
    def swapped(a, b):
        """Do nothing.

        Parameters
        ----------
        b : int
            Second.
        a : int
            First.
        """
    codes = {code for code, _ in Validator(get_doc_object(swapped)).parameter_mismatches}
    assert codes == {"PR03"} and "PR03" in CHECKS
