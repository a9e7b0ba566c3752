"""A fold's outcomes kept across runs: what one method's programs and step predictions did on one fold's tests.

Once a method is fitted on a fold, what it predicts and what its programs do
on the fold's test scenarios is a pure function of the code that runs them,
the method's settings, its fitted weights and the fold's test data (the
planner, the simulator and the judging are deterministic). After a change to
one method's module, a re-run of the evaluation stages fits nothing new (the
fit cache) and would still replay every other method's programs; with this
cache they are read back, and only the changed method's programs run.

A job's key hashes:
- the code: the source files of the experiment's module
  (`experiments.crossval`, `.robustness` or `.teaching`, with all they import),
  of the module of every function the method's factory is made of (its
  method module: `taskseq/methods/noise_trained.py` and what it imports) and
  of the method's class, read by `runtime.sources`, and the libraries'
  versions;
- the method: its type and every setting but the model store's path (where a
  fit is found changes nothing but the weights), and, fitted, its scorer's
  weights and settings (`planner_`), so a model the store trained otherwise
  misses;
- the data: every step of the pool with its metadata, every scenario (rooms,
  objects, task, demonstrations), the fold's test scenarios, the world states
  of the test steps, and the job's own settings (step cap, conditions, seeds).

It lives in the `outcomes/` folder of the cache `TASKSEQ_CACHE` names
(`runtime.cache`): one JSON file an entry, written atomically; one that cannot
be read is run again and replaced, with a warning. An entry holds outcomes,
not programs (a program holds every world state it met): a job read back
that keeps some programs for recordings runs those few again.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from dataclasses import fields, is_dataclass
from functools import partial
from pathlib import Path
from typing import Any, TypeVar

from ..demonstrations.benchmark import Benchmark
from ..demonstrations.records import scenario_digest, state_digest
from ..features.context import StepContext
from ..features.dataset import StepMeta
from ..learn.fit_cache import hash_steps
from ..runtime.atomic import atomic_file
from ..runtime.cache import Entries, versions
from ..runtime.sources import code_fingerprint
from ..sim.scenarios import Scenario

FORMAT = "taskseq.outcomes/1"
T = TypeVar("T")
# a fold job's data: the pool's steps and their metadata, its scenarios, the job's test scenarios, the world
# states of the demonstrations (None where the job reads none)
FoldData = tuple[Sequence[StepContext], Sequence[StepMeta], dict[str, Scenario], set[str] | frozenset[str],
                 Benchmark | None]
# what a program's steps depend on beyond the project's code: arrays, compiled scoring, SAT, the multiclass SVM
_LIBRARIES = ("numpy", "scipy", "numba", "python-sat", "scikit-learn")


class OutcomeCache(Entries):
    """A folder of fold outcomes, `<key>.json` each (the JSON the experiment's encoder wrote)."""

    kind = "outcomes"

    def load(self, key: str) -> Any | None:
        """The outcomes stored under `key`, or None if there are none or they cannot be read."""
        return self.read(key, _parsed, "run again")

    def save(self, key: str, outcomes: Any) -> None:
        """Store `outcomes` (JSON) under `key`, atomically (not one of the command's outputs)."""
        with atomic_file(self.path(key), output=False) as tmp:
            Path(tmp).write_text(json.dumps({"format": FORMAT, "outcomes": outcomes}), encoding="utf-8")


def _parsed(path: Path) -> Any:
    entry = json.loads(path.read_text(encoding="utf-8"))
    if entry.get("format") != FORMAT:
        raise ValueError(f"format {entry.get('format')!r}, expected {FORMAT!r}")
    return entry["outcomes"]


def read_or_run(experiment: str, make: Callable[[], Any], method: Any, data: FoldData, job: dict[str, Any],
                run: Callable[[], T], encode: Callable[[T], Any], decode: Callable[[Any], T]) -> T:
    """`run()` (the fitted `method`'s outcomes on one fold job of `experiment`), or, with the cache on, what an
    earlier run of the same job stored (`decode`d), else `run()` stored (`encode`d as JSON)."""
    cache = OutcomeCache.active()
    if cache is None:
        return run()
    key = job_key(experiment, make, method, *data, job)
    stored = cache.load(key)
    if stored is not None:
        return decode(stored)
    result = run()
    cache.save(key, encode(result))
    return result


def job_key(experiment: str, make: Callable[[], Any], method: Any, contexts: Sequence[StepContext],
            meta: Sequence[StepMeta], scenarios: dict[str, Scenario], test: set[str] | frozenset[str],
            demos: Benchmark | None, job: dict[str, Any]) -> str:
    """sha256 of what decides one fold job of `experiment` (a module of this package): its code, the fitted
    `method` that `make` made, the pool of steps and scenarios, the test scenarios and the job's settings."""
    h = hashlib.sha256()
    modules = _factory_modules(make) | _factory_modules(type(method))  # a method module may define its own class
    code = [code_fingerprint(f"taskseq.experiments.{experiment}"), *(code_fingerprint(m) for m in sorted(modules))]
    h.update(json.dumps({"format": FORMAT, "code": code, **versions(*_LIBRARIES), "method": _described(method),
                         "test": sorted(test), "job": job}, sort_keys=True, default=repr).encode())
    fitted = getattr(method, "planner_", None)  # a scorer's weights: the store may have trained them otherwise
    if fitted is not None:
        h.update(repr(fitted).encode())
        h.update(fitted.w_.tobytes())
    hash_steps(h, contexts)
    h.update(json.dumps([[m.sequence_id, m.scenario_id, m.step] for m in meta]).encode())
    for sid in sorted(scenarios):
        h.update(scenario_digest(scenarios[sid]))
    if demos is not None:
        for m in meta:
            if m.scenario_id in test:
                h.update(state_digest(demos.states[(m.sequence_id, m.step)]))
                h.update(json.dumps([str(a) for a in demos.actions[m.sequence_id]]).encode())
    return h.hexdigest()


def _described(method: Any) -> dict[str, str]:
    """The method's type and settings (a dataclass's fields), without the model store's path."""
    out = {"type": f"{type(method).__module__}.{type(method).__qualname__}"}
    if is_dataclass(method):
        out.update({f.name: repr(getattr(method, f.name)) for f in fields(method) if f.name != "store"})
    else:
        out["repr"] = repr(method)
    return out


def _factory_modules(make: Callable[[], Any]) -> set[str]:
    """The project modules of every function `make` is built of (partials unwrapped, callable arguments too)."""
    out: set[str] = set()
    todo: list[Any] = [make]
    while todo:
        f = todo.pop()
        if isinstance(f, partial):
            todo.append(f.func)
            todo.extend(a for a in (*f.args, *f.keywords.values()) if callable(a))
        elif getattr(f, "__module__", "").split(".")[0] == "taskseq":
            out.add(f.__module__)
    return out
