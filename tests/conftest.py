"""Shared models and markers for the four tiers of tests:

    symbolic/        the SymPy derivations against hand formulas (identities)
    generated_code/  the generated NumPy and C kernels against hand formulas, and their build
    behaviour/       the runtime against independent truths (matrix exponential, solve_ivp,
                     scipy.signal, closed forms) and convergence orders
    application/     the public face, scenes, results, the command, the README and docstrings

Helpers shared by several files (reference problems as dicts, `rel_error`, `uniform_chain`) are
in tests/problems.py; the reference problems themselves are defined once, in dtdyn.app._problems.
`-m "not slow"` leaves out the few tests that take several seconds.
"""
import pytest

import problems


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: takes several seconds (deselect with -m 'not slow')")


@pytest.fixture(scope="session")
def p2():
    """P2 (dtdyn.problem("P2")): the 2-DOF chain with M, C, K."""
    return problems.p2()


@pytest.fixture(scope="session")
def p3():
    """P3 (dtdyn.problem("P3")): the undamped 15-DOF chain with M, C, K."""
    return problems.p3()
