"""Forced response as a bank of modal digital filters (reference.md section 6).

Each selected mode of the receptance H(s) = sum_r R_r/(s - s_r) + conj becomes one real
second-order section (a real pole, one first-order section) whose coefficients come from
dtdyn.generated.modal_filters; the bank runs in a generated C kernel over the whole record.

Quantities: displacement uses the residues R_r; velocity s_r R_r plus the constant
sum_r 2 Re R_r; acceleration s_r^2 R_r plus sum_r 2 Re(s_r R_r) (= M^-1 with every mode). The
remaining term of the acceleration, s sum_r 2 Re R_r, is zero for a complete mode set of a
mechanical system and is dropped for a truncated one (part of the truncation error).

Force convention: samples x_n at t_n = n / fs, shape (n_samples, len(inputs)); the filters start
at rest with x_{-1} = 0 (the ramp invariant then assumes the force ramps up from 0 over the sample
before t_0: start records at zero force to compare with `exact_response`).
"""
from __future__ import annotations

import ctypes
import time
from functools import lru_cache
from importlib import resources

import numpy as np

from dtdyn.generated import modal_filters as coef

from . import cbuild, validate
from .modal import ModalModel, modal_model
from .result import Response

QUANTITIES = ("displacement", "velocity", "acceleration")


def _quantity_residues(model: ModalModel, quantity: str):
    """Residues of the asked quantity and its direct (feedthrough) term, (n_out, n_in)."""
    s = model.poles[:, None, None]
    R = model.residues
    weight = np.where(model.oscillatory, 2.0, 1.0)[:, None, None]  # a pair counts twice
    if quantity == "displacement":
        return R, np.zeros(R.shape[1:])
    if quantity == "velocity":
        return s * R, np.sum(weight * R.real, axis=0)
    if quantity == "acceleration":
        return s * s * R, np.sum(weight * (s * R).real, axis=0)
    raise ValueError(f"quantity must be one of {QUANTITIES}, got {quantity!r}")


def sections(model: ModalModel, fs: float, invariant="ramp", quantity="displacement"):
    """All sections of the bank: ``(sos, in_col, out_col, direct)``.

    ``sos`` has rows (b0, b1, b2, a1, a2) (scipy's a0 = 1 omitted), one per mode and
    (output, input) pair; ``direct`` (n_out, n_in) multiplies the current sample.
    """
    fs = validate.positive_scalar("fs", fs)
    T = 1.0 / fs
    R, direct = _quantity_residues(model, quantity)
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


def to_sos(model: ModalModel, fs: float, output: int = 0, input: int = 0, invariant="ramp",
           quantity="displacement") -> np.ndarray:
    """The sections of one (output, input) pair as a scipy.signal sos array (n_sections, 6).

    The bank adds these sections in parallel (plus the direct term); scipy's sosfilt cascades
    its rows, so filter each row separately and sum to reproduce the bank.
    """
    sos, in_col, out_col, _ = sections(model, fs, invariant, quantity)
    keep = (in_col == input) & (out_col == output)
    rows = sos[keep]
    return np.column_stack([rows[:, :3], np.ones(len(rows)), rows[:, 3:]])


@lru_cache(maxsize=None)
def _c_bank():
    source = resources.files("dtdyn.generated").joinpath("filter_bank.c").read_text()
    lib = cbuild.load_library(source, "filter_bank")
    if lib is None:
        return None
    fn = lib.dtdyn_filter_bank
    fn.argtypes = [ctypes.c_long] * 4 + [ctypes.c_void_p] * 5
    fn.restype = ctypes.c_int
    return fn


def run_bank(sos, in_col, out_col, direct, x, n_out, backend="c"):
    """y (n, n_out) = sum of the sections applied to the columns of x (n, n_in) + x direct^T."""
    x = np.ascontiguousarray(x, dtype=float)
    n, n_in = x.shape
    y = np.zeros((n, n_out))
    fn = _c_bank() if backend == "c" else None
    if fn is None:
        from scipy.signal import lfilter

        for (b0, b1, b2, a1, a2), i, o in zip(sos, in_col, out_col):
            y[:, o] += lfilter([b0, b1, b2], [1.0, a1, a2], x[:, i])
    else:
        sos = np.ascontiguousarray(sos)
        fn(n, n_in, n_out, len(sos), sos.ctypes.data, in_col.ctypes.data, out_col.ctypes.data,
           x.ctypes.data, y.ctypes.data)
    if np.any(direct):
        y += x @ direct.T
    return y


def modal_filter_response(force, fs, M, C, K, inputs, outputs, modes=None, invariant="ramp",
                          quantity="displacement", backend="c") -> Response:
    """Response of M q'' + C q' + K q = f by modal digital filters.

    Parameters
    ----------
    force : array_like, shape (n_samples, len(inputs))
        Force samples at t_n = n / fs on the 0-based DOFs ``inputs``.
    fs : float
        Sampling rate, Hz.
    inputs, outputs : sequence of int
        Loaded DOFs and response DOFs.
    modes : sequence of int, optional
        Indices of the modes to keep, sorted by frequency (all by default).
    invariant : {"ramp", "step", "impulse"}
        How the force is rebuilt between samples: linear (exact for a piecewise-linear force;
        spectrum bias (sin(pi f/fs)/(pi f/fs))^2, no phase error), held (half-sample lag),
        impulses (aliasing).
    quantity : {"displacement", "velocity", "acceleration"}

    Returns
    -------
    Response
        ``t`` and ``x``, ``v`` or ``a`` (the asked quantity) of shape (n_samples, len(outputs)).

    References
    ----------
    Ahlin, Magnevall & Josefsson (2006), Simulation of forced response in linear and nonlinear
    mechanical systems using digital filters, ISMA.
    """
    model = modal_model(M, C, K, inputs, outputs)
    if modes is not None:
        model = model.select(modes)
    fs = validate.positive_scalar("fs", fs)
    f = np.asarray(force, dtype=float)
    if f.ndim == 1 and model.inputs.size == 1:
        f = f[:, None]
    if f.ndim != 2 or f.shape[1] != model.inputs.size or f.shape[0] < 1:
        raise ValueError(f"force has shape {f.shape}, expected (n_samples, len(inputs)) = "
                         f"(n, {model.inputs.size})")
    bad = ~np.isfinite(f)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ValueError(f"force[{i}, {j}] = {f[i, j]!r} is not finite")
    t0 = time.perf_counter()
    sos, in_col, out_col, direct = sections(model, fs, invariant, quantity)
    t1 = time.perf_counter()
    y = run_bank(sos, in_col, out_col, direct, f, model.outputs.size, backend)
    t2 = time.perf_counter()
    key = {"displacement": "x", "velocity": "v", "acceleration": "a"}[quantity]
    return Response(np.arange(f.shape[0]) / fs, model.outputs, **{key: y},
                    info={"method": f"modal filters ({invariant} invariant)", "fs": fs,
                          "modes": int(model.poles.size), "sections": len(sos),
                          "setup_time": t1 - t0, "run_time": t2 - t1,
                          "backend": "c" if backend == "c" and _c_bank() else "scipy.lfilter"})
