"""Every public name of `dtdyn` has a numpydoc docstring (Parameters or Attributes, and an
Examples section), and the examples run and print what they show."""
import doctest
import inspect

import pytest

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
