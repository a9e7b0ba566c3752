"""Fits kept across runs, addressed by everything that decides them, so that a fit is done once per content.

A fit of `StepScorer` is a pure function of the learner's code, its
settings, the training steps with their labels and the cuts it starts from
(`ssvm.Cuts`): the weights are the same bytes in any process
(`estimator.StepScorer.fit`). The cache keys each fit by a hash of exactly
those, the code taken as the files `taskseq.learn.estimator` imports
(`runtime.sources`), so a change to the learner, the features or the
simulator's vocabulary misses every entry, while a change anywhere else
(a method's module, the planner, a report) keeps them: a stage re-run after
such a change loads the fits it had and fits only what is new. A method
whose training steps come from the planner (DAgger's rollouts) misses exactly
when those steps changed, since they are hashed.

The cache is used only where it is asked for (`runtime.cache`: the `fits/`
folder of the cache `TASKSEQ_CACHE` names, set by the stages' `--cache`
option). An entry is a NumPy .npz of arrays and JSON (no pickles), written
atomically; one that cannot be read is fitted again and replaced, with a
warning.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..features.context import StepContext
from ..runtime.atomic import atomic_file
from ..runtime.cache import Digests, Entries, versions
from ..runtime.sources import code_fingerprint
from .ssvm import Cuts, Iteration

FORMAT = "taskseq.fit/1"
# what the learner's bytes depend on beyond its own code
_LIBRARIES = ("numpy", "scipy", "numba")


def step_digest(x: StepContext) -> bytes:
    """sha256 of every field of one step, computed once per step object (`runtime.cache.Digests`): a model's key
    hashes hundreds of steps, and the same steps are hashed again for every method, C and stage that meets them."""
    return _DIGESTS(x, _step_digest)


def _step_digest(x: StepContext) -> bytes:
    h = hashlib.sha256()
    gold = None if x.gold is None else list(x.gold)
    h.update(json.dumps([x.object_ids, x.task, list(x.prev_prims), list(x.prev_args), gold]).encode())
    for a in (x.objects, x.task_rel, x.collide):
        h.update(np.ascontiguousarray(a).tobytes())
    if x.relations is not None:
        h.update(np.ascontiguousarray(x.relations).tobytes())
    return h.digest()


_DIGESTS = Digests(200_000)  # about 20 MB


def hash_steps(h: Any, contexts: Sequence[StepContext]) -> None:
    """Feed every step (`step_digest`, in order) to the hash `h` (hashlib's `update` protocol)."""
    for x in contexts:
        h.update(step_digest(x))


def _hash_cuts(h: Any, cuts: Cuts | None) -> None:
    if cuts is None:
        h.update(b"cold")
        return
    d = sp.csr_matrix(cuts.deltas)
    h.update(json.dumps([list(d.shape), cuts.C, cuts.n_examples, cuts.fingerprint]).encode())
    for a in (d.indptr.astype(np.int64), d.indices.astype(np.int64), d.data, cuts.losses, cuts.examples,
              cuts.alpha):
        h.update(np.ascontiguousarray(a).tobytes())


@cache
def _environment() -> dict[str, str]:
    """What a fit's bytes depend on besides its inputs: the learner's code and the libraries under it."""
    return {"format": FORMAT, "code": code_fingerprint("taskseq.learn.estimator"), **versions(*_LIBRARIES)}


def fit_key(params: dict[str, Any], X: Sequence[StepContext], y: Sequence[tuple[int, int, int]],
            warm_start: Cuts | None) -> str:
    """sha256 of the learner's code and libraries, its settings, the steps, their labels and the starting cuts."""
    h = hashlib.sha256()
    h.update(json.dumps({**_environment(), **params}, sort_keys=True).encode())
    hash_steps(h, X)
    h.update(np.asarray(y, dtype=np.int64).tobytes())
    _hash_cuts(h, warm_start)
    return h.hexdigest()


@dataclass(frozen=True)
class FitRecord:
    """What the cache keeps of a fit: all a `StepScorer` needs to be that fit again (`StepScorer.record_`)."""

    w: np.ndarray
    history: list[Iteration]
    cuts: Cuts | None  # where a neighbouring fit starts (None with grouped slacks)
    primal_objective: float
    dual_objective: float
    converged: bool
    n_qp_steps: int
    seconds_oracle: float
    seconds_qp: float
    fit_seconds: float  # of the fit that stored it
    n_steps: int


_SCALARS = tuple(f.name for f in fields(FitRecord) if f.name not in ("w", "history", "cuts"))


def _parsed(path: Path) -> FitRecord:
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        if meta.get("format") != FORMAT:
            raise ValueError(f"format {meta.get('format')!r}, expected {FORMAT!r}")
        arrays = {name: z[name] for name in z.files if name != "meta"}
    cuts = None
    if meta["cuts"] is not None:
        c = meta["cuts"]
        deltas = sp.csr_matrix((arrays["cut_data"], arrays["cut_indices"], arrays["cut_indptr"]),
                               shape=tuple(c["shape"]))
        cuts = Cuts(deltas, arrays["cut_losses"], arrays["cut_examples"], arrays["cut_alpha"], c["C"],
                    c["n_examples"], c["fingerprint"])
    return FitRecord(arrays["w"], [Iteration(**it) for it in meta["history"]], cuts, **{k: meta[k] for k in _SCALARS})


class FitCache(Entries):
    """A folder of fits, `<key>.npz` each: the weights, the learner's record of the fit and its final cuts."""

    kind = "fits"

    def load(self, key: str) -> FitRecord | None:
        """The fit stored under `key`, or None if there is none or it cannot be read."""
        return self.read(key, _parsed, "fitted again")

    def save(self, key: str, fit: FitRecord) -> None:
        """Store `fit` under `key`, atomically: a reader sees the whole entry or none (not one of the command's
        outputs: `runtime.atomic.WRITTEN` does not list it)."""
        arrays = {"w": np.asarray(fit.w, dtype=np.float64)}
        meta: dict[str, Any] = {"format": FORMAT, "history": [asdict(it) for it in fit.history], "cuts": None,
                                **{k: getattr(fit, k) for k in _SCALARS}}
        if fit.cuts is not None:
            d = sp.csr_matrix(fit.cuts.deltas)
            arrays.update(cut_data=d.data, cut_indices=d.indices, cut_indptr=d.indptr, cut_losses=fit.cuts.losses,
                          cut_examples=fit.cuts.examples, cut_alpha=fit.cuts.alpha)
            meta["cuts"] = {"shape": list(d.shape), "C": fit.cuts.C, "n_examples": fit.cuts.n_examples,
                            "fingerprint": fit.cuts.fingerprint}
        arrays["meta"] = np.array(json.dumps(meta))
        with atomic_file(self.path(key), output=False) as tmp:
            np.savez_compressed(tmp, **arrays)
