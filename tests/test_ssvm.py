"""The cutting-plane SSVM: the optimum of the full QP for every slack grouping, the working-set QP,
the scikit-learn equivalence, convergence."""

import itertools

import cvxpy as cp
import numpy as np
import pytest
from sklearn.svm import LinearSVC

from taskseq.learn.multiclass import MulticlassModel
from taskseq.learn.ssvm import CuttingPlaneSSVM
from taskseq.learn.working_set import WorkingSet


class PairModel:
    """A toy two-node MRF: y = (a, b) in 3 x 3, unary features of x for each node, a pairwise table."""

    K = 3

    def __init__(self, d: int) -> None:
        self.d = d
        self.size_joint_feature = 2 * d * self.K + self.K * self.K

    def labels(self):
        return list(itertools.product(range(self.K), repeat=2))

    def joint_feature(self, x, y):
        a, b = y
        out = np.zeros(self.size_joint_feature)
        out[a * self.d : (a + 1) * self.d] = x[: self.d]
        o = self.K * self.d
        out[o + b * self.d : o + (b + 1) * self.d] = x[self.d :]
        out[2 * o + a * self.K + b] = 1.0
        return out

    def loss(self, y, y_hat):
        return float((y[0] != y_hat[0]) + (y[1] != y_hat[1]))

    def inference(self, x, w):
        return max(self.labels(), key=lambda y: w @ self.joint_feature(x, y))

    def loss_augmented_inference(self, x, y, w):
        return max(self.labels(), key=lambda yh: w @ self.joint_feature(x, yh) + self.loss(y, yh))


def brute_force_optimum(model, X, Y, C):
    """The n-slack QP with one constraint per example and labeling, solved directly."""
    w = cp.Variable(model.size_joint_feature)
    xi = cp.Variable(len(X))
    cons = [xi >= 0]
    for i, (x, y) in enumerate(zip(X, Y, strict=True)):
        psi = model.joint_feature(x, y)
        for yh in model.labels():
            cons.append(w @ (psi - model.joint_feature(x, yh)) >= model.loss(y, yh) - xi[i])
    prob = cp.Problem(cp.Minimize(0.5 * cp.sum_squares(w) + C * cp.sum(xi)), cons)
    prob.solve(solver=cp.CLARABEL)
    return prob.value


@pytest.fixture
def toy():
    rng = np.random.default_rng(3)
    d = 4
    X = [rng.normal(size=2 * d) for _ in range(12)]
    Y = [(int(np.argmax(x[:3])), int(np.argmax(x[d : d + 3]))) for x in X]
    Y[0] = (2, 0)  # one noisy label so that slacks are active
    return PairModel(d), X, Y


def test_reaches_the_optimum_of_the_full_qp(toy):
    model, X, Y = toy
    C, tol = 2.0, 1e-5
    ssvm = CuttingPlaneSSVM(model, C=C, tol=tol, max_iter=500).fit(X, Y)
    optimum = brute_force_optimum(model, X, Y, C)
    assert ssvm.converged_
    assert ssvm.dual_objective_ <= optimum + 1e-6 * abs(optimum)
    assert ssvm.primal_objective_ >= optimum - 1e-6 * abs(optimum)
    assert ssvm.primal_objective_ - optimum <= 2 * tol * max(1.0, abs(optimum))


@pytest.mark.parametrize("n_slacks", [1, 3, 12, 0])
def test_every_slack_grouping_reaches_the_same_optimum(toy, n_slacks):
    model, X, Y = toy
    C = 2.0
    optimum = brute_force_optimum(model, X, Y, C)
    ssvm = CuttingPlaneSSVM(model, C=C, tol=1e-9, max_iter=2000, n_slacks=n_slacks).fit(X, Y)
    assert ssvm.converged_
    assert ssvm.primal_objective_ == pytest.approx(optimum, rel=1e-6)
    assert ssvm.dual_objective_ <= optimum + 1e-6 * abs(optimum)


def test_working_set_dual_matches_a_direct_cvxpy_solve():
    """The pairwise solver of the working-set QP against the same QP stated in cvxpy."""
    from taskseq.learn.working_set import WorkingSet

    rng = np.random.default_rng(7)
    K, d, B, C = 40, 15, 3, 2.5
    base = rng.normal(size=(5, d))
    deltas = rng.normal(size=(K, 5)) @ base + 0.1 * rng.normal(size=(K, d))  # nearly parallel cuts, as in training
    losses = rng.uniform(1.0, 20.0, size=K)
    groups = rng.integers(B, size=K)
    ws = WorkingSet(d, B, C)
    ws.add(deltas[:25], losses[:25], groups[:25], iteration=1)
    ws.solve(1e-10)
    ws.add(deltas[25:], losses[25:], groups[25:], iteration=2)  # warm start from the previous optimum
    ws.solve(1e-10)
    a = cp.Variable(K)
    cons = [a >= 0] + [cp.sum(a[groups == g]) <= C for g in range(B)]
    prob = cp.Problem(cp.Maximize(losses @ a - 0.5 * cp.sum_squares(deltas.T @ a)), cons)
    prob.solve(solver=cp.CLARABEL)
    assert ws.dual() == pytest.approx(prob.value, rel=1e-7)
    assert np.all(ws.alpha >= 0)
    assert all(ws.alpha[groups == g].sum() <= C * (1 + 1e-12) for g in range(B))


@pytest.mark.parametrize("sparse", [False, True])
def test_many_groups_with_shrinking_match_a_direct_cvxpy_solve(sparse):
    """One group per few cuts, as the n-slack problem has, and enough of them that the solver sets cuts aside
    (shrinking) and brings them back: the optimum is the one cvxpy finds, added in three batches."""
    import scipy.sparse as sps

    from taskseq.learn.working_set import WorkingSet

    rng = np.random.default_rng(11)
    K, d, B, C = 900, 30, 300, 1.5
    deltas = rng.normal(size=(K, d)) * (rng.uniform(size=(K, d)) < 0.3)  # sparse rows, as the MRF's cuts
    losses = rng.uniform(0.5, 3.0, size=K)
    groups = rng.integers(B, size=K)
    ws = WorkingSet(d, B, C)
    for part in np.array_split(np.arange(K), 3):
        ws.add(sps.csr_matrix(deltas[part]) if sparse else deltas[part], losses[part], groups[part], iteration=1)
        ws.solve(1e-9)
    a = cp.Variable(K)
    cons = [a >= 0] + [cp.sum(a[groups == g]) <= C for g in range(B)]
    prob = cp.Problem(cp.Maximize(losses @ a - 0.5 * cp.sum_squares(deltas.T @ a)), cons)
    prob.solve(solver=cp.CLARABEL)
    assert ws.n_shrinks > 0  # the case this test is for
    assert ws.dual() == pytest.approx(prob.value, rel=1e-7)
    assert np.all(ws.alpha >= 0)
    assert np.bincount(groups, weights=ws.alpha, minlength=B).max() <= C * (1 + 1e-12)
    # the slacks it reports are those of its own solution
    xi = np.zeros(B)
    np.maximum.at(xi, groups, losses - deltas @ ws.w)
    np.testing.assert_allclose(ws.slacks(), xi, atol=1e-9)


def test_the_gram_matrix_is_scipys_sparse_product_bit_for_bit():
    """Cuts added in batches: every entry is d_i . d_j summed in scipy's order (so the fitted weights are the
    bytes they were with scipy's product), and the matrix is exactly symmetric."""
    import scipy.sparse as sps

    from taskseq.learn.working_set import WorkingSet

    rng = np.random.default_rng(3)
    K, d = 260, 400
    deltas = sps.random(K, d, density=0.05, random_state=rng, format="csr") * 7.3
    deltas.data -= 3.1  # signs of both kinds, and values that round
    ws = WorkingSet(d, 10, 1.0)
    for part in np.array_split(np.arange(K), [1, 90, 91]):  # one cut, many, one, many again
        ws.add(deltas[part], np.ones(len(part)), part % 10, iteration=1)
    gram = ws._gram[:K, :K]
    expected = (deltas @ deltas.T).toarray()
    assert gram.tobytes() == expected.tobytes()
    assert np.array_equal(gram, gram.T)


@pytest.mark.parametrize("window", [0, 1, 50])
def test_pruning_the_working_set_never_changes_the_optimum(toy, window):
    model, X, Y = toy
    optimum = brute_force_optimum(model, X, Y, 2.0)
    ssvm = CuttingPlaneSSVM(model, C=2.0, tol=1e-9, max_iter=2000, n_slacks=len(X), inactive_window=window).fit(X, Y)
    assert ssvm.converged_
    assert ssvm.primal_objective_ == pytest.approx(optimum, rel=1e-6)


def test_bounds_move_monotonically_and_the_gap_closes(toy):
    model, X, Y = toy
    ssvm = CuttingPlaneSSVM(model, C=2.0, tol=1e-5, max_iter=500, inactive_window=0).fit(X, Y)
    hist = ssvm.history_
    best = [h.best_primal for h in hist]
    dual = [h.dual for h in hist]
    scale = max(1.0, abs(best[-1]))
    assert all(b2 <= b1 for b1, b2 in zip(best, best[1:], strict=False))
    assert all(d2 >= d1 - 1e-6 * scale for d1, d2 in zip(dual, dual[1:], strict=False))
    assert hist[-1].gap <= 1e-5 * scale
    assert all(h.gap >= -1e-6 * scale for h in hist)  # dual never passes primal


def test_multiclass_matches_linearsvc_crammer_singer():
    rng = np.random.default_rng(0)
    n, d, k = 80, 6, 4
    centers = rng.normal(scale=2.0, size=(k, d))
    y = rng.integers(k, size=n)
    X = centers[y] + rng.normal(size=(n, d))
    C = 0.3
    ssvm = CuttingPlaneSSVM(MulticlassModel(d, k), C=C, tol=1e-7, max_iter=5000).fit(list(X), list(y))
    svc = LinearSVC(multi_class="crammer_singer", fit_intercept=False, C=C, tol=1e-10, max_iter=200000).fit(X, y)
    w_svc = svc.coef_.ravel()

    def objective(w):
        scores = X @ w.reshape(k, d).T
        margins = scores + 1.0 - np.eye(k)[y]
        return 0.5 * w @ w + C * np.sum(margins.max(axis=1) - scores[np.arange(n), y])

    assert objective(ssvm.w_) == pytest.approx(objective(w_svc), rel=1e-3)
    assert ssvm.primal_objective_ == pytest.approx(objective(ssvm.w_), rel=1e-9)
    assert np.linalg.norm(ssvm.w_ - w_svc) <= 1e-3 * np.linalg.norm(w_svc)


def test_bad_arguments_are_refused(toy):
    model, X, Y = toy
    with pytest.raises(ValueError, match="C must be positive"):
        CuttingPlaneSSVM(model, C=0).fit(X, Y)
    with pytest.raises(ValueError, match="examples"):
        CuttingPlaneSSVM(model).fit(X, Y[:-1])
    with pytest.raises(ValueError, match="n_slacks"):
        CuttingPlaneSSVM(model, n_slacks=-1).fit(X, Y)


def _gap(ssvm) -> float:
    return ssvm.primal_objective_ - ssvm.dual_objective_


@pytest.mark.parametrize("C_from, C_to", [(1.0, 1.0), (0.3, 3.0), (3.0, 0.3)])
def test_a_warm_start_reaches_the_same_certified_gap_and_weights_within_its_bound(toy, C_from, C_to):
    """The primal is 1-strongly convex, so a fit whose primal is within g of the dual is within sqrt(2 g) of the
    optimum: a warm and a cold fit lie within the sum of their bounds of each other, whatever their paths."""
    model, X, Y = toy
    X, Y = X * 3, Y * 3  # 36 examples: more cuts than iterations
    neighbour = CuttingPlaneSSVM(model, C=C_from, tol=1e-4, n_slacks=0).fit(X, Y)
    cold = CuttingPlaneSSVM(model, C=C_to, tol=1e-4, n_slacks=0).fit(X, Y)
    warm = CuttingPlaneSSVM(model, C=C_to, tol=1e-4, n_slacks=0).fit(X, Y, warm_start=neighbour.cuts_)
    for fit in (cold, warm):
        assert fit.converged_
        assert _gap(fit) <= 1e-4 * max(1.0, fit.primal_objective_)
    bound = np.sqrt(2 * _gap(cold)) + np.sqrt(2 * _gap(warm))
    assert np.linalg.norm(warm.w_ - cold.w_) <= bound
    assert warm.n_iter_ <= cold.n_iter_
    if C_from == C_to:
        assert warm.n_iter_ == 1  # the neighbour's optimum is certified at once


def test_a_warm_start_on_more_examples_starts_from_the_first_ones(toy):
    model, X, Y = toy
    first = CuttingPlaneSSVM(model, C=1.0, tol=1e-4, n_slacks=0).fit(X[:8], Y[:8])
    more = CuttingPlaneSSVM(model, C=1.0, tol=1e-4, n_slacks=0).fit(X, Y, warm_start=first.cuts_)
    cold = CuttingPlaneSSVM(model, C=1.0, tol=1e-4, n_slacks=0).fit(X, Y)
    assert more.converged_
    assert np.linalg.norm(more.w_ - cold.w_) <= np.sqrt(2 * _gap(more)) + np.sqrt(2 * _gap(cold))
    assert more.cuts_.n_examples == len(X) and set(more.cuts_.examples) <= set(range(len(X)))


def test_a_warm_start_from_other_examples_or_grouped_slacks_is_refused(toy):
    model, X, Y = toy
    start = CuttingPlaneSSVM(model, C=1.0, n_slacks=0).fit(X, Y).cuts_
    relabelled = [(2 - a, b) for a, b in Y]
    with pytest.raises(ValueError, match="cuts are of other examples"):
        CuttingPlaneSSVM(model, C=1.0, n_slacks=0).fit(X, relabelled, warm_start=start)
    with pytest.raises(ValueError, match="cuts are of other examples"):
        CuttingPlaneSSVM(model, C=1.0, n_slacks=0).fit(X[:5], Y[:5], warm_start=start)
    with pytest.raises(ValueError, match="one slack per example"):
        CuttingPlaneSSVM(model, C=1.0, n_slacks=3).fit(X, Y, warm_start=start)
    assert CuttingPlaneSSVM(model, C=1.0, n_slacks=3).fit(X, Y).cuts_ is None  # grouped cuts mix examples


def test_seeded_weights_scaled_to_a_smaller_C_stay_within_every_budget(toy):
    model, X, Y = toy
    start = CuttingPlaneSSVM(model, C=10.0, tol=1e-4, n_slacks=0).fit(X, Y).cuts_
    for C in (10.0, 1.0, 0.1, 1 / 3):
        alpha = start.alpha_at(C, len(X))
        budget = np.zeros(len(X))
        np.add.at(budget, start.examples, alpha)
        assert np.all(alpha >= 0) and np.all(budget <= C)


def test_a_working_set_refuses_an_infeasible_seed():
    ws = WorkingSet(dim=2, n_groups=2, C=1.0)
    rows = np.array([[1.0, 0.0], [0.0, 1.0]])
    with pytest.raises(ValueError, match="at most C"):
        ws.seed(rows, np.ones(2), np.array([0, 0]), np.array([0.7, 0.7]))
    ws.seed(rows, np.ones(2), np.array([0, 1]), np.array([0.7, 0.7]))
    assert np.allclose(ws.w, [0.7, 0.7]) and ws.dual() == pytest.approx(1.4 - 0.49)
    with pytest.raises(ValueError, match="empty"):
        ws.seed(rows, np.ones(2), np.array([0, 1]), np.array([0.1, 0.1]))
