"""Where independent jobs run: joblib's processes on this machine, or a Dask cluster.

Every grid of independent jobs (folds x methods, folds x conditions) goes
through `run_jobs`, so the choice of backend is one setting for the whole
pipeline. It is a setting of the machine, not of the results: the jobs are
pure functions of their arguments and a fit pins its BLAS to one thread, so
the same jobs give the same bytes on either backend (a test checks it).

- default: joblib's loky processes, `n_jobs` of them;
- `TASKSEQ_DASK_SCHEDULER=tcp://host:8786` (the address of a running
  `dask scheduler`): the jobs go to that cluster's workers through joblib's
  Dask backend, `n_jobs` is ignored (the cluster decides), and the workers
  need this package installed (`pip install -e '.[dask]'`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from typing import Any

from joblib import Parallel, delayed, parallel_config

SCHEDULER_ENV = "TASKSEQ_DASK_SCHEDULER"

Job = tuple[Callable[..., Any], tuple[Any, ...]]


def run_jobs(jobs: Iterable[Job], n_jobs: int = 1, verbose: int = 0) -> list[Any]:
    """`[f(*args) for f, args in jobs]`, in that order, run in parallel where the setting says."""
    calls = [delayed(f)(*args) for f, args in jobs]
    address = os.environ.get(SCHEDULER_ENV, "").strip()
    if address:
        try:
            from distributed import Client
        except ImportError as e:  # an optional extra: say which one
            raise RuntimeError(f"{SCHEDULER_ENV} is set but Dask is not installed: pip install -e '.[dask]'") from e
        with Client(address) as client, parallel_config(backend="dask", client=client):
            return Parallel(verbose=verbose)(calls)
    # joblib refuses `verbose` on serial runs
    return Parallel(n_jobs=n_jobs, verbose=verbose if n_jobs != 1 else 0)(calls)

