"""Monte Carlo statistics across the cases of a batch: the mean of each per-case reduction and
its confidence interval.

A batch of one scene under random loads with a root seed (``run_batch(scene, vary=[{}] * n,
seed=...)`` or ``dtdyn batch --seed``) is a Monte Carlo run: its cases are independent draws
of the same random response. `monte_carlo_summary` reduces them over ``case``:

=================== =============================================================================
variable            estimate and interval
=================== =============================================================================
``rms_<q>``         sqrt of the mean of the cases' mean squares (the rms of all their samples,
                    every case of equal length); the interval is the square root of the Student
                    t interval of the mean square
``peak_<q>``,       the mean over cases; Student t interval: mean +- t_{(1+c)/2, n-1} s / sqrt(n),
``damage_<q>``      s the standard deviation over the n done cases
``welch_<q>``       the mean PSD over cases; chi-square interval with nu = the sum of the cases'
                    ``welch_dof``: [nu G / chi2_{(1+c)/2}(nu), nu G / chi2_{(1-c)/2}(nu)]
=================== =============================================================================

The Student t interval assumes the per-case values are independent and their mean about normal
(the central limit theorem: a few tens of cases); the chi-square interval, that each PSD bin of
a Gaussian response is G chi^2_nu / nu (`dtdyn.app._batch.Welch`), which holds approximately for
the response of a nonlinear model too (each bin is a sum of many Fourier coefficients).
"""
from __future__ import annotations

import os

import numpy as np

from dtdyn._engine.public import public

__all__ = ["monte_carlo_summary"]

#: the prefixes of the per-case variables with a Student t interval of their mean
MEAN_PREFIXES = ("peak_", "damage_")


def _dataset(result):
    if isinstance(result, (str, os.PathLike)):
        import xarray as xr

        from dtdyn.app._batch.store import ZARR_FORMAT
        if not os.path.isdir(result):
            raise ValueError(f"result = {str(result)!r}: no such Zarr store (a folder written "
                             "by run_batch(out=...))")
        return xr.open_zarr(result, zarr_format=ZARR_FORMAT, consolidated=True)
    if not hasattr(result, "data_vars") or "status" not in getattr(result, "data_vars", ()):
        raise ValueError(f"result = {type(result).__name__}: give the Dataset run_batch returns "
                         "or the path of its Zarr store")
    return result


@public
def monte_carlo_summary(result, *, confidence=0.95):
    """The mean over a batch's done cases of each per-case reduction, with its confidence
    interval: rms and peaks and damage by Student t over the cases, Welch PSDs by chi-square.

    Parameters
    ----------
    result : xarray.Dataset or path
        What `run_batch` returned, or the path of its Zarr store; reduced with ``"rms"``
        (or `Rms`), ``"peak"``, `Damage` and/or ``"welch"`` (or `Welch`). Failed cases are
        left out.
    confidence : float
        The two-sided confidence level c of the intervals, 0 < c < 1 (default 0.95).

    Returns
    -------
    xarray.Dataset
        For each reduced variable ``name`` (``rms_x``, ``damage_x``, ``welch_a``, ...): ``name``
        (the estimate), ``name_low`` and ``name_high`` (the interval), over the variable's own
        dims (output, freq_hz). ``attrs``: ``confidence``, ``cases`` (the done cases used),
        ``failed`` (left out) and ``welch_dof`` (nu of the mean PSDs; None without them).

    Raises
    ------
    ValueError
        Fewer than two done cases, no variable to summarize, or a bad ``confidence``.

    Notes
    -----
    With n independent per-case values y_i, mean ybar and standard deviation s, the interval
    ybar +- t_{(1+c)/2, n-1} s / sqrt(n) (Student 1908) holds the ensemble mean with probability
    c. ``rms_<q>`` is sqrt(mean of rms_i^2): the rms of the records put end to end, whose square
    is an unbiased estimate of the mean square (the mean of the rms_i is biased low); its
    interval is the square root of the mean square's. A mean of K Welch PSDs with nu_i degrees
    of freedom each is G chi^2_nu / nu, nu = sum nu_i, so G lies in
    [nu Ghat / chi2_{(1+c)/2}(nu), nu Ghat / chi2_{(1-c)/2}(nu)] with probability c (Bendat &
    Piersol, *Random Data*, 4th ed., sec. 8.5.4).

    Examples
    --------
    >>> import numpy as np, xarray as xr
    >>> from dtdyn.app._batch import monte_carlo_summary
    >>> ds = xr.Dataset({"rms_x": (("case", "output"), [[1.0], [1.2], [0.9], [1.1]]),
    ...                  "status": ("case", ["done"] * 4)})
    >>> s = monte_carlo_summary(ds, confidence=0.9)
    >>> round(float(s["rms_x"][0]), 4), s.attrs["cases"]
    (1.0559, 4)
    """
    import xarray as xr
    from scipy import stats

    if isinstance(confidence, bool) or not isinstance(
            confidence, (int, float, np.integer, np.floating)) or not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence = {confidence!r}: must be a level between 0 and 1 "
                         "(e.g. 0.95)")
    ds = _dataset(result)
    status = np.array([str(v) for v in np.asarray(ds["status"].values).ravel()])
    done = np.flatnonzero(status == "done")
    n = int(done.size)
    if n < 2:
        raise ValueError(f"result has {n} done case(s): a confidence interval needs at least "
                         "two")
    names = [v for v in ds.data_vars if "case" in ds[v].dims and (
        v.startswith(("rms_", "welch_", *MEAN_PREFIXES)) and v != "welch_dof")]
    if not names:
        raise ValueError("result has no variable to summarize: run the batch with reduce "
                         "'rms', 'peak', 'welch' or a Damage")
    tq = float(stats.t.ppf(0.5 + confidence / 2.0, n - 1))
    out = {}
    nu = None
    for name in names:
        y = ds[name].isel(case=done).load()
        if name.startswith("welch_"):
            if "welch_dof" not in ds:
                raise ValueError(f"{name}: the result has no welch_dof (the Welch reducer "
                                 "stores it)")
            nu = float(np.asarray(ds["welch_dof"].values)[done].sum())
            mean = y.mean("case")
            out[name] = mean
            # nu holds away from 0 Hz and the Nyquist frequency (there a detrended, windowed
            # estimate has about half the degrees of freedom, or none): no interval at those bins
            f = mean["freq_hz"] if "freq_hz" in mean.coords else None
            inner = True if f is None else (f > f.min()) & (f < f.max())
            out[f"{name}_low"] = (nu * mean / stats.chi2.ppf(0.5 + confidence / 2.0, nu)
                                  ).where(inner)
            out[f"{name}_high"] = (nu * mean / stats.chi2.ppf(0.5 - confidence / 2.0, nu)
                                   ).where(inner)
            continue
        if name.startswith("rms_"):
            y = y**2
        mean = y.mean("case")
        half = tq * y.std("case", ddof=1) / np.sqrt(n)
        low, high = mean - half, mean + half
        if name.startswith("rms_"):
            mean, low, high = np.sqrt(mean), np.sqrt(np.maximum(low, 0.0)), np.sqrt(high)
        out[name], out[f"{name}_low"], out[f"{name}_high"] = mean, low, high
    return xr.Dataset(out, attrs={"confidence": float(confidence), "cases": n,
                                  "failed": int(np.sum(status == "failed")), "welch_dof": nu})
