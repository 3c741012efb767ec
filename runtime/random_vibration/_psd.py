r"""Power spectral density tables as test specifications write them: breakpoints joined by
straight lines on log-log axes.

Between breakpoints :math:`(f_1, G_1)` and :math:`(f_2, G_2)` the PSD is the power law

.. math::

    G(f) = G_1 \left(\frac{f}{f_1}\right)^{n}, \qquad
    n = \frac{\ln(G_2 / G_1)}{\ln(f_2 / f_1)}, \qquad
    \text{slope} = 10 \log_{10}(2)\, n \ \text{dB/octave},

and its mean square over the segment is, exactly,

.. math::

    \int_{f_1}^{f_2} G\,df = \frac{G_1 f_1}{n + 1}\left[\left(\frac{f_2}{f_1}\right)^{n + 1}
    - 1\right] \quad (n \ne -1), \qquad G_1 f_1 \ln\frac{f_2}{f_1} \quad (n = -1)

(the usual "grms" of a table: the square root of the sum over the segments). The PSD is zero
outside the first and last breakpoints.
"""
from __future__ import annotations

import re

import numpy as np

from dtdyn._engine.public import public

__all__ = ["PsdTable", "psd_table"]

#: dB per octave of the power law f^1: 10 log10(2)
DB_PER_OCTAVE = 10.0 * np.log10(2.0)
_SLOPE = re.compile(r"^\s*([+-]?\d+(?:\.\d*)?(?:[eE][+-]?\d+)?)\s*dB\s*/\s*oct(?:ave)?\s*$",
                    flags=re.I)


class PsdTable:
    """A one-sided PSD given by breakpoints, log-log between them (module docstring); made by
    `psd_table`.

    Calling it, ``table(f)``, gives the PSD at the frequencies ``f`` (Hz), zero outside
    ``freqs_hz[0] .. freqs_hz[-1]``.

    Attributes
    ----------
    freqs_hz : (n,) ndarray
        The breakpoints' frequencies, Hz, increasing.
    values : (n,) ndarray
        The PSD at the breakpoints, (unit)^2/Hz.
    slopes : (n - 1,) ndarray
        Each segment's slope, dB/octave.
    rms : float
        The square root of the exact mean square of the table (module docstring); ``grms``
        is the same number (the name engineers use when the unit is g).
    """

    def __init__(self, freqs_hz, values):
        self.freqs_hz = np.array(freqs_hz, dtype=float)
        self.values = np.array(values, dtype=float)
        f, g = self.freqs_hz, self.values
        if f.ndim != 1 or f.shape != g.shape or f.size < 2:
            raise ValueError(f"PsdTable: freqs_hz and values must be two 1-D arrays of the same "
                             f"length >= 2; got shapes {f.shape} and {g.shape}")
        if not (np.isfinite(f).all() and np.isfinite(g).all() and (f > 0).all()
                and (np.diff(f) > 0).all() and (g > 0).all()):
            raise ValueError("PsdTable: the breakpoints must be finite, the frequencies > 0 and "
                             "increasing, the values > 0 (log-log interpolation); psd_table "
                             "builds a table from breakpoints as specifications write them")
        for a in (self.freqs_hz, self.values):
            a.flags.writeable = False
        f, g = self.freqs_hz, self.values
        with np.errstate(divide="ignore"):
            self._n = np.log(g[1:] / g[:-1]) / np.log(f[1:] / f[:-1])

    @property
    def slopes(self) -> np.ndarray:
        return self._n * DB_PER_OCTAVE

    @property
    def mean_square(self) -> float:
        f, g, n = self.freqs_hz, self.values, self._n
        ratio = f[1:] / f[:-1]
        minus_one = np.isclose(n, -1.0, rtol=0.0, atol=1e-12)
        p = np.where(minus_one, 1.0, n + 1.0)
        seg = np.where(minus_one, g[:-1] * f[:-1] * np.log(ratio),
                       g[:-1] * f[:-1] / p * np.expm1(p * np.log(ratio)))
        return float(seg.sum())

    @property
    def rms(self) -> float:
        return float(np.sqrt(self.mean_square))

    grms = rms

    def __call__(self, f) -> np.ndarray:
        f = np.asarray(f, dtype=float)
        if np.isnan(f).any():
            raise ValueError("the frequencies at which a PSD table is read must not be NaN")
        fb, g = self.freqs_hz, self.values
        i = np.clip(np.searchsorted(fb, f, side="right") - 1, 0, fb.size - 2)
        inside = (f >= fb[0]) & (f <= fb[-1])
        with np.errstate(divide="ignore", invalid="ignore"):
            out = g[i] * np.exp(self._n[i] * np.log(np.where(inside, f, fb[0]) / fb[i]))
        return np.where(inside, out, 0.0)

    def __repr__(self) -> str:
        rows = ", ".join(f"({f:g}, {g:g})" for f, g in zip(self.freqs_hz, self.values))
        return f"PsdTable([{rows}]; rms {self.rms:.4g})"


def _slope(text):
    """dB/octave from '+3 dB/oct' (or '-6 dB/octave'), None if ``text`` is not such a string."""
    if not isinstance(text, str):
        return None
    m = _SLOPE.match(text)
    if m is None:
        raise ValueError(f"psd_table: {text!r} is neither a number nor a slope such as "
                         "'+3 dB/oct'")
    return float(m.group(1))


@public
def psd_table(breakpoints) -> PsdTable:
    """A one-sided PSD from breakpoints ``(f_hz, value)``, straight lines on log-log axes
    between them, zero outside (module docstring), with its rms (``grms``).

    Parameters
    ----------
    breakpoints : sequence of (float, float or str)
        ``(frequency in Hz, PSD in (unit)^2/Hz)``, frequencies increasing and > 0, PSD > 0.
        A value may instead be a slope, ``"+3 dB/oct"`` or ``"-6 dB/octave"``: the slope of
        the segment that ends at this breakpoint (for the first breakpoint: of the segment
        that starts there), its PSD following from the neighbour's.

    Returns
    -------
    PsdTable
        Callable: ``table(f)`` is the PSD at ``f`` (Hz).

    Examples
    --------
    >>> from dtdyn.random_vibration import psd_table
    >>> t = psd_table([(20, 0.01), (80, 0.04), (350, 0.04), (2000, 0.007)])
    >>> round(t.grms, 3), t.slopes.round(2).tolist()
    (6.058, [3.01, 0.0, -3.01])
    >>> s = psd_table([(20, "+3 dB/oct"), (80, 0.04), (350, 0.04), (2000, "-3 dB/oct")])
    >>> s.values.round(5).tolist()
    [0.01005, 0.04, 0.04, 0.00704]
    """
    try:
        rows = [tuple(b) for b in breakpoints]
    except TypeError:
        raise ValueError(f"psd_table: breakpoints = {breakpoints!r}: give a sequence of "
                         "(frequency in Hz, PSD) pairs") from None
    if len(rows) < 2 or any(len(r) != 2 for r in rows):
        raise ValueError(f"psd_table: breakpoints = {breakpoints!r}: give at least two "
                         "(frequency in Hz, PSD) pairs")
    f = np.empty(len(rows))
    for i, (fi, _) in enumerate(rows):
        try:
            f[i] = float(fi)
        except (TypeError, ValueError):
            raise ValueError(f"psd_table: breakpoints[{i}] frequency = {fi!r} is not a "
                             "number") from None
    if not np.all(np.isfinite(f)) or np.any(f <= 0) or np.any(np.diff(f) <= 0):
        raise ValueError(f"psd_table: frequencies {f.tolist()} must be finite, > 0 and "
                         "increasing")
    slopes = [_slope(v) for _, v in rows]
    g = np.full(len(rows), np.nan)
    for i, (_, v) in enumerate(rows):
        if slopes[i] is None:
            try:
                g[i] = float(v)
            except (TypeError, ValueError):
                raise ValueError(f"psd_table: breakpoints[{i}] value = {v!r} is neither a "
                                 "number nor a slope such as '+3 dB/oct'") from None
            if not np.isfinite(g[i]) or g[i] <= 0:
                raise ValueError(f"psd_table: breakpoints[{i}] value = {v!r} must be finite "
                                 "and > 0 (a PSD on log-log axes)")

    def power(a, b, db):          # G_b from G_a and the slope of the segment a-b
        return g[a] * (f[b] / f[a]) ** (db / DB_PER_OCTAVE)

    if slopes[0] is not None:
        if len(rows) < 2 or slopes[1] is not None:
            raise ValueError("psd_table: breakpoints[0] and breakpoints[1] are both slopes: "
                             "give the PSD of one of them")
        g[0] = power(1, 0, slopes[0])
    for i in range(1, len(rows)):
        if slopes[i] is not None:
            g[i] = power(i - 1, i, slopes[i])
    return PsdTable(f, g)
