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

Arguments that every job of a grid takes (the benchmark's steps, its
scenarios) go in a `Shared`: it is pickled once, crosses to each worker as
one array and is unpickled once per worker process.
"""

from __future__ import annotations

import os
import pickle
import uuid
from collections import OrderedDict
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
from joblib import Parallel, delayed, parallel_config

from . import stopping
from .cache import NotStored, in_force, stored_only

SCHEDULER_ENV = "TASKSEQ_DASK_SCHEDULER"

Job = tuple[Callable[..., Any], tuple[Any, ...]]


class Shared:
    """A value that many jobs of one grid take as an argument, sent to each worker once.

    Handed as a plain argument, the ~900 step contexts of a benchmark were
    pickled again for every job by loky's reducers, which run in Python for
    every NumPy array inside: about 150 ms a job in the parent, while the
    workers waited. A `Shared` is pickled at most once (standard pickle, at
    C speed) into a byte array; loky memory-maps arrays over 1 MB to a file
    that each worker opens, Dask ships it as any argument, and a worker
    unpickles a given payload once and keeps it for the grid's later jobs. A
    job receives the value itself (`run_jobs` unwraps it), so jobs must not
    change it: in one process, later jobs see the same object.
    """

    __slots__ = ("value", "_key", "_blob")

    def __init__(self, value: Any) -> None:
        self.value = value
        self._key = uuid.uuid4().hex  # one payload, whatever its content: it is never compared across grids
        self._blob: np.ndarray | None = None

    def __reduce__(self) -> tuple[Callable[[str, np.ndarray], Shared], tuple[str, np.ndarray]]:
        if self._blob is None:
            self._blob = np.frombuffer(pickle.dumps(self.value, protocol=pickle.HIGHEST_PROTOCOL), dtype=np.uint8)
        return _received, (self._key, self._blob)


_RECEIVED: OrderedDict[str, Any] = OrderedDict()  # in a worker: the values of the payloads met most recently
_RECEIVED_MAX = 4


def _received(key: str, blob: np.ndarray) -> Shared:
    if key in _RECEIVED:
        _RECEIVED.move_to_end(key)
    else:
        _RECEIVED[key] = pickle.loads(blob)
        if len(_RECEIVED) > _RECEIVED_MAX:
            _RECEIVED.popitem(last=False)
    out = Shared.__new__(Shared)
    out.value, out._key, out._blob = _RECEIVED[key], key, blob
    return out


def _call(f: Callable[..., Any], args: tuple[Any, ...]) -> Any:
    stopping.check()  # run in this process: a stop dropped during the last job ends the grid here
    return f(*(a.value if isinstance(a, Shared) else a for a in args))


def default_jobs() -> int:
    """Workers for parallel work (stages, the VEIL experiment): `TASKSEQ_N_JOBS` if set, else one per CPU."""
    value = os.environ.get("TASKSEQ_N_JOBS")
    if value is None:
        return os.cpu_count() or 1
    if not value.isdigit() or int(value) < 1:
        raise SystemExit(f"error: TASKSEQ_N_JOBS must be a positive whole number, got {value!r}")
    return int(value)


def run_jobs(jobs: Iterable[Job], n_jobs: int = 1, verbose: int = 0,
             cost: Sequence[float] | None = None, stored_first: bool = False) -> list[Any]:
    """`[f(*args) for f, args in jobs]`, in that order, run in parallel where the setting says.

    An argument may be a `Shared` (the job gets its value). `cost`, one
    number per job, sends the costliest first, so that no long job starts
    last while the other workers idle; the results keep the jobs' order.

    `stored_first`, for grids whose jobs look their work up in the cache
    (`runtime.cache`) before doing much of it: with a cache in force, the
    jobs first run here, in their order, with only stored entries to go on
    (`cache.stored_only`), and only those that miss one go to the workers. A
    re-run after a change to one method then starts no worker for the jobs
    it does not touch. Once most of the jobs tried have missed (at least
    `PROBES` tried), the grid is taken as run afresh and the rest go to the
    workers untried, so a first run pays for a few lookups only. The results
    are the same either way: an entry holds what the work gave.
    """
    jobs = list(jobs)
    if cost is not None and len(cost) != len(jobs):
        raise ValueError(f"run_jobs: {len(cost)} costs for {len(jobs)} jobs")
    order = list(range(len(jobs))) if cost is None else sorted(range(len(jobs)), key=lambda i: -cost[i])
    out: list[Any] = [None] * len(jobs)
    if stored_first and in_force():
        answered = _read_back(jobs, out)
        order = [i for i in order if i not in answered]
    results = _dispatch([delayed(_call)(*jobs[i]) for i in order], n_jobs, verbose) if order else []
    for i, r in zip(order, results, strict=True):
        out[i] = r
    return out


PROBES = 4  # jobs tried here before a grid whose tries mostly missed is sent to the workers whole


def _read_back(jobs: list[Job], out: list[Any]) -> set[int]:
    """The jobs run in this process from stored entries alone (their results into `out`), tried in order until
    most of those tried have missed."""
    answered: set[int] = set()
    for i, job in enumerate(jobs):
        missed = i - len(answered)
        if i >= PROBES and 2 * missed > i:
            break
        try:
            with stored_only():
                out[i] = _call(*job)
        except NotStored:
            continue
        answered.add(i)
    return answered


def _dispatch(calls: list[Any], n_jobs: int, verbose: int) -> list[Any]:
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

