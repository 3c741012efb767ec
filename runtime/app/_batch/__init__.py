"""Batches: many scenes and load cases on Dask distributed, on one machine or a cluster.

`run_batch` (in `run`) takes the cases (`cases`: scenes, a base scene with a table of
variations, per-case seeds), sends them to the workers in tasks (`worker`: the warm-up, the
cases, the C requirement), reduces each response there (`reducers`) and writes the results to
a Zarr store (`store`) case by case, so that a batch stopped at any moment can be
resumed; `montecarlo` gives the means over the cases with their confidence intervals.
``docs/batch.md`` shows how to run it on a cluster.
"""
from dtdyn.app._batch.montecarlo import monte_carlo_summary
from dtdyn.app._batch.reducers import REDUCERS, Damage, Rms, Spectrum, Welch
from dtdyn.app._batch.run import run_batch
from dtdyn.app._batch.store import ResumeMismatchError
from dtdyn.app._batch.worker import RUN_ERRORS, CBackendError

__all__ = ["run_batch", "Spectrum", "Rms", "Welch", "Damage", "monte_carlo_summary",
           "REDUCERS", "CBackendError", "RUN_ERRORS", "ResumeMismatchError"]
