"""The job grid: values shared by every job reach each worker once, and costly jobs start first."""

from __future__ import annotations

import os
import pickle
import uuid
from pathlib import Path

import numpy as np
import pytest

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
