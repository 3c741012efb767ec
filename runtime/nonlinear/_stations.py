"""Shafts and beams with localized nonlinear elements at stations: O(N) per step.

The same condensed per-step problem as the chain (dtdyn.nonlinear._chain, its module docstring),
around the model's own linear step: the tree sweep of `shaft_response` (T = S phi + R from the
leaves to the root) or the 2 x 2 block Riccati sweep of `beam_response` on the whole node system
(held DOFs decoupled). The step is linear in the loads, so with the element forces g as loads
-L^T g the state after a step is H_lin + sum_e g_e U_e, U_e the step's response to element e's
unit load pair from rest (one sweep per element, once per run); the element deformations then
satisfy w - Dwg g(w, z) = Q, solved by Newton (`condensed_response`, the one loop of the chain,
the shaft and the beam). Each step: one sweep (O(N)), the Newton solve in the element unknowns,
an O(N n_e) update.

Elements address DOFs by index into the model's ``dof_names`` (`Shaft.dof`, `Beam.dof` map a
name to it: ``dd.Cubic(shaft.dof("main.3"), k3=...)``); a beam's indices are mapped to the node
system by ``beam.free`` as `beam_response` does for its outputs.
"""
from __future__ import annotations

import time

import numpy as np

from dtdyn._engine import ground as support
from dtdyn._engine import linalg, validate
from dtdyn._engine.result import Response
from dtdyn._engine.schemes import get_scheme
from dtdyn._engine.stepping import check_quantities
from dtdyn.nonlinear._chain import condensed_response
from dtdyn.nonlinear._elements import check_elements
from dtdyn.nonlinear._response import QUANTITIES


def _checked(model, n, dof_names, elements, substeps, scheme, scheme_params, backend,
             form, quantities):
    """The checks the shaft and the beam share: (elements, S, scheme info, quantities)."""
    quantities = check_quantities(quantities, QUANTITIES)
    elements = check_elements(elements)
    if not elements:
        raise ValueError(f"elements is empty: use simulate_{model} for a linear {model}")
    for e, el in enumerate(elements):
        for name, d in (("i", el.i), ("j", el.j)):
            if d is not None and d >= n:
                raise ValueError(f"elements[{e}] ({type(el).__name__}).{name} = {d} is outside "
                                 f"the {model}'s DOFs 0..{n - 1} (indices into {model}.dof_names"
                                 f"; {model}.dof({dof_names[-1]!r}) gives one by name)")
    S = validate.step_count("substeps", substeps)
    if backend not in ("c", "numpy"):
        raise ValueError(f"backend must be 'c' or 'numpy', got {backend!r}")
    if form not in ("displacement", "acceleration"):
        raise ValueError(f"form must be 'displacement' or 'acceleration', got {form!r}")
    info = get_scheme(scheme, **scheme_params)
    if info.startup_steps:
        raise ValueError(f"scheme {info.name!r} is multistep; the nonlinear {model} needs a "
                         "one-step scheme (newmark, hht, generalized_alpha, ...)")
    return elements, S, info, quantities


def _response(dt, outputs, dof_names, store, stats, quantities, info, form, S, backend, method,
              elements, t0, kind):
    n_samples = store["x"].shape[0]
    res = Response(dt * np.arange(n_samples), outputs,
                   **{q: store[q] if q in quantities else None for q in ("x", "v", "a")},
                   g=store["g"], z=store["z"],
                   info={"method": method, "scheme": info.name, "params": dict(info.params),
                         "form": form, "dt": dt, "n_steps": n_samples - 1, "substeps": S,
                         "backend": backend,
                         "elements": [el.describe() for el in elements],
                         "setup_time": stats.pop("setup_end") - t0, **stats})
    res.dof_names = tuple(dof_names[i] for i in outputs)
    # units of files and plots: kind(name) is "translation" or "rotation"; an element's force
    # and internal states take the kind of its DOF i
    res.dof_kinds = tuple(kind(n) for n in res.dof_names)
    res.element_kinds = tuple(kind(dof_names[el.i]) for el in elements)
    res.state_kinds = tuple(kind(dof_names[el.i]) for el in elements
                            for _ in range(el.n_internal))
    return res


def nonlinear_shaft_response(shaft, force, dt, *, elements, force_dofs=None, scheme="newmark",
                             form="displacement", substeps=1, outputs=None,
                             quantities=("x", "v", "a"), backend="c", tol=1e-12, max_iter=30,
                             ground_acceleration=None, ground_velocity=None,
                             ground_displacement=None, influence=None, x0=None, v0=None,
                             **scheme_params) -> Response:
    """Forced response of a shaft or tree with nonlinear elements by the DT-TMM tree sweep.

    Each step: one sweep of `shaft_response` (O(N)) and the condensed per-step problem in the
    element unknowns (module docstring); equal to `nonlinear_mck_response` on `shaft_matrices`
    (same scheme, same substeps) to rounding.

    Parameters
    ----------
    shaft : Shaft
        The linear model (its lumped form).
    force : array_like, shape (n_steps + 1, len(force_dofs))
        Torque samples (N m) at t_k = k dt, linear between samples; may be None under support
        motion.
    dt : float
        Sample step, s.
    elements : sequence of elements
        `Cubic`, `Polynomial`, `Gap`, `Law`, `BoucWen` with i, j indices into
        ``shaft.dof_names`` (``shaft.dof("main.3")``); j None: to the ground. A torsional
        element's y is a rotation (rad) and g a torque (N m).
    force_dofs : sequence of int or DOF names, optional
        As `shaft_response`; all DOFs when None.
    scheme, form, substeps
        As `nonlinear_chain_response`: a one-step scheme, "displacement" or "acceleration"
        form, steps per sample.
    outputs : sequence of int or DOF names, optional
        The DOFs stored, as ``force_dofs``; all DOFs when None.
    quantities, backend, tol, max_iter
        As `nonlinear_chain_response`: what to store (also "g", "z"), "c" (the generated C
        sweep and compiled residual inside the Python Newton loop) or "numpy", Newton's
        tolerance and iteration limit.
    ground_acceleration, ground_velocity, ground_displacement, influence : optional
        Support motion as in `shaft_response` (default influence `rigid_rotation`): the
        rotations, and so the elements' y, are relative to the supports.
    x0, v0
        As `nonlinear_chain_response`: initial rotations and rates.
    **scheme_params
        As `nonlinear_chain_response`: the scheme's parameters.

    Returns
    -------
    Response
        ``x``, ``v``, ``a`` of shape (n_steps + 1, len(outputs)), ``g``, ``z`` when asked,
        ``dof_names`` of the outputs, ``info`` with the Newton statistics.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> s = dd.Shaft([1.0, 2.0, 1.5], [1e4, 2e4, 2e4], [1.0, 1.0, 1.0])
    >>> bearing = dd.Cubic(s.dof("main.1"), k3=1e9)
    >>> r = dd.nonlinear_shaft_response(s, np.full(201, 50.0), 1e-3, force_dofs=["main.2"],
    ...                                 elements=[bearing])
    >>> r.x.shape, r.dof_names
    ((201, 3), ('main.0', 'main.1', 'main.2'))
    """
    from dtdyn.linear._shaft import (_advance_factory, _check_shaft, check_connections,
                                    rigid_rotation, shaft_matrices)
    t0 = time.perf_counter()
    _check_shaft(shaft)
    tree = shaft.tree
    N = tree.J.size
    dt = validate.positive_scalar("dt", dt)
    force, force_dofs, ground = support.prepare_model(
        np.diag(tree.J), force, force_dofs, tree.names, lambda k: rigid_rotation(shaft),
        dt=dt, ground_acceleration=ground_acceleration, ground_velocity=ground_velocity,
        ground_displacement=ground_displacement, influence=influence)
    force_dofs = validate.dof_indices("force_dofs", force_dofs, N)
    outputs = validate.dof_indices("outputs", outputs, N, names=tree.names)
    elements, S, info, quantities = _checked("shaft", N, tree.names, elements,
                                             substeps, scheme, scheme_params, backend, form,
                                             quantities)
    f = validate.force_record(force, force_dofs.size)
    x0, v0 = validate.initial_conditions(x0, v0, N)
    validate.output_size("nonlinear_shaft_response", f.shape[0], 3 * outputs.size)
    h = dt / S
    check_connections(tree, info, form, h)
    _, C, K = shaft_matrices(shaft)
    ei = np.array([el.i for el in elements], dtype=np.int64)
    ej = np.array([-1 if el.j is None else el.j for el in elements], dtype=np.int64)
    none = np.zeros(0, dtype=np.int64)

    def make_advance(loaded):
        return _advance_factory(backend, tree, h, loaded, none, form)(
            info, info.coefficients(form, h))

    def accel(f0):  # a_0 = J^-1 (f_0 - L^T g_0 - C v_0 - K x_0)
        return (f0 - C @ v0 - K @ x0) / tree.J

    store, stats = condensed_response(make_advance, N, info.history, elements, ei, ej,
                                      force_dofs, outputs, f, x0, v0, accel, S, h, quantities,
                                      tol, max_iter, backend)
    res = _response(dt, outputs, tree.names, store, stats, quantities, info, form, S, backend,
                    f"DT-TMM {info.name} ({form} form, tree sweep)", elements, t0,
                    lambda name: "rotation")
    return support.finish(res, ground)


def nonlinear_beam_response(beam, force, dt, *, elements, force_dofs=None, scheme="newmark",
                            form="displacement", substeps=1, outputs=None,
                            quantities=("x", "v", "a"), backend="c", tol=1e-12, max_iter=30,
                            ground_acceleration=None, ground_velocity=None,
                            ground_displacement=None, influence=None, x0=None, v0=None,
                            **scheme_params) -> Response:
    """Forced response of a `Beam` with nonlinear elements by the matrix Riccati sweep.

    Each step: one 2 x 2 block Riccati sweep of `beam_response` (O(N)) and the condensed
    per-step problem in the element unknowns (module docstring); equal to `nonlinear_mck_response`
    on `beam_matrices` (same scheme, same substeps) to rounding.

    Parameters
    ----------
    beam : Beam
    force : array_like, shape (n_steps + 1, len(force_dofs))
        Force (N) or moment (N m) samples at t_k = k dt, linear between samples; may be None
        under support motion.
    dt : float
        Sample step, s.
    elements : sequence of elements
        `Cubic`, `Polynomial`, `Gap`, `Law`, `BoucWen` with i, j indices into
        ``beam.dof_names`` (``beam.dof("w200")``); j None: to the ground. On a w DOF y is a
        deflection (m) and g a force; on a psi DOF a rotation and a moment.
    force_dofs : sequence of int or DOF names, optional
        As `beam_response`; all DOFs when None.
    scheme, form, substeps
        As `nonlinear_chain_response`.
    outputs : sequence of int or DOF names, optional
        The DOFs stored, as ``force_dofs``; all DOFs when None.
    quantities, backend, tol, max_iter
        As `nonlinear_chain_response`; backend "c": the generated C loop with the block
        Riccati sweep and the compiled residual inside the Python Newton loop; "numpy": a
        sparse LU of the same effective matrix.
    ground_acceleration, ground_velocity, ground_displacement, influence : optional
        Support motion as in `beam_response` (default influence: a rigid translation).
    x0, v0
        As `nonlinear_chain_response`, over ``beam.dof_names``.
    **scheme_params
        As `nonlinear_chain_response`: the scheme's parameters.

    Returns
    -------
    Response
        ``x``, ``v``, ``a`` of shape (n_steps + 1, len(outputs)), ``g``, ``z`` when asked,
        ``dof_names`` of the outputs, ``info`` with the Newton statistics.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> beam = dd.Beam(E=2.1e11, I=8e-6, rho_A=20.0, length=3.0, elements=20)
    >>> stop = dd.Gap(beam.dof("w20"), gap=1e-4, stiffness=1e7)
    >>> r = dd.nonlinear_beam_response(beam, np.full(201, 100.0), 1e-4, force_dofs=["w20"],
    ...                                elements=[stop], outputs=["w20"],
    ...                                quantities=("x", "g"))
    >>> r.x.shape, r.g.shape
    ((201, 1), (201, 1))
    """
    from dtdyn.linear import _mck as mck
    from dtdyn.linear._beam import Beam, beam_matrices, node_system, rigid_translation
    t0 = time.perf_counter()
    if not isinstance(beam, Beam):
        raise ValueError(f"beam must be a Beam, got {type(beam).__name__}")
    M, C, K = beam_matrices(beam)
    n = beam.n_dof
    dt = validate.positive_scalar("dt", dt)
    force, force_dofs, ground = support.prepare_model(
        M, force, force_dofs, beam.dof_names, lambda k: rigid_translation(beam, k), dt=dt,
        ground_acceleration=ground_acceleration, ground_velocity=ground_velocity,
        ground_displacement=ground_displacement, influence=influence)
    force_dofs = validate.dof_indices("force_dofs", force_dofs, n)
    outputs = validate.dof_indices("outputs", outputs, n, names=beam.dof_names)
    elements, S, info, quantities = _checked("beam", n, beam.dof_names, elements,
                                             substeps, scheme, scheme_params, backend, form,
                                             quantities)
    f = validate.force_record(force, force_dofs.size)
    x0, v0 = validate.initial_conditions(x0, v0, n)
    validate.output_size("nonlinear_beam_response", f.shape[0], 3 * outputs.size)
    h = dt / S
    Mg, Cg, Kg = node_system(beam)
    nf = Mg.shape[0]
    free = beam.free
    ei = free[[el.i for el in elements]]
    ej = np.array([-1 if el.j is None else free[el.j] for el in elements], dtype=np.int64)
    loop = mck._c_loop() if backend == "c" else None

    def make_advance(loaded):
        return mck.make_advance(form, info, info.coefficients(form, h), Mg, Cg, Kg, loaded,
                                np.zeros(0, dtype=np.int64), loop, blocks=loop is not None)

    def accel(f0):  # a_0 = M^-1 (f_0 - L^T g_0 - C v_0 - K x_0) on the kept DOFs
        a0 = np.zeros(nf)
        a0[free] = linalg.solver(M, "M")(f0[free] - C @ v0 - K @ x0)
        return a0

    full = [np.zeros(nf), np.zeros(nf)]
    full[0][free], full[1][free] = x0, v0
    store, stats = condensed_response(make_advance, nf, info.history, elements, ei, ej,
                                      free[force_dofs], free[outputs], f, *full, accel, S, h,
                                      quantities, tol, max_iter, backend)
    method = (f"DT-TMM {info.name} ({form} form, matrix Riccati sweep)" if loop is not None
              else f"{info.name} ({form} form, assembled matrices, sparse LU)")
    res = _response(dt, outputs, beam.dof_names, store, stats, quantities, info, form, S,
                    "c" if loop is not None else "numpy", method, elements, t0,
                    lambda name: "rotation" if name.startswith("psi") else "translation")
    return support.finish(res, ground)
