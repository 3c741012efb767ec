"""Bad input gets a clear error naming the field and the value."""
import numpy as np
import pytest

from dtdyn.linear import chain_response, mck_response

M, K, C = [2.0, 3.0], [20.0, 15.0], [5.0, 6.0]
F = np.ones((11, 1))


def run(**kw):
    args = dict(mass=M, stiffness=K, damping=C, force=F, dt=0.01, force_dofs=[1])
    args.update(kw)
    return chain_response(**args)


@pytest.mark.parametrize("kw, words", [
    (dict(mass=[2.0, 0.0]), ["mass[1]", "0.0"]),
    (dict(mass=[2.0, -1.0]), ["mass[1]", "-1.0"]),
    (dict(stiffness=[20.0, -15.0]), ["stiffness[1]", "-15.0"]),
    (dict(damping=[-5.0, 6.0]), ["damping[0]", "-5.0"]),
    (dict(stiffness=[20.0]), ["stiffness", "length 1"]),
    (dict(force=np.array([[1.0]] * 5 + [[np.nan]] + [[1.0]] * 5)), ["force[5, 0]", "nan"]),
    (dict(force=np.full((11, 1), np.inf)), ["force[0, 0]", "inf"]),
    (dict(force=np.ones((1, 1))), ["force", "1 sample"]),
    (dict(force=np.ones((10, 2))), ["force", "(10, 2)"]),
    (dict(dt=0.0), ["dt", "0.0"]),
    (dict(dt=-1e-3), ["dt", "-0.001"]),
    (dict(force_dofs=[2]), ["force_dofs", "[2]"]),
    (dict(x0=[0.0, np.nan]), ["x0[1]", "nan"]),
    (dict(v0=[0.0]), ["v0", "length 1"]),
    (dict(outputs=[-1]), ["outputs", "[-1]"]),
    (dict(scheme="rk4"), ["unknown scheme", "'rk4'"]),
    (dict(scheme="central_difference", form="displacement"), ["explicit", "acceleration"]),
    (dict(scheme="newmark", beta=0.0, form="displacement"), ["explicit", "acceleration"]),
    (dict(scheme="newmark", gamma=0.4), ["gamma", "0.4"]),
    (dict(scheme="hht", alpha=0.2), ["alpha", "0.2"]),
    (dict(form="velocity"), ["form", "'velocity'"]),
    (dict(sweep="fast"), ["sweep", "'fast'"]),
    (dict(backend="gpu"), ["backend", "'gpu'"]),
    (dict(quantities=("x", "j")), ["quantities"]),
    (dict(scheme="central_difference", form="acceleration", damping=[5.0, 0.0]),
     ["damping[1]", "explicit"]),
    (dict(stiffness=[20.0, 0.0], damping=[5.0, 0.0]), ["station 1", "disconnected"]),
])
def test_chain_errors(kw, words):
    with pytest.raises(ValueError) as exc:
        run(**kw)
    for w in words:
        assert w in str(exc.value)


def test_parameter_of_another_scheme_is_a_type_error():
    with pytest.raises(TypeError, match=r"scheme 'wilson' takes parameters \(theta\), got beta"):
        run(scheme="wilson", beta=0.3)


def test_mck_errors():
    Mm, Cm, Km = np.diag(M), np.zeros((2, 2)), np.eye(2)
    with pytest.raises(ValueError, match="M is singular"):
        mck_response(np.zeros((2, 2)), Cm, Km, F, 0.01, force_dofs=[1])
    with pytest.raises(ValueError, match=r"K has shape \(3, 3\)"):
        mck_response(Mm, Cm, np.eye(3), F, 0.01, force_dofs=[1])
    with pytest.raises(ValueError, match=r"C\[0, 0\] = nan"):
        mck_response(Mm, np.full((2, 2), np.nan), Km, F, 0.01, force_dofs=[1])
