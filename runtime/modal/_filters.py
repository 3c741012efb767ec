"""Forced response as a bank of modal digital filters.

Each selected mode of the receptance H(s) = sum_r R_r/(s - s_r) + conj has the recursion
eta_n = e^{sT} eta_{n-1} + c0 x_{n-1} + c1 x_n, with c0, c1 from dtdyn.generated.modal_filters.
Two equivalent ways to run it over the whole record (``method``):

- "modes": one complex state per mode (per factor of its residue R_r = sum_k u_k v_k^T: one
  factor for a model from M, C, K), driven by the modal input p = v^T x and updated in increment
  form eta <- eta + (d eta + c0 p_{n-1} + c1 p_n), d = e^{sT} - 1, in the generated C kernel
  modal_states.c; the outputs y = sum_r w_r Re(u_r eta_r) (w = 2 for a conjugate pair) come from
  one matrix product per block of samples. Work: one recursion per mode and input factor plus
  an (n_samples x 2 n_states) @ (2 n_states x n_outputs) product.
- "sections": one real second-order section per (mode, output, input) (a real pole, one
  first-order section), as exported by `to_sos`, run by the generated C kernel filter_bank.c.
  Work: n_modes n_outputs n_inputs sections.

"auto" (`choose_method`) estimates both run times: "modes" unless there are only a few modes and
outputs (benchmarks/modal_filter_speed.py: P3, 15 modes, is faster by modes with one output
and with all 15).
The two agree to round-off over short records; over long records of lightly damped modes the
per-mode form is the more accurate: a section stores a1 = -2 e^{sigma T} cos(omega T), whose
rounding moves the pole angle omega T by ~ eps/(omega T), a frequency error that grows into a
phase error ~ n eps/(omega T) after n samples, while d is stored to ~ eps |d| (~ n eps |sT| after
n samples).

Quantities: displacement uses the residues R_r; velocity s_r R_r plus the constant
sum_r 2 Re R_r; acceleration s_r^2 R_r plus sum_r 2 Re(s_r R_r) (= M^-1 with every mode). The
remaining term of the acceleration, s sum_r 2 Re R_r, is zero for a complete mode set of a
mechanical system and is dropped for a truncated one (part of the truncation error).

Force convention: samples x_n at t_n = n dt (fs = 1 / dt), shape (n_samples, len(force_dofs));
the filters start at rest with x_{-1} = 0 (the ramp invariant then assumes the force ramps up
from 0 over the sample before t_0: start records at zero force to compare with `exact_response`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np

from dtdyn.generated import modal_filters as coef

from dtdyn._engine import ground as support
from dtdyn._engine import linalg
from dtdyn._engine import cbuild
from dtdyn._engine import validate
from dtdyn._engine.result import Response
from dtdyn._engine.stepping import check_quantities
from dtdyn.modal._model import ModalModel, modal_model, quantity_name

QUANTITIES = ("displacement", "velocity", "acceleration")
METHODS = ("auto", "modes", "sections")
#: relative imaginary part of a mode shape (turned to make its largest entry real) below which
#: it is round-off and dropped (the per-mode outputs then use only the real parts of the states)
REAL_SHAPE_TOLERANCE = 1e-13
#: rough run time per sample, in ns, of a section update, a state update and the product of one
#: state part with one output, measured by benchmarks/modal_filter_speed.py (2-core x86_64); used
#: by `choose_method` for method="auto"
COST_NS = {"c": {"section": 5.0, "state": 2.0, "product": 0.3},
           "numpy": {"section": 9.0, "state": 50.0, "product": 0.5}}
#: samples per block of the NumPy (scipy.signal.lfilter) per-mode fallback
_LFILTER_BLOCK = 1 << 16


def quantity_residues(model: ModalModel, quantity: str):
    """Residues of the asked quantity, (n_modes, n_out, n_in), and its direct (feedthrough) term,
    (n_out, n_in): R_r, s_r R_r or s_r^2 R_r (module docstring)."""
    s = model.poles[:, None, None]
    R = model.residues
    weight = np.where(model.oscillatory, 2.0, 1.0)[:, None, None]  # a pair counts twice
    quantity = quantity_name(quantity)
    if quantity == "displacement":
        return R, np.zeros(R.shape[1:])
    if quantity == "velocity":
        return s * R, np.sum(weight * R.real, axis=0)
    if quantity == "acceleration":
        return s * s * R, np.sum(weight * (s * R).real, axis=0)
    raise AssertionError(quantity)  # quantity_name refused anything else


def sections(model: ModalModel, fs: float, invariant="ramp", quantity="displacement"):
    """All sections of the bank: ``(sos, in_col, out_col, direct)``.

    ``sos`` has rows (b0, b1, b2, a1, a2) (scipy's a0 = 1 omitted), one per mode and
    (output, input) pair; ``direct`` (n_out, n_in) multiplies the current sample.
    """
    fs = validate.positive_scalar("fs", fs)
    T = 1.0 / fs
    R, direct = quantity_residues(model, quantity)
    n_modes, n_out, n_in = R.shape
    poles = model.poles[:, None, None] * np.ones((1, n_out, n_in))
    osc = np.broadcast_to(model.oscillatory[:, None, None], R.shape)
    parts = np.empty(R.shape + (5,))
    if osc.any():
        parts[osc] = np.stack(coef.pair_sections(invariant, poles[osc], R[osc], T), axis=-1)
    if (~osc).any():
        parts[~osc] = np.stack(coef.real_sections(invariant, poles[~osc], R[~osc].real, T), -1)
    out_col, in_col = np.meshgrid(np.arange(n_out), np.arange(n_in), indexing="ij")
    return (parts.reshape(-1, 5), np.tile(in_col.ravel(), n_modes).astype(np.int64),
            np.tile(out_col.ravel(), n_modes).astype(np.int64), direct)


def to_sos(model: ModalModel, dt: float, output: int = 0, input: int = 0, invariant="ramp",
           quantity="x") -> np.ndarray:
    """The sections of one (output, input) pair as a scipy.signal sos array (n_sections, 6).

    ``dt`` is the sample step, ``output``, ``input`` index ``model.outputs``,
    ``model.force_dofs``; ``quantity`` is "x", "v" or "a". The bank adds these sections in
    parallel (plus the direct term); scipy's sosfilt cascades its rows, so filter each row
    separately and sum to reproduce the bank.

    Parameters
    ----------
    model : ModalModel
    dt : float
        Sample step, s.
    output, input : int
        Indices into ``model.outputs`` and ``model.force_dofs``.
    invariant : {"ramp", "step", "impulse"}
    quantity : {"x", "v", "a"}

    Returns
    -------
    (n_modes, 6) ndarray
        scipy.signal sos rows (b0, b1, b2, 1, a1, a2).

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> model = dd.modal_model(np.eye(1), 0.2 * np.eye(1), 4.0 * np.eye(1))
    >>> dd.to_sos(model, 0.01).shape
    (1, 6)
    """
    sos, in_col, out_col, _ = sections(model, 1.0 / validate.positive_scalar("dt", dt),
                                       invariant, quantity)
    keep = (in_col == input) & (out_col == output)
    rows = sos[keep]
    return np.column_stack([rows[:, :3], np.ones(len(rows)), rows[:, 3:]])


@dataclass(frozen=True, eq=False)
class ModalStates:
    """The per-mode form of the bank: one complex state per mode and residue factor.

    Attributes
    ----------
    mode : int ndarray (m,)
        Index of the state's mode in the model (m = number of states).
    poles : complex ndarray (m,)
        s_j of the state's mode (imaginary part 0 for a real pole).
    increment : complex ndarray (m,)
        d_j = e^{s_j T} - 1, evaluated as z phi1(z) (z = s_j T), without cancellation.
    c0, c1 : complex ndarray (m,)
        Weights of x_{n-1} and x_n for a unit residue (generated forced_coefficients).
    inputs : complex ndarray (m, n_in)
        v_j: the state's modal input is p_j = v_j . x.
    weights : complex ndarray (m, n_out)
        w_j u_j (w = 2 for a conjugate pair, 1 for a real pole): y = Re(eta @ weights) + D x.
    direct : ndarray (n_out, n_in)
        D, the direct term (zero for displacement).

    The residues of the quantity are R_r = sum over the states j of mode r of outer(u_j, v_j).
    """

    mode: np.ndarray
    poles: np.ndarray
    increment: np.ndarray
    c0: np.ndarray
    c1: np.ndarray
    inputs: np.ndarray
    weights: np.ndarray
    direct: np.ndarray

    @property
    def n_states(self) -> int:
        return int(self.mode.size)


def _residue_factors(R: np.ndarray):
    """(mode, u, v) with R[r] = sum over the j with mode[j] = r of outer(u[j], v[j]).

    One factor per mode for one input or one output; otherwise the SVD of each R_r, keeping the
    singular values above max(n_out, n_in) eps times the largest (a residue of `modal_model` is
    rank one: psi_q x_f). Each u is then turned so that its largest entry is real (v turned
    back); when what remains of its imaginary part is below REAL_SHAPE_TOLERANCE times its
    largest entry (real mode shapes: undamped or proportionally damped, up to the eigensolver's
    round-off), it is dropped, and the outputs need only the real parts of the states.
    """
    n_modes, n_out, n_in = R.shape
    if n_in == 1:
        r, u, v = np.arange(n_modes), R[:, :, 0], np.ones((n_modes, 1), complex)
    elif n_out == 1:
        r, u, v = np.arange(n_modes), np.ones((n_modes, 1), complex), R[:, 0, :]
    else:
        U, S, Vh = np.linalg.svd(R, full_matrices=False)
        keep = S > max(n_out, n_in) * np.finfo(float).eps * S[:, :1]
        r, k = np.nonzero(keep)
        u, v = U[r, :, k], S[r, k, None] * Vh[r, k, :]
    size = np.abs(u).max(axis=1)
    big = u[np.arange(r.size), np.argmax(np.abs(u), axis=1)]
    turn = np.where(size > 0, big / np.where(size > 0, np.abs(big), 1.0), 1.0)
    u = u * np.conj(turn)[:, None]
    v = v * turn[:, None]
    real = np.abs(u.imag).max(axis=1) <= REAL_SHAPE_TOLERANCE * size
    u[real] = u[real].real
    return r, u, v


def modal_states(model: ModalModel, fs: float, invariant="ramp",
                 quantity="displacement") -> ModalStates:
    """The per-mode recursions of the bank (module docstring, method "modes").

    Each state runs eta_n = eta_{n-1} + (d eta_{n-1} + c0 p_{n-1} + c1 p_n), p = v . x, with the
    same c0, c1 (unit residue) as `sections`; y_n = Re(eta_n @ weights) + direct x_n.
    """
    fs = validate.positive_scalar("fs", fs)
    T = 1.0 / fs
    R, direct = quantity_residues(model, quantity)
    mode, u, v = _residue_factors(R)
    poles = model.poles[mode]
    c0, c1 = coef.forced_coefficients(invariant, poles, np.ones_like(poles), T)
    z = poles * T
    increment = z * coef.phi(z)[0]  # e^z - 1 = z phi1(z): the definition of phi1
    w = np.where(model.oscillatory[mode], 2.0, 1.0)
    return ModalStates(mode, poles, increment, c0, c1, np.asarray(v, complex),
                       w[:, None] * u, direct)


@cache
def _c_bank():
    source = resources.files("dtdyn.generated").joinpath("filter_bank.c").read_text()
    lib = cbuild.load_library(source, "filter_bank")
    if lib is None:
        return None
    cbuild.bind(lib, "dtdyn_filter_bank")
    return lib


@cache
def _c_modes():
    source = resources.files("dtdyn.generated").joinpath("modal_states.c").read_text()
    lib = cbuild.load_library(source, "modal_states")
    if lib is None:
        return None
    fn = cbuild.bind(lib, "dtdyn_modal_filters")
    cbuild.bind(lib, "dtdyn_modal_filters_work")
    cbuild.bind(lib, "dtdyn_modal_filters_lanes")
    return fn, lib.dtdyn_modal_filters_lanes, lib.dtdyn_modal_filters_work, lib


def run_bank(sos, in_col, out_col, direct, x, n_out, backend="c"):
    """y (n, n_out) = sum of the sections applied to the columns of x (n, n_in) + x direct^T.

    Each output is accumulated in a contiguous row (y is returned as the transpose of an
    (n_out, n) array, i.e. Fortran-ordered; its values do not depend on the layout).
    """
    x = np.asarray(x, dtype=float)
    n, n_in = x.shape
    sos = np.ascontiguousarray(sos, dtype=float)
    in_col = np.ascontiguousarray(in_col, dtype=np.int64)
    out_col = np.ascontiguousarray(out_col, dtype=np.int64)
    yt = np.zeros((n_out, n))
    lib = _c_bank() if backend == "c" else None
    if lib is None:
        from scipy.signal import lfilter

        for (b0, b1, b2, a1, a2), i, o in zip(sos, in_col, out_col):
            yt[o] += lfilter([b0, b1, b2], [1.0, a1, a2], x[:, i])
    elif len(sos):
        xt = np.ascontiguousarray(x.T)
        state = np.zeros(2 * len(sos))
        args = (n, n_in, n_out, len(sos), sos.ctypes.data, in_col.ctypes.data,
                out_col.ctypes.data, xt.ctypes.data, yt.ctypes.data, state.ctypes.data)
        cbuild.interruptible(lib, lambda: lib.dtdyn_filter_bank(*args), work=n * len(sos))
    y = yt.T
    if np.any(direct):
        y += x @ np.asarray(direct).T
    return y


def run_modes(states: ModalStates, x, backend="c", at_rest_under=None, timing=None):
    """y (n, n_out) of the per-mode recursions (`modal_states`) over the columns of x (n, n_in).

    The states start at zero with x_{-1} = 0: for the ramp invariant that is a force ramping
    up from 0 at t_{-1}, so eta_0 = c1 p_0. ``at_rest_under`` = x_0 starts them instead at
    eta_{-1} = -c1 p_0 / e^{sT}, i.e. eta_0 = 0: the system at rest at t_0 under the force x_0
    (what `exact_response` and the schemes assume).

    C (generated modal_states.c): all states advance together, sample by sample, over a block
    of samples; then each output is accumulated over the block from the states (module
    docstring), written contiguously. NumPy: scipy.signal.lfilter per state with the pole
    e^{sT} = 1 + d, outputs by a matrix product. ``timing``: a list that receives the C
    kernel's own run time (`cbuild.interruptible`).
    """
    x = np.ascontiguousarray(x, dtype=float)
    n, n_in = x.shape
    m = states.n_states
    n_out = states.weights.shape[1]
    y = np.zeros((n, n_out))
    c = _c_modes() if backend == "c" else None
    eta0 = np.zeros(m, complex)  # the states before sample 0 (eta_{-1})
    if at_rest_under is not None:
        eta0 = -states.c1 * (states.inputs @ np.asarray(at_rest_under, float)) / (
            1.0 + states.increment)
    if m and c is None:
        from scipy.signal import lfilter

        # lfilter's state before sample 0 for b = [c1, c0], a = [1, -e^{sT}] with x_{-1} = 0
        zi = ((1.0 + states.increment) * eta0)[:, None]
        a = np.stack([np.ones(m), -(1.0 + states.increment)], axis=1)
        b = np.stack([states.c1, states.c0], axis=1)
        v, W = states.inputs, states.weights
        w2 = np.concatenate([W.real, -W.imag])  # y = Re(eta) W_re - Im(eta) W_im
        for start in range(0, n, _LFILTER_BLOCK):
            xb = x[start:start + _LFILTER_BLOCK].T
            p = v.real @ xb + 1j * (v.imag @ xb)  # (m, block): one contiguous row per state
            for j in range(m):
                p[j], zi[j] = lfilter(b[j], a[j], p[j], zi=zi[j])
            y[start:start + xb.shape[1]] = np.concatenate([p.real, p.imag]).T @ w2
    elif m:
        fn, lanes, work_size, lib = c
        mp = m + (-m % lanes(m))  # zero states up to a multiple of the kernel's chunk

        def padded(v):
            out = np.zeros((mp,) + v.shape[1:], complex)
            out[:m] = v
            return out

        d = padded(states.increment)
        g = [padded(cj[:, None] * states.inputs) for cj in (states.c0, states.c1)]
        coefs = np.concatenate([d.real, d.imag,
                                *(part.T.ravel() for gj in g for part in (gj.real, gj.imag))])
        W = padded(states.weights)
        wt = np.concatenate([W.real, -W.imag]).T.copy()  # (n_out, 2 mp): y = E_re W_re - E_im W_im
        im_out = int(np.any(W.imag))
        xp = np.concatenate([np.zeros((1, n_in)), x])  # row 0: x_{-1} = 0 (at rest)
        e = np.concatenate([padded(eta0).real, padded(eta0).imag])
        work = np.empty(work_size(mp, n_out))  # 2 mp (c_api.MODAL_BLOCK + n_out) doubles
        args = (n, mp, n_in, n_out, im_out, coefs.ctypes.data, wt.ctypes.data, xp.ctypes.data,
                e.ctypes.data, y.ctypes.data, work.ctypes.data, work.size)
        rc = cbuild.interruptible(lib, lambda: fn(*args), work=n * mp * (n_in + n_out),
                                  timing=timing)
        if rc != 0:
            from dtdyn._engine.kernels import DtdynKernelError

            raise DtdynKernelError("dtdyn_modal_filters", rc, f"m = {mp}, n_out = {n_out}, "
                                   f"n_work = {work.size}")
    if np.any(states.direct):
        y += x @ states.direct.T
    return y


def choose_method(states: ModalStates, n_sections: int, backend="c") -> str:
    """"modes" or "sections", whichever `COST_NS` estimates to be the faster.

    Per sample: the bank costs its n_sections = n_modes n_out n_in section updates; the
    per-mode form costs its states (C: padded to the kernel's chunk of states) plus the products
    with the mode shapes (one or two state parts per state and output). The per-mode form wins
    except with a few modes and outputs (and with the NumPy backend, whose complex lfilter is
    slow, with few outputs).
    """
    n_out = states.weights.shape[1]
    c = _c_modes() if backend == "c" else None
    cost = COST_NS["c" if c is not None and _c_bank() is not None else "numpy"]
    n_states = states.n_states
    if c is not None:
        chunk = c[1](n_states)
        n_states = -(-n_states // chunk) * chunk
    parts = 2 if np.any(states.weights.imag) else 1
    modes = n_states * (cost["state"] + parts * n_out * cost["product"])
    return "modes" if modes <= cost["section"] * n_sections else "sections"


#: samples per block of the free response (its exponentials are samples x modes)
_FREE_BLOCK = 1 << 14


def _free_response(M, C, K, outputs, modes, x0, v0, t, quantities):
    """x, v, a at the outputs of M q'' + C q' + K q = 0 from q(0) = x0, q'(0) = v0:

        q(t) = sum_r e^{s_r t} R_r (M v0 + C x0 + s_r M x0)   (+ conjugates),

    R_r the residues from every DOF (Laplace transform of the equations with their initial
    state, H(s) = sum_r R_r / (s - s_r)); v and a multiply each term by s_r and s_r^2."""
    M, C, K = linalg.mck(M, C, K)
    n = M.shape[0]
    x0, v0 = validate.initial_conditions(x0, v0, n)
    full = modal_model(M, C, K, None, outputs)
    if modes is not None:
        full = full.select(modes)
    s = full.poles
    weight = np.where(full.oscillatory, 2.0, 1.0)          # a pair's conjugate: 2 Re(.)
    load = (M @ v0 + C @ x0)[None, :] + s[:, None] * (M @ x0)[None, :]   # (modes, n)
    coef = weight[:, None] * np.einsum("rij,rj->ri", full.residues, load)  # (modes, n_out)
    power = {"x": 0, "v": 1, "a": 2}
    out = {q: np.empty((t.size, outputs.size)) for q in quantities}
    for start in range(0, t.size, _FREE_BLOCK):
        E = np.exp(np.outer(t[start:start + _FREE_BLOCK], s))
        for q in quantities:
            out[q][start:start + E.shape[0]] = (E @ (s[:, None] ** power[q] * coef)).real
    return out


def modal_filter_response(M, C, K, force, dt, *, force_dofs=None, outputs=None,
                          quantities=("x", "v", "a"), modes=None, invariant="ramp",
                          algorithm="auto", backend="c", ground_acceleration=None,
                          ground_velocity=None, ground_displacement=None,
                          influence=None, x0=None, v0=None) -> Response:
    """Response of M q'' + C q' + K q = f by modal digital filters.

    Parameters
    ----------
    M, C, K : (N, N) array_like
        Mass (nonsingular), damping (general), stiffness.

    force : array_like, shape (n_steps + 1, len(force_dofs))
        Force samples at t_k = k dt on the 0-based DOFs ``force_dofs`` (all DOFs when None); the
        system is at rest at t_0 (also when force[0] != 0).

    dt : float
        Sample step, s (the filters' sampling rate is 1 / dt).

    force_dofs, outputs : sequence of int, optional
        Loaded DOFs and stored DOFs (all DOFs when None).

    quantities : subset of ("x", "v", "a")
        What is stored; each quantity is one run of the filters (its own residues).

    modes : sequence of int, optional
        Indices of the modes to keep, sorted by frequency (all by default).

    invariant : {"ramp", "step", "impulse"}
        How the force is rebuilt between samples: linear (exact for a piecewise-linear force;
        spectrum bias (sin(pi f dt)/(pi f dt))^2, no phase error), held (half-sample lag),
        impulses (aliasing).

    algorithm : {"auto", "modes", "sections"}
        One recursion per mode, outputs combined by a matrix product ("modes"), or one
        second-order section per mode, output and input ("sections", the filters of `to_sos`);
        "auto": the one `choose_method` estimates to be the faster. Same results to round-off
        over short records; "modes" drifts less over long ones (module docstring).

    backend : {"c", "numpy"}
        The generated C kernels, or scipy.signal.lfilter (also used when no compiler is found).

    ground_acceleration : (n_steps + 1,) or (n_steps + 1, n_dir) array_like, optional
        Support acceleration at the force's times, linear between samples: the DOFs are then
        relative to the support, loaded by f - M r a_g, and the result adds ``a_abs``
        (``force`` may be None).

    ground_velocity, ground_displacement : array_like, optional
        Instead of ``ground_acceleration`` (one ground record at most): the support velocity
        (m/s) or displacement (m), shaped like it, turned direction by direction into the
        acceleration record linear between samples whose motion passes through it
        (`ground_acceleration_from`); a displacement record also gives ``x_abs = x + r u_g``.

    influence : (N,) or (N, n_dir) array_like, optional
        r, each DOF's motion per unit support motion (default: ones).

    x0, v0 : (N,) array_like, optional
        Initial displacement and velocity (rest when None): their free response, the residue
        sum of the module docstring of `dtdyn.modal._model` applied to M v0 + C x0 + s_r M x0,
        is added (with ``modes``, of the kept modes only).

    Returns
    -------
    Response
        ``t`` and ``x``, ``v``, ``a`` (those asked for) of shape (n_steps + 1, len(outputs));
        ``info`` says which algorithm and backend ran ("filters": "modes" or "sections") and
        the times.

    Examples
    --------
    >>> import numpy as np, dtdyn as dd
    >>> M, C, K = np.diag([2.0, 1.0]), np.diag([0.5, 0.2]), np.array([[30.0, -10], [-10, 10]])
    >>> r = dd.modal_filter_response(M, C, K, np.ones(1001), 0.01, force_dofs=[1],
    ...                              quantities=("x",))
    >>> r.x.shape
    (1001, 2)

    References
    ----------
    Ahlin, Magnevall & Josefsson (2006), Simulation of forced response in linear and nonlinear
    mechanical systems using digital filters, ISMA.
    """
    if algorithm not in METHODS:
        raise ValueError(f"algorithm must be one of {METHODS}, got {algorithm!r}")
    quantities = check_quantities(quantities)
    grounded = support.given(ground_acceleration, ground_velocity, ground_displacement)
    M_ = None if grounded is None else linalg.mck(M, C, K)[0]
    n_dof = linalg.square_matrix("M", M, keep_sparse=True).shape[0]  # M checked, then sized
    force, force_dofs, ground = support.prepare(M_, force, force_dofs, n_dof,
                                                ground_acceleration, influence, dt=dt,
                                                ground_velocity=ground_velocity,
                                                ground_displacement=ground_displacement)
    if x0 is not None or v0 is not None:  # checked before the run, used after it
        validate.initial_conditions(x0, v0, n_dof)
    model = modal_model(M, C, K, force_dofs, outputs)
    if modes is not None:
        model = model.select(modes)
    dt = validate.positive_scalar("dt", dt)
    f = validate.force_record(force, model.force_dofs.size)
    fs = 1.0 / dt
    n_out, n_in = model.outputs.size, model.force_dofs.size
    validate.output_size("modal_filter_response", f.shape[0], n_out * len(quantities))
    n_sec = model.n_modes * n_out * n_in
    # at rest at t_0 under f_0: the ramp invariant's filters would start from a ramp from 0 at
    # t_{-1} (run_modes); the step invariant is at rest already, the impulse one models an
    # impulse T f_0 at t_0 (cont2discrete's "impulse" convention)
    rest = f[0] if invariant == "ramp" and np.any(f[0]) else None
    store, setup, run = {}, 0.0, 0.0
    for q in quantities:
        quantity = quantity_name(q)
        t0 = time.perf_counter()
        states = modal_states(model, fs, invariant, quantity) if algorithm != "sections" else None
        use = choose_method(states, n_sec, backend) if algorithm == "auto" else algorithm
        kernel = []  # the C kernels' own times (without the Python around them)
        if use == "modes":
            t1 = time.perf_counter()
            store[q] = run_modes(states, f, backend, at_rest_under=rest, timing=kernel)
            c_ok = _c_modes() is not None
        else:
            sos, in_col, out_col, direct = sections(model, fs, invariant, quantity)
            t1 = time.perf_counter()
            store[q] = run_bank(sos, in_col, out_col, direct, f, n_out, backend)
            if rest is not None:  # the free response that brings the bank to rest at t_0
                states = modal_states(model, fs, invariant, quantity)
                store[q] += run_modes(states, np.zeros_like(f), backend, at_rest_under=rest,
                                      timing=kernel)
            c_ok = _c_bank() is not None
        wall = time.perf_counter() - t1
        kernel_time = sum(kernel) if kernel else wall  # else the whole call (NumPy, sections)
        run += kernel_time
        setup += (t1 - t0) + (wall - kernel_time)
    if x0 is not None or v0 is not None:
        free = _free_response(M, C, K, model.outputs, modes, x0, v0,
                              dt * np.arange(f.shape[0]), store)
        for q in store:
            store[q] = store[q] + free[q]
    validate.finite_response("modal_filter_response", dt, *store.values())
    response = Response(dt * np.arange(f.shape[0]), model.outputs, store.get("x"), store.get("v"),
                        store.get("a"),
                        info={"method": f"modal filters ({invariant} invariant)", "filters": use,
                              "dt": dt, "n_steps": f.shape[0] - 1, "modes": int(model.poles.size),
                              "states": states.n_states if use == "modes" else None,
                              "sections": n_sec, "setup_time": setup, "run_time": run,
                              "backend": "c" if backend == "c" and c_ok else "scipy.lfilter"})
    return support.finish(response, ground)
