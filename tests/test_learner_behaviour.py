"""The learner on problems small enough to solve by hand: the cutting plane's optimum and its record, the
working set's invariants, and the step scorer's settings, fit, prediction and model file."""

from __future__ import annotations

import logging
import time
from dataclasses import asdict

import cvxpy as cp
import numpy as np
import pytest
import scipy.sparse as sps
from threadpoolctl import threadpool_info

from taskseq.features.context import NO_PRIM, OBJECT_COLUMNS, RELATION_COLUMNS, StepContext
from taskseq.learn.estimator import StepScorer
from taskseq.learn.mrf import StepMRF
from taskseq.learn.multiclass import MulticlassModel
from taskseq.learn.persist import save_model
from taskseq.learn.ssvm import CuttingPlaneSSVM, Iteration, learning_curve
from taskseq.learn.working_set import WorkingSet
from taskseq.selection import UNTUNED_C
from taskseq.settings import Learner

# --- the cutting plane ---------------------------------------------------------------------------------------
# Two classes, one feature, x = +1 of class 0 and x = -1 of class 1. With u = w0 - w1 both examples ask
# u >= 1 - xi, so the optimum has w = (u/2, -u/2) and minimises u^2/4 + 2C max(0, 1 - u):
# u = min(4C, 1), objective 2C - 4C^2 for C < 1/4 and 1/4 beyond.
X2, Y2 = [np.array([1.0]), np.array([-1.0])], [0, 1]


def two_points(C: float) -> tuple[np.ndarray, float]:
    u = min(4 * C, 1.0)
    return np.array([u / 2, -u / 2]), 0.25 * u * u + 2 * C * max(0.0, 1 - u)


class Batched(MulticlassModel):
    """The same model with the batch methods, counting the calls of each."""

    def __init__(self, *args) -> None:
        super().__init__(*args)
        self.calls: dict[str, int] = {}

    def _count(self, name: str) -> None:
        self.calls[name] = self.calls.get(name, 0) + 1

    def batch_loss_augmented_inference(self, X, Y, w):
        self._count("oracle")
        return [self.loss_augmented_inference(x, y, w) for x, y in zip(X, Y, strict=True)]

    def batch_loss(self, Y, Y_hat):
        self._count("loss")
        return np.array([self.loss(y, yh) for y, yh in zip(Y, Y_hat, strict=True)])

    def batch_joint_feature_rows(self, X, Y):
        self._count("rows")
        return sps.csr_matrix(np.array([self.joint_feature(x, y) for x, y in zip(X, Y, strict=True)]))

    def batch_inference(self, X, w):
        self._count("inference")
        return [1 - self.inference(x, w) for x in X]  # marked: shows which path predict took


@pytest.mark.parametrize("C", [0.1, 0.2, 1.0])
@pytest.mark.parametrize("n_slacks", [0, 1, 2, 5])
def test_two_points_reach_the_optimum_known_by_hand(C, n_slacks):
    w, objective = two_points(C)
    ssvm = CuttingPlaneSSVM(MulticlassModel(1, 2), C=C, tol=1e-9, n_slacks=n_slacks).fit(X2, Y2)
    assert ssvm.converged_
    np.testing.assert_allclose(ssvm.w_, w, atol=1e-6)
    assert ssvm.primal_objective_ == pytest.approx(objective, rel=1e-9)
    assert ssvm.dual_objective_ == pytest.approx(objective, rel=1e-8)
    assert ssvm.dual_objective_ <= ssvm.primal_objective_
    assert ssvm.predict(X2) == Y2
    assert ssvm.n_iter_ == len(ssvm.history_) and ssvm.n_qp_steps_ > 0


@pytest.mark.parametrize(("n_slacks", "groups"), [(0, 4), (1, 1), (2, 2), (3, 3), (4, 4), (9, 4)])
def test_the_first_iteration_adds_one_cut_per_slack_group(n_slacks, groups):
    X, Y = X2 * 2, Y2 * 2
    ssvm = CuttingPlaneSSVM(MulticlassModel(1, 2), C=1.0, tol=1e-9, n_slacks=n_slacks, inactive_window=0).fit(X, Y)
    first = ssvm.history_[0]
    # at w = 0 every example's wrong class is the most violated labelling, with loss 1
    assert (first.iteration, first.primal, first.best_primal, first.loss) == (1, 4.0, 4.0, 4.0)
    assert first.n_constraints == groups
    assert ssvm.primal_objective_ == pytest.approx(two_points(2.0)[1], rel=1e-9)  # two copies: C doubled


def test_the_record_of_each_iteration():
    seen: list[Iteration] = []
    ssvm = CuttingPlaneSSVM(MulticlassModel(1, 2), C=0.1, tol=1e-9, inactive_window=0, progress=seen.append)
    ssvm.fit(X2, Y2)
    h = ssvm.history_
    assert seen == h and [it.iteration for it in h] == list(range(1, len(h) + 1)) and len(h) >= 2
    assert all(it.best_primal == min(x.primal for x in h[: k + 1]) for k, it in enumerate(h))
    assert all(it.gap == it.best_primal - it.dual for it in h)
    assert all(a.n_constraints <= b.n_constraints for a, b in zip(h, h[1:], strict=False))
    assert all(0 <= a.seconds <= b.seconds for a, b in zip(h, h[1:], strict=False))
    assert h[-1].gap <= 1e-9 * max(1.0, h[-1].best_primal)
    assert ssvm.dual_objective_ == h[-1].dual and ssvm.primal_objective_ == h[-1].best_primal
    assert ssvm.seconds_oracle_ > 0 and ssvm.seconds_qp_ > 0
    assert learning_curve(h) == {"primal": [it.primal for it in h], "best_primal": [it.best_primal for it in h],
                                 "dual": [it.dual for it in h], "gap": [it.gap for it in h]}


def test_primal_is_the_objective_at_the_weights_of_its_iteration():
    """Each iteration's primal is exact: 0.5 |w|^2 + C sum of the losses the oracle's labellings cost at w."""
    ws_seen = []

    class Spy(MulticlassModel):
        def loss_augmented_inference(self, x, y, w):
            ws_seen.append(w.copy())
            return super().loss_augmented_inference(x, y, w)

    C = 0.3
    ssvm = CuttingPlaneSSVM(Spy(1, 2), C=C, tol=1e-9).fit(X2, Y2)
    for it, w in zip(ssvm.history_, ws_seen[::2], strict=True):
        hinge = sum(max(0.0, 1 - (w[y] - w[1 - y]) * x[0]) for x, y in zip(X2, Y2, strict=True))
        assert it.primal == pytest.approx(0.5 * w @ w + C * hinge, abs=1e-12)


def test_one_iteration_returns_the_zero_weights_unconverged():
    ssvm = CuttingPlaneSSVM(MulticlassModel(1, 2), C=0.5, tol=1e-9, max_iter=1).fit(X2, Y2)
    assert ssvm.n_iter_ == 1 and not ssvm.converged_
    assert np.array_equal(ssvm.w_, np.zeros(2)) and ssvm.primal_objective_ == 1.0  # C times two losses
    assert 0 < ssvm.dual_objective_ <= two_points(0.5)[1] + 1e-12


def test_the_stop_is_relative_to_the_best_primal_and_inclusive():
    # C = 100: at w = 0 the primal is 200 and the dual 0, a gap of exactly 1.0 times the primal
    at_once = CuttingPlaneSSVM(MulticlassModel(1, 2), C=100.0, tol=1.0).fit(X2, Y2)
    assert at_once.converged_ and at_once.n_iter_ == 1 and at_once.dual_objective_ == 0.0
    assert at_once.history_[0].n_constraints == 0 and np.array_equal(at_once.w_, np.zeros(2))
    later = CuttingPlaneSSVM(MulticlassModel(1, 2), C=100.0, tol=0.99).fit(X2, Y2)
    assert later.converged_ and later.n_iter_ > 1
    assert later.primal_objective_ - later.dual_objective_ <= 0.99 * later.primal_objective_
    # below a primal of 1 the gap is absolute: with C = 0.2 (optimum 0.24) a tolerance of 0.3 holds at once
    # after the first cut, where a relative one (0.3 * 0.4) would not
    small = CuttingPlaneSSVM(MulticlassModel(1, 2), C=0.2, tol=0.3).fit(X2, Y2)
    assert small.converged_ and small.n_iter_ == 2


def test_batch_methods_are_used_when_the_model_has_them_and_give_the_same_fit():
    plain = CuttingPlaneSSVM(MulticlassModel(1, 2), C=0.1, tol=1e-9).fit(X2, Y2)
    model = Batched(1, 2)
    batched = CuttingPlaneSSVM(model, C=0.1, tol=1e-9).fit(X2, Y2)
    assert batched.w_.tobytes() == plain.w_.tobytes() and batched.n_iter_ == plain.n_iter_
    n = plain.n_iter_
    assert model.calls == {"oracle": n, "loss": n, "rows": n + 1}  # the true labels' rows once, then each oracle's
    assert batched.predict(X2) == [1, 0] and model.calls["inference"] == 1


def test_parameters_and_bad_arguments():
    ssvm = CuttingPlaneSSVM(MulticlassModel(1, 2))
    assert ssvm.get_params() == {"C": 1.0, "tol": 1e-3, "max_iter": 2000, "n_slacks": 1, "inactive_window": 1}
    assert ssvm.progress is None
    model = MulticlassModel(1, 2)
    with pytest.raises(ValueError, match=r"^X has 2 examples but Y has 1$"):
        CuttingPlaneSSVM(model).fit(X2, Y2[:1])
    with pytest.raises(ValueError, match=r"^cannot fit on no examples$"):
        CuttingPlaneSSVM(model).fit([], [])
    for C in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match=rf"^C must be positive and finite, got {C}$"):
            CuttingPlaneSSVM(model, C=C).fit(X2, Y2)
    with pytest.raises(ValueError, match=r"^n_slacks must be 0 \(one per example\) or more, got -1$"):
        CuttingPlaneSSVM(model, n_slacks=-1).fit(X2, Y2)
    for tol in (0.0, -1e-3, float("nan"), float("inf")):
        with pytest.raises(ValueError, match=rf"^tol must be positive and finite \(a relative gap\), got {tol}$"):
            CuttingPlaneSSVM(model, tol=tol).fit(X2, Y2)
    for max_iter in (-1, 2.5):
        with pytest.raises(ValueError, match=rf"^max_iter must be a whole number, 0 \(no oracle call: the start is "
                                             rf"returned, certifying nothing\) or more, got {max_iter}$"):
            CuttingPlaneSSVM(model, max_iter=max_iter).fit(X2, Y2)
    for window in (-1, 0.5):
        with pytest.raises(ValueError, match=rf"^inactive_window must be a whole number, 0 \(keep every cut\) or "
                                             rf"more, got {window}$"):
            CuttingPlaneSSVM(model, inactive_window=window).fit(X2, Y2)


def test_the_default_settings_solve_to_the_default_tolerance():
    ssvm = CuttingPlaneSSVM(MulticlassModel(1, 2)).fit(X2, Y2)  # C = 1: the optimum is 1/4
    assert ssvm.converged_ and ssvm.primal_objective_ - 0.25 <= 1e-3 * 1.0


# --- the working set -----------------------------------------------------------------------------------------

def cvxpy_dual(deltas: np.ndarray, losses: np.ndarray, groups: np.ndarray, n_groups: int, C: float) -> float:
    a = cp.Variable(len(losses))
    cons = [a >= 0] + [cp.sum(a[groups == g]) <= C for g in range(n_groups) if np.any(groups == g)]
    prob = cp.Problem(cp.Maximize(losses @ a - 0.5 * cp.sum_squares(deltas.T @ a)), cons)
    prob.solve(solver=cp.CLARABEL)
    return prob.value


def test_an_empty_working_set():
    ws = WorkingSet(3, 2, 1.5)
    assert len(ws) == 0 and ws.C == 1.5 and isinstance(ws.C, float)
    assert np.array_equal(ws.w, np.zeros(3)) and ws.dual() == 0.0
    assert np.array_equal(ws.slacks(), np.zeros(2))
    assert ws.solve(1e-6) == 0.0 and ws.n_steps == 0 and ws.n_shrinks == 0
    ws.add(np.zeros((0, 3)), np.zeros(0), np.zeros(0, dtype=int), iteration=1)
    assert len(ws) == 0


def test_one_cut_by_hand():
    """max a L - 0.5 a^2 |d|^2 with a <= C: a = min(C, L / |d|^2)."""
    ws = WorkingSet(2, 1, 10.0)
    ws.add(np.array([[3.0, 4.0]]), np.array([5.0]), np.array([0]), iteration=1)
    assert len(ws) == 1 and np.array_equal(ws.alpha, [0.0]) and np.array_equal(ws.losses, [5.0])
    assert np.array_equal(ws.slacks(), [5.0])  # at w = 0 the slack is the loss
    gap = ws.solve(1e-12)
    assert gap <= 1e-12 and ws.alpha[0] == pytest.approx(0.2)
    np.testing.assert_allclose(ws.w, [0.6, 0.8])
    assert ws.dual() == pytest.approx(0.5) and ws.dual(np.array([0.0, 0.0])) == pytest.approx(1.0)
    np.testing.assert_allclose(ws.slacks(), [0.0], atol=1e-12)  # the cut holds with equality
    capped = WorkingSet(2, 1, 0.1)
    capped.add(sps.csr_matrix([[3.0, 4.0]]), np.array([5.0]), np.array([0]), iteration=1)
    capped.solve(1e-12)
    assert capped.alpha[0] == pytest.approx(0.1) and capped.slacks()[0] == pytest.approx(5.0 - 0.1 * 25)


def test_slacks_are_per_group_and_never_negative():
    ws = WorkingSet(2, 3, 1.0)
    ws.add(np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]), np.array([2.0, 3.0, -1.0]), np.array([0, 0, 2]), 1)
    assert np.array_equal(ws.slacks(), [3.0, 0.0, 0.0])
    assert np.array_equal(ws.groups, [0, 0, 2])


def test_new_cuts_see_the_current_weights():
    ws = WorkingSet(2, 2, 10.0)
    ws.add(np.array([[3.0, 4.0]]), np.array([5.0]), np.array([0]), iteration=1)
    ws.solve(1e-12)  # w = (0.6, 0.8)
    ws.add(np.array([[1.0, 0.0]]), np.array([2.0]), np.array([1]), iteration=2)
    np.testing.assert_allclose(ws.slacks(), [0.0, 2.0 - 0.6], atol=1e-12)
    assert ws.alpha[1] == 0.0 and np.allclose(ws.w, [0.6, 0.8])


@pytest.mark.parametrize("n_groups", [1, 3])
def test_solve_reaches_cvxpys_optimum_within_the_gap_it_returns(n_groups):
    rng = np.random.default_rng(5)
    K, d, C = 12, 4, 0.7
    deltas, losses = rng.normal(size=(K, d)), rng.uniform(0.5, 2.0, size=K)
    groups = np.arange(K) % n_groups
    ws = WorkingSet(d, n_groups, C)
    ws.add(deltas, losses, groups, iteration=1)
    optimum = cvxpy_dual(deltas, losses, groups, n_groups, C)
    rough = ws.solve(0.05)
    assert rough <= 0.05 and optimum - ws.dual() <= rough + 1e-9
    steps = ws.n_steps
    fine = ws.solve(1e-10)
    assert ws.n_steps >= steps and ws.dual() == pytest.approx(optimum, rel=1e-7) and fine <= 1e-10
    assert np.all(ws.alpha >= 0) and np.bincount(groups, ws.alpha).max() <= C * (1 + 1e-12)


def test_max_steps_bounds_a_solve():
    rng = np.random.default_rng(2)
    deltas, losses = rng.normal(size=(30, 5)), rng.uniform(1, 2, size=30)
    bounded, free = WorkingSet(5, 1, 1.0), WorkingSet(5, 1, 1.0)
    for ws in (bounded, free):
        ws.add(deltas, losses, np.zeros(30, dtype=int), iteration=1)
    gap = bounded.solve(1e-12, max_steps=1)  # one visit of the group, then the bound stops the solve
    assert free.solve(1e-12) <= 1e-12 < gap and 0 < bounded.n_steps < free.n_steps


def test_capacity_grows_and_keeps_every_cut():
    rng = np.random.default_rng(4)
    K, d = 150, 6
    deltas, losses = rng.normal(size=(K, d)), rng.uniform(0.5, 2.0, size=K)
    groups = np.arange(K) % 4
    ws = WorkingSet(d, 4, 0.5)
    for k in range(K):  # one at a time, past every growth of the buffers
        ws.add(deltas[k : k + 1], losses[k : k + 1], groups[k : k + 1], iteration=k)
    assert len(ws) == K and np.array_equal(ws.losses, losses) and np.array_equal(ws.groups, groups)
    np.testing.assert_allclose(ws._gram[:K, :K], deltas @ deltas.T, rtol=1e-12, atol=1e-12)
    ws.solve(1e-10)
    assert ws.dual() == pytest.approx(cvxpy_dual(deltas, losses, groups, 4, 0.5), rel=1e-7)


def pruned_case():
    """Three cuts, one group; the third never gets weight (no loss to gain, its gradient -5 (w1 + w2) < 0)."""
    deltas = np.array([[1.0, 0.0], [0.0, 1.0], [5.0, 5.0]])
    ws = WorkingSet(2, 1, 10.0)
    ws.add(deltas[:2], np.array([1.0, 1.0]), np.array([0, 0]), iteration=1)
    ws.add(deltas[2:], np.array([0.0]), np.array([0]), iteration=2)
    ws.solve(1e-12)
    return ws, deltas


def test_prune_drops_only_cuts_idle_for_the_window():
    ws, deltas = pruned_case()
    assert ws.alpha[2] == 0.0 and np.all(ws.alpha[:2] > 0)
    w, dual = ws.w.copy(), ws.dual()
    ws.prune(3, 2)  # idle since iteration 2: 1 iteration < 2, kept
    assert len(ws) == 3
    ws.prune(4, 2)  # 2 iterations: dropped
    assert len(ws) == 2 and np.array_equal(ws.losses, [1.0, 1.0]) and np.array_equal(ws.groups, [0, 0])
    np.testing.assert_allclose(ws.w, w, atol=0) and np.isclose(ws.dual(), dual)
    np.testing.assert_array_equal(ws._gram[:2, :2], deltas[:2] @ deltas[:2].T)
    ws.add(np.array([[1.0, 1.0]]), np.array([3.0]), np.array([0]), iteration=5)
    ws.solve(1e-12)
    kept = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    assert ws.dual() == pytest.approx(cvxpy_dual(kept, np.array([1.0, 1.0, 3.0]), np.zeros(3, int), 1, 10.0))


def test_cuts_with_weight_stay_and_window_zero_keeps_all():
    ws, _ = pruned_case()
    ws.prune(100, 0)
    assert len(ws) == 3
    ws.prune(100, 1)  # the cuts with weight were active at 100 (marked by the call before): only the idle one goes
    assert len(ws) == 2 and np.all(ws.alpha > 0)
    ws.prune(101, 1)  # and still have weight at 101
    assert len(ws) == 2


# --- the step scorer -----------------------------------------------------------------------------------------

def step(rng: np.random.Generator, n: int, task: int, gold: tuple[int, int, int] | None) -> StepContext:
    """A hand-made step of n objects; the gold arguments are marked as the task's in `task_rel`."""
    objects = rng.uniform(size=(n, len(OBJECT_COLUMNS)))
    objects[:, 0] = 0.0
    task_rel = np.zeros((n, 4))
    if gold is not None and gold[1] >= 0:
        task_rel[gold[1], 0] = 1.0
    return StepContext([f"o{i}" for i in range(n)], objects, task_rel, np.zeros((n, n), dtype=bool), task,
                       (NO_PRIM, NO_PRIM), (-1, -1, -1, -1), gold, rng.uniform(size=(n, len(RELATION_COLUMNS))))


@pytest.fixture
def steps() -> list[StepContext]:
    rng = np.random.default_rng(0)
    golds = [(1, 0, -1), (1, 2, -1), (0, 1, -1), (7, -1, -1), (3, 0, 1), (1, 3, -1)]
    return [step(rng, 4, k % 2, g) for k, g in enumerate(golds)]


SETTINGS = {"C": 0.5, "tol": 1e-6, "max_iter": 300, "n_slacks": 0}
DEFAULTS = {"features": "full", "C": 3.0, "tol": 1e-3, "max_iter": 2000, "n_slacks": 0}


def test_settings_default_to_the_estimators_own_and_round_trip():
    # the learner's defaults are its own numbers (it imports nothing of the pipeline); they agree with the
    # pipeline's learner and its untuned C, so a model fitted either way is the same
    default = StepScorer()
    assert default.get_params() == DEFAULTS == {"features": "full", "C": UNTUNED_C, **asdict(Learner())}
    assert default.get_params(deep=False) == default.get_params()
    s = StepScorer("edge", **SETTINGS)
    assert list(s.get_params()) == ["features", "C", "tol", "max_iter", "n_slacks"]
    assert s.set_params(C=2.0, tol=0.1) is s and s.C == 2.0 and s.tol == 0.1
    with pytest.raises(ValueError, match=r"^StepScorer has no parameter gamma, rho: its parameters are "
                                         r"features, C, tol, max_iter, n_slacks$"):
        s.set_params(rho=1, gamma=2, C=3.0)
    assert s.C == 2.0  # nothing set when a name is wrong
    copy = s.clone()
    assert type(copy) is StepScorer and copy is not s and copy.get_params() == s.get_params()
    assert repr(s) == "StepScorer(features='edge', C=2.0, tol=0.1, max_iter=300, n_slacks=0)"


@pytest.mark.parametrize(("bad", "message"), [
    ({"features": "nope"},
     r"^features must be one of \['choice', 'clique', 'edge', 'full', 'relations'\], got 'nope'$"),
    ({"C": 0.0}, "C and tol must be positive"), ({"tol": 0.0}, "C and tol must be positive"),
    ({"C": float("nan")}, "C and tol must be positive"), ({"max_iter": 0}, "max_iter at least 1"),
    ({"n_slacks": -1}, r"n_slacks at least 0 \(one per step\): \{'features': 'edge'"),
])
def test_bad_settings_are_refused_when_fitting(steps, bad, message):
    with pytest.raises(ValueError, match=message):
        StepScorer(**{"features": "edge", **SETTINGS, **bad}).fit(steps)


def test_the_least_settings_are_accepted(steps):
    s = StepScorer("edge", C=1e-9, tol=1e-9, max_iter=1, n_slacks=0).fit(steps)
    assert s.ssvm_.n_iter_ == 1


def test_fit_is_the_structural_svm_of_the_mrf_with_these_settings(steps):
    s = StepScorer("edge", **SETTINGS).fit(steps)
    direct = CuttingPlaneSSVM(StepMRF("edge"), **SETTINGS).fit(steps, [x.gold for x in steps])
    assert s.w_.tobytes() == direct.w_.tobytes() and s.ssvm_.n_iter_ == direct.n_iter_
    assert s.ssvm_.get_params() == {**SETTINGS, "inactive_window": 1} and s.ssvm_.converged_
    assert s.model_.features == "edge" and s.n_steps_ == 6 and s.fit_seconds_ > 0
    assert s.ssvm_.progress is None and s.model_._batch_cache is None  # keeps neither its bar nor its steps
    one_slack = StepScorer("edge", **{**SETTINGS, "n_slacks": 1}).fit(steps)
    assert one_slack.ssvm_.history_[0].n_constraints == 1 and s.ssvm_.history_[0].n_constraints == 6


def test_fit_takes_given_labels_over_the_demonstrated_ones(steps):
    y = [(7, -1, -1)] * len(steps)
    s = StepScorer("edge", **SETTINGS).fit(steps, y)
    assert s.predict(steps) == y
    gold = StepScorer("edge", **SETTINGS).fit(steps)
    assert gold.w_.tobytes() == StepScorer("edge", **SETTINGS).fit(steps, [x.gold for x in steps]).w_.tobytes()
    unlabelled = steps[:2] + [step(np.random.default_rng(1), 4, 0, None)]
    with pytest.raises(ValueError, match=r"^steps without a demonstrated label need `y`$"):
        StepScorer("edge", **SETTINGS).fit(unlabelled)
    assert StepScorer("edge", **SETTINGS).fit(unlabelled, [(7, -1, -1)] * 3).n_steps_ == 3
    with pytest.raises(ValueError, match=r"^no training steps$"):
        StepScorer("edge", **SETTINGS).fit([])


def test_predict_and_top_k_read_the_fitted_weights(steps):
    s = StepScorer("full", **SETTINGS).fit(steps)
    model = StepMRF("full")
    assert s.predict(steps) == [model.inference(x, s.w_) for x in steps]
    assert s.model_._batch_cache is None
    assert s.top_k(steps[4], 3) == model.top_k(steps[4], s.w_, 3) and len(s.top_k(steps[4], 3)) == 3
    for x in steps[:5]:  # the lazy ranking: every candidate, in top_k's order, by the fitted weights
        ranked = list(s.ranked(x))
        assert ranked == list(model.ranked(x, s.w_)) == model.top_k(x, s.w_, len(ranked))
        assert len(ranked) > 3 and ranked[:3] == s.top_k(x, 3)
    for unfitted in (StepScorer().predict, lambda X: StepScorer().top_k(X[0], 1), lambda X: StepScorer().save("m"),
                     lambda X: StepScorer().ranked(X[0])):
        with pytest.raises(ValueError, match=r"^this StepScorer is not fitted yet: call fit or load first$"):
            unfitted(steps)


def test_a_saved_scorer_loads_with_its_settings_weights_and_meta(steps, tmp_path):
    s = StepScorer("edge", **SETTINGS).fit(steps)
    s.save(tmp_path / "m.npz", method="mrf", seed=3)
    loaded = StepScorer.load(tmp_path / "m.npz")
    assert loaded.get_params() == s.get_params() and loaded.ssvm_ is None
    assert loaded.w_.tobytes() == s.w_.tobytes() and loaded.model_.features == "edge"
    assert loaded.meta_ == {"format": "taskseq.mrf/3", "features": "edge", **SETTINGS, "method": "mrf", "seed": 3}
    assert loaded.predict(steps) == s.predict(steps)
    save_model(tmp_path / "bare.npz", StepMRF("clique"), np.ones(StepMRF("clique").size_joint_feature), {})
    bare = StepScorer.load(tmp_path / "bare.npz")  # settings not saved: the defaults
    assert bare.get_params() == {**DEFAULTS, "features": "clique"}


def test_a_scorer_from_given_weights(steps):
    d = StepMRF("edge").size_joint_feature
    p = StepScorer.from_weights("edge", np.arange(d), C=2.0)
    assert p.w_.dtype == np.float64 and p.C == 2.0 and p.ssvm_ is None and p.model_.features == "edge"
    assert p.get_params() == {**DEFAULTS, "features": "edge", "C": 2.0}
    assert p.predict(steps) == StepMRF("edge").batch_inference(steps, np.arange(d, dtype=float))
    with pytest.raises(ValueError, match=rf"^edge weights must have shape \({d},\), got \({d - 1},\)$"):
        StepScorer.from_weights("edge", np.zeros(d - 1))


# --- what a fit reports beside its weights -------------------------------------------------------------------


class Bar:
    """Stands in for tqdm: what the bar was made with and what it was shown, and the BLAS threads meanwhile."""

    made: list[Bar] = []

    def __init__(self, **kwargs) -> None:
        self.kwargs, self.updates, self.postfix, self.closed, self.threads = kwargs, [], [], False, set()
        Bar.made.append(self)

    def update(self, n):
        self.updates.append(n)
        self.threads |= {pool["num_threads"] for pool in threadpool_info()}

    def set_postfix(self, **kwargs):
        self.postfix.append(kwargs)

    def close(self):
        self.closed = True


@pytest.mark.parametrize("progress", [False, True])
def test_the_progress_bar_counts_iterations_with_the_gap_and_constraints(steps, monkeypatch, progress):
    monkeypatch.setattr("taskseq.learn.estimator.tqdm", Bar)
    Bar.made = []
    s = StepScorer("edge", **SETTINGS)
    (s.fit(steps, progress=True) if progress else s.fit(steps))
    (bar,) = Bar.made
    # a bar on a terminal only (disable=None lets tqdm decide) when asked for, none otherwise
    assert bar.kwargs == {"total": 300, "desc": "ssvm edge", "unit": "it", "disable": None if progress else True,
                          "leave": False, "mininterval": 0.5}
    h = s.ssvm_.history_
    assert bar.updates == [1] * len(h) and bar.closed
    assert bar.postfix == [{"gap": f"{it.gap:.3g}", "constraints": it.n_constraints} for it in h]
    assert bar.threads == {1}  # one BLAS thread while the learner runs: the same sums in any process


def test_a_failed_fit_closes_its_bar(steps, monkeypatch):
    def fails(self, X, y, warm_start=None):
        raise RuntimeError("the solver gave up")

    monkeypatch.setattr("taskseq.learn.estimator.tqdm", Bar)
    monkeypatch.setattr("taskseq.learn.estimator.CuttingPlaneSSVM.fit", fails)
    Bar.made = []
    with pytest.raises(RuntimeError, match="gave up"):
        StepScorer("edge", **SETTINGS).fit(steps)
    assert Bar.made[0].closed


def test_a_label_that_is_not_a_candidate_is_refused_by_name(steps):
    labels = [x.gold for x in steps]
    labels[1] = (0, 99, -1)  # an argument no step has
    with pytest.raises(ValueError, match=r"label 1 \(0, 99, -1\) is not a candidate of its step \(\d+ objects\): a "
                                         r"primitive index, then argument indices among the step's objects or -1$"):
        StepScorer("edge", **SETTINGS).fit(steps, labels)
    with pytest.raises(ValueError, match="2 labels"):
        StepScorer("edge", **SETTINGS).fit(steps, labels[:2])


def test_the_times_a_fit_reports_are_within_its_wall_time(steps):
    start = time.perf_counter()
    s = StepScorer("edge", **SETTINGS).fit(steps)
    elapsed = time.perf_counter() - start
    assert 0 < s.fit_seconds_ <= elapsed
    ssvm = s.ssvm_
    assert 0 < ssvm.seconds_oracle_ + ssvm.seconds_qp_ <= elapsed
    assert 0 < ssvm.history_[-1].seconds <= elapsed


class SlowFirst(MulticlassModel):
    """The first oracle call does a fixed amount of extra work; each call times itself."""

    def __init__(self, *args) -> None:
        super().__init__(*args)
        self.spent = 0.0
        self.calls = 0

    def loss_augmented_inference(self, x, y, w):
        t = time.perf_counter()
        if self.calls == 0:
            np.linalg.svd(np.random.default_rng(0).normal(size=(150, 150)))
        self.calls += 1
        out = super().loss_augmented_inference(x, y, w)
        self.spent += time.perf_counter() - t
        return out


class SlowFirstSolve(WorkingSet):
    spent = 0.0
    solves = 0

    def solve(self, tol, max_steps=10_000_000):
        t = time.perf_counter()
        if SlowFirstSolve.solves == 0:
            np.linalg.svd(np.random.default_rng(0).normal(size=(150, 150)))
        SlowFirstSolve.solves += 1
        out = super().solve(tol, max_steps)
        SlowFirstSolve.spent += time.perf_counter() - t
        return out


def test_oracle_and_qp_times_add_up_over_the_iterations(monkeypatch):
    monkeypatch.setattr("taskseq.learn.ssvm.WorkingSet", SlowFirstSolve)
    SlowFirstSolve.spent, SlowFirstSolve.solves = 0.0, 0
    model = SlowFirst(1, 2)
    start = time.perf_counter()
    ssvm = CuttingPlaneSSVM(model, C=0.1, tol=1e-9).fit(X2, Y2)
    elapsed = time.perf_counter() - start
    assert ssvm.n_iter_ >= 2 and SlowFirstSolve.solves >= 1
    assert model.spent <= ssvm.seconds_oracle_ and SlowFirstSolve.spent <= ssvm.seconds_qp_
    assert ssvm.seconds_oracle_ + ssvm.seconds_qp_ <= elapsed


def test_each_iteration_is_logged(caplog):
    with caplog.at_level(logging.DEBUG, logger="taskseq.learn.ssvm"):
        ssvm = CuttingPlaneSSVM(MulticlassModel(1, 2), C=0.1, tol=1e-9).fit(X2, Y2)
    lines = [r.getMessage() for r in caplog.records if r.name == "taskseq.learn.ssvm"]
    assert lines == [f"iteration {it.iteration}: primal {it.primal:.6g} best {it.best_primal:.6g} dual {it.dual:.6g}"
                     for it in ssvm.history_]
    assert lines[0].startswith("iteration 1: primal 0.2 best 0.2 dual ")


def test_no_iteration_certifies_nothing():
    ssvm = CuttingPlaneSSVM(MulticlassModel(1, 2), max_iter=0).fit(X2, Y2)
    assert ssvm.converged_ is False and ssvm.n_iter_ == 0 and ssvm.primal_objective_ == np.inf
    assert np.array_equal(ssvm.w_, np.zeros(2))


def blobs():
    rng = np.random.default_rng(0)
    n, d, k = 30, 3, 3
    centers = rng.normal(scale=2.0, size=(k, d))
    y = rng.integers(k, size=n)
    return list(centers[y] + rng.normal(size=(n, d))), [int(c) for c in y], MulticlassModel(d, k)


def test_idle_cuts_leave_the_working_set_only_with_a_window():
    X, Y, model = blobs()
    kept = CuttingPlaneSSVM(model, C=0.3, tol=1e-7, n_slacks=0, inactive_window=0).fit(X, Y)
    pruned = CuttingPlaneSSVM(model, C=0.3, tol=1e-7, n_slacks=0, inactive_window=1).fit(X, Y)
    sizes = [h.n_constraints for h in pruned.history_]
    assert any(b < a for a, b in zip(sizes, sizes[1:], strict=False))  # cuts left
    sizes = [h.n_constraints for h in kept.history_]
    assert all(b >= a for a, b in zip(sizes, sizes[1:], strict=False))
    assert pruned.primal_objective_ == pytest.approx(kept.primal_objective_, rel=1e-6)


def test_an_example_the_weights_already_separate_adds_no_cut():
    X, Y, _ = blobs()
    wrong: list[int] = []

    class Counting(MulticlassModel):
        def loss_augmented_inference(self, x, y, w):
            out = super().loss_augmented_inference(x, y, w)
            wrong[-1] += out != y
            return out

    class Start(Counting):
        def batch_loss_augmented_inference(self, X, Y, w):
            wrong.append(0)
            return [self.loss_augmented_inference(x, y, w) for x, y in zip(X, Y, strict=True)]

    ssvm = CuttingPlaneSSVM(Start(3, 3), C=0.3, tol=1e-7, n_slacks=0, inactive_window=0).fit(X, Y)
    sizes = [0] + [h.n_constraints for h in ssvm.history_]
    added = [b - a for a, b in zip(sizes, sizes[1:], strict=False)]
    assert all(a <= w for a, w in zip(added, wrong, strict=True)) and wrong[-1] < len(X)
    assert sum(wrong) > sum(added)  # some violated examples were within their slack already


def test_shrinkings_are_counted_over_all_solves():
    rng = np.random.default_rng(11)
    K, d, B = 300, 20, 100
    deltas = rng.normal(size=(K, d)) * (rng.uniform(size=(K, d)) < 0.3)
    losses, groups = rng.uniform(0.5, 3.0, size=K), rng.integers(B, size=K)
    ws = WorkingSet(d, B, 1.5)
    for part in np.array_split(np.arange(K), 3):
        ws.add(deltas[part], losses[part], groups[part], iteration=1)
        ws.solve(1e-9)
    shrinks = ws.n_shrinks
    assert shrinks > 0
    ws.solve(1e-9)  # at the optimum already: no step, no shrinking, and the count stays
    assert ws.n_shrinks == shrinks
    assert ws.dual() == pytest.approx(cvxpy_dual(deltas, losses, groups, B, 1.5), rel=1e-7)


# --- the working set past its Gram matrix ---------------------------------------------------------------------

def sparse_cuts(seed: int, K: int, d: int, B: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cuts with a third of their entries non-zero and one slack group per few cuts, as the n-slack problem has."""
    rng = np.random.default_rng(seed)
    deltas = rng.normal(size=(K, d)) * (rng.uniform(size=(K, d)) < 0.3)
    return deltas, rng.uniform(0.5, 3.0, size=K), rng.integers(B, size=K)


@pytest.mark.parametrize("sparse", [False, True])
def test_explicit_weights_reach_cvxpys_optimum(sparse):
    """With no Gram matrix at all (limit 0) the sweeps on explicit weights solve the same QP, batch after batch."""
    K, d, B, C = 300, 20, 100, 1.5
    deltas, losses, groups = sparse_cuts(11, K, d, B)
    ws = WorkingSet(d, B, C, gram_limit=0)
    for part in np.array_split(np.arange(K), 3):
        ws.add(sps.csr_matrix(deltas[part]) if sparse else deltas[part], losses[part], groups[part], iteration=1)
        gap = ws.solve(1e-9)
        assert gap <= 1e-9
    assert ws._gram is None and ws.n_sweeps > 0 and ws.n_shrinks == 0
    assert ws.dual() == pytest.approx(cvxpy_dual(deltas, losses, groups, B, C), rel=1e-7)
    assert np.all(ws.alpha >= 0) and np.bincount(groups, ws.alpha, minlength=B).max() <= C * (1 + 1e-12)
    np.testing.assert_allclose(ws.w, deltas.T @ ws.alpha, rtol=1e-12, atol=1e-12)  # w is the alpha it reports
    xi = np.zeros(B)
    np.maximum.at(xi, groups, losses - deltas @ ws.w)
    np.testing.assert_allclose(ws.slacks(), xi, atol=1e-9)


def test_explicit_weights_by_hand():
    """One cut, a = min(C, L / |d|^2), as with the Gram matrix; a second solve at the optimum takes no step."""
    ws = WorkingSet(2, 1, 10.0, gram_limit=0)
    ws.add(np.array([[3.0, 4.0]]), np.array([5.0]), np.array([0]), iteration=1)
    assert np.array_equal(ws.slacks(), [5.0])
    assert ws.solve(1e-12) <= 1e-12 and ws.alpha[0] == pytest.approx(0.2)
    np.testing.assert_allclose(ws.w, [0.6, 0.8])
    assert ws.dual() == pytest.approx(0.5)
    steps, sweeps = ws.n_steps, ws.n_sweeps
    ws.solve(1e-9)
    assert (ws.n_steps, ws.n_sweeps) == (steps, sweeps)
    ws.add(np.array([[1.0, 0.0]]), np.array([2.0]), np.array([0]), iteration=2)  # new cuts see the weights
    np.testing.assert_allclose(ws.slacks(), [2.0 - 0.6], atol=1e-12)
    w = ws.w
    w[:] = 7.0  # a copy: the set's weights do not change with it
    np.testing.assert_allclose(ws.w, [0.6, 0.8])


def test_max_steps_bounds_a_solve_on_explicit_weights():
    deltas, losses, groups = sparse_cuts(2, 60, 8, 3)
    bounded, free = WorkingSet(8, 3, 1.0, gram_limit=0), WorkingSet(8, 3, 1.0, gram_limit=0)
    for ws in (bounded, free):
        ws.add(deltas, losses, groups, iteration=1)
    gap = bounded.solve(1e-12, max_steps=1)
    assert free.solve(1e-12) <= 1e-12 < gap and 0 < bounded.n_steps < free.n_steps


def test_the_gram_matrix_goes_past_the_limit_and_comes_back_when_pruned():
    """A set that outgrows its limit drops the Gram matrix and keeps the weights; pruned back under the limit
    it forms the Gram matrix again, exactly symmetric and equal to every cross product. The optimum is the one
    a set that always kept its Gram matrix finds."""
    K, d, B, C = 240, 30, 80, 1.5
    deltas, losses, groups = sparse_cuts(5, K, d, B)
    limited, kept = WorkingSet(d, B, C, gram_limit=150), WorkingSet(d, B, C, gram_limit=10_000)
    for ws in (limited, kept):
        for it, part in enumerate(np.array_split(np.arange(K), 3), start=1):
            ws.add(deltas[part], losses[part], groups[part], iteration=it)
            ws.solve(1e-9)
        assert ws.dual() == pytest.approx(cvxpy_dual(deltas, losses, groups, B, C), rel=1e-7)
    assert limited._gram is None and limited.n_sweeps > 0  # 240 cuts > 150
    assert kept._gram is not None and kept.n_sweeps == 0
    limited.prune(10, 1)  # only the cuts with weight stay
    size = len(limited)
    assert size <= 150 and limited._gram is None
    w = limited.w
    limited.solve(1e-9)
    gram = limited._gram[:size, :size]
    assert np.array_equal(gram, gram.T)
    held = limited._deltas.toarray()
    np.testing.assert_allclose(gram, held @ held.T, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(limited.w, w, rtol=1e-12, atol=1e-12)  # the optimum did not move


def test_a_fit_past_the_gram_limit_reaches_the_optimum(monkeypatch):
    """The whole cutting plane with every working set on explicit weights still certifies the optimum."""
    monkeypatch.setattr("taskseq.learn.working_set.GRAM_LIMIT", 0)
    X, Y, model = blobs()
    explicit = CuttingPlaneSSVM(model, C=0.3, tol=1e-7, n_slacks=0).fit(X, Y)
    monkeypatch.setattr("taskseq.learn.working_set.GRAM_LIMIT", 10_000)
    gram = CuttingPlaneSSVM(model, C=0.3, tol=1e-7, n_slacks=0).fit(X, Y)
    assert explicit.converged_ and gram.converged_
    assert explicit.primal_objective_ == pytest.approx(gram.primal_objective_, rel=1e-6)


def test_the_gram_limit_is_inclusive_both_ways():
    """A set of exactly `gram_limit` cuts keeps its Gram matrix, one more drops it; pruned back to exactly the
    limit, the next solve forms it again."""
    deltas, losses, groups = sparse_cuts(9, 6, 5, 3)
    ws = WorkingSet(5, 3, 1.0, gram_limit=4)
    ws.add(deltas[:4], losses[:4], groups[:4], iteration=1)
    assert ws._gram is not None
    ws.add(deltas[4:], losses[4:], groups[4:], iteration=2)
    assert ws._gram is None
    ws.solve(1e-9)
    keep = np.zeros(6, dtype=bool)
    keep[np.argsort(-ws.alpha, kind="stable")[:4]] = True
    ws._last_active[:6] = np.where(keep, 10, 0)
    ws._alpha[:6][~keep] = 0.0  # as if only four cuts had weight: pruning leaves exactly the limit
    ws.prune(10, 1)
    assert len(ws) == 4 and ws._gram is None
    ws.solve(1e-9)
    assert ws._gram is not None
