"""The threads dtdyn's splittable C loops use by default (chain_response's stable sweep,
shock_response_spectrum's filter bank): the CPUs this process may run on, capped by the
environment variable DTDYN_THREADS (set it to 1 where each process owns one core, e.g. the
worker processes of a batch; `run_batch`'s own cluster does)."""
from __future__ import annotations

import os

#: the environment variable that caps the default thread count
ENV = "DTDYN_THREADS"


def available() -> int:
    """CPUs of this process (its affinity where the OS has one), at most DTDYN_THREADS."""
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    cpus = max(1, cpus or 1)
    raw = os.environ.get(ENV, "").strip()
    if raw:
        try:
            cap = int(raw)
        except ValueError:
            cap = 0
        if cap < 1:
            raise ValueError(f"{ENV} = {raw!r}: must be an integer >= 1 (the default threads of "
                             "dtdyn's C loops)")
        cpus = min(cpus, cap)
    return cpus
