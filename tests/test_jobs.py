"""The job grid: values shared by every job reach each worker once, costly jobs start first, and jobs the cache
answers run in the calling process."""

from __future__ import annotations

import hashlib
import os
import pickle
import uuid
import warnings
from pathlib import Path

import numpy as np
import pytest

from taskseq.experiments.outcome_cache import OutcomeCache
from taskseq.runtime import cache
from taskseq.runtime.jobs import Shared, run_jobs

CALLS: list[int] = []


class Loads:
    """Leaves a file named for the process each time it is unpickled."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder

    def __reduce__(self):
        return _loaded, (self.folder,)


def _loaded(folder: Path) -> Loads:
    (folder / f"{os.getpid()}-{uuid.uuid4().hex}").touch()
    return Loads(folder)


def _where(payload: dict, k: int) -> tuple[int, float]:
    """Which process ran job k, and a sum over the payload."""
    return os.getpid(), float(payload["steps"].sum()) + k


def _record(k: int) -> int:
    CALLS.append(k)
    return k * k


def test_a_shared_value_is_unpickled_once_per_worker_and_gives_what_plain_arguments_give(tmp_path):
    plain_dir, shared_dir = tmp_path / "plain", tmp_path / "shared"
    plain_dir.mkdir(), shared_dir.mkdir()
    steps = np.arange(300_000, dtype=float)  # over 1 MB: loky maps it from a file
    plain = run_jobs([(_where, ({"steps": steps, "loads": Loads(plain_dir)}, k)) for k in range(12)], n_jobs=2)
    shared = Shared({"steps": steps, "loads": Loads(shared_dir)})
    wrapped = run_jobs([(_where, (shared, k)) for k in range(12)], n_jobs=2)
    assert [r[1] for r in wrapped] == [r[1] for r in plain]
    assert len(list(plain_dir.iterdir())) == 12  # a plain argument is unpickled for every job
    workers = {pid for pid, _ in wrapped}
    loads = sorted(int(f.name.split("-")[0]) for f in shared_dir.iterdir())
    assert loads == sorted(workers)  # a shared one once in each worker that ran a job


def test_a_shared_value_round_trips_exactly_and_serial_runs_hand_over_the_object_itself():
    payload = {"w": np.random.default_rng(0).normal(size=50), "t": ("a", 1)}
    back = pickle.loads(pickle.dumps(Shared(payload))).value
    assert back["t"] == payload["t"] and back["w"].tobytes() == payload["w"].tobytes()
    assert run_jobs([(_where, (Shared(payload | {"steps": np.ones(3)}), 0))])[0][1] == 3.0
    shared = Shared(payload)
    assert run_jobs([(id, (shared,))]) == [id(payload)]


def test_costly_jobs_start_first_and_results_keep_the_jobs_order():
    CALLS.clear()
    out = run_jobs([(_record, (k,)) for k in range(5)], cost=[1.0, 5.0, 2.0, 5.0, 0.5])
    assert out == [0, 1, 4, 9, 16]
    assert CALLS == [1, 3, 2, 0, 4]  # ties keep their order
    with pytest.raises(ValueError, match="2 costs for 5 jobs"):
        run_jobs([(_record, (k,)) for k in range(5)], cost=[1.0, 2.0])


def _stored_square(k: int, root: str) -> tuple[int, int]:
    """k * k, read back from the outcome cache at `root` when it holds it (else stored there); and which process
    answered."""
    entries = OutcomeCache(Path(root) / "outcomes")
    key = hashlib.sha256(str(k).encode()).hexdigest()
    kept = entries.load(key)
    if kept is None:
        kept = k * k
        entries.save(key, kept)
    return os.getpid(), kept


def test_with_stored_first_the_jobs_found_in_the_cache_run_here_and_the_rest_in_workers(tmp_path, monkeypatch):
    root = str(tmp_path / "cache")
    jobs = [(_stored_square, (k, root)) for k in range(6)]
    monkeypatch.delenv(cache.CACHE_ENV, raising=False)
    unprobed = run_jobs(jobs, n_jobs=2, stored_first=True)  # no cache in force: every job goes to the workers
    assert [v for _, v in unprobed] == [k * k for k in range(6)]
    assert os.getpid() not in {pid for pid, _ in unprobed}
    monkeypatch.setenv(cache.CACHE_ENV, root)
    for k in (1, 4):  # two entries gone: those jobs miss
        (OutcomeCache(Path(root) / "outcomes").path(hashlib.sha256(str(k).encode()).hexdigest())).unlink()
    out = run_jobs(jobs, n_jobs=2, cost=[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], stored_first=True)
    assert [v for _, v in out] == [k * k for k in range(6)]  # in the jobs' order, whoever ran them
    here = [k for k, (pid, _) in enumerate(out) if pid == os.getpid()]
    assert here == [0, 2, 3, 5]
    assert run_jobs(jobs, n_jobs=2, stored_first=True) == [(os.getpid(), k * k) for k in range(6)]  # all stored now
    assert [pid for pid, _ in run_jobs(jobs, n_jobs=2)] != [os.getpid()] * 6  # not asked: workers, as before
    entries = OutcomeCache(Path(root) / "outcomes")
    for k in range(4):  # the first four tried all miss: a grid run afresh, so the two stored ones are not tried
        entries.path(hashlib.sha256(str(k).encode()).hexdigest()).unlink()
    out = run_jobs(jobs, n_jobs=2, stored_first=True)
    assert [v for _, v in out] == [k * k for k in range(6)]
    assert os.getpid() not in {pid for pid, _ in out}


def test_within_stored_only_a_missing_or_unreadable_entry_raises_and_nothing_is_written(tmp_path):
    entries = OutcomeCache(tmp_path / "outcomes")
    key = hashlib.sha256(b"k").hexdigest()
    with cache.stored_only(), pytest.raises(cache.NotStored):
        _stored_square(7, str(tmp_path))
    assert not (tmp_path / "outcomes").exists()
    entries.path(key).parent.mkdir(parents=True)
    entries.path(key).write_text("{not json", encoding="utf-8")
    with cache.stored_only(), pytest.raises(cache.NotStored), warnings.catch_warnings():
        warnings.simplefilter("error")  # the process that redoes the work warns, not this one
        entries.load(key)
    with pytest.warns(UserWarning, match="unreadable entry"):
        assert entries.load(key) is None  # outside the block, as before
